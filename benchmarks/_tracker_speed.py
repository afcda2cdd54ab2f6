"""The tracking stage alone (:func:`topopose.sequence.follow.follow`) on real recordings, this
tree against a peer tree in the same run: CPU time a frame by step, and the poses compared.

    python benchmarks/tracking.py --speed --peer PEER_SRC [--child CHILD_ROPE]
                                          [--pose2sim RECORDING] [--rounds 3] [--out PREFIX]

Per recording, ``topopose run CAPTURE --model human`` (100³) of this tree runs once with the
inputs of its tracking stage kept (the sequence stage's poses, the kinematic tree and lengths,
every frame's :class:`~topopose.sequence.kept.KeptFrame`, the options); then each side runs
``follow`` on those same inputs in its own process (``PYTHONPATH`` its ``src``), the sides
alternating for ``--rounds`` rounds (peer, ours, peer, ours …), each run twice in its process
and the second one measured (the first loads the Numba kernels). Figures per side: the stage's
CPU time a frame by step, as the stage records it (``timings_ms``: ``track_data`` the fit's
points and rays, ``track_fit`` the fits, ``track_quality`` the silhouette IoU; mean of the
rounds, and each round's), the whole call's CPU time, the 1-minute load average before each
run. The poses of the two sides are compared frame by frame: status, fit, joints and parts
(exact equality of the floats), the track's diagnostics.

CHILD_ROPE: the 10-camera recording set up as ``benchmarks/_real_child.py`` does (nothing
copied); RECORDING: Pose2Sim's balancing trial, ``person`` silhouettes (needs MediaPipe).
Writes ``PREFIX.md`` / ``.json`` (default ``benchmarks/results/tracker_speed``).
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OURS = HERE.parent / "src"
STEPS = ("track_data", "track_fit", "track_quality")


# --------------------------------------------------------------------------- in a side's process
def keep_inputs(capture, out):
    """``topopose run`` of ``capture`` with the tracking stage's inputs pickled to ``out``."""
    import topopose.sequence.follow as follow_module
    from topopose.batch.run import run

    original = follow_module.follow

    def keeping(poses, model, tree, lengths, hull, options=None, fps=None, *rest):
        hulls = {}
        for p in poses:
            try:
                hulls[p.frame] = hull(p.frame)
            except Exception as exc:           # noqa: BLE001  (a frame that failed to load)
                hulls[p.frame] = exc
        with open(out, "wb") as fh:
            pickle.dump(dict(poses=poses, model=model, tree=tree, lengths=lengths, hulls=hulls,
                             options=options, fps=fps), fh)
        return original(poses, model, tree, lengths, hull, options, fps, *rest)

    follow_module.follow = keeping
    with tempfile.TemporaryDirectory() as tmp:
        run(capture, "human", 100, output=Path(tmp) / "poses.jsonl", progress=False)


def time_follow(inputs, out):
    """``follow`` on the kept inputs twice; the second call's CPU time and steps, its poses
    pickled to ``out``; one JSON line."""
    import inspect

    import numpy as np

    from topopose.sequence.follow import follow

    with open(inputs, "rb") as fh:
        d = pickle.load(fh)

    def hull(frame):
        v = d["hulls"][frame]
        if isinstance(v, Exception):
            raise v
        return v

    rate = {"fps": d.get("fps")} if "fps" in inspect.signature(follow).parameters else {}
    for _ in range(2):
        c = time.process_time()
        poses = follow(d["poses"], d["model"], d["tree"], d["lengths"], hull, d["options"],
                       **rate)
        cpu = time.process_time() - c
    steps = {k: poses[0].timings_ms.get(k) for k in STEPS} if poses else {}
    keep = [(p.frame, p.status, p.fit,
             {k: np.asarray(v) for k, v in (p.joints or {}).items()},
             {k: None if v is None else np.asarray(v) for k, v in (p.parts or {}).items()},
             {"follow": _followed(p.diagnostics),
              **{k: p.diagnostics.get(k) for k in ("track_body", "fit_cameras")}})
            for p in poses]
    with open(out, "wb") as fh:
        pickle.dump(keep, fh)
    print(json.dumps({"frames": len(poses), "cpu_s": round(cpu, 3),
                      "cpu_ms_frame": round(1e3 * cpu / max(len(poses), 1), 3), **steps}))


def _followed(diagnostics) -> dict:
    """The followed body's start frame and re-initialization (``diagnostics.follow``; a tree
    before it kept them in ``diagnostics.track``)."""
    rec = diagnostics.get("follow") or diagnostics.get("track") or {}
    return {k: rec.get(k) for k in ("from", "reinitialized")}


# --------------------------------------------------------------------------- the comparison
def same_poses(a, b) -> dict:
    """Frames of two pickled ``time_follow`` outputs equal in every field, exactly."""
    import numpy as np

    with open(a, "rb") as fh:
        A = pickle.load(fh)
    with open(b, "rb") as fh:
        B = pickle.load(fh)

    def arrays_equal(x, y):
        return x.keys() == y.keys() and all(
            (x[k] is None) == (y[k] is None) and
            (x[k] is None or (x[k].shape == y[k].shape and np.array_equal(x[k], y[k])))
            for k in x)

    same, differ = 0, []
    for x, y in zip(A, B):
        ok = (x[0] == y[0] and x[1] == y[1] and x[2] == y[2] and x[5] == y[5]
              and arrays_equal(x[3], y[3]) and arrays_equal(x[4], y[4]))
        same += ok
        if not ok:
            differ.append(x[0])
    return {"frames": len(A), "identical": same if len(A) == len(B) else 0,
            "differ": differ[:10], "lengths": [len(A), len(B)]}


