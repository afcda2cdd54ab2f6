"""One side of a same-run comparison (``benchmarks/_real_child.py``): run with whichever
topopose ``PYTHONPATH`` points at (this branch or the peer's tree), print one JSON line.

    python benchmarks/_capture_run.py decode CAPTURE
    python benchmarks/_capture_run.py run CAPTURE OUT.jsonl [--frames A:B]
    python benchmarks/_capture_run.py memory CAPTURE --frames N

Only the API both trees share is used (``load_capture``, ``run``, ``FrameEstimator``; found
where either layout keeps them).
"""
from __future__ import annotations

import argparse
import json
import sys
import time

T0 = time.perf_counter()

STAGES = ("hull", "fill", "thinning", "tree", "alignment", "placement", "trim", "centre",
          "support", "total")
#: the tracking stage's CPU time a frame (its mean over the run, on every frame's pose)
TRACK = ("track_hull", "track_data", "track_fit", "track_quality")


def medians(poses) -> dict:
    import numpy as np

    done = [p for p in poses if p.status != "failed"]
    out = {}
    for k in STAGES + TRACK:
        v = [p.timings_ms[k] for p in done if k in p.timings_ms]
        if v:
            out[k] = round(float(np.median(v)), 2)
    return out


def decode(capture) -> dict:
    """One thread's bare decoding of every mask file of the capture (``cv2.imread``)."""
    from pathlib import Path

    import cv2

    cv2.setNumThreads(1)
    files = sorted(p for d in (Path(capture) / "silhouettes").iterdir() if d.is_dir()
                   for p in d.iterdir() if p.suffix.lower() == ".png")
    t = time.perf_counter()
    for p in files:
        cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    return {"files": len(files), "seconds": round(time.perf_counter() - t, 3)}


def max_rss_mb() -> float:
    """This process's peak resident memory so far (MB)."""
    import resource

    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


def run_capture(capture, out, frames=None) -> dict:
    import topopose
    try:
        from topopose.batch.run import run
    except ImportError:                      # a tree of the earlier layout
        from topopose.pose.run import run

    t_import = time.perf_counter() - T0
    first = []
    t = time.perf_counter()
    res = run(capture, "human", 100, output=out, frames=frames, progress=False,
              on_pose=lambda p: first.append(time.perf_counter() - t) if not first else None)
    wall = time.perf_counter() - t
    poses = res.poses
    return {"topopose": topopose.__file__, "import_s": round(t_import, 3),
            "first_frame_s": round(first[0], 3) if first else None,
            "first_frame_since_start_s": round(first[0] + t - T0, 3) if first else None,
            "frame_loop_s": round(res.seconds, 3), "run_s": round(wall, 3),
            "after_loop_s": round(wall - res.seconds, 3), "max_rss_mb": max_rss_mb(),
            "frames": len(poses), "counts": res.counts,
            "failed": {p.frame: p.error for p in poses if p.status == "failed"},
            "beyond": sum(p.diagnostics.get("hull_grid") == "beyond" for p in poses),
            "stage_ms": medians(poses)}


def memory(capture, n) -> dict:
    """Compute alone: ``n`` frames spread over the capture, their masks decoded beforehand, as
    an in-memory capture; the estimator as ``run`` builds it (support and centre recorded)."""
    import numpy as np

    from topopose.capture import Capture, load_capture
    try:
        from topopose.frame.estimate import FrameEstimator
    except ImportError:                      # a tree of the earlier layout
        from topopose.pose.estimate import FrameEstimator

    cap0 = load_capture(capture)
    idx = np.unique(np.round(np.linspace(0, len(cap0.frames) - 1, n)).astype(int))
    names = [cap0.frames[i] for i in idx]
    masks = {f: cap0.silhouettes(f) for f in names}
    cap = Capture(cap0.cameras, names, None, cap0.up, cap0.units, cap0.fps, cap0.volume, {},
                  masks)
    est = FrameEstimator(cap, "human", 100, support=True, centre=True)
    factors = est.mask_factors() if hasattr(est, "mask_factors") else None
    if factors is not None:    # held as the decoding threads of a run give them: reduced
        from topopose.capture.io import reduce_masks
        for f in names:
            masks[f] = reduce_masks(masks[f], factors)
    t = time.perf_counter()
    est.estimate(names[0])                       # the volume, tables and kernels
    setup = time.perf_counter() - t
    poses, wall, cpu = [], [], []
    for f in names:
        t, c = time.perf_counter(), time.process_time()
        poses.append(est.estimate(f))
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)      # the process' own time: less of the load
    med = float(np.median(wall))
    return {"frames": len(names), "setup_s": round(setup, 3),
            "median_ms": round(1e3 * med, 2), "mean_ms": round(1e3 * float(np.mean(wall)), 2),
            "fps_median": round(1.0 / med, 2), "fps_mean": round(len(wall) / sum(wall), 2),
            "cpu_median_ms": round(1e3 * float(np.median(cpu)), 2),
            "stage_ms": medians(poses),
            "counts": {s: sum(p.status == s for p in poses) for s in ("matched", "rejected",
                                                                        "failed")}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=("decode", "run", "memory"))
    ap.add_argument("capture")
    ap.add_argument("out", nargs="?")
    ap.add_argument("--frames")
    a = ap.parse_args(argv)
    if a.mode == "decode":
        r = decode(a.capture)
    elif a.mode == "run":
        r = run_capture(a.capture, a.out, a.frames)
    else:
        r = memory(a.capture, int(a.frames or 30))
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
