"""Masks read reduced to the resolution the grid needs (``FrameEstimator(mask_resolution=…)``)
against the full masks, on synthetic captures with ground truth at two image sizes.

    python studies/mask_resolution.py [--frames N] [--out PREFIX]

Per setting: the reduction factors per camera, the frames' quality classes
(:func:`topopose.batch.quality.evaluate`, gate off), the mean and median part error and the time
per frame (the estimator alone, masks in memory). Writes ``PREFIX.md`` / ``.json`` (default
``benchmarks/results/mask_resolution``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(HERE.parent / "benchmarks"))  # the benchmarks a study builds on


def main(argv=None) -> int:
    from _machine import machine, machine_line, results_dir

    from topopose.synth import synthetic_capture
    from topopose.hull.hull import MaskResolution
    from topopose.frame.estimate import FrameEstimator
    from topopose.batch.quality import evaluate

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--out", default=str(results_dir() / "mask_resolution"))
    a = ap.parse_args(argv)
    rows = []
    for seed, size in ((11, (1280, 960)), (12, (960, 720))):
        cap = synthetic_capture("human", frames=a.frames, seed=seed, cameras=8, size=size,
                                noise=2)
        gt = cap.options["gt"]
        for name, mr in (("full", False), ("1.25 px/voxel", MaskResolution(1.25)),
                         ("2 px/voxel", MaskResolution(2.0))):
            est = FrameEstimator(cap, "human", 100, mask_resolution=mr, gate=False)
            est.estimate(cap.frames[0])
            t = time.perf_counter()
            poses = [est.estimate(f) for f in cap.frames]
            ms = (time.perf_counter() - t) / len(poses) * 1e3
            ev = evaluate(gt, poses)
            err = [v for f in ev.frames for v in f.errors.values()]
            rows.append({"seed": seed, "size": list(size), "setting": name,
                         "factors": est.mask_factors(), "classes": ev.counts,
                         "mean_error_cm": round(100 * float(np.mean(err)), 2),
                         "median_error_cm": round(100 * float(np.median(err)), 2),
                         "ms_per_frame": round(ms, 1)})
            print(json.dumps(rows[-1]), flush=True)
    m = machine()
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps({"machine": m, "rows": rows}, indent=1))
    lines = ["# Masks at the resolution the grid needs against full masks (synthetic, noise 2, "
             "8 cameras, 100³)", "", machine_line(m), "",
             "| seed | image | setting | factors | good | missing limb | misplaced | bad | "
             "mean error (cm) | median (cm) | ms/frame |", "|---" * 11 + "|"]
    for r in rows:
        c = r["classes"]
        lines.append(f"| {r['seed']} | {r['size'][0]}×{r['size'][1]} | {r['setting']} | "
                     f"{r['factors']} | {c['good']} | {c['missing limb']} | {c['misplaced']} | "
                     f"{c['bad']} | {r['mean_error_cm']} | {r['median_error_cm']} | "
                     f"{r['ms_per_frame']} |")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out}.md / .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
