"""A per-frame test against a hand in a phantom volume of the hull, chosen on
synthetic development seeds: is it possible?

    python studies/hand_depth.py [--setups 4,4p] [--dev-seeds 41,...] [--work DIR]

The real recording's wrong frames that ``run --consistency`` passes (``benchmarks/
real_hands.py``) hold a hand in a phantom volume in front of the chest: it projects inside the
silhouettes, deep inside two of the four (in front of the chest in one view, behind the back in
another). The candidate test: the deepest hand's depth in its second deepest view
(:func:`real_hands.hand_depth`: distance to the contour over the silhouette's largest inscribed
radius). Here its distribution over the frames ``run --consistency`` passes on the synthetic
4-camera walks of ``benchmarks/consistency.py`` (development seeds; right = a true positive (TP) of the quality classes),
next to the real recording's (``results/real_hands.json``, only reported). A limit is usable
only if it keeps the synthetic right frames while rejecting wrong ones.

Writes ``results/hand_depth.{md,json}``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on


def synthetic_depths(setups, seeds, frames, work) -> dict:
    """Per set-up: (depth, right) of each frame ``run --consistency`` passes."""
    import consistency as CB
    import real_hands as RH
    from topopose.synth.capture import synthetic_capture
    from topopose.pose.model import load_model

    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    out = {}
    for setup in setups:
        rows = []
        for seed in seeds:
            poses, gt = CB.sequence(setup, seed, frames, work)
            ps = CB.as_run(poses, model, up)
            right = CB.right_frames(ps, gt, model)
            js, _ = CB.judged(ps, model, {})
            cams, size, noise = CB.SETUPS[setup]
            cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, size=size,
                                    noise=noise, motion="walk",
                                    build=CB.BUILDS[seed % len(CB.BUILDS)])
            for p, r in zip(js, right):
                if p.status == "matched":
                    rows.append((round(RH.hand_depth(p.parts, list(cap.cameras),
                                                     cap.silhouettes(p.frame)), 3), bool(r)))
            print(f"{setup} seed {seed}: {len(rows)} passing", file=sys.stderr, flush=True)
        out[setup] = rows
    return out


def main(argv=None):
    import consistency as CB
    from _machine import machine, machine_line

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--setups", default="4,4p")
    ap.add_argument("--dev-seeds", default=",".join(map(str, CB.DEV_SEEDS)))
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--work", default=None, help="cache of the per-frame poses (consistency.py's)")
    ap.add_argument("--real-json", default=str(HERE / "results" / "real_hands.json"))
    ap.add_argument("--out", default=str(HERE / "results" / "hand_depth"))
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.dev_seeds.split(",")]
    syn = synthetic_depths(a.setups.split(","), seeds, a.frames, a.work)
    real = None
    if Path(a.real_json).is_file():
        g = json.loads(Path(a.real_json).read_text()).get("geometric") or {}
        real = {k: g.get(k, {}).get("depth", []) for k in ("right", "wrong")}
    mach = machine()
    doc = {"machine": mach, "dev_seeds": seeds, "synthetic": syn, "real": real}
    out = Path(a.out)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))

    def rng(x):
        return f"{min(x):.2f}–{max(x):.2f} (median {np.median(x):.2f})" if x else "–"
    L = ["# A hand in a phantom volume: its depth inside the silhouettes as a per-frame test", "",
         f"{machine_line(mach)}. Written by `studies/hand_depth.py`; synthetic "
         f"development seeds {seeds[0]}–{seeds[-1]}"
         + (f" (per-frame poses from the cache {a.work}, as `benchmarks/consistency.py` wrote "
            "them)" if a.work else "") + ".", "",
         "Frames `run --consistency` passes; depth: the deepest hand's distance to the contour "
         "over the silhouette's largest inscribed radius, in its second deepest view.", "",
         "| frames | right: n, depth | wrong: n, depth |", "|---|---|---|"]
    for setup, rows in syn.items():
        r = [d for d, ok in rows if ok]
        w = [d for d, ok in rows if not ok]
        L.append(f"| synthetic {setup}-camera walks, development | {len(r)}, {rng(r)} | "
                 f"{len(w)}, {rng(w)} |")
    if real:
        L.append(f"| real recording (`person`; reported only) | {len(real['right'])}, "
                 f"{rng(real['right'])} | {len(real['wrong'])}, {rng(real['wrong'])} |")
    allr = [d for rows in syn.values() for d, ok in rows if ok]
    if real and real["wrong"] and allr:
        lim = min(real["wrong"])
        keep = max(allr)
        L += ["", f"The lowest limit that keeps every right synthetic frame passing on the "
              f"development seeds ({keep:.2f}) rejects {sum(d > keep for d in real['wrong'])} "
              f"of the {len(real['wrong'])} real wrong frames; a limit low enough to reject "
              f"them all (≤ {lim:.2f}) would reject {sum(d >= lim for d in allr)} of the "
              f"{len(allr)} right synthetic frames (walking hands hang in front of the hips in "
              "the front and back views): the development seeds do not support such a test, "
              "and it is not used."]
    out.with_suffix(".md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0


if __name__ == "__main__":
    sys.exit(main())
