"""A real recording: Pose2Sim's balancing trial, from its 4 videos and Calib.toml as shipped.

    python benchmarks/real.py [RECORDING] [--methods sequence,selfie,sequence+selfie,person] [--frames N]
    python benchmarks/real.py [RECORDING] --child CHILD_ROPE [--peer-src PEER/src]

``--child``: the 10-camera studio recording as it comes, against the current main in the same
run, with this recording's ``person`` run and a synthetic accuracy check
(:mod:`_real_child`).

RECORDING (default ``benchmarks/data/pose2sim_balancing/``): ``videos/cam01.mp4`` …,
``Calib.toml`` (tables ``cam_01`` …), ``reference/pose2sim_3d.trc`` (Pose2Sim's own 3D result,
TRC axes (X, Y, Z) = world (y, z, x)). No hand-made masks, no 2D keypoints: silhouettes come
from the sequence itself (``[silhouettes] method``, see ``topopose.capture.background``).

Scores (all frames, best guesses of rejected frames included; a failed frame counts as wrong):

- head: distance to the TRC ``Head`` marker;
- hands: distance to the segment from the wrist to 0.1 m beyond it along elbow → wrist
  (the hand: the model's hand is the end of the arm's skeleton branch, beyond the wrist);
- feet: distance to the segment ankle → big toe;
- ``hand_1``/``hand_2`` (and feet) are paired to left/right per frame to minimize the sum;
- a frame is *right* when head, both hands and both feet are within 0.15 m;
- precision of ``matched``: right frames among matched ones.

Two columns of the same run: *per frame* (each frame's :class:`FrameEstimator` result, the
confidence gate off so both decisions are scored) and *as ``run`` writes it* (:func:`as_run`:
the run's default gate decision, then the sequence stages ``topopose run`` applies,
:func:`topopose.sequence.motion.process_sequence`: identities over time with misplaced parts held
at their prediction or snapped to the free skeleton leaf nearest it, the kinematic skeleton,
left/right, and ``matched`` decided with the run's own consistency: by default the union of
the confidence gate and the consistency). *Precision of matched against recall*:
:func:`confidence_curve`. *Matched by the run's own consistency*: the same poses with the gate
alone (``run --no-consistency``), the consistency instead of the gate (``--consistency``)
and their union (the default) side by side (:mod:`topopose.sequence.consistency`, whose settings
were chosen on synthetic walks by ``benchmarks/consistency.py``, never on this recording).

Speed: end to end from the videos, one process as ``topopose run`` (a reader thread decodes
the 4 videos and computes the foreground probabilities ahead of the hull, skeleton and
alignment), resolution 100; the set-up (learning the background from 25 sampled frames;
``person`` has none: its zone grid is sized on the first frame) and the first frame are
reported apart, with their breakdowns.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
DEFAULT = HERE / "data" / "pose2sim_balancing"
RIGHT = 0.15            # metres
#: ``METHOD+VARIANT[+VARIANT]``: extra ``[silhouettes]`` lines of a variant of a method
VARIANTS = {"track": "person_track = true\n",              # MediaPipe's tracking mode
            # each camera segmented every 2nd (3rd) frame, staggered; the others keep theirs
            "every2": "person_every = 2\n", "every3": "person_every = 3\n",
            # the reader without read-ahead: FFmpeg's own threads, decoding in the reader thread
            "oldreader": "decode_threads = 0\ndecode_ahead = 0\n",
            # the hull carved from the full-size masks (not from the network's small ones)
            "fullmasks": "upsampled = false\n"}
HAND_EXT = 0.10         # metres beyond the wrist


def read_trc(path: Path) -> dict:
    """marker → (frames, 3) world coordinates (TRC (X, Y, Z) = world (y, z, x))."""
    lines = Path(path).read_text().splitlines()
    names = [x for x in lines[3].split("\t")[2:] if x.strip()]
    rows = [np.array([float(v) for v in ln.split("\t")[2:2 + 3 * len(names)]])
            for ln in lines[5:] if ln.strip()]
    a = np.array(rows).reshape(len(rows), len(names), 3)
    world = a[:, :, [2, 0, 1]]
    return {n: world[:, i] for i, n in enumerate(names)}


def seg_dist(p, a, b) -> float:
    if p is None:
        return float("inf")
    p, a, b = (np.asarray(x, float) for x in (p, a, b))
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0, 1)
    return float(np.linalg.norm(p - (a + t * ab)))


def frame_errors(parts: dict, ref: dict, i: int) -> dict:
    """Errors of one frame's head, hands, feet against the reference (metres)."""
    g = {k: v[i] for k, v in ref.items()}
    out = {"head": float("inf") if parts.get("head") is None
           else float(np.linalg.norm(np.asarray(parts["head"]) - g["Head"]))}
    hands = {}
    for side in "LR":
        w, e = g[f"{side}Wrist"], g[f"{side}Elbow"]
        d = (w - e) / max(np.linalg.norm(w - e), 1e-9)
        hands[side] = (w, w + HAND_EXT * d)
    feet = {side: (g[f"{side}Ankle"], g[f"{side}BigToe"]) for side in "LR"}
    for kind, segs in (("hand", hands), ("foot", feet)):
        a, b = parts.get(f"{kind}_1"), parts.get(f"{kind}_2")
        s1 = [seg_dist(a, *segs["L"]), seg_dist(b, *segs["R"])]
        s2 = [seg_dist(a, *segs["R"]), seg_dist(b, *segs["L"])]
        best = s1 if sum(min(x, 1e9) for x in s1) <= sum(min(x, 1e9) for x in s2) else s2
        # by side: s2 pairs hand_1 with R, so its distances are (R, L)
        out[f"{kind}_L"], out[f"{kind}_R"] = best if best is s1 else best[::-1]
    return out


