"""Diagnosis of the wrong and missing-limb frames of the ``body`` subject.

For every frame of a set of ``body`` captures (builds × seeds × frames, 8 cameras, noise 1,
100³, the human model, the confidence gate off so that every frame the alignment accepts is
seen): its class at 0.08 × height, and for every part its error relative to the tolerance and
its offset from the ground-truth segment in the body's own frame (*up*: crotch → neck base;
*left*: right hip → left hip; *front*: left × up). A wrong part is called

- *near miss* when its error is below 1.5 × the tolerance (a systematic offset),
- *wrong branch* otherwise (it sits on another limb, or a spur).

Writes benchmarks/results/diagnose_body.{md,json} (and, with ``--pictures``, typical failures as
PNG). ``--seeds`` defaults to training seeds (41, 42), not the held-out 21, 22 of quality.py.

    python studies/diagnose_body.py [--seeds 41,42] [--frames 12] [--pictures N] [--tag T]
                                        [--option key=value ...]
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import results_dir  # noqa: E402
from pipeline import machine  # noqa: E402
from quality import BODY_BUILDS, BODY_TOLERANCE, body_captures  # noqa: E402


def body_frame(gt_frame):
    """(up, left, front) unit vectors of the body in one gt frame."""
    s, j = gt_frame["segments"], gt_frame["joints"]
    up = np.asarray(s["torso"][0], float) - np.mean(np.asarray(s["crotch"], float), axis=0)
    up /= np.linalg.norm(up)
    left = np.asarray(j["LeftUpLeg_head"], float) - np.asarray(j["RightUpLeg_head"], float)
    left -= (left @ up) * up
    left /= np.linalg.norm(left)
    return up, left, np.cross(left, up)


def offset(p, seg):
    """Vector from the nearest point of segment ``seg`` to ``p``."""
    a, b = (np.asarray(x, float) for x in seg)
    ab = b - a
    t = float(np.clip((p - a) @ ab / (ab @ ab), 0, 1)) if ab @ ab > 0 else 0.0
    return np.asarray(p, float) - (a + t * ab)


def run(caps, options, pictures=0, tag=""):
    from topopose.frame import FrameEstimator
    from topopose.pose import load_model
    from topopose.batch.quality import evaluate

    model = load_model("human")
    recs, shown = [], Counter()
    for cap in caps:
        est = FrameEstimator(cap, "human", 100, gate=False, **options)
        h = cap.gt["height"]
        tol = BODY_TOLERANCE * h
        for f in cap.frames:
            pose, det = est.estimate(f, detail=True)
            ev = evaluate(cap.gt, [pose], model=model, tolerance=tol, junction_factor=1.0)
            fs = ev.frames[0]
            g = cap.gt["frames"][f]
            up, left, front = body_frame(g)
            parts = {}
            for p, gp in fs.assignment.items():
                x = pose.parts.get(p)
                if x is None:
                    parts[p] = None
                    continue
                o = offset(np.asarray(x, float), g["segments"][gp])
                parts[gp] = {"ratio": fs.errors[p] / tol,
                             "up": float(o @ up) / h, "left": float(o @ left) / h,
                             "front": float(o @ front) / h}
            rec = {"capture": (cap.gt["synth"].get("build") or {}).get("name"),
                   "seed": cap.gt["synth"].get("seed"), "frame": f,
                   "separated": bool(g.get("separated")), "status": pose.status,
                   "quality": fs.quality, "parts": parts, "height": h,
                   "distance": pose.distance, "error": pose.error,
                   "missing": (pose.diagnostics or {}).get("missing"),
                   "confidence": (pose.diagnostics or {}).get("confidence"),
                   "features": (pose.diagnostics or {}).get("confidence_features")}
            recs.append(rec)
            if pictures and rec["quality"] in ("misplaced", "missing limb") \
                    and shown[rec["quality"]] < pictures and pose.status == "matched":
                from topopose.viz.view import render_frame

                shown[rec["quality"]] += 1
                wrong = [p for p, v in parts.items() if v is None or v["ratio"] > 1]
                name = f"diagnose_body{tag}_{rec['quality'].replace(' ', '_')}{shown[rec['quality']]}"
                render_frame(results_dir() / f"{name}.png", model, pose, det, cap=cap,
                             title=f"body {rec['capture']} seed {rec['seed']} frame {f}: "
                                   f"{rec['quality']} ({', '.join(wrong)})")
    return recs


def summarize(recs):
    """Counts of failing parts, near misses and wrong branches, and the median offset of every
    part in body coordinates (× height) over the matched frames."""
    out = {}
    matched = [r for r in recs if r["status"] == "matched"]
    out["classes"] = dict(Counter(r["quality"] for r in matched))
    fail = Counter()
    near = Counter()
    hist = {}
    missing = Counter()
    for r in matched:
        for p, v in r["parts"].items():
            if v is None:
                if r["quality"] == "missing limb":
                    missing[p] += 1
                continue
            if v["ratio"] > 1:
                fail[p] += 1
                near[p] += v["ratio"] < 1.5
                hist.setdefault(p, []).append(v["ratio"])
    out["wrong_part"] = dict(fail)
    out["near_miss"] = dict(near)
    out["missing_part"] = dict(missing)
    bins = [1, 1.25, 1.5, 2, 3, 5, 100]
    out["ratio_histogram"] = {p: np.histogram(x, bins)[0].tolist() for p, x in hist.items()}
    out["histogram_bins"] = bins
    off = {}
    for p in ("head", "torso", "crotch"):
        v = [r["parts"][p] for r in matched if r["parts"].get(p)]
        right = [x for x in v if x["ratio"] <= 1]
        off[p] = {k: float(np.median([x[k] for x in right])) for k in ("up", "left", "front")} \
            if right else None
        off[p + " (wrong)"] = {k: float(np.median([x[k] for x in v if x["ratio"] > 1]))
                               for k in ("up", "left", "front")} if any(x["ratio"] > 1 for x in v) else None
    out["median_offset_height"] = off
    # frames with exactly one wrong part, just beyond tolerance
    out["one_part_near_miss_frames"] = sum(
        1 for r in matched if r["quality"] == "misplaced"
        and sum(1 for v in r["parts"].values() if v and v["ratio"] > 1) == 1
        and max(v["ratio"] for v in r["parts"].values() if v) < 1.5)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="41,42")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--pictures", type=int, default=0)
    ap.add_argument("--tag", default="")
    ap.add_argument("--option", action="append", default=[],
                    help="FrameEstimator option key=value (Python literal)")
    a = ap.parse_args()
    import ast
    options = {k: ast.literal_eval(v) for k, v in (o.split("=", 1) for o in a.option)}
    seeds = tuple(int(s) for s in a.seeds.split(","))
    res = {}
    for sep in (True, False):
        caps = body_captures(sep, 1, seeds, a.frames, BODY_BUILDS)
        recs = run(caps, options, a.pictures if sep else 0, a.tag)
        key = "separated" if sep else "all poses"
        res[key] = {"summary": summarize(recs), "frames": recs}
        print(key, json.dumps(res[key]["summary"], indent=1))
    out = results_dir()
    name = f"diagnose_body{a.tag}"
    (out / f"{name}.json").write_text(json.dumps(
        {"machine": machine(), "seeds": seeds, "options": options, **res},
        separators=(",", ":")))
    L = [f"# Diagnosis of the body subject's failures", "",
         f"Seeds {', '.join(map(str, seeds))} × builds {', '.join(BODY_BUILDS)} × {a.frames} "
         f"frames, 8 cameras, noise 1, 100³, gate off, options {options or 'default'}; "
         "matched frames only. Ratio: error / (0.08 × height). Offsets: median, × height, in the "
         "body's frame (up, left, front).", ""]
    for key, r in res.items():
        s = r["summary"]
        L += [f"## {key}", "", f"classes (matched): {s['classes']}", "",
              f"wrong part (frames): {s['wrong_part']}; of them near misses (< 1.5 × tolerance): "
              f"{s['near_miss']}; misplaced frames with a single near miss: "
              f"{s['one_part_near_miss_frames']}", "",
              f"missing part of the missing-limb frames: {s['missing_part']}", "",
              "| wrong part | " + " | ".join(f"{a}–{b}" for a, b in
                                            zip(s["histogram_bins"], s["histogram_bins"][1:])) + " |",
              "|---|" + "---:|" * (len(s["histogram_bins"]) - 1)]
        for p, hcount in s["ratio_histogram"].items():
            L.append(f"| {p} | " + " | ".join(map(str, hcount)) + " |")
        L += ["", "| part | up | left | front |", "|---|---:|---:|---:|"]
        for p, o in s["median_offset_height"].items():
            if o:
                L.append(f"| {p} | {o['up']:+.3f} | {o['left']:+.3f} | {o['front']:+.3f} |")
        L.append("")
    (out / f"{name}.md").write_text("\n".join(L) + "\n")
    print(f"wrote {out / name}.md")


if __name__ == "__main__":
    main()
