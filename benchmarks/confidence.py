"""Calibrate the minimum confidence that decides ``matched`` (topopose.pose.confidence) on
synthetic captures only: the capsule human, 4 and 8 cameras, silhouette noise 1, walking and
random poses, several seeds. For each candidate minimum: precision of ``matched`` (share of
matched frames whose quality is "good", every part within tolerance) and share matched.

    python benchmarks/confidence.py [--frames 20] [--seeds 2]
"""
from __future__ import annotations

import argparse
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
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--seeds", type=int, default=2)
    a = ap.parse_args(argv)
    rows = []
    for cams in (4, 8):
        for motion in ("walk", "random"):
            for seed in range(a.seeds):
                cap = synthetic_capture("human", frames=a.frames, seed=seed, cameras=cams,
                                        noise=1, motion=motion)
                est = FrameEstimator(cap, "human", 100, gate=False)
                poses = [est.estimate(f) for f in cap.frames]
                temporal_confidence(poses, {f: i for i, f in enumerate(cap.frames)}, gate=False)
                ev = evaluate(cap.gt, poses, model=est.model)
                for p, s in zip(poses, ev.frames):
                    if p.status == "failed":
                        continue
                    rows.append({"cameras": cams, "motion": motion, "seed": seed,
                                 "status": p.status, "good": s.quality == "good",
                                 "confidence": p.diagnostics.get("confidence", 0.0)})
    out = {"machine": machine(), "frames": len(rows), "table": []}
    for c in (0.0, 0.1, 0.2, 0.3, 0.35, 0.4, 0.5, 0.6):
        m = [r for r in rows if r["status"] == "matched" and r["confidence"] >= c]
        prec = sum(r["good"] for r in m) / len(m) if m else None
        out["table"].append({"min_confidence": c, "matched": len(m),
                             "precision": None if prec is None else round(prec, 3)})
    good = [r for r in rows if r["good"]]
    out["good_frames"] = len(good)
    (HERE / "results" / "confidence.json").write_text(json.dumps(out, indent=1))
    L = ["# Calibrating the minimum confidence (synthetic capsule human only)", "",
         f"{len(rows)} processed frames (4 and 8 cameras × walk/random × {a.seeds} seeds × "
         f"{a.frames} frames, noise 1, 100³), {len(good)} good. Machine: "
         f"{out['machine']['cpu']}, {out['machine']['date']}.", "",
         "| min confidence | matched | precision of matched |", "| --- | --- | --- |"]
    for t in out["table"]:
        L.append(f"| {t['min_confidence']} | {t['matched']} | {t['precision']} |")
    (HERE / "results" / "confidence.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