def estimated_frames(est, cap, ref):
    """Each frame of ``cap`` through ``est`` with its stages (``detail=True``): (index, frame,
    pose, detail, errors against ``ref`` — :func:`frame_errors`, None for a failed frame)."""
    for i, f in enumerate(cap.frames):
        p, det = est.estimate(f, detail=True)
        yield i, f, p, det, (None if p.status == "failed" else frame_errors(p.parts, ref, i))


def make_capture(rec: Path, out: Path, method: str, extra: str = "") -> None:
    """A capture folder over the recording as shipped: ``calibration.toml`` = ``Calib.toml``
    (tables ``cam_01`` … matched to the videos ``cam01`` … by name), ``videos`` linked, and a
    ``capture.toml`` (Z up, metres, ``size_policy = "pad"`` for the 1080-wide videos, the
    silhouette method)."""
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(rec / "Calib.toml", out / "calibration.toml")
    (out / "videos").symlink_to((rec / "videos").resolve(), target_is_directory=True)
    (out / "capture.toml").write_text(
        '[capture]\nup = "+z"\nunits = "m"\nsize_policy = "pad"\n\n'
        f'[silhouettes]\nmethod = "{method}"\n{extra}')


def open_recording(path):
    """The recording's folder and Pose2Sim's 3D result, or None (said) when it is absent."""
    rec = Path(path)
    if not (rec / "videos").is_dir() or not (rec / "reference" / "pose2sim_3d.trc").is_file():
        print(f"{rec}: recording not found (needs videos/, Calib.toml, reference/); pass its path")
        return None
    return rec, read_trc(rec / "reference" / "pose2sim_3d.trc")


def person_recording(path):
    """:func:`open_recording` for a benchmark of the ``person`` silhouettes: ``(folder,
    reference)``, or the exit code after saying why not (2: no recording; 0: no MediaPipe,
    nothing measured)."""
    opened = open_recording(path)
    if opened is None:
        return 2
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        print("mediapipe not installed: the person silhouettes, hence this benchmark, are "
              "skipped (pip install mediapipe)")
        return 0
    return opened


def person_capture(rec: Path, out: Path, settings=()):
    """The recording as a loaded ``person`` capture in ``out`` (extra ``[silhouettes]`` lines)."""
    import topopose as tp

    make_capture(rec, out, "person", "".join(x + "\n" for x in settings))
    return tp.load_capture(out)


def summarize(poses, ref, frames_index, min_confidence) -> dict:
    """Scores of ``poses`` judged without the gate; *gated*: matched with the confidence gate at
    ``min_confidence`` (:func:`topopose.frame.confidence.passes_gate`, as ``run`` decides)."""
    errs, right, matched_right, matched = [], 0, 0, 0
    per = {k: [] for k in ("head", "hand", "foot")}
    from topopose.frame.confidence import passes_gate

    rows, gated, gated_right = [], 0, 0
    for p in poses:
        i = frames_index[p.frame]
        e = frame_errors(p.parts, ref, i) if p.status != "failed" else None
        ok = e is not None and all(v <= RIGHT for v in e.values())
        right += ok
        if p.status == "matched":
            matched += 1
            matched_right += ok
        if passes_gate(p.status, p.error, p.diagnostics.get("confidence"), min_confidence):
            gated += 1
            gated_right += ok
        if e is not None:
            per["head"].append(e["head"])
            per["hand"] += [e["hand_L"], e["hand_R"]]
            per["foot"] += [e["foot_L"], e["foot_R"]]
        rows.append({"frame": p.frame, "status": p.status, "right": bool(ok),
                     "confidence": p.diagnostics.get("confidence"), "distance": p.distance,
                     "errors": None if e is None else {k: round(v, 3) for k, v in e.items()},
                     "error": p.error})
    n = len(poses)
    stats = {}
    for k, v in per.items():
        v = np.asarray(v, float)
        v = v[np.isfinite(v)] if v.size else v
        stats[k] = {"median": round(float(np.median(v)), 3) if v.size else None,
                    "p90": round(float(np.percentile(v, 90)), 3) if v.size else None,
                    "placed": int(v.size)}
    return {"frames": n, "matched": matched, "matched_share": round(matched / n, 3),
            "confidence_curve": confidence_curve(rows),
            "right": right, "right_share": round(right / n, 3),
            "matched_precision": round(matched_right / matched, 3) if matched else None,
            "gated_matched": gated,
            "gated_precision": round(gated_right / gated, 3) if gated else None,
            "failed": sum(p.status == "failed" for p in poses), "errors": stats, "rows": rows}


