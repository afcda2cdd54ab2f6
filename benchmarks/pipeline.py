"""Pipeline speed (thesis §13.2.1, Fig. 13.2): per-frame time split by stage and frames/s at
grid resolutions 50–200, 8 cameras, one core, silhouettes already in memory.

Reference (no in-process peer runs the same pipeline): the thesis reaches real time, 25 frames/s,
below 100³ voxels (C++, visual hull on a GeForce 9800 GT GPU, Core 2 Quad Q8200 2.33 GHz), with
time linear in the number of grid voxels. Targets here: ≥ 100 frames/s at 100³ and ≥ 25 frames/s
at 200³, one core, and a linear fit of time against grid voxels.

    python benchmarks/pipeline.py [--quick] [--frames N] [--subject human]

Writes benchmarks/results/pipeline.{md,json,png}.
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

STAGES = ("hull", "fill", "thinning", "tree", "alignment", "placement")
THESIS_FPS = {"reference": "thesis Fig. 13.2: 25 frames/s reached below 100^3 (C++, GPU hull, "
                           "Core 2 Quad Q8200 2.33 GHz)"}


def measure(cap, subject, resolution, repeats):
    """Per frame: the minimum over ``repeats`` of each stage time (ms)."""
    from topopose.frame import FrameEstimator

    est = FrameEstimator(cap, subject, resolution, threshold=2.0)
    t0 = time.perf_counter()
    _, det = est.estimate(cap.frames[0], detail=True)       # compile + projection tables
    warm = time.perf_counter() - t0
    grid = int(det.volume.data.size) if det.volume is not None else 0
    rows, statuses = [], []
    for f in cap.frames:
        best = None
        for _ in range(repeats):
            p = est.estimate(f)
            t = {k: p.timings_ms.get(k, 0.0) for k in (*STAGES, "total")}
            best = t if best is None else {k: min(best[k], t[k]) for k in t}
        rows.append(best)
        statuses.append(p.status)
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
    median_total = float(np.median([r["total"] for r in rows]))
    return {"resolution": resolution, "grid_voxels": grid, "grid_shape": list(det.volume.data.shape),
            "ms": mean, "median_total_ms": median_total, "fps": 1000.0 / mean["total"],
            "warmup_s": warm, "frames": len(rows),
            "failed": statuses.count("failed"), "matched": statuses.count("matched")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 resolutions, 6 frames, 1 repeat")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--subject", default="human")
    ap.add_argument("--noise", type=int, default=1)
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--child", help="the child_rope recording: compute alone on it (masks in "
                                    "memory, one core, 100³) against --peer, in the same run "
                                    "(benchmarks/_real_child.py)")
    ap.add_argument("--peer", default=str(Path(__file__).resolve().parents[2] / "peer-capture"
                                          / "src"), help="src folder of the peer tree")
    a = ap.parse_args(argv)
    if a.child:
        import _real_child as real_child
        rec, peer = Path(a.child), Path(a.peer)
        bad = real_child.missing_inputs(rec, peer)
        if bad:
            print(bad)
            return 2
        return real_child.memory_compare(rec, peer, 6 if a.quick else 40,
                                         Path(a.out) / "pipeline_child")
    from topopose.synth import synthetic_capture

    load0 = os.getloadavg()[0]
    resolutions = [50, 100, 200] if a.quick else [50, 75, 100, 125, 150, 175, 200]
    frames = 6 if a.quick else a.frames
    repeats = 1 if a.quick else a.repeats
    cap = synthetic_capture(subject=a.subject, frames=frames, seed=0, noise=a.noise,
                            separated=True, cameras=8)
    for f in cap.frames:                 # silhouettes in memory, as booleans
        cap.masks[f] = [np.asarray(m, dtype=bool) for m in cap.masks[f]]
    res = []
    print(f"pipeline speed: {a.subject}, {frames} frames, 8 cameras {cap.cameras[0].size}, "
          f"noise {a.noise}, one core, min of {repeats} repeats")
    head = f"{'res':>5} {'voxels':>9} " + " ".join(f"{s:>9}" for s in STAGES) + f" {'total':>8} {'fps':>7}"
    print(head + "   (ms per frame, mean over frames)")
    for r in resolutions:
        m = measure(cap, a.subject, r, repeats)
        res.append(m)
        print(f"{r:5d} {m['grid_voxels']:9d} " + " ".join(f"{m['ms'][s]:9.2f}" for s in STAGES)
              + f" {m['ms']['total']:8.2f} {m['fps']:7.1f}", flush=True)
    x = np.array([m["grid_voxels"] for m in res], float) / 1e6
    y = np.array([m["ms"]["total"] for m in res])
    slope, icpt = np.polyfit(x, y, 1)
    pred = slope * x + icpt
    r2 = 1 - np.sum((y - pred) ** 2) / max(np.sum((y - y.mean()) ** 2), 1e-12)
    by = {m["resolution"]: m for m in res}
    targets = {"fps_100": by.get(100, {}).get("fps"), "fps_200": by.get(200, {}).get("fps")}
    fit = {"slope_ms_per_Mvoxel": float(slope), "intercept_ms": float(icpt), "r2": float(r2)}
    print(f"linear fit: total ms = {slope:.3f} ms/Mvoxel × voxels + {icpt:.2f} ms (R² = {r2:.3f})")
    print(f"targets: ≥ 100 fps at 100³: {targets['fps_100']:.1f}; ≥ 25 fps at 200³: "
          f"{targets['fps_200']:.1f}" if targets["fps_200"] else "")
    mach = machine()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "pipeline_quick" if a.quick else "pipeline"
    data = {"machine": mach, "load_average_start": round(load0, 2), "subject": a.subject, "noise": a.noise, "frames": frames,
            "repeats": repeats, "results": res, "fit": fit, "targets": targets, **THESIS_FPS}
    (out / f"{name}.json").write_text(json.dumps(data, indent=1))
    lines = [f"# Pipeline speed ({a.subject}, 8 cameras, one core)", "",
             f"Machine: {mach['cpu']}, {mach['cores']} cores (shared, loaded), Python "
             f"{mach['python']}, Numba {mach['numba']}, {mach['threads']}; {mach['date']}; "
             f"1-minute load average {load0:.2f} at the start, {mach['load_average']} at the end "
             f"(other jobs share the cores).", "",
             f"{frames} synthetic frames (noise {a.noise}, limbs separated), silhouettes "
             f"{cap.cameras[0].size[0]}×{cap.cameras[0].size[1]} in memory; each stage timed per "
             f"frame, minimum of {repeats} repeats, mean over frames. Default pipeline settings: "
             f"hull = consensus hull (tolerance 1 restricted to 1 voxel around the strict hull, "
             f"both from one carve), cavity fill, D6I1D thinning, data tree (with bump pruning and the "
             f"frame's Euclidean distance transform, which the placement reuses), AHA "
             f"(with the thickness term); placement = the parts from the alignment (extremity "
             f"tips, spine shift, head from the hull), the frame's judgement (confidence) and "
             f"the skeleton curves. The total is the whole FrameEstimator.estimate call.", "",
             "| resolution | grid voxels | hull ms | cavity fill ms | thinning ms | tree ms | alignment ms | placement ms | total ms | frames/s |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for m in res:
        lines.append(f"| {m['resolution']}³ | {m['grid_voxels']:,} | " +
                     " | ".join(f"{m['ms'][s]:.2f}" for s in STAGES) +
                     f" | {m['ms']['total']:.2f} | {m['fps']:.1f} |")
    lines += ["", f"Linear fit of the total time against the number of grid voxels: "
                  f"**{slope:.3f} ms per million voxels** + {icpt:.2f} ms (R² = {r2:.3f}).", "",
              f"Targets: ≥ 100 frames/s at 100³ → {targets['fps_100']:.1f} "
              f"({'met' if (targets['fps_100'] or 0) >= 100 else 'NOT met'}); ≥ 25 frames/s at 200³ → "
              + (f"{targets['fps_200']:.1f} ({'met' if targets['fps_200'] >= 25 else 'NOT met'})"
                 if targets["fps_200"] else "not measured") + ".", "",
              f"Reference: {THESIS_FPS['reference']} — ratio at 100³: "
              f"{(targets['fps_100'] or 0) / 25:.1f}× the thesis' real-time rate.", ""]
    (out / f"{name}.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4), dpi=100)
        bottom = np.zeros(len(res))
        for s in STAGES:
            v = np.array([m["ms"][s] for m in res])
            a0.bar([str(m["resolution"]) for m in res], v, bottom=bottom, label=s)
            bottom += v
        a0.set_xlabel("resolution (voxels along the longest side)")
        a0.set_ylabel("ms per frame")
        a0.set_title("time per stage")
        a0.legend()
        a1.plot(x, y, "o", label="measured")
        a1.plot(x, pred, "-", label=f"fit {slope:.2f} ms/Mvoxel, R²={r2:.3f}")
        a1.set_xlabel("grid voxels (millions)")
        a1.set_ylabel("ms per frame")
        a1.set_title("time against grid size")
        a1.legend()
        fig.tight_layout()
        fig.savefig(out / f"{name}.png")
    except Exception as exc:  # figure is a bonus
        print(f"(no figure: {exc})", file=sys.stderr)
    print(f"wrote {out / (name + '.md')}")


if __name__ == "__main__":
    sys.exit(main())
