"""Development study: the trunk joints (neck, shoulders, hips, pelvis) of the kinematic
skeleton on 8 cameras against 4 phone-like cameras (``tracking.py``'s set-ups ``8``, ``4p``,
``4pd``), with the hull radius the hips' ``width`` is scaled by beside the truth's half hip
width.

    python studies/trunk_dev.py --work DIR [--setups 8,4p,4pd] [--seeds 41,...,56]
                                   [--walk-frames 40] [--frames 30] [--variants base,...]
                                   [--out benchmarks/results]

The per-frame results (as ``tracking.bias_sequence``: AHA threshold and gate off) are cached in
``--work`` (a few seconds per sequence), the sequence stage alone re-run per variant (a
``kinematic_fit`` constant set: ``NAME=value``, Python literal). Per set-up and variant: MPJPE
median over the good frames (the per-frame pose right) and over all matched frames, per joint;
the trunk joints' signed bias (outward / forward / up, truth's body frame, median) and the
median absolute of each component; hip and shoulder widths ours / truth. Per sequence: the
hull radius (the spine shift's length, median over frames) against the truth's half hip width,
and the hull fatness (litres / height³). Development seeds only (walks 41–46, random motion
51–56, unrelated random poses 21–32); writes ``trunk_dev.md``.
"""
import argparse
import ast
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import tracking as T  # noqa: E402
from _machine import machine, machine_line  # noqa: E402

from topopose.capture import load_capture  # noqa: E402
from topopose.sequence import kinematic_fit as kf  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.batch.quality import evaluate  # noqa: E402
from topopose.sequence.track import track  # noqa: E402

JOINTS = ("neck", "shoulder", "hip", "pelvis", "elbow", "wrist", "knee", "ankle")
TRUNK = ("neck", "shoulder", "hip", "pelvis")


def cached(work, setup, motion, seed, build, n, model):
    """The per-frame results of one sequence (cached in ``work``)."""
    f = Path(work) / f"poses_{setup}_{motion}_{seed}.pkl"
    if not f.exists():
        cap = load_capture(T.make_sequence(work, motion, seed, build, n, setup))
        res = T.run(cap, model=model, resolution=100, progress=False, track=False, sides=False,
                    skeleton=False, threshold=1e9, gate=False)
        good = {fs.frame for fs in evaluate(cap.gt, res.poses, model=model).frames
                if fs.quality == "good"}
        f.write_bytes(pickle.dumps({"poses": res.poses, "good": good, "gt": cap.gt,
                                    "up": cap.up_vector, "seed": seed, "build": build,
                                    "motion": motion}))
    return pickle.loads(f.read_bytes())


def score(d, consts, model):
    """Errors, trunk biases and widths of one sequence's fit with the sequence options
    ``consts`` (``SequenceOptions`` field names)."""
    fitted, tree, _ = kf.fit_sequence(track(d["poses"], model), model, **consts)
    out = {"good": [], "all": [], "bias": {}, "hip width": [], "shoulder width": []}
    for p in fitted:
        if not (p.matched and p.joints) or p.diagnostics.get("interpolated"):
            continue
        gj = d["gt"]["frames"][p.frame]["joints"]
        P = np.array([p.joints[n] for n in tree.names])
        e = T.joint_errors(tree.names, P, gj)
        out["all"].append(e)
        if p.frame in d["good"]:
            out["good"].append(e)
            b, ln = T.joint_bias(tree.names, P, gj, d["up"])
            for k, x in b.items():
                out["bias"].setdefault(k, []).extend(x)
            for k in ("hip width", "shoulder width"):
                if k in ln:
                    out[k].append(ln[k][0] / ln[k][1])
    return out


def row(rs, key):
    errs = [e for r in rs for e in r[key]]
    if not errs:
        return ["–"] * (2 + len(JOINTS))
    frame = [np.mean([x for k, v in e.items() if k in T.MPJPE_JOINTS for x in v]) for e in errs]
    pj = {}
    for e in errs:
        for k, v in e.items():
            pj.setdefault(k, []).extend(v)
    return ([f"{100 * np.median(frame):.2f}", str(len(errs))]
            + [f"{100 * np.median(pj[k]):.1f}" if k in pj else "–" for k in JOINTS])