def confidence_curve(rows, precisions=(1.0, 0.95, 0.9, 0.8, 0.75, 0.7, 0.0)) -> list:
    """How many right frames the confidence gate lets through, at which precision: for each
    target precision, the lowest gate threshold (:func:`~topopose.frame.confidence.passes_gate`
    at a frame's confidence) whose passing frames are right in at least that share, the frames
    passing and the right ones among them (None, 0, 0: no threshold reaches it)."""
    from topopose.frame.confidence import passes_gate

    levels = sorted({r["confidence"] for r in rows if r["confidence"] is not None}, reverse=True)
    out = []
    for target in precisions:
        best = {"precision_target": target, "threshold": None, "passing": 0, "right": 0}
        for t in levels:
            ok = [r["right"] for r in rows
                  if passes_gate(r["status"], r["error"], r["confidence"], t)]
            if ok and sum(ok) / len(ok) >= target:
                best = {"precision_target": target, "threshold": round(float(t), 3),
                        "passing": len(ok), "right": int(sum(ok))}
        out.append(best)
    return out


def as_run(poses, model, up, min_confidence, consistency=None, trim=None) -> list:
    """The poses as ``topopose run`` writes them (:func:`topopose.batch.run.run`): the confidence
    gate's decision at ``min_confidence`` unless None (the run's default gate,
    :func:`~topopose.frame.rules.default_gate`, at its minimum for the camera count; a frame
    rejected for its AHA distance that the gate judged too gets the gate's reason after it,
    as ``confidence.judge_frame`` writes it), then
    :func:`~topopose.sequence.motion.process_sequence` (track, skeleton, sides; ``consistency``:
    None, the run's default, the union of the gate and the consistency; False:
    ``topopose run --no-consistency``; True: ``--consistency``; ``trim=False``: without the
    hands' trim), the mirror names
    turned back into numbered parts for scoring. ``poses`` are left as they are."""
    import copy

    from topopose.sequence.chirality import numbered
    from topopose.frame.confidence import distance_only, passes_gate
    from topopose.sequence.motion import process_sequence

    ps = copy.deepcopy(poses)
    if min_confidence is not None:
        for p in ps:
            c = p.diagnostics.get("confidence")
            if passes_gate(p.status, p.error, c, min_confidence):
                p.status, p.error = "matched", None
            elif p.status == "matched":
                p.status = "rejected"
                p.error = f"confidence {c if c is None else round(c, 2)} below {min_confidence:g}"
            elif distance_only(p.error) and c is not None:
                p.error += f"; confidence {round(c, 2)} below {min_confidence:g}"
    motion = process_sequence(ps, model, up, track=True, sides=True, skeleton=True,
                              consistency=consistency, trim=trim)
    return [numbered(p, model) for p in motion.poses]


def same_poses(a, b) -> int:
    """How many frames of two runs have the same status and bit-identical part positions."""
    def key(p):
        return p.frame, p.status, sorted((k, None if v is None else np.asarray(v, float).tobytes())
                                         for k, v in p.parts.items())
    return sum(key(x) == key(y) for x, y in zip(a, b))


def thread_cpu() -> dict:
    """CPU seconds so far of this process's threads by kind (Linux ``/proc``; {} elsewhere):
    ``pipeline`` (the main thread: hull, skeleton, alignment, placement), ``decode`` (the
    read-ahead thread), ``reader`` (resizing, the silhouettes' Python side), ``person pool``
    (the threads that feed the cameras' networks), ``native`` (threads that Python did not
    start: MediaPipe's graphs and their inference, OpenCV's and FFmpeg's workers)."""
    import os
    import threading

    names = {t.native_id: t.name for t in threading.enumerate()}
    kinds = (("MainThread", "pipeline"), ("topopose-decode", "decode"),
             ("topopose-reader", "reader"), ("topopose-person", "person pool"))
    out = {}
    try:
        tick = os.sysconf("SC_CLK_TCK")
        for d in Path("/proc/self/task").iterdir():
            f = (d / "stat").read_text().rsplit(")", 1)[1].split()
            name = names.get(int(d.name), "")
            kind = next((k for n, k in kinds if name.startswith(n)), "native")
            out[kind] = out.get(kind, 0.0) + (int(f[11]) + int(f[12])) / tick
    except OSError:
        return {}
    return out


