"""The tracker's snap on the real recording: a snap gives way to the per-frame trajectory after
``max_gap`` frames against snaps that never give way (the rule before).

    python studies/real_snap.py [RECORDING] [--methods person+track+every2,person]
                                   [--resolutions 100,96] [--out DIR] [--quick]

Per method and grid resolution, one end-to-end run (:func:`real.run_method`), then the poses as
``topopose run`` writes them (:func:`real.as_run`) twice from the same per-frame poses: with
:func:`topopose.sequence.track.track`'s default ``snap_run`` (``max_gap``) and with
``snap_run = 10**9`` (never). Scores as ``real.py``: frames right as written, ``matched`` and
its precision, part-frames snapped. The picture (``real_snap.png``) shows, for the first method
and resolution, each frame's worst hand or foot error against Pose2Sim: per frame, as written
now, as written before (on the Pose2Sim recording at 100³ with ``person_track``,
``person_every = 2``, a raised foot stayed on a phantom leaf for frames 26–48).
"""
from __future__ import annotations

import functools
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

NEVER = 10 ** 9


def written(poses, model, up, mc, snap_run):
    """:func:`real.as_run` with the tracker's ``snap_run``."""
    import real

    from topopose.sequence import motion
    from topopose.sequence.track import track

    keep = motion.track_identities
    motion.track_identities = functools.partial(track, snap_run=snap_run)
    try:
        return real.as_run(poses, model, up, mc)
    finally:
        motion.track_identities = keep


def worst(summary) -> list:
    """Each frame's largest hand or foot error (m; NaN when a part is not placed)."""
    out = []
    for r in summary["rows"]:
        e = r["errors"] or {}
        v = [e.get(k) for k in ("hand_L", "hand_R", "foot_L", "foot_R")]
        out.append(max((x for x in v if x is not None), default=np.nan)
                   if all(x is not None for x in v) else np.nan)
    return out


def compare(rec, methods, resolutions, ref) -> dict:
    import real

    from topopose.pose.model import load_model

    model = load_model("human")
    out = {}
    for m, r, res, poses in real.runs_over(rec, methods, resolutions, ref):
        poses = sorted(poses, key=lambda p: p.frame)
        idx = {p.frame: i for i, p in enumerate(poses)}
        mc = res["min_confidence"]
        row = {"right per frame": res["right_share"], "worst per frame": worst(res)}
        for label, run_ in (("now", None), ("before", NEVER)):
            ps = written(poses, model, np.array([0.0, 0.0, 1.0]), mc, run_)
            s = real.summarize(ps, ref, idx, mc)
            row[label] = {"right": s["right_share"], "matched": s["matched"],
                          "precision": s["matched_precision"],
                          "snapped": sum(len(p.diagnostics.get("snapped") or []) for p in ps),
                          "worst": worst(s)}
        out[f"{m} @ {r}"] = row
        print(m, r, {k: (v if not isinstance(v, dict) else
                         {a: b for a, b in v.items() if a != "worst"})
                     for k, v in row.items() if k != "worst per frame"}, flush=True)
    return out


def picture(path, key, row):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = np.arange(len(row["worst per frame"]))
    fig, ax = plt.subplots(figsize=(9, 3.4))
    ax.plot(f, row["worst per frame"], ".", color="0.6", label="per frame")
    ax.plot(f, row["before"]["worst"], "-", color="tab:red",
            label=f"as written, snaps never give way (right {100 * row['before']['right']:.0f} %)")
    ax.plot(f, row["now"]["worst"], "-", color="tab:blue",
            label=f"as written, snaps give way after max_gap (right {100 * row['now']['right']:.0f} %)")
    ax.axhline(0.15, color="k", lw=0.6, ls="--")
    ax.set_ylim(0, 1.0)
    ax.set_xlabel("frame")
    ax.set_ylabel("worst hand / foot error (m)")
    ax.set_title(f"Pose2Sim balancing, {key}: the tracker's snap", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(doc) -> str:
    m = doc["machine"]
    L = ["# The tracker's snap on the real recording", "",
         f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         "Written by `studies/real_snap.py`: the same per-frame poses written as `topopose "
         "run` writes them with snaps that give way after `max_gap` frames (now) and with "
         "snaps that never do (before).", "",
         "| method @ resolution | right per frame | right as written, now / before | matched "
         "(precision), now / before | part-frames snapped, now / before |",
         "|---|---|---|---|---|"]
    pc = lambda x: "–" if x is None else f"{100 * x:.0f} %"      # noqa: E731
    for k, r in doc["runs"].items():
        a, b = r["now"], r["before"]
        L.append(f"| {k} | {pc(r['right per frame'])} | {pc(a['right'])} / {pc(b['right'])} | "
                 f"{a['matched']} ({pc(a['precision'])}) / {b['matched']} ({pc(b['precision'])}) | "
                 f"{a['snapped']} / {b['snapped']} |")
    L += ["", f"Picture: `{doc['picture']}`.", ""]
    return "\n".join(L)


def main(argv=None):
    from _machine import machine, write_results
    from real import runs_command

    got = runs_command(__doc__, argv, "person+track+every2,person", "100,96",
                       "person+track+every2")
    if isinstance(got, int):
        return got
    rec, ref, methods, resolutions, out = got
    runs = compare(rec, methods, resolutions, ref)
    first = next(iter(runs))
    picture(out / "real_snap.png", first, runs[first])
    doc = {"recording": str(rec), "machine": machine(), "picture": "real_snap.png", "runs": runs}
    write_results(out / "real_snap", doc, report)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
