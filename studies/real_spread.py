"""The real recording's figures over several voxel grids: how much the grid alone moves them.

    python studies/real_spread.py [RECORDING] [--methods person,person+track+every2]
                                     [--resolutions 96,98,100,102,104] [--out DIR] [--quick]

``benchmarks/real.py``'s run (:func:`real.run_method`: end to end from the 4 videos, scored
against Pose2Sim's 3D result) at each resolution: the voxel size and the lattice move, the
subject does not. A change of the method is a gain only when it beats this spread: one grid's
figure is a draw from it (``real_motion.py`` reports the same for the full skeleton's MPJPE,
``grid_spread``). Per method and resolution: frames *right* per frame and as ``topopose run``
writes them, ``matched`` as ``run`` writes it and its precision; then the mean, min and max
over the resolutions. To compare two versions of topopose, run this script under each (e.g. a
``git worktree`` of the older commit with ``PYTHONPATH=<worktree>/src``).

Writes ``real_spread.md`` and ``real_spread.json``. Needs ``mediapipe`` (``person``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

FIELDS = (("right per frame", lambda r: r["right_share"]),
          ("right as run writes it", lambda r: r["as_run"]["right_share"]),
          ("matched as run writes it", lambda r: r["as_run"]["matched"]),
          ("precision of matched", lambda r: r["as_run"]["matched_precision"]))


def spread(rec: Path, methods, resolutions, ref) -> dict:
    """``{method: {resolution: {field: value}}}`` (fields: :data:`FIELDS`)."""
    from real import runs_over

    out = {m: {} for m in methods}
    for m, r, res, _poses in runs_over(rec, methods, resolutions, ref):
        out[m][r] = {name: get(res) for name, get in FIELDS}
        print(m, r, out[m][r], flush=True)
    return out


def report(doc) -> str:
    m = doc["machine"]
    L = ["# The real recording over several voxel grids", "",
         f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         "Written by `studies/real_spread.py` (`real.py`'s run at each resolution; 0.15 m "
         "for *right*, Pose2Sim's 3D result as reference).", ""]
    for meth, rows in doc["spread"].items():
        res = list(rows)
        L += [f"## `{meth}`", "", "| | " + " | ".join(str(r) for r in res)
              + " | mean | min – max |", "|---" * (len(res) + 3) + "|"]
        for name, _get in FIELDS:
            v = [rows[r][name] for r in res]
            w = [x for x in v if x is not None]
            fmt = (lambda x: "–" if x is None else f"{x:.0f}") if name.startswith("matched") else \
                (lambda x: "–" if x is None else f"{100 * x:.0f} %")
            L.append(f"| {name} | " + " | ".join(fmt(x) for x in v) + " | "
                     + (f"{fmt(float(np.mean(w)))} | {fmt(min(w))} – {fmt(max(w))} |" if w else "– | – |"))
        L.append("")
    return "\n".join(L)


def main(argv=None):
    from _machine import machine, write_results
    from real import runs_command

    got = runs_command(__doc__, argv, "person,person+track+every2", "96,98,100,102,104", "person")
    if isinstance(got, int):
        return got
    rec, ref, methods, resolutions, out = got
    doc = {"recording": str(rec), "machine": machine(), "resolutions": resolutions,
           "spread": spread(rec, methods, resolutions, ref)}
    write_results(out / "real_spread", doc, report)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