def run_method(rec, method, resolution, nframes, work: Path, ref, picture=None, extra=""):
    """Run the recording end to end from its videos (decoding and silhouettes in the reader
    thread, as ``topopose run`` does), score it, time it."""
    import warnings

    import topopose as tp
    from topopose.capture import prefetch
    from topopose.frame.confidence import temporal_confidence
    from topopose.frame.estimate import FrameEstimator, default_gate
    from topopose.batch.run import CENTRE as RUN_CENTRE     # the limbs' centring, on by default

    cdir = work / method.replace("+", "_")
    if cdir.exists():
        shutil.rmtree(cdir)
    base, *opts = method.split("+")
    if base == "sequence" and opts and opts[0] == "selfie":
        base, opts = "sequence+selfie", opts[1:]
    for o in opts:
        extra += VARIANTS[o]
    make_capture(rec, cdir, base, extra)
    def one_pass(support):
        """The run end to end, timed; ``support``: record the silhouette the model leaves
        unexplained (:mod:`topopose.frame.support`, which the run's consistency reads: on by
        default)."""
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")          # the "pad" policy warns for cam01/cam02
            cap = tp.load_capture(cdir)
            frames = cap.frames[:nframes] if nframes else cap.frames
            est = FrameEstimator(cap, "human", resolution, gate=False,   # both decisions scored
                                 support=support, centre=RUN_CENTRE)    # as `topopose run`
            poses = []
            with prefetch(cap, frames):
                t_setup = time.perf_counter() - t0    # background learned (prefetch learns it first)
                poses.append(est.estimate(frames[0]))
                t_first = time.perf_counter() - t0
                t1, c1, m1 = time.perf_counter(), time.process_time(), time.thread_time()
                # by thread: until the reader (≤ 4 frames ahead, decoding 2 more) may have ended
                k1, k2, nk = thread_cpu(), {}, max(len(frames) - 9, 1)
                for j, f in enumerate(frames[1:]):
                    if j == nk:
                        k2 = thread_cpu()
                    poses.append(est.estimate(f))
                k2 = k2 or thread_cpu()
                t_rest = time.perf_counter() - t1
                c_rest = time.process_time() - c1     # every thread's CPU (reader included)
                m_rest = time.thread_time() - m1      # this thread's: the geometric pipeline
        return (cap, frames, est, poses, t_setup, t_first, t_rest, c_rest, m_rest, k1, k2, nk)

    # the run as `topopose run` does it by default (timed, scored; the silhouette support
    # recorded: the consistency reads it, on by default)
    cap, frames, est, poses, t_setup, t_first, t_rest, c_rest, m_rest, k1, k2, nk = one_pass(True)
    sup_poses = poses
    temporal_confidence(poses, {f: i for i, f in enumerate(cap.frames)}, gate=False)
    idx = {f: i for i, f in enumerate(cap.frames)}
    mc = est.min_confidence                   # the run's minimum for this camera count
    res = summarize(poses, ref, idx, mc)
    run_poses = as_run(poses, est.model, cap.up_vector, mc if default_gate(cap) else None)
    res["as_run"] = summarize(run_poses, ref, idx, mc)
    res["as_run"]["trimmed"] = sum(bool(p.diagnostics.get("trimmed")) for p in run_poses)
    res["as_run"]["predicted"] = sum(bool(p.diagnostics.get("predicted")) for p in run_poses)
    res["as_run"]["snapped"] = sum(bool(p.diagnostics.get("snapped")) for p in run_poses)
    # `topopose run --no-consistency` (the gate alone) and `--consistency`
    # (topopose.sequence.consistency: the run's own consistency instead of the confidence's absolute
    # minimum); the run's default (as_run) is their union
    for key, mode in (("as_run_gate", False), ("as_run_consistency", True)):
        ps = as_run(poses, est.model, cap.up_vector, mc if default_gate(cap) else None,
                    consistency=mode)
        res[key] = summarize(ps, ref, idx, mc)
    # the same without the hands' trim (topopose.frame.trim), its peer in this run
    for key, mode in (("as_run_no_trim", None), ("as_run_consistency_no_trim", True)):
        ps = as_run(poses, est.model, cap.up_vector, mc if default_gate(cap) else None,
                    consistency=mode, trim=False)
        res[key] = summarize(ps, ref, idx, mc)
    stages = {}
    for p in poses[1:]:
        for k, v in p.timings_ms.items():
            stages.setdefault(k, []).append(v)
    per = t_rest / max(len(frames) - 1, 1)
    res["speed"] = {
        "setup_s": round(t_setup, 3),
        "first_frame_s": round(t_first, 3),
        "per_frame_ms": round(1000 * per, 2),
        "end_to_end_fps": round(1 / per, 2),
        # the process's CPU per frame (reader thread included): less sensitive to the other
        # processes on a shared machine; cores / CPU bounds the rate on an idle machine
        "cpu_ms_per_frame": round(1000 * c_rest / max(len(frames) - 1, 1), 2),
        "main_thread_cpu_ms_per_frame": round(1000 * m_rest / max(len(frames) - 1, 1), 2),
        "stages_median_ms": {k: round(float(np.median(v)), 2) for k, v in stages.items()},
        # the support feature's own cost (recorded by default; in the figures above)
        "support_median_ms": round(float(np.median([p.timings_ms.get("support", 0.0)
                                                    for p in sup_poses[1:]] or [0.0])), 2),
        # CPU per frame by thread kind (thread_cpu): where the 2 cores' time goes
        "thread_cpu_ms_per_frame": {k: round(1000 * (v - k1.get(k, 0.0)) / nk, 1)
                                    for k, v in sorted(k2.items(), key=lambda x: -x[1])},
        # where the first frame's time went: the set-up's steps, then the first frame's stages
        "setup_breakdown_s": {k: round(v, 3) for k, v in
                              (cap.cache.get(("setup_seconds",)) or {}).items()},
        "first_frame_stages_ms": {k: round(v, 1) for k, v in poses[0].timings_ms.items()},
    }
    res["min_confidence"] = mc
    res["method"] = method
    if picture is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _picture(cap, est, poses, res, picture)
    return res, poses


