"""`topopose run --workers N` against one process: real frames per second (frames over wall time).

Synthetic human captures (8 cameras 640×480, 100³ grid) of 40 frames (the issue's case) and of
``--long`` frames (default 200); for each, ``topopose.run`` in this process (``workers=1``, kernels
already compiled: a second run in the same process) and with ``workers=2`` (a Dask ``LocalCluster`` of
two worker processes, started by the call, each loading the kernels from the disk cache and
building its estimator: what a user's ``--workers 2`` costs), interleaved over ``--rounds``
rounds; minimum wall time per setting. The rate is frames / wall time of the whole call
(cluster start included). The CLI runs captures with fewer than ``MIN_FRAMES_PER_WORKER``
frames per worker in one process (``topopose.batch.run``), from these figures.

Usage: ``python benchmarks/workers.py [--quick] [--rounds 2] [--long 200]``.
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the 40-frame capture only, one round")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--long", type=int, default=200)
    args = ap.parse_args()
    from topopose.capture import load_capture
    from topopose.synth import synthesize
    from topopose.batch.run import MIN_FRAMES_PER_WORKER, run

    sizes = [40] if args.quick else [40, args.long]
    rounds = 1 if args.quick else args.rounds
    mach = machine()
    rows = []
    with tempfile.TemporaryDirectory(prefix="topopose-workers-") as tmp:
        caps = {}
        for n in sizes:
            d = synthesize(Path(tmp) / f"human{n}", subject="human", frames=n, seed=1, separated=True)
            caps[n] = d
        run(load_capture(caps[40]), frames="0:2", progress=False)        # compile (warm caches)
        for n in sizes:
            best = {1: [], 2: []}
            for _ in range(rounds):
                for w in (1, 2):
                    cap = load_capture(caps[n])             # a new capture: no cached tables
                    t0 = time.perf_counter()
                    res = run(cap, workers=w, progress=False)
                    wall = time.perf_counter() - t0
                    assert len(res.poses) == n
                    best[w].append(wall)
                    print(f"  {n} frames, workers={w}: {wall:.2f} s ({n / wall:.1f} frames/s)", flush=True)
            one, two = min(best[1]), min(best[2])
            rows.append({"frames": n, "one_process_s": round(one, 3), "workers2_s": round(two, 3),
                         "one_fps": round(n / one, 2), "workers2_fps": round(n / two, 2),
                         "speedup_workers2": round(one / two, 3), "walls": {str(k): v for k, v in best.items()}})
    out = results_dir()
    out.mkdir(parents=True, exist_ok=True)
    name = "workers_quick" if args.quick else "workers"
    (out / f"{name}.json").write_text(json.dumps({"machine": mach, "rows": rows,
                                                 "min_frames_per_worker": MIN_FRAMES_PER_WORKER}, indent=1))
    L = [f"# `--workers 2` vs one process{' — quick' if args.quick else ''}", "",
         f"Machine: {mach['cpu']}, {mach['cores']} cores, shared with other jobs (load average "
         f"{mach['load_average']} at the start), Python {mach['python']}, Numba {mach['numba']}, "
         f"{mach['date']}. Human, 8 cameras 640×480, 100³; frames/s = frames / wall time of the "
         f"whole `topopose.run` call (Dask cluster start included); minimum over {rounds} interleaved "
         "round(s).", "",
         "| frames | one process (s) | frames/s | workers=2 (s) | frames/s | speed-up of workers=2 |",
         "|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        L.append(f"| {r['frames']} | {r['one_process_s']:.2f} | {r['one_fps']:.1f} | {r['workers2_s']:.2f} | "
                 f"{r['workers2_fps']:.1f} | {r['speedup_workers2']:.2f}× |")
    L += ["", f"The CLI (`topopose run --workers N`) runs in one process when the capture has fewer "
          f"than {MIN_FRAMES_PER_WORKER} frames per worker, and says so."]
    (out / f"{name}.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
