"""Development study: the joints of a part not found over time (held from the last
fitted frame, hand hints) on the development
sequences of ``benchmarks/tracking.py`` (walks 41–46, random motion 51–56, unrelated random
poses 21–32), the per-frame results cached (``--work``), only the sequence stage re-run.

    python studies/held_dev.py --work DIR [--only walk|random-smooth|random] [--seeds 51,52]
                                  [--stage frames|variants] [--variants base,hold3,...]
                                  [--out benchmarks/results]

Prints, per variant and motion, the median over the sequences' pooled frames of the MPJPE of
the fit (tracking.py's figure, gate on) and of the frames holding joints. Never the held-out
seeds. Writes ``tracking_held_dev.md`` / ``.json`` (all three motions and every variant only).
"""
import argparse
import json
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import tracking as T  # noqa: E402
from _machine import machine  # noqa: E402

from topopose.capture import load_capture  # noqa: E402
from topopose.sequence import kinematic_fit as kf  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.sequence.track import track  # noqa: E402


def frames(work, motion, seed, build, n, model):
    """The per-frame result of one development sequence (gate on), cached in ``work``."""
    d = T.make_sequence(work, motion, seed, build, n)
    f = d / "raw.pkl"
    if not f.exists():
        res = run(load_capture(d), model=model, resolution=100, output=d / "poses.jsonl",
                  progress=False, track=False, sides=False, skeleton=False, gate=True)
        f.write_bytes(pickle.dumps(res.poses))
    return d, pickle.loads(f.read_bytes())


def score(fitted, tree, gt):
    """Per-frame MPJPE errors of the fit (all fitted frames, those holding joints)."""
    err, held = [], []
    for p in fitted:
        if not (p.matched and p.joints) or p.diagnostics.get("interpolated"):
            continue
        P = np.array([p.joints[n] for n in tree.names])
        e = T.joint_errors(tree.names, P, gt["frames"][p.frame]["joints"])
        err.append(e)
        if p.diagnostics.get("held_joints"):
            held.append(e)
    return err, held


VARIANTS = {}


def variant(name):
    def deco(f):
        VARIANTS[name] = f
        return f
    return deco


@variant("base")
def _base(tracked, model):
    return kf.fit_sequence(tracked, model)


def _with(**options):
    """A variant: fit_sequence with these sequence options (``SequenceOptions`` fields)."""
    def f(tracked, model):
        return kf.fit_sequence(tracked, model, **options)
    return f


# HOLD_FRAMES 3 was the default before these runs
VARIANTS["hold3"] = _with(hold_frames=3)
for _h in (10, 15):
    VARIANTS[f"hold{_h}"] = _with(hold_frames=_h)
VARIANTS["nohint"] = _with(hints=False)
VARIANTS["hold3_nohint"] = _with(hold_frames=3, hints=False)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", required=True)
    ap.add_argument("--only", default=None)
    ap.add_argument("--seeds", default=None)
    ap.add_argument("--stage", default="variants", choices=("frames", "variants"))
    ap.add_argument("--variants", default=None)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args(argv)
    model = load_model("human")
    seqs = [s for s in T.DEV_SEQUENCES if (a.only is None or s[0] == a.only)
            and (a.seeds is None or s[1] in {int(x) for x in a.seeds.split(",")})]
    names = a.variants.split(",") if a.variants else list(VARIANTS)
    res = {}
    for motion, seed, build in seqs:
        n = {"walk": 40}.get(motion, 60)
        d, raw = frames(a.work, motion, seed, build, n, model)
        if a.stage == "frames":
            print(motion, seed, "cached", flush=True)
            continue
        gt = load_capture(d).gt
        tracked = track(raw, model)
        for v in names:
            fitted, tree, _ = VARIANTS[v](tracked, model)
            err, held = score(fitted, tree, gt)
            r = res.setdefault(v, {}).setdefault(motion, {"all": [], "held": [], "seq": []})
            m, mh = T.mpjpe(err), T.mpjpe(held)
            r["all"] += m[3]
            r["held"] += mh[3]
            r["seq"].append(m[0])
        print(motion, seed, {v: round(100 * res[v][motion]["seq"][-1], 2) for v in names},
              flush=True)
    lines = []
    for v in names:
        for motion, r in res.get(v, {}).items():
            lines.append(f"| {v} | {motion} | {100 * np.median(r['all']):.2f} | "
                         f"{100 * np.median(r['held']):.2f} ({len(r['held'])}) | "
                         + " / ".join(f"{100 * x:.2f}" for x in r["seq"]) + " |")
            print(lines[-1], flush=True)
    Path(a.work, "held_dev.json").write_text(json.dumps(
        {v: {m: {k: list(map(float, x)) for k, x in r.items()} for m, r in rv.items()}
         for v, rv in res.items()}))
    if a.stage == "variants" and a.only is None and a.seeds is None and a.variants is None:
        info = machine(resolution=100, cameras=8, noise=1, subject="body", confidence_gate=True)
        md = ["# Held joints over time on the development sequences", "",
              f"Machine: {info['cpu']}, {info['cores']} cores, load {info['load_average']}, "
              f"{info['date']}. Produced by `studies/held_dev.py` (development seeds of "
              "`tracking.py --dev`: walks 41–46, random motion 51–56, unrelated random poses "
              "21–32; gate on; per-frame results cached, the sequence stage re-run per variant).",
              "", "Variants (kinematic_fit's defaults otherwise): `base` the defaults "
              "(`HOLD_FRAMES` 5, kept from these runs); `holdN` `HOLD_FRAMES` N (`hold3`: the "
              "default before); `nohint` "
              "`HAND_HINTS` off.", "",
              "| variant | motion | MPJPE median (cm) | frames holding joints (cm, frames) | "
              "per sequence (cm) |", "|---|---|---|---|---|"] + lines
        out = Path(a.out)
        (out / "tracking_held_dev.md").write_text("\n".join(md) + "\n")
        (out / "tracking_held_dev.json").write_text(json.dumps(
            {"machine": info, "variants": {v: {m: {k: list(map(float, x)) for k, x in r.items()}
                                               for m, r in rv.items()} for v, rv in res.items()}}))


if __name__ == "__main__":
    main()