def time_breakdown(rec: Path, n: int = 20) -> dict:
    """Where the time goes, per frame of 4 cameras (process CPU time and wall time):
    decoding the videos, resizing, the colour probability at several scales (full resolution
    vs downscaled; against a stand-in background of the right size: timing only), the
    selfie and person networks, reading a JPEG frame."""
    import cv2

    from topopose.capture.background import SequenceBackground, foreground_probability
    from topopose.capture.options import SILHOUETTE_DEFAULTS

    vids = sorted((rec / "videos").glob("*.mp4"))
    frames = [[] for _ in vids]
    out = {}
    for v in vids:                           # the frames kept for the steps below
        vc = cv2.VideoCapture(str(v))
        frames[vids.index(v)] = [vc.read()[1] for _ in range(n)]

    def decode(params):                      # decoding alone (the frames are not kept)
        t0, c0 = time.perf_counter(), time.process_time()
        for v in vids:
            vc = cv2.VideoCapture(str(v), cv2.CAP_FFMPEG, params) if params else cv2.VideoCapture(str(v))
            for _ in range(n):
                if not vc.read()[0]:
                    break
        return (time.perf_counter() - t0) / n, (time.process_time() - c0) / n

    out["decode 4 videos"] = decode([])     # FFmpeg's own threads
    # as the reader decodes: one FFmpeg thread per video
    out["decode 4 videos, 1 FFmpeg thread each"] = decode([cv2.CAP_PROP_N_THREADS, 1])
    p = dict(SILHOUETTE_DEFAULTS, method="sequence")

    def clock(name, fn):
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(n):
            for k in range(len(vids)):
                fn(frames[k][i])
        out[name] = ((time.perf_counter() - t0) / n, (time.process_time() - c0) / n)

    for s in (1.0, 0.5, 0.25, 0.125):
        h, w = (int(round(x * s)) for x in frames[0][0].shape[:2])
        bg = SequenceBackground(np.full((h, w, 3), 90, np.uint8), np.ones((h, w), bool), None, None)
        if s < 1:
            clock(f"resize to {s}", lambda f, w=w, h=h: cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA))
        clock(f"colour probability at {s}",
              lambda f, w=w, h=h, bg=bg: foreground_probability(
                  f if s == 1 else cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA), bg, p))
    try:
        from topopose.capture.segment import selfie_probability
        zone = np.zeros((480, 272), bool)
        zone[100:400, 60:220] = True
        clock("selfie network (zone crop at 0.25)",
              lambda f: selfie_probability(cv2.resize(f, (272, 480)), zone, stream="timing"))
    except Exception:                      # noqa: BLE001  (mediapipe absent)
        pass
    try:
        from topopose.capture.segment import person_probability
        clock("person network (whole image at 0.25)",
              lambda f: person_probability(cv2.resize(f, (272, 480)), stream="timing"))
        from topopose.capture.segment import person_probabilities
        small = [[cv2.resize(f, (272, 480)) for f in fr] for fr in frames]
        person_probabilities([x[0] for x in small], [("timing4", k) for k in range(len(vids))])
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(n):                 # one graph per camera, the 4 cameras at once
            person_probabilities([x[i] for x in small], [("timing4", k) for k in range(len(vids))])
        out["person network, 4 cameras in threads"] = ((time.perf_counter() - t0) / n,
                                                       (time.process_time() - c0) / n)
        person_probabilities([x[0] for x in small], [("timing4t", k) for k in range(len(vids))], 0)
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(1, n):              # tracking mode: the detector skipped between frames
            person_probabilities([x[i] for x in small], [("timing4t", k) for k in range(len(vids))], i)
        out["person network, 4 cameras in threads, tracking mode"] = (
            (time.perf_counter() - t0) / (n - 1), (time.process_time() - c0) / (n - 1))
        for s in (0.125, 0.5):             # the network's input is fixed-size: a smaller image
            clock(f"person network (whole image at {s})",   # (or a crop) costs the same
                  lambda f, s=s: person_probability(cv2.resize(f, None, fx=s, fy=s,
                                                               interpolation=cv2.INTER_AREA),
                                                    stream=("timing", s)))
    except Exception:                      # noqa: BLE001  (mediapipe absent)
        pass
    enc = cv2.imencode(".jpg", frames[0][0], [cv2.IMWRITE_JPEG_QUALITY, 95])[1]
    clock("read a JPEG frame (as images/)", lambda f: cv2.imdecode(enc, cv2.IMREAD_COLOR))
    return {k: {"wall_ms": round(1000 * a, 2), "cpu_ms": round(1000 * b, 2)} for k, (a, b) in out.items()}


def runs_over(rec, methods, resolutions, ref):
    """:func:`run_method` for each method at each resolution, in a temporary folder: yields
    ``(method, resolution, result, poses)``."""
    with tempfile.TemporaryDirectory() as tmp:
        for r in resolutions:
            for m in methods:
                res, poses = run_method(rec, m, r, 0, Path(tmp), ref)
                yield m, r, res, poses