def side(src, *args) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_NUM_THREADS="1")
    r = subprocess.run([sys.executable, str(Path(__file__).resolve()), *map(str, args)],
                       env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{src}: {' '.join(map(str, args))} failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1]) if r.stdout.strip() else {}


def recording(name, capture, peer, rounds, tmp) -> dict:
    inputs = tmp / f"{name}.pkl"
    side(OURS, "--keep", capture, inputs)
    runs = {"peer": [], "ours": []}
    for k in range(rounds):
        for who, src in (("peer", peer), ("ours", OURS)):
            load = os.getloadavg()[0]
            r = side(src, "--time", inputs, tmp / f"{name}_{who}.pkl")
            r["load_before"] = round(load, 2)
            runs[who].append(r)
            print(name, who, json.dumps(r), flush=True)
    mean = {who: {k: round(sum(r[k] for r in rs) / len(rs), 3)
                  for k in ("cpu_ms_frame", *STEPS)} for who, rs in runs.items()}
    return {"runs": runs, "mean": mean,
            "same": same_poses(tmp / f"{name}_peer.pkl", tmp / f"{name}_ours.pkl")}


def report(doc) -> str:
    from _machine import machine_line

    m = doc["machine"]
    out = ["# The tracking stage alone on real recordings, against the peer", "",
           machine_line(m) + f"; nproc {m['nproc']}", "",
           "Produced by `benchmarks/tracking.py --speed`: each recording's tracking-stage inputs "
           "kept from one `topopose run` (100³), then `follow` on them in each side's own "
           f"process, the sides alternating for {doc['rounds']} rounds (the second call in "
           "each process measured). CPU time a frame (ms; the process' own time, mean of the "
           "rounds). Peer: `" + doc["peer"] + "`.", ""]
    for name, r in doc["recordings"].items():
        o, p = r["mean"]["ours"], r["mean"]["peer"]
        out += [f"## {name}", "", "| step | ours | peer | ours / peer |", "|---|---|---|---|"]
        for k in (*STEPS, "cpu_ms_frame"):
            label = {"cpu_ms_frame": "the whole call (also the body's learning)"}.get(k, k)
            out.append(f"| {label} | {o[k]:.2f} | {p[k]:.2f} | {o[k] / p[k]:.2f} |")
        tot_o, tot_p = (sum(x[k] for k in STEPS) for x in (o, p))
        out += [f"| data + fit + quality | {tot_o:.2f} | {tot_p:.2f} | {tot_o / tot_p:.2f} |",
                "", "Each round (ours / peer, ms a frame, data + fit + quality; load before): "
                + "; ".join(f"{sum(a[k] for k in STEPS):.1f} / {sum(b[k] for k in STEPS):.1f} "
                            f"({a['load_before']} / {b['load_before']})"
                            for a, b in zip(r["runs"]["ours"], r["runs"]["peer"])) + ".", "",
                f"Poses identical to the peer's, field by field (status, fit, joints, parts, "
                f"the track's diagnostics; floats exactly): {r['same']['identical']} of "
                f"{r['same']['frames']} frames.", ""]
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="tracking.py --speed", description=__doc__.split("\n")[0])
    ap.add_argument("--peer", required=True, help="src folder of the peer tree")
    ap.add_argument("--child", help="the child_rope recording's folder")
    ap.add_argument("--pose2sim", help="Pose2Sim's balancing trial")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=str(Path(os.environ.get("TOPOPOSE_BENCH_RESULTS",
                                                          HERE / "results")) / "tracker_speed"))
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--keep"]:                  # a side's process (:func:`side`)
        keep_inputs(*argv[1:3])
        return 0
    if argv[:1] == ["--time"]:
        time_follow(*argv[1:3])
        return 0
    a = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    peer = Path(a.peer)
    if not (peer / "topopose" / "__init__.py").is_file():
        print(f"{peer}: no peer tree (its src folder holding topopose/); pass --peer")
        return 2
    from _real_child import machine_now

    doc = {"machine": machine_now(), "peer": str(peer), "rounds": a.rounds, "recordings": {}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if a.child:
            import _real_child

            cap = _real_child.child_capture(Path(a.child), tmp / "child")
            doc["recordings"]["child_rope (10 cameras)"] = recording("child", cap, peer,
                                                                     a.rounds, tmp)
        if a.pose2sim:
            import real

            if isinstance(real.person_recording(a.pose2sim), tuple):
                cap = tmp / "p2s"
                real.make_capture(Path(a.pose2sim), cap, "person")
                doc["recordings"]["Pose2Sim balancing, person (4 cameras)"] = recording(
                    "p2s", cap, peer, a.rounds, tmp)
    if not doc["recordings"]:
        print("no recording given (--child, --pose2sim)")
        return 2
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc["machine_after"] = {"load_average": round(os.getloadavg()[0], 2)}
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    out.with_suffix(".md").write_text(report(doc))
    print(f"wrote {out}.md / .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
