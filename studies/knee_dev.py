"""Development study: the knees placed by their distance from the leg curve's far end
(:func:`topopose.sequence.kinematic_fit.from_end`, :data:`~topopose.sequence.kinematic_fit.FROM_END`)
against their fraction ``at`` from the junction; the full skeleton's MPJPE per camera set-up
(``benchmarks/tracking.py``'s ``8``, ``4p``, ``4pd``) on development sequences.

    python studies/knee_dev.py --work DIR [--seeds 41,42,43,44,51,52,53] [--setups 8,4p,4pd]
                                  [--frames 40] [--variants off,knee40] [--out benchmarks/results]
                                  [--set NAME=VALUE ...]

The per-frame runs are ``centre_dev.py``'s (cached in ``--work``, the same files: a work dir
of ``centre_dev.py`` is reused); per variant the sequence stage only. Variants: ``off`` (no
joint from the end), ``JOINTpercentile`` joined by ``_`` (JOINT: knee, ankle, elbow, wrist;
e.g. ``knee40``, ``knee40_elbow50``: those joints from the end, the reference length at that
percentile; ``_w1``: from the end alone, else half-way to the place at ``at``,
``FROM_END_WEIGHT``). MPJPE over the good
frames (median), per joint the median error. ``--set``: any other
:mod:`~topopose.sequence.kinematic_fit` constant for the run (a Python literal, e.g. ``--set
"FROM_START={}"``). Never the held-out seeds. Writes ``knee_dev.md``
/ ``.json``.
"""
import argparse
import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import centre_dev as CD  # noqa: E402
import tracking as T  # noqa: E402
from _machine import machine, sequence_settings  # noqa: E402

from topopose.sequence import kinematic_fit as kf  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402


def ends(variant) -> dict:
    """``knee40_elbow50`` → {("foot", "knee"): 40.0, ("hand", "elbow"): 50.0}; ``off`` → {}."""
    if variant == "off":
        return {}
    stem = {"knee": "foot", "ankle": "foot", "elbow": "hand", "wrist": "hand"}
    return {(stem[m.group(1)], m.group(1)): float(m.group(2))
            for m in (re.fullmatch(r"([a-z]+)([0-9.]+)", tok) for tok in variant.split("_"))
            if m.group(1) != "w"}


def weight(variant, default) -> float:
    """``knee40_w1`` → 1.0; without ``w``: ``default`` (the module's ``FROM_END_WEIGHT``)."""
    for tok in variant.split("_"):
        if re.fullmatch(r"w[0-9.]+", tok):
            return float(tok[1:])
    return default


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True)
    ap.add_argument("--seeds", default="41,42,43,44,51,52,53")
    ap.add_argument("--setups", default="8,4p,4pd")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--variants", default="off,knee40_w1,knee40,knee40_elbow50")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--set", action="append", metavar="NAME=VALUE",
                    help="a sequence option (SequenceOptions field) for this run (a Python literal; "
                         "repeatable)")
    a = ap.parse_args(argv)
    settings = sequence_settings(a.set)
    model = load_model("human")
    keep = {int(x) for x in a.seeds.split(",")}
    seqs = [s for s in T.DEV_SEQUENCES if s[1] in keep]
    setups, variants = a.setups.split(","), a.variants.split(",")
    rows, old_w = [], kf.FIT.from_end_weight
    for st in setups:
        for motion, seed, build in seqs:
            cap, poses = CD.per_frame(a.work, motion, seed, build, a.frames, model, st, "on")
            for v in variants:
                r = CD.measure(cap, poses, model, True, **{
                    **settings, "from_end": ends(v), "from_end_weight": weight(v, old_w)})
                r.update(setup=st, motion=motion, seed=seed, variant=v, ms=0.0)
                rows.append(r)
                print(json.dumps({k: r[k] for k in ("setup", "motion", "seed", "variant",
                                                    "frames", "mpjpe")}), flush=True)
    info = machine(resolution=100, subject="body", seeds=a.seeds, frames=a.frames,
                   settings=settings)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "knee_dev.json").write_text(json.dumps(
        {"machine": info, "rows": [{k: v for k, v in r.items() if k != "joint_errors"}
                                   for r in rows]}))
    text = CD.report(rows, setups, variants, info).replace(
        "# Limb curves on the silhouettes' centre lines (development seeds)",
        "# Knees from the leg curve's far end (development seeds)").replace(
        "`off`: the hull's curves; `on`: the limbs' curves centred (`pose/centre.py`).",
        "The limbs' curves centred. `off`: every joint at its fraction `at` of its curve; "
        "`knee40_w1`: the knees by their distance from the leg curve's far end, the reference "
        "length the 40th percentile of the sequence's leg curves (`kinematic_fit.from_end`); "
        "`knee40` (kept): half-way between that and the place at `at` (`FROM_END_WEIGHT` 0.5); "
        "`_elbow50`: the elbows too (not kept). "
        "ms/frame: unused (0)." + "".join(f" Set: `{k} = {v}`." for k, v in settings.items()))
    (out / "knee_dev.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