def runs_command(doc, argv, methods, resolutions, quick_method):
    """The command line of a benchmark over :func:`runs_over` (``real_spread.py``,
    ``real_snap.py``): ``(recording, reference, methods, resolutions, out folder)``, or the exit
    code after saying why not (:func:`person_recording`). ``--quick``: ``quick_method`` at 100³."""
    from _machine import results_dir

    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(DEFAULT))
    ap.add_argument("--methods", default=methods)
    ap.add_argument("--resolutions", default=resolutions)
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--quick", action="store_true", help="one method at 100³ only")
    a = ap.parse_args(argv)
    if a.quick:
        a.methods, a.resolutions = quick_method, "100"
    opened = person_recording(a.recording)
    if isinstance(opened, int):
        return opened
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    return (*opened, [m for m in a.methods.split(",") if m],
            [int(r) for r in a.resolutions.split(",") if r], out)


def _picture(cap, est, poses, res, path):
    """Silhouettes with the reprojected parts and the hull/skeleton of a matched, right frame
    (else the best-confidence one) at ``path``, and of the worst wrong frame (largest error of
    a placed head, hand or foot; a part left unplaced ranks as just wrong, 0.15 m) at ``path``
    with suffix ``_wrong``."""
    from topopose.viz.view import render_frame

    rows = {r["frame"]: r for r in res["rows"]}
    good = [p for p in poses if p.status == "matched" and rows[p.frame]["right"]]
    pick = good[len(good) // 2] if good else max(
        (p for p in poses if p.status != "failed"), key=lambda p: p.diagnostics.get("confidence", 0))
    wrong = [p for p in poses if rows[p.frame]["errors"] and not rows[p.frame]["right"]]
    worst = max(wrong, key=lambda p: max(v if np.isfinite(v) else RIGHT
                                         for v in rows[p.frame]["errors"].values()), default=None)
    for p, out in ((pick, Path(path)), (worst, Path(path).with_name(Path(path).stem + "_wrong.png"))):
        if p is None:
            continue
        _, det = est.estimate(p.frame, detail=True)
        e = rows[p.frame]["errors"] or {}
        render_frame(str(out), est.model, p, det, cap=cap, silhouettes=True, up=cap.up_vector,
                     title=f"Pose2Sim balancing, frame {p.frame}: {p.status}, confidence "
                           f"{p.diagnostics.get('confidence')}, "
                           f"{'right' if rows[p.frame]['right'] else 'wrong'} (≤ 0.15 m); largest "
                           f"error {max(e.values(), default=float('nan')):.2f} m"
                           + (" (a part not placed)" if any(np.isinf(v) for v in e.values()) else ""))
    return pick.frame


def main(argv=None):
    from _machine import machine

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(DEFAULT))
    ap.add_argument("--methods", default="sequence,selfie,sequence+selfie,person,person+track,"
                                         "person+track+every2")
    ap.add_argument("--resolution", type=int, default=100)
    ap.add_argument("--frames", type=int, default=0, help="first N frames only (0: all)")
    ap.add_argument("--out", default=str(HERE / "results" / "real"))
    ap.add_argument("--peer", default="person+oldreader",
                    help="method the speed ratios and pose identity are measured against")
    ap.add_argument("--set", action="append", default=[],
                    help="extra [silhouettes] field, e.g. --set occupancy=0.9 (TOML value)")
    ap.add_argument("--child", help="the child_rope studio recording: measured as it comes "
                                    "against the current main instead (benchmarks/_real_child.py;"
                                    " RECORDING gives its Pose2Sim part)")
    ap.add_argument("--peer-src", help="with --child: src folder of the peer tree")
    a = ap.parse_args(argv)
    if a.child:
        import _real_child as real_child
        return real_child.main([a.child, "--pose2sim", a.recording, "--synthetic", "40"]
                               + (["--peer", a.peer_src] if a.peer_src else []))
    rec = Path(a.recording)
    if not (rec / "videos").is_dir() or not (rec / "Calib.toml").is_file():
        print(f"{rec}: recording not found (needs videos/ and Calib.toml); pass its path")
        return 2
    ref = read_trc(rec / "reference" / "pose2sim_3d.trc")
    methods = [m for m in a.methods.split(",") if m]
    if "selfie" in a.methods or "person" in a.methods:
        try:
            import mediapipe  # noqa: F401
        except ImportError:
            print("mediapipe not installed: the selfie and person methods are skipped")
            methods = [m for m in methods if "selfie" not in m and not m.startswith("person")]
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    results, all_poses = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for m in methods:
            pic = out.parent / f"real_{m.replace('+', '_')}_frame.png"
            res, poses = run_method(rec, m, a.resolution, a.frames, Path(tmp), ref, picture=pic,
                                    extra="".join(x + "\n" for x in a.set))
            res["picture"] = pic.name
            results[m], all_poses[m] = res, poses
            print(m, {k: res[k] for k in ("matched_share", "right_share", "matched_precision")},
                  "as run:", {k: res["as_run"][k] for k in ("matched_share", "right_share")},
                  res["errors"], res["speed"])
    peer = results.get(a.peer)
    for m, r in results.items():         # against the peer measured in the same run
        if peer is not None:
            r["speed"]["fps_ratio_to_peer"] = round(r["speed"]["end_to_end_fps"]
                                                    / peer["speed"]["end_to_end_fps"], 2)
            r["speed"]["cpu_ratio_to_peer"] = round(r["speed"]["cpu_ms_per_frame"]
                                                    / peer["speed"]["cpu_ms_per_frame"], 2)
            r["same_poses_as_peer"] = same_poses(all_poses[m], all_poses[a.peer])
    breakdown = time_breakdown(rec)
    doc = {"peer": a.peer if peer is not None else None,"recording": str(rec), "machine": machine(), "resolution": a.resolution,
           "time_breakdown_per_frame": breakdown,
           "silhouette_settings": a.set,
           "right_within_m": RIGHT, "hand_extension_m": HAND_EXT, "methods": results}
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    out.with_suffix(".md").write_text(report(doc))
    print(f"wrote {out}.md / .json")
    return 0


