"""Does a frame's pose depend on which frames were processed before it? The real recording,
``person`` silhouettes, run three ways.

    python studies/real_order.py [RECORDING] [--out DIR] [--quick]

The per-frame stage of :func:`topopose.batch.run` (AHA threshold and gate off, no sequence
stages) on every frame in order, with two workers (frames processed in another order, in two
processes), and on the second half only (``frames="50:100"``); counts the frames whose status,
parts (1e-8 m) and hull voxel count equal the serial run's. A ``person`` grid that grows with the
subject makes these runs disagree; to measure an older version, run this script
with ``PYTHONPATH=<worktree of it>/src``. ``--quick``: frames 80–99 only.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on


def poses(rec, work: Path, frames=None, workers=1) -> dict:
    from real import person_capture

    from topopose.batch import run
    if work.exists():
        shutil.rmtree(work)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = person_capture(rec, work, ["scale = 0.5"])
        r = run(cap, threshold=1e9, gate=False, progress=False, track=False, sides=False,
                skeleton=False, output=work / "poses.jsonl", frames=frames, workers=workers)
    return {p.frame: p for p in r.poses}


def same(a, b) -> bool:
    if a.status != b.status or set(a.parts) != set(b.parts):
        return False
    if a.diagnostics.get("hull_voxels") != b.diagnostics.get("hull_voxels"):
        return False
    for k, x in a.parts.items():
        y = b.parts[k]
        if (x is None) != (y is None) or (x is not None and not np.allclose(x, y, rtol=0, atol=1e-8)):
            return False
    return True


def main(argv=None):
    import topopose
    from _machine import machine, results_dir
    from real import DEFAULT, person_recording

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(DEFAULT))
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--quick", action="store_true", help="frames 80-99 only")
    a = ap.parse_args(argv)
    opened = person_recording(a.recording)
    if isinstance(opened, int):
        return opened
    rec = opened[0]
    whole, half = ("80:100", "90:100") if a.quick else (None, "50:100")
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        serial = poses(rec, t / "serial", whole)
        rows = {"two workers": poses(rec, t / "workers", whole, workers=2),
                f"frames {half} only": poses(rec, t / "half", half)}
    m = machine()
    L = ["# A frame's pose and the frames processed before it (real recording, `person`)", "",
         f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         f"topopose from `{Path(topopose.__file__).parent}`. Written by `studies/real_order.py`.",
         "", "| run | frames identical to the serial run's |", "|---|---|"]
    for k, ps in rows.items():
        L.append(f"| {k} | {sum(same(serial[f], p) for f, p in ps.items())} / {len(ps)} |")
    text = "\n".join(L) + "\n"
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "real_order.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
