"""Speed options of the ``person`` silhouettes on a real recording, against the previous default
in the same run (≥ 20 frames/s end to end from the 4 videos, first frame ≤ 2 s).

    python studies/real_speed.py RECORDING [--variants person+oldreader,person,...] [--rounds 3]

RECORDING: Pose2Sim's balancing trial as :mod:`real` reads it (``videos/``, ``Calib.toml``,
``reference/pose2sim_3d.trc``). Each variant (``METHOD+VARIANT``, :data:`real.VARIANTS`) runs
end to end as ``benchmarks/real.py`` runs it (reader thread, FrameEstimator at 100³), ``--rounds``
times, the variants interleaved (A B C A B C …) so that the load of a shared machine falls on
all of them alike; speed figures are the medians over the rounds, accuracy (right per frame,
right as ``topopose run`` writes it) is scored on the first round's poses, and ``same poses``
counts the frames whose status and part positions are bit-identical to the peer's.
Also per variant: the errors per part (first round) and the CPU per frame by thread kind
(:func:`real.thread_cpu`: the pipeline, decoding, the reader, MediaPipe's native threads).
``+every2``/``+every3``: ``[silhouettes] person_every``, e.g. ``--variants
person,person+track+every2 --peer person --out benchmarks/results/real_speed_every``.

Writes ``benchmarks/results/real_speed.md`` / ``.json`` (machine noted).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on


def main(argv=None):
    import real
    from _machine import machine

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--variants", default="person+oldreader+fullmasks,person+oldreader,person,"
                                          "person+track+oldreader+fullmasks,person+track")
    ap.add_argument("--peer", default="person+oldreader+fullmasks")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--frames", type=int, default=0, help="first N frames only (0: all)")
    ap.add_argument("--out", default=str(HERE / "results" / "real_speed"))
    a = ap.parse_args(argv)
    got = real.open_recording(a.recording)
    if got is None:
        return 2
    rec, ref = got
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        print("mediapipe not installed (pip install \"topopose[segment]\"): nothing to measure")
        return 2
    names = [v for v in a.variants.split(",") if v]
    speed = {v: [] for v in names}
    first, poses = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.rounds):
            for v in names:
                res, ps = real.run_method(rec, v, 100, a.frames, Path(tmp), ref)
                speed[v].append(res["speed"])
                if r == 0:
                    first[v], poses[v] = res, ps
                print(r, v, {k: res["speed"][k] for k in ("first_frame_s", "end_to_end_fps",
                                                            "cpu_ms_per_frame")}, flush=True)
    rows = {}
    for v in names:
        med = {k: round(float(np.median([s[k] for s in speed[v]])), 3)
               for k in ("first_frame_s", "per_frame_ms", "end_to_end_fps", "cpu_ms_per_frame",
                         "main_thread_cpu_ms_per_frame")}
        st = {k: round(float(np.median([s["stages_median_ms"][k] for s in speed[v]])), 2)
              for k in speed[v][0]["stages_median_ms"]}
        rows[v] = {**med, "stages_median_ms": st, "rounds": [
            {k: s[k] for k in ("first_frame_s", "end_to_end_fps", "cpu_ms_per_frame")} for s in speed[v]],
            "thread_cpu_ms_per_frame": {k: round(float(np.median(
                [x.get("thread_cpu_ms_per_frame", {}).get(k, 0.0) for x in speed[v]])), 1)
                for k in speed[v][0].get("thread_cpu_ms_per_frame", {})},
            "errors": first[v]["errors"],
            "right_per_frame": first[v]["right_share"],
            "right_as_run": first[v]["as_run"]["right_share"],
            "same_poses_as_peer": (real.same_poses(poses[v], poses[a.peer])
                                   if a.peer in poses else None),
            "frames": first[v]["frames"]}
    peer = rows.get(a.peer)
    for r in rows.values():
        if peer is not None:
            r["fps_ratio"] = round(r["end_to_end_fps"] / peer["end_to_end_fps"], 2)
            r["cpu_ratio"] = round(r["cpu_ms_per_frame"] / peer["cpu_ms_per_frame"], 2)
            r["first_frame_ratio"] = round(r["first_frame_s"] / peer["first_frame_s"], 2)
    doc = {"recording": str(rec), "machine": machine(), "resolution": 100, "rounds": a.rounds,
           "peer": a.peer, "variants": rows, "time_breakdown_per_frame": real.time_breakdown(rec)}
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    out.with_suffix(".md").write_text(report(doc))
    print(f"wrote {out}.md / .json")
    return 0


def report(doc) -> str:
    import real

    m = doc["machine"]
    L = ["# Speed of the `person` silhouettes on the real recording", "",
         f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         f"Resolution {doc['resolution']}³, end to end from the 4 videos (decoding included), one "
         f"process. Medians over {doc['rounds']} interleaved rounds; ratios against "
         f"`{doc['peer']}` in the same run. Written by "
         "`studies/real_speed.py`.", "",
         "Variants: `+oldreader` = the reader as it was (FFmpeg's own threads per video, decoding "
         "in the silhouettes' thread); without it, the new default (`[silhouettes] "
         "decode_threads = 1`, `decode_ahead = 2`). `+fullmasks` = the hull carved from the "
         "full-size (1088 × 1920) masks as before, not from the network's 272 × 480 ones "
         "(`capture.background.UpsampledMask`). `+track` = `person_track = true` (MediaPipe's "
         "tracking mode). `+every2` (`+every3`) = `person_every = 2` (3): each camera segmented "
         "every 2nd (3rd) frame, the cameras staggered, the others keeping their last map. "
         "Same poses: frames whose status and part positions are bit-identical "
         "to the peer's. Right: head, both hands and both feet within 0.15 m of Pose2Sim's 3D "
         "result.", ""]
    rows = []
    for v, r in doc["variants"].items():
        rows.append([v, r["end_to_end_fps"], r.get("fps_ratio", ""), r["first_frame_s"],
                     r.get("first_frame_ratio", ""), r["cpu_ms_per_frame"], r.get("cpu_ratio", ""),
                     r["main_thread_cpu_ms_per_frame"], round(2000 / r["cpu_ms_per_frame"], 1),
                     f"{100 * r['right_per_frame']:.0f} %", f"{100 * r['right_as_run']:.0f} %",
                     "" if r["same_poses_as_peer"] is None else f"{r['same_poses_as_peer']}/{r['frames']}",
                     ", ".join(f"{k} {x}" for k, x in r["stages_median_ms"].items())])
    L += real._table(["variant", "frames/s (target ≥ 20)", "ratio", "first frame s (target ≤ 2)",
                      "ratio", "CPU ms/frame", "ratio", "of which the geometric pipeline (main thread)",
                      "bound on 2 idle cores (2000 / CPU ms) frames/s", "right per frame", "right as run",
                      "same poses as peer", "stage medians ms (hull includes waiting)"], rows)
    L += ["", "## Accuracy (first round): errors against Pose2Sim's 3D result (m)", ""]
    L += real._table(["variant", "right per frame", "right as run", "head med / p90",
                      "hands med / p90", "feet med / p90"],
                     [[v, f"{100 * r['right_per_frame']:.0f} %", f"{100 * r['right_as_run']:.0f} %",
                       *(f"{r['errors'][k]['median']} / {r['errors'][k]['p90']}"
                         for k in ("head", "hand", "foot"))]
                      for v, r in doc["variants"].items() if "errors" in r])
    L += ["", "## Where the CPU goes, per frame (ms, by thread; medians; frames 2 to n - 8, "
          "while every thread runs)", "",
          "*pipeline*: the main thread (hull, skeleton, alignment, placement); *decode*: the "
          "read-ahead thread; *reader*: resizing and the silhouettes' Python side; *person "
          "pool*: the threads feeding the cameras' networks; *native*: threads Python did not "
          "start (MediaPipe's graphs and their inference, OpenCV's and FFmpeg's workers). Each "
          "stage runs in its own thread, ahead of the next (the reader up to 4 frames ahead of "
          "the pipeline, decoding 2 ahead of the reader), so the 2 cores idle only when every "
          "thread waits: the rate is bounded by 2000 / CPU ms, and by the busiest thread.", ""]
    L += real._table(["variant", "CPU ms/frame", "by thread"],
                     [[v, r["cpu_ms_per_frame"], ", ".join(
                         f"{k} {x}" for k, x in r.get("thread_cpu_ms_per_frame", {}).items())]
                      for v, r in doc["variants"].items()])
    L += ["", "Each round (frames/s, CPU ms/frame):", ""]
    L += real._table(["variant", "rounds"],
                     [[v, "; ".join(f"{x['end_to_end_fps']} / {x['cpu_ms_per_frame']}" for x in r["rounds"])]
                      for v, r in doc["variants"].items()])
    L += ["", "## Where the time goes (per frame of 4 cameras, one thread at a time)", ""]
    tm = doc.get("time_breakdown_machine")
    if tm:
        L += [f"Re-measured alone at {tm['date']}, load {tm['load_average']}.", ""]
    L += real._table(["step", "wall ms", "CPU ms"],
                     [[k, v["wall_ms"], v["cpu_ms"]] for k, v in doc["time_breakdown_per_frame"].items()])
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    sys.exit(main())