def _pc(x):
    return "—" if x is None else f"{100 * x:.0f} %"


def _table(head: list, rows: list) -> list:
    """Markdown table lines."""
    return (["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
            + ["| " + " | ".join(str(x) for x in r) + " |" for r in rows])


def report(doc) -> str:
    m = doc["machine"]
    L = ["# Real recording: Pose2Sim balancing trial (4 phone cameras, 100 frames)", "",
         f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         f"Resolution {doc['resolution']}³. Written by `benchmarks/real.py`.", "",
         "A frame is *right* when head, both hands and both feet are within "
         f"{doc['right_within_m']} m of Pose2Sim's 3D result (hands: wrist → "
         f"{doc['hand_extension_m']} m beyond it; feet: ankle → big toe). Errors in metres over "
         "all processed frames (rejected frames' best guesses included).", ""]
    rows = []
    for name, r in doc["methods"].items():
        e = r["errors"]
        prec = "—" if r["matched_precision"] is None else f"{100 * r['matched_precision']:.0f} %"
        gp = "" if r.get("gated_precision") is None else f" ({100 * r['gated_precision']:.0f} % right)"
        rows.append([name, f"{r['matched']}/{r['frames']}", f"{100 * r['right_share']:.0f} %", prec,
                     f"{r.get('gated_matched', 0)}{gp}",
                     *(f"{e[k]['median']} / {e[k]['p90']}" for k in ("head", "hand", "foot")),
                     r["failed"]])
    L += _table(["silhouettes", "matched without the gate", "right (target ≥ 70 %)",
                 "precision of matched (target ≥ 95 %)",
                 "matched with the confidence gate (per frame; the run's default adds its consistency: below)", "head med / p90",
                 "hands med / p90", "feet med / p90", "failed"], rows)
    L += ["", "## As `topopose run` writes it", "",
          "The same run's poses after the run's default confidence gate and its sequence stages "
          "(tracking: misplaced numbered parts held at their prediction, flagged `predicted`, or "
          "moved to the free skeleton leaf nearest it, flagged `snapped`; "
          "kinematic skeleton; left/right; `matched` by default the union of the confidence "
          "gate and the run's own consistency, `--no-consistency`: the gate alone), scored the "
          "same way.", ""]
    rows = []
    for name, r in doc["methods"].items():
        a = r.get("as_run")
        if a is None:
            continue
        e = a["errors"]
        g = r.get("as_run_gate", a)
        rows.append([name, f"{100 * r['right_share']:.0f} %", f"{100 * a['right_share']:.0f} %",
                     f"{a['matched']}/{a['frames']}", _pc(a["matched_precision"]),
                     f"{g['matched']}/{g['frames']}",
                     f"{a.get('predicted', 0)} / {a.get('snapped', 0)}",
                     *(f"{e[k]['median']} / {e[k]['p90']}" for k in ("head", "hand", "foot"))])
    L += _table(["silhouettes", "right per frame", "right as `run` writes it",
                 "matched (the run's default: gate ∪ consistency)", "precision of matched",
                 "matched (`--no-consistency`: gate alone)", "frames with a held / snapped part",
                 "head med / p90", "hands med / p90", "feet med / p90"], rows)
    L += ["", "## `matched` by the run's own consistency: gate, consistency, union", "",
          "The same poses as `run` writes them, with `matched` decided by the confidence gate "
          "alone (`run --no-consistency`), by `topopose.sequence.consistency` instead of it "
          "(`--consistency`: agreement with the neighbouring frames, no part held at its "
          "tracked prediction, and the share of the silhouettes the placed model leaves "
          "unexplained, `topopose.frame.support`, recorded by the run; thresholds chosen on "
          "synthetic walks, never on this recording: `benchmarks/consistency.py`), and by "
          "their union (the run's default: the gate's frames, and those the gate alone "
          "rejected that are consistent).",
          ""]
    rows = []
    for name, r in doc["methods"].items():
        a, c = r.get("as_run"), r.get("as_run_consistency")
        g = r.get("as_run_gate")
        if a is None or c is None or g is None:
            continue
        rows.append([name, f"{100 * a['right_share']:.0f} %",
                     *(x for y in (g, c, a) for x in (f"{y['matched']}/{y['frames']}",
                                                      _pc(y["matched_precision"])))])
    L += _table(["silhouettes", "right as `run` writes it", "matched (gate)",
                 "precision (gate)", "matched (consistency)", "precision (consistency)",
                 "matched (union, the default)", "precision (union; target ≥ 95 %)"], rows)
    L += ["", "## The hands' trim (`topopose.frame.trim`, on by default) against its peer", "",
          "The same run's poses as `run` writes them, without the trim (`run --no-trim`) → with it "
          "(hands moved back out of the hull's phantom volume: frames trimmed).", ""]
    # (as_run: the run's default, the union; as_run_consistency: --consistency)
    rows = []
    for name, r in doc["methods"].items():
        a, c = r.get("as_run"), r.get("as_run_consistency")
        a0, c0 = r.get("as_run_no_trim"), r.get("as_run_consistency_no_trim")
        if None in (a, c, a0, c0):
            continue
        pc = ["—" if x["matched_precision"] is None else f"{100 * x['matched_precision']:.0f} %"
              for x in (c0, c)]
        rows.append([name, a.get("trimmed", 0),
                     f"{100 * a0['right_share']:.0f} % → {100 * a['right_share']:.0f} %",
                     f"{a0['errors']['hand']['p90']} → {a['errors']['hand']['p90']}",
                     f"{a0['matched']} at {_pc(a0['matched_precision'])} → {a['matched']} at "
                     f"{_pc(a['matched_precision'])}",
                     f"{c0['matched']} at {pc[0]} → {c['matched']} at {pc[1]}"])
    L += _table(["silhouettes", "frames trimmed", "right as `run` writes it", "hands p90 (m)",
                 "the run's default: matched, precision", "`--consistency`: matched, precision"],
                rows)
    L += ["", "## Precision of `matched` against recall", "",
          "How many right frames a confidence gate lets through (per frame, as the first table): "
          "the lowest threshold on the frame's confidence whose passing frames are right in at "
          "least the target share (the run's default threshold in parentheses: "
          + ", ".join(f"{n} {r.get('min_confidence')}" for n, r in doc["methods"].items()) + ").", ""]
    rows = []
    for name, r in doc["methods"].items():
        for c in r.get("confidence_curve", []) if r["right"] else []:
            rows.append([name, f"{100 * c['precision_target']:.0f} %" if c["precision_target"]
                         else "any (every frame)", c["threshold"], c["passing"],
                         f"{c['right']} of {r['right']}"])
    L += _table(["silhouettes", "precision at least", "confidence threshold", "frames passing",
                 "right frames passing"], rows)
    L += ["", "## Speed (one process)", ""]
    if doc.get("peer"):
        L += [f"Ratios and pose identity against `{doc['peer']}` in the same run (`+oldreader`: "
              "the reader without the read-ahead thread, FFmpeg's own threads per video; "
              "same poses: status and part positions bit-identical).", ""]
    rows = []
    peer = bool(doc.get("peer"))
    for name, r in doc["methods"].items():
        s = r["speed"]
        vs = [s.get("fps_ratio_to_peer", ""), s.get("cpu_ratio_to_peer", ""),
              "" if r.get("same_poses_as_peer") is None
              else f"{r['same_poses_as_peer']}/{r['frames']}"] if peer else []
        rows.append([name, s["setup_s"], s["first_frame_s"], s["per_frame_ms"], s["end_to_end_fps"],
                     s.get("cpu_ms_per_frame", ""), *vs,
                     ", ".join(f"{k} {v}" for k, v in s["stages_median_ms"].items()),
                     s.get("support_median_ms", "")])
    L += _table(["silhouettes", "set-up s (background)", "first frame s incl. set-up (target ≤ 2)",
                 "ms/frame after", "end-to-end frames/s (target ≥ 20)", "CPU ms/frame (all threads)",
                 *(["frames/s ratio to peer", "CPU ratio to peer", "same poses as peer"] if peer
                   else []),
                 "stage medians ms (hull includes waiting for the reader)",
                 "of which the silhouette support ms (on by default)"], rows)
    L += ["", "## Where the first frame's time goes (s)", ""]
    L += _table(["silhouettes", "set-up steps", "first frame's stages"],
                [[name, ", ".join(f"{k} {v}" for k, v in r["speed"].get("setup_breakdown_s", {}).items()),
                  ", ".join(f"{k} {round(v / 1000, 3)}" for k, v in
                            r["speed"].get("first_frame_stages_ms", {}).items())]
                 for name, r in doc["methods"].items()])
    L += ["", "## Where the time goes (per frame of 4 cameras)", ""]
    L += _table(["step", "wall ms", "CPU ms"],
                [[k, v["wall_ms"], v["cpu_ms"]] for k, v in doc["time_breakdown_per_frame"].items()])
    L += ["", "Pictures: " + ", ".join(f"`{r['picture']}`" for r in doc["methods"].values()), ""]
    return "\n".join(L)


if __name__ == "__main__":
    sys.exit(main())
