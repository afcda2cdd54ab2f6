"""Development study: the limbs' curves moved onto the silhouettes' centre lines
(:mod:`topopose.frame.centre`) and the full skeleton's MPJPE, with it and without it, per
camera set-up (``benchmarks/tracking.py``'s ``8``, ``4p``, ``4pd``) on development sequences.

    python studies/centre_dev.py --work DIR [--seeds 41,42,51,52] [--setups 8,4p,4pd]
                                    [--frames 40] [--variants off,on] [--out benchmarks/results]

One per-frame run per sequence (as ``tracking.py --bias``: AHA threshold and confidence gate
off, ``centre=True``: the offsets recorded, nothing else changes), cached in ``--work``; the
motion stage (tracking, trim, the kinematic fit) per variant: ``off`` the curves as the hull
gives them (:data:`topopose.sequence.kinematic_fit.CENTRED` False), ``on`` centred; other variants
change :mod:`topopose.frame.centre`'s settings (``NAME=value`` joined by ``+``: they need the
per-frame run again, cached per variant). MPJPE (the issue's joints) median over the frames
whose per-frame pose is right (``evaluate``: good), per joint the median error; ms per frame
of the centring. Never the held-out seeds. Writes ``centre_dev.md`` / ``.json``.
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
from _machine import machine, machine_line  # noqa: E402

from topopose.capture import load_capture  # noqa: E402
from topopose.frame import centre as C  # noqa: E402
from topopose.sequence import kinematic_fit as kf  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.batch.quality import evaluate  # noqa: E402
from topopose.sequence.track import track  # noqa: E402

JOINTS = ("neck", "shoulder", "elbow", "wrist", "hip", "knee", "ankle")


def settings(variant) -> dict:
    """``NAME=value+NAME=value`` → {NAME: value} (centre module settings); {} for off / on."""
    if variant in ("off", "on"):
        return {}
    out = {}
    for kv in variant.split("+"):
        k, v = kv.split("=")
        out[k] = float(v)
    return out


def per_frame(work, motion, seed, build, frames, model, setup, variant):
    """The per-frame results (cached) of one sequence with ``centre`` recorded."""
    d = T.make_sequence(work, motion, seed, build, frames, setup)
    s = settings(variant)
    tag = "" if not s else "_" + variant.replace("=", "").replace("+", "_")
    f = Path(d) / f"centre_poses{tag}.pkl"
    cap = load_capture(d)
    if f.exists():
        return cap, pickle.loads(f.read_bytes())
    old = {k: getattr(C, k) for k in s}
    try:
        for k, v in s.items():
            setattr(C, k, type(old[k])(v))
        res = run(cap, model=model, resolution=100, progress=False, track=False, sides=False,
                  skeleton=False, threshold=1e9, gate=False, centre=True)
    finally:
        for k, v in old.items():
            setattr(C, k, v)
    f.write_bytes(pickle.dumps(res.poses))
    return cap, res.poses


def measure(cap, poses, model, centred, **options):
    """MPJPE (median, per joint) of the fit over the good frames, with or without centring
    (and other sequence ``options``)."""
    fitted, tree, _ = kf.fit_sequence(track(poses, model), model, centred=centred, **options)
    good = {fs.frame for fs in evaluate(cap.gt, poses, model=model).frames
            if fs.quality == "good"}
    errs = []
    for p in fitted:
        if not (p.matched and p.joints) or p.diagnostics.get("interpolated") \
                or p.frame not in good:
            continue
        P = np.array([p.joints[n] for n in tree.names])
        errs.append(T.joint_errors(tree.names, P, cap.gt["frames"][p.frame]["joints"]))
    m = T.mpjpe(errs)
    return {"mpjpe": m[0], "per_joint": m[1], "frames": m[2], "per_frame": m[3],
            "joint_errors": m[4]}


def report(rows, setups, variants, info) -> str:
    lines = ["# Limb curves on the silhouettes' centre lines (development seeds)", "",
             machine_line(info), "",
             "Per set-up: the full skeleton's MPJPE (cm; median over the good frames of the "
             "per-frame mean over the issue's joints, pooled over the sequences), per joint "
             "(median cm), and the centring's cost (ms per frame, mean). `off`: the hull's "
             "curves; `on`: the limbs' curves centred (`pose/centre.py`).", "",
             "| set-up | variant | frames | MPJPE | " + " | ".join(JOINTS) + " | ms/frame |",
             "|---|---|---|---|" + "---|" * len(JOINTS) + "---|"]
    for st in setups:
        for v in variants:
            rs = [r for r in rows if r["setup"] == st and r["variant"] == v]
            if not rs:
                continue
            pf = [x for r in rs for x in r["per_frame"]]
            pj = {}
            for r in rs:
                for k, e in r["joint_errors"].items():
                    pj.setdefault(k, []).extend(e)
            ms = np.mean([r["ms"] for r in rs])
            lines.append(f"| {st} | {v} | {len(pf)} | {100 * np.median(pf):.2f} | "
                         + " | ".join(f"{100 * np.median(pj[j]):.1f}" if j in pj else "–"
                                      for j in JOINTS) + f" | {ms:.1f} |")
    lines += ["", "Per sequence (MPJPE cm):", "",
              "| set-up | sequence | " + " | ".join(variants) + " |",
              "|---|---|" + "---|" * len(variants)]
    for st in setups:
        seqs = sorted({(r["motion"], r["seed"]) for r in rows if r["setup"] == st})
        for mo, sd in seqs:
            vals = []
            for v in variants:
                r = [r for r in rows if (r["setup"], r["motion"], r["seed"], r["variant"])
                     == (st, mo, sd, v)]
                vals.append(f"{100 * r[0]['mpjpe']:.2f}" if r and r[0]["mpjpe"] else "–")
            lines.append(f"| {st} | {mo} {sd} | " + " | ".join(vals) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True)
    ap.add_argument("--seeds", default="41,42,51,52")
    ap.add_argument("--setups", default="8,4p,4pd")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--variants", default="off,on")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--name", default="centre_dev")
    a = ap.parse_args(argv)
    model = load_model("human")
    keep = {int(x) for x in a.seeds.split(",")}
    seqs = [s for s in T.DEV_SEQUENCES if s[1] in keep]
    setups, variants = a.setups.split(","), a.variants.split(",")
    rows = []
    for st in setups:
        for motion, seed, build in seqs:
            for v in variants:
                cap, poses = per_frame(a.work, motion, seed, build, a.frames, model, st,
                                       "on" if v == "off" else v)
                r = measure(cap, poses, model, v != "off")
                r.update(setup=st, motion=motion, seed=seed, variant=v,
                         ms=float(np.mean([p.timings_ms.get("centre", 0.0) for p in poses])),
                         kb=float(np.mean([len(json.dumps(
                             {k: p.diagnostics.get(k) for k in ("centred", "centred_trim")},
                             separators=(",", ":"))) for p in poses])) / 1000)
                rows.append(r)
                print(json.dumps({k: r[k] for k in ("setup", "motion", "seed", "variant",
                                                    "frames", "mpjpe", "ms", "kb")}),
                      flush=True)
    info = machine(resolution=100, subject="body", seeds=a.seeds, frames=a.frames)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{a.name}.json").write_text(json.dumps(
        {"machine": info, "rows": [{k: v for k, v in r.items() if k != "joint_errors"}
                                   for r in rows]}))
    text = report(rows, setups, variants, info)
    (out / f"{a.name}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