def geometry(d):
    """(radius, truth's half hip width, hull fatness): medians over the matched frames."""
    r = [np.linalg.norm(p.diagnostics["spine_shift"]) for p in d["poses"]
         if p.matched and p.diagnostics.get("spine_shift") is not None]
    hh = [0.5 * np.linalg.norm(np.subtract(d["gt"]["frames"][p.frame]["joints"]["LeftUpLeg_head"],
                                           d["gt"]["frames"][p.frame]["joints"]["RightUpLeg_head"]))
          for p in d["poses"] if p.matched]
    fat = [p.diagnostics["hull_litres"] / p.diagnostics["height"] ** 3 for p in d["poses"]
           if p.diagnostics.get("height")]
    return (float(np.median(r)) if r else np.nan, float(np.median(hh)) if hh else np.nan,
            float(np.median(fat)) if fat else np.nan)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True)
    ap.add_argument("--setups", default="8,4p,4pd")
    ap.add_argument("--seeds", default="41,42,43,44,45,46,51,52,53,54,55,56,"
                    "21,22,23,24,25,26,27,28,29,30,31,32")
    ap.add_argument("--walk-frames", type=int, default=40)
    ap.add_argument("--frames", type=int, default=30, help="frames of the other motions")
    ap.add_argument("--variants", default="base",
                    help="comma-separated: base, or name=value;name=value (SequenceOptions fields)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args(argv)
    model = load_model("human")
    keep = {int(x) for x in a.seeds.split(",")}
    seqs = [s for s in T.DEV_SEQUENCES if s[1] in keep]
    variants = {}
    for v in a.variants.split(","):
        variants[v] = {} if v == "base" else {
            k: ast.literal_eval(x) for k, x in (kv.split("=", 1) for kv in v.split(";"))}
    lines = ["# The trunk joints on 8 and 4 cameras (development seeds)", "",
             f"{machine_line(machine())}. Written by `studies/trunk_dev.py --setups "
             f"{a.setups} --seeds {a.seeds}` (frames per sequence as cached: below); AHA "
             "threshold and gate off. MPJPE median over frames (cm), per joint "
             "median; *good*: the frames whose per-frame pose is right; bias (out, fwd, up) "
             "and |component| medians on the good frames, truth's body frame.", "",
             "| set-up | variant | MPJPE good | n | " + " | ".join(JOINTS)
             + " | MPJPE all | n | hip width | shoulder width |",
             "|---|---|---|---|" + "---|" * len(JOINTS) + "---|---|---|---|"]
    biases, geo = [], []
    for st in a.setups.split(","):
        data = [cached(a.work, st, m, s, b, a.walk_frames if m == "walk" else a.frames, model)
                for m, s, b in seqs]
        for d in data:
            r, hh, fat = geometry(d)
            geo.append(f"| {st} | {d['motion']} {d['seed']} ({d['build']}, "
                       f"{len(d['poses'])} frames) | {100 * r:.1f} | "
                       f"{100 * hh:.1f} | {r / hh:.2f} | {fat:.1f} |")
        for v, consts in variants.items():
            rs = [score(d, consts, model) for d in data]
            g, al = row(rs, "good"), row(rs, "all")
            w = [np.median([x for r in rs for x in r[k]]) if any(r[k] for r in rs) else np.nan
                 for k in ("hip width", "shoulder width")]
            lines.append(f"| {st} | {v} | " + " | ".join(g) + f" | {al[0]} | "
                         f"{al[1]} | {w[0]:.2f} | {w[1]:.2f} |")
            b = {}
            for r in rs:
                for k, x in r["bias"].items():
                    b.setdefault(k, []).extend(x)
            biases.append(f"| {st} | {v} | " + " | ".join(
                "({:+.1f}, {:+.1f}, {:+.1f}) / ({:.1f}, {:.1f}, {:.1f})".format(
                    *(100 * np.median(b[k], axis=0)), *(100 * np.median(np.abs(b[k]), axis=0)))
                if k in b else "–" for k in TRUNK) + " |")
            print(lines[-1], flush=True)
    lines += ["", "Trunk joints' bias / |component| (cm; out, fwd, up):", "",
              "| set-up | variant | " + " | ".join(TRUNK) + " |",
              "|---|---|" + "---|" * len(TRUNK)] + biases
    lines += ["", "Hull radius (the spine shift's length) against the truth's half hip width:", "",
              "| set-up | sequence | radius (cm) | half hip (cm) | ratio | fatness |",
              "|---|---|---|---|---|---|"] + geo
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "trunk_dev.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
