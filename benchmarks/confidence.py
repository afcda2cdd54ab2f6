"""Calibrate the minimum confidence that decides ``matched`` (topopose.pose.confidence) on
synthetic captures only: the capsule human and the anatomical ``body``, 4 and 8 cameras,
silhouette noise 1, walking and random poses. The first half of the seeds chose the constants
(calibration), the second half checks them. For each candidate minimum: precision of
``matched`` (share of matched frames whose quality is "good", every part within tolerance).

    python benchmarks/confidence.py [--frames 15] [--seeds 4]
"""
from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def main(argv=None):
    import topopose as tp
    from _machine import machine
    from topopose.capture.synth import synthetic_capture
    from topopose.pose.confidence import temporal_confidence
    from topopose.pose.estimate import FrameEstimator
    from topopose.pose.quality import evaluate

    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--subjects", default="human,body")
    a = ap.parse_args(argv)
    rows = []
    for subject in a.subjects.split(","):
        for cams, motion, seed in itertools.product((4, 8), ("walk", "random"), range(a.seeds)):
            cap = synthetic_capture(subject, frames=a.frames, seed=seed, cameras=cams,
                                    noise=1, motion=motion)
            est = FrameEstimator(cap, "human", 100, gate=False)
            poses = [est.estimate(f) for f in cap.frames]
            temporal_confidence(poses, {f: i for i, f in enumerate(cap.frames)}, gate=False)
            ev = evaluate(cap.gt, poses, model=est.model)
            for p, s in zip(poses, ev.frames):
                if p.status == "failed":
                    continue
                dg = p.diagnostics
                rows.append({"subject": subject, "cameras": cams, "motion": motion,
                             "seed": seed, "frame": p.frame,
                             "status": p.status, "good": s.quality == "good",
                             "quality": s.quality, "distance": p.distance,
                             "confidence": dg.get("confidence", 0.0),
                             "factors": dg.get("confidence_factors"),
                             "litres": dg.get("hull_litres"), "height": dg.get("height"),
                             "leaves": dg.get("data_leaves"),
                             "share": dg.get("largest_share")})
    out = {"machine": machine(), "frames": len(rows), "table": [], "rows": rows}
    half = max(1, a.seeds // 2)
    for part, sel in (("calibration (seeds < %d)" % half, lambda r: r["seed"] < half),
                      ("check (seeds ≥ %d)" % half, lambda r: r["seed"] >= half)):
        for c in (0.0, 0.3, 0.5, 0.6, 0.7, 0.8):
            m = [r for r in rows if sel(r) and r["status"] == "matched" and r["confidence"] >= c]
            by = {}
            for key in itertools.product(a.subjects.split(","), ("walk", "random")):
                ms = [r for r in m if (r["subject"], r["motion"]) == key]
                by["/".join(key)] = (len(ms), round(sum(r["good"] for r in ms) / len(ms), 3)
                                     if ms else None)
            prec = sum(r["good"] for r in m) / len(m) if m else None
            out["table"].append({"seeds": part, "min_confidence": c, "matched": len(m),
                                 "good": sum(r["good"] for r in rows if sel(r)),
                                 "precision": None if prec is None else round(prec, 3),
                                 "by_subject": by})
    good = [r for r in rows if r["good"]]
    out["good_frames"] = len(good)
    (HERE / "results" / "confidence.json").write_text(json.dumps(out, indent=1))
    L = ["# Calibrating the minimum confidence (synthetic subjects only)", "",
         f"{len(rows)} processed frames ({a.subjects}; 4 and 8 cameras × walk/random × {a.seeds} seeds × "
         f"{a.frames} frames, noise 1, 100³), {len(good)} good. Machine: "
         f"{out['machine']['cpu']}, {out['machine']['date']}.", "",
         "| seeds | min confidence | matched (good frames) | precision of matched | "
         "per subject/motion (matched, precision) |", "| --- | --- | --- | --- | --- |"]
    for t in out["table"]:
        L.append(f"| {t['seeds']} | {t['min_confidence']} | {t['matched']} ({t['good']}) | "
                 f"{t['precision']} | {t['by_subject']} |")
    (HERE / "results" / "confidence.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
