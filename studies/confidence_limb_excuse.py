"""Would a "missing-limb excuse" help the confidence gate? (measured, not shipped)

Idea: when the alignment leaves a hand (or foot) unmatched — a *missing limb* of §13.2.2, a
right frame by the issue's count — the unmatched data branch that most plausibly is that limb
should not count as spurious; re-score a rejected frame with the spurious features of
:func:`topopose.frame.confidence.frame_features` recomputed without it, at judgement time (as
``head_doubt`` does for the head), and match it when that reaches the minimum.

Offline, from the frames ``benchmarks/confidence.py`` collected
(``results/confidence.json.gz``: the calibration captures' rows, every seed, and the body
benchmark's frames, seeds 21, 22, scored by the shipped model). A row keeps its features, not
its tree, so the excused features are bounded rather than exact:

- eligible: a fitted-confidence candidate (matched, or rejected for its distance alone) below
  the minimum (8 cameras: 0.72), with a limb missing besides an unmatched head (``missing``
  minus 1 when the alignment's head features are all 0) and ≥ 1 unmatched branch; ``arm``
  variants only when the longest unmatched branch has an arm's share of the data tree
  (0.11–0.23: 1 %–99 % of the hand branch of right 8-camera calibration frames left unplaced,
  the ``drops`` rows);
- excused: ``spurious`` − 1, ``spurious_share`` − the longest branch's share,
  ``spurious_length`` → the next longest, bounded by min(longest, the rest's share) (``ub``,
  the least the excuse can do) or 0 (``zero``, the most); ``+md``: ``matched_distance`` also
  lowered by the branch's share / T_d (0.4; the branch's deletion cost if it is its weight);
- ``ceiling``: every spurious feature 0 and the distances capped (0.5 T_d, 0.3 T_d for the
  matched one) — no excuse can do more for a frame.

The attachment of the branch (at the shoulder) cannot be checked from the rows; it would not
change the misplaced frames let through below, whose unmatched branch is an arm as well.
Writes ``results/confidence_limb_excuse.{md,json}``.
"""
from __future__ import annotations

import collections
import gzip
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import machine, results_dir  # noqa: E402

from topopose.frame.confidence import (CONFIDENCE_MODEL, fitted_confidence,  # noqa: E402
                                      min_confidence_for, min_drop_for)

HALF = {"human": 3, "body": 10, "pose": 105}       # first held-out seed (benchmarks/confidence.py)
ARM = (0.11, 0.23)
TD = 0.4


def conf(f) -> float:
    return fitted_confidence(f, 1.0 - f["lost"])["confidence"]


def candidate(r) -> bool:
    e = str(r.get("error") or "")
    return r["status"] == "matched" or (e.startswith("AHA distance") and "inf" not in e)


def limb_missing(f) -> bool:
    headless = f["head_radius"] == 0 and f["head_low"] == 0 and f["head_reach"] == 0
    return f["missing"] - (1 if headless else 0) >= 1 and f["spurious"] >= 1


def excuse(f, spur="ub", md=False, arm=False, ceiling=False):
    """The features with the longest unmatched branch excused (module docstring); None when the
    frame is not eligible."""
    if not limb_missing(f):
        return None
    sl = f["spurious_length"]
    if arm and not ARM[0] <= sl <= ARM[1]:
        return None
    if ceiling:
        return {**f, "spurious": 0.0, "spurious_length": 0.0, "spurious_share": 0.0,
                "distance": min(f["distance"], 0.5),
                "matched_distance": min(f["matched_distance"], 0.3)}
    g = dict(f, spurious=f["spurious"] - 1, spurious_share=max(0.0, f["spurious_share"] - sl))
    g["spurious_length"] = min(sl, g["spurious_share"]) if spur == "ub" else 0.0
    if md:
        g["matched_distance"] = max(0.0, f["matched_distance"] - sl / TD)
    return g


VARIANTS = {"ub": {}, "ub, arm": {"arm": True}, "zero": {"spur": "zero"},
            "zero, arm": {"spur": "zero", "arm": True}, "zero +md": {"spur": "zero", "md": True},
            "zero +md, arm": {"spur": "zero", "md": True, "arm": True}, "ceiling": {"ceiling": True}}


def kind_of(r) -> str:
    a = r.get("augmented")
    return "rod" if a == "rod" else "swap" if a else "right" if r["good"] else "wrong"


def main():
    d = json.load(gzip.open(HERE.parent / "benchmarks" / "results" / "confidence.json.gz"))
    assert d["model"]["base"] == CONFIDENCE_MODEL["base"], "rows scored by another model"
    m8 = min_confidence_for(8)
    m_drop = min_drop_for(m8)
    rows8 = [r for r in d["rows"] if r["cameras"] == "8" and candidate(r)]
    doubt = [r for r in rows8 if conf(r["features"]) < m8]
    room = collections.Counter((kind_of(r), limb_missing(r["features"])) for r in doubt)
    body = [r for r in d["body_rows"] if candidate(r)]
    out = {}
    for name, kw in VARIANTS.items():
        cal = collections.Counter()
        for r in doubt:
            g = excuse(r["features"], **kw)
            if g is not None and conf(g) >= m_drop:
                seed0 = HALF["pose"] if r["motion"] in ("separated", "all") else HALF[r["subject"]]
                cal[("held out" if r["seed"] >= seed0 else "calibration", kind_of(r))] += 1
        bb = collections.Counter()
        for r in body:
            if conf(r["features"]) >= m8:
                continue
            g = excuse(r["features"], **kw)
            if g is not None and conf(g) >= m_drop:
                bb[(r["kind"], r["quality"])] += 1
        out[name] = {"calibration rows": {" / ".join(k): v for k, v in sorted(cal.items())},
                     "body 21/22": {" / ".join(k): v for k, v in sorted(bb.items())}}
    res = {"machine": machine(), "minimum": m8, "doubted 8-camera candidates":
           {f"{k} ({'limb missing' if lm else 'no limb missing'})": v
            for (k, lm), v in sorted(room.items())}, "variants": out}
    rd = results_dir()
    (rd / "confidence_limb_excuse.json").write_text(json.dumps(res, indent=1))
    lines = ["# Missing-limb excuse: frames it would let through (offline, not shipped)", "",
             "`python studies/confidence_limb_excuse.py` (module docstring: the variants). "
             f"Rows of `confidence.json.gz` (shipped model, 8 cameras, minimum {m8}); doubted "
             "candidates: " + ", ".join(f"{k} {v}" for k, v in res["doubted 8-camera candidates"]
                                        .items()) + ".", "",
             "| variant | calibration captures: let through (seed half / kind) | "
             "body benchmark 21/22: let through (poses / class) |", "| --- | --- | --- |"]
    for name, v in out.items():
        lines.append(f"| {name} | " + (", ".join(f"{k} {n}" for k, n in
                                                  v["calibration rows"].items()) or "none")
                     + " | " + (", ".join(f"{k} {n}" for k, n in v["body 21/22"].items())
                                or "none") + " |")
    lines += ["", f"Machine: {res['machine']}"]
    (rd / "confidence_limb_excuse.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
