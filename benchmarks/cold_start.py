"""Cold start: the first `topopose run` frame and the first `topopose demo`, with empty caches.

Each measurement is a fresh process with an empty Numba cache (``NUMBA_CACHE_DIR``) and an empty
look-up-table cache (``TOPOPOSE_CACHE_DIR``), as on a fresh install:

* ``run``: ``topopose run CAPTURE --frames 0 --output ...`` on a small synthetic human capture
  (8 cameras, 100³ grid) — wall time of the whole process (import, capture, first frame) and the
  frame's own time;
* ``demo``: ``topopose demo DIR`` (4 subjects × 6 frames) — wall time and exit status.

Peer, in the same run: the code of another checkout (``--before SRC``, e.g. main's ``src``), run
the same way, interleaved round by round with this checkout's (``after``). CPU time (user + system
of the process and every helper process it waited for) is recorded beside the wall time: the
machine is shared, so the wall time also measures the other jobs (load average noted).
Targets (2 cores, empty caches): first frame of ``run`` ≤ 30 s, first ``demo`` ≤ 60 s.

Usage: ``python benchmarks/cold_start.py [--before /path/to/other/src] [--rounds 2] [--quick]``
(``--quick``: the ``run`` measurement only).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

SRC = HERE.parent / "src"


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd, src, cwd, tmp) -> dict:
    """Run ``python -m topopose.cli CMD`` with ``src`` on the path and empty caches."""
    nb, tc = Path(tmp) / "numba", Path(tmp) / "tables"
    for d in (nb, tc):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(nb), TOPOPOSE_CACHE_DIR=str(tc),
               PYTHONDONTWRITEBYTECODE="1")
    load0 = os.getloadavg()[0]
    c0, t0 = _child_cpu(), time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "topopose.cli", *cmd], env=env, cwd=cwd,
                       capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "exit": r.returncode,
            "load_start": round(load0, 2), "load_end": round(os.getloadavg()[0], 2),
            "stderr_tail": r.stderr.replace("\r", "\n").strip().splitlines()[-1:] if r.returncode else []}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=None, help="src folder of the peer checkout (e.g. main's)")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="the run measurement only, one round")
    args = ap.parse_args()
    if args.quick:
        args.rounds = 1
    labels = {"after": SRC}
    if args.before:
        if not (Path(args.before) / "topopose").is_dir():
            sys.exit(f"cold_start: --before {args.before}: no topopose package there")
        labels = {"before": Path(args.before), "after": SRC}
    mach = machine()
    rows = []
    with tempfile.TemporaryDirectory(prefix="topopose-cold-") as tmp:
        cap = Path(tmp) / "capture"
        env = dict(os.environ, PYTHONPATH=str(SRC))
        subprocess.run([sys.executable, "-m", "topopose.cli", "synth", str(cap), "--frames", "2",
                        "--size", "320x240", "--separated"], env=env, check=True, capture_output=True)
        for rnd in range(args.rounds):
            for label, src in labels.items():
                out = Path(tmp) / f"p-{label}-{rnd}.jsonl"
                r = timed(["run", str(cap), "--frames", "0", "--output", str(out)], src, tmp, Path(tmp) / "c")
                frame_ms = None
                if out.exists():
                    for line in out.read_text().splitlines():
                        d = json.loads(line)
                        if "frame" in d:
                            frame_ms = d.get("timings_ms", {}).get("total")
                r.update(kind="run first frame", label=label, round=rnd,
                         frame_s=None if frame_ms is None else round(frame_ms / 1e3, 2))
                rows.append(r)
                print(r, flush=True)
                if args.quick:
                    continue
                r = timed(["demo", str(Path(tmp) / f"demo-{label}-{rnd}")], src, tmp, Path(tmp) / "c")
                r.update(kind="demo", label=label, round=rnd)
                rows.append(r)
                print(r, flush=True)
    outdir = results_dir()
    outdir.mkdir(parents=True, exist_ok=True)
    name = "cold_start_quick" if args.quick else "cold_start"
    res = {"machine": mach, "rounds": args.rounds, "before": str(args.before) if args.before else None,
           "rows": rows, "targets": {"run_first_frame_s": 30, "demo_s": 60}}
    (outdir / f"{name}.json").write_text(json.dumps(res, indent=1))
    L = [f"# Cold start (empty Numba and look-up-table caches){' — quick' if args.quick else ''}", "",
         f"Machine: {mach['cpu']}, {mach['cores']} cores, shared with other jobs (1-minute load "
         f"average per run below), Python {mach['python']}, Numba {mach['numba']}, {mach['date']}. "
         "Each row: a fresh process with empty `NUMBA_CACHE_DIR` and `TOPOPOSE_CACHE_DIR`. "
         "Wall time of the process; CPU time of the process and its helper processes. "
         + (f"`before`: {args.before}; " if args.before else "")
         + "`after`: this checkout. Rounds interleaved.", "",
         "| what | code | round | wall (s) | first frame (s) | CPU (s) | exit | load start → end |",
         "|---|---|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        L.append(f"| {r['kind']} | {r['label']} | {r['round']} | {r['wall_s']:.1f} | "
                 f"{r.get('frame_s') if r.get('frame_s') is not None else ''} | {r['cpu_s']:.1f} | "
                 f"{r['exit']} | {r['load_start']} → {r['load_end']} |")
    L += ["", "Minimum over rounds (wall s; CPU s):", ""]
    for kind in ("run first frame", "demo"):
        cells = []
        for label in labels:
            sel = [r for r in rows if r["kind"] == kind and r["label"] == label]
            if sel:
                cells.append(f"{label} {min(r['wall_s'] for r in sel):.1f} s wall, "
                             f"{min(r['cpu_s'] for r in sel):.1f} s CPU")
        if cells:
            L.append(f"- {kind}: " + "; ".join(cells))
    L += ["", "Targets: first frame of `run` ≤ 30 s, first `demo` ≤ 60 s (2 cores, empty caches)."]
    (outdir / f"{name}.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
