"""Batch pose initialization over a capture: progress, incremental output, resume, parallel
workers and Dask clusters (DESIGN.md, ``topopose run``).

Every frame is independent (thesis §12.1: initialization needs no previous frame), so frames
run in any order on any number of processes. Each finished frame is written to the output
as one JSON line and flushed at once, so an interrupted run keeps what it computed and
``resume=True`` skips the frames already in the file; a frame that fails is reported with
its reason and never stops the run. At the end the file is rewritten sorted by frame.

Parallel runs use one code path for local processes and clusters: a
``dask.distributed.Client`` on ``LocalCluster(n_workers=N, processes=True)`` or on a
scheduler address. Each worker process builds its :class:`FrameEstimator` (model
precomputation, hull projection tables) once, on first use, and keeps it for all its frames.
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from topopose.errors import InputError
from topopose.frame.estimate import FrameEstimator
from topopose.pose.model import load_model
from topopose.pose.pose import Pose, read_poses, write_poses


@dataclass
class RunResult:
    """What a run produced (all frames of the output file, including resumed ones)."""

    poses: list
    output: Path | None
    computed: int = 0
    skipped: int = 0
    seconds: float = 0.0
    counts: dict = field(default_factory=dict)

    @property
    def failed(self) -> list:
        return [p for p in self.poses if p.status == "failed"]

    @property
    def exit_status(self) -> int:
        """0: every frame processed (rejections included); 1: some frames failed."""
        return 1 if self.failed else 0


def _frame_bound(cap, text: str, whole: str):
    """One bound of ``--frames a:b``: an index, or a time ``1.5s`` (frame i is at i / fps)."""
    t = text.strip()
    if not t:
        return None
    if t.lower().endswith("s"):
        try:
            sec = float(t[:-1])
        except ValueError:
            raise InputError(f"--frames: {whole!r}: {t!r} is not a time like 1.5s") from None
        if not cap.fps:
            raise InputError(f"--frames: {whole!r} gives times but the capture has no frame rate "
                             f"(videos give it; else set [capture] fps in capture.toml)")
        return max(0, math.ceil(sec * cap.fps - 1e-9))
    return int(t)


def select_frames(cap, frames) -> list:
    """Frame names from None (all), a list, or a text: ``"a:b"`` / ``"a:b:s"`` (indices, Python
    slice rules), ``"0.5s:1.2s"`` (times in seconds: the frames i with 0.5 ≤ i / fps < 1.2; the
    step, if any, is in frames; times and indices mix, e.g. ``"2s:"``), or ``"f1,f2"``."""
    if frames is None:
        return list(cap.frames)
    given = frames
    if isinstance(frames, str):
        text = frames.strip()
        if ":" in text:
            bits = text.split(":")
            try:
                if len(bits) > 3:
                    raise ValueError
                sl = slice(*[_frame_bound(cap, b, frames) if k < 2
                             else (int(b) if b.strip() else None) for k, b in enumerate(bits)])
            except InputError:
                raise
            except (ValueError, TypeError):
                raise InputError(f"--frames: {frames!r} must be START:STOP[:STEP] (indices, or "
                                 "times like 0.5s:1.2s) or a comma-separated list of frame "
                                 "names") from None
            out = list(cap.frames)[sl]
            if not out:
                raise InputError(f"--frames: {frames!r} selects no frame ({len(cap.frames)} frames)")
            return out
        frames = [f.strip() for f in text.split(",") if f.strip()]
    if not frames:
        raise InputError(f"--frames: {given!r} selects no frame")
    out = [cap.frame_name(int(f) if isinstance(f, str) and f.isdigit() and f not in cap.frames
                          else f) for f in frames]
    return out


def _spec(cap, model, resolution, threshold, options):
    """A small, picklable description from which each worker builds its estimator once."""
    spec = {"model": model.to_dict(), "resolution": resolution, "threshold": threshold,
            "options": options}
    if cap.path is not None and cap.masks is None:
        spec["capture_path"] = str(cap.path)
    else:
        spec["capture"] = cap          # in-memory capture: shipped once per worker
    return spec


def _key(spec) -> str:
    d = {k: v for k, v in spec.items() if k != "capture"}
    d["capture_id"] = id(spec.get("capture")) if "capture" in spec else None
    return json.dumps(d, sort_keys=True, default=str)


def _build(spec) -> FrameEstimator:
    from topopose.capture import load_capture
    from topopose.pose.model import model_from_dict

    cap = spec["capture"] if "capture" in spec else load_capture(spec["capture_path"])
    model = model_from_dict(spec["model"], source="model")
    return FrameEstimator(cap, model, spec["resolution"], spec["threshold"], **spec["options"])


def _worker_estimate(spec_key, spec, frame) -> dict:
    """Runs on a Dask worker: estimate one frame with the worker's cached estimator."""
    from distributed import get_worker

    w = get_worker()
    cache = getattr(w, "_topopose_estimators", None)
    if cache is None:
        cache = {}
        w._topopose_estimators = cache   # one estimator per worker process and run spec
    est = cache.get(spec_key)
    if est is None:
        cache.clear()
        est = cache[spec_key] = _build(spec)
    return est.estimate(frame).to_dict()


def _progress(total, enabled, desc):
    if not enabled:
        return None
    from tqdm import tqdm

    # smoothing 0: the rate is frames over time since the end of the first frame (see run)
    return tqdm(total=total, unit="frame", desc=desc, dynamic_ncols=True, file=sys.stderr,
                smoothing=0)


#: ``run``'s default for ``centre`` (:mod:`topopose.frame.centre`: the limbs' curves onto the
#: silhouettes' centre lines, recorded per frame for the kinematic fit): on — development
#: MPJPE 8 cameras 3.63 → 3.44 cm, 4 phones (4p / 4pd) unchanged (benchmarks/centre_dev.py)
CENTRE = True


def run(capture, model="human", resolution=100, threshold=None, output=None, *, frames=None,
        workers=1, scheduler=None, resume=False, progress=True, trc=None, csv=None, c3d=None,
        constraints=True, betweenness=True, relation=None, max_missing=1, thinning="d6i1d",
        tolerance=None, refocus=False, on_pose=None, gate=None, thickness=None, track=True,
        sides=True, skeleton=True, smooth=None, bvh=None, consistency=None,
        support=None, support_test=False, trim=None, centre=None, follow=None) -> RunResult:
    """Estimate the pose in every frame of a capture (thesis §12.1), writing as it goes.

    Parameters
    ----------
    capture : Capture or path
    model : Model, built-in name or TOML path
    resolution, threshold : see :class:`FrameEstimator`
    output : path, optional
        JSON Lines output; each frame is appended and flushed as soon as it is done.
    frames : None, list or "a:b" / "f1,f2"
    workers : int
        > 1: run frames in that many worker processes (Dask ``LocalCluster``).
    scheduler : str, optional
        Address of a Dask scheduler (e.g. ``"tcp://host:8786"``): run on that cluster.
    resume : bool
        Skip the frames already in ``output`` (an interrupted run continues).
    trc, csv, c3d : path, optional
        Exports of the matched frames (TRC in metres, wide CSV, C3D with the optional extra).
    constraints : bool
        False drops the model's coordinate constraints (acrobatics).
    betweenness, relation : apply the betweenness constraints; ``relation`` overrides the
        model's relation (``"b"`` or ``"i"``, thesis §13.2.2.2).
    tolerance : int or None
        Visual-hull tolerance (voxels seen by C − tolerance cameras); None: 1 with ≥ 6
        cameras, else 0 (see :class:`FrameEstimator`).
    refocus : bool
        Visual hull on a grid refocused on the subject every frame, fixed voxel size
        (thesis §13.2.2.1; as ``topopose hull --refocus``).
    on_pose : callable, optional
        Called with each :class:`Pose` as it finishes (e.g. a live viewer).
    gate : bool or None
        ``matched`` also needs the frame's confidence (:mod:`.confidence`, with the time
        factors computed over the run at the end) above its minimum; False: the confidence is
        reported only; None: :func:`~topopose.frame.estimate.default_gate` (on with fewer than
        6 cameras).
    thickness : float or None
        Weight of the thickness term of the arc cost (see :class:`FrameEstimator`); 0: off.
    track : bool
        Sequences (more than one frame): give the numbered parts stable identities over time
        (:func:`topopose.sequence.track.track`); the output file is rewritten with them.
    sides : bool
        Name the model's mirror pairs left / right (:mod:`topopose.sequence.chirality`).
    skeleton : bool
        Fit the full kinematic skeleton (:mod:`topopose.sequence.kinematic_fit`): ``Pose.joints``.
    smooth : int, optional
        Savitzky–Golay window (frames) smoothing the skeleton over runs of continuing motion
        (default :func:`topopose.sequence.kinematic_fit.smooth_window` of the capture's frame
        rate: 9 frames at 25 frames/s, 0.36 s; 0: off).
    trim : bool, optional
        Hands trimmed back out of the hull's phantom volume where the silhouettes' evidence
        ends (:mod:`topopose.frame.trim`, recorded per frame, applied after the identities;
        default :data:`topopose.sequence.motion.TRIM`, on).
    centre : bool, optional
        Record per frame the limbs' curves moved onto the silhouettes' centre lines
        (:mod:`topopose.frame.centre`, ``diagnostics["centred"]``; the kinematic fit uses them,
        :data:`topopose.sequence.kinematic_fit.CENTRED`); None (default): :data:`CENTRE`. Recorded
        in the run's per-frame options (the poses file's header).
    bvh : path, optional
        BVH export of the fitted skeleton (Blender).
    consistency : bool, "union", dict or None
        Sequences of one subject (a run of unrelated poses is left as it is): ``matched``
        decided with the run's own consistency (:mod:`topopose.sequence.consistency`). None
        (default): :data:`topopose.sequence.motion.CONSISTENCY`, ``"union"`` — a frame the
        confidence gate matched stays matched (unless a part of it was held at its tracked
        prediction) and a frame the gate alone rejected is matched when consistent with the
        run; True (``run --consistency``): the consistency instead of the gate; False
        (``--no-consistency``): the gate alone; a dict gives
        :func:`~topopose.sequence.consistency.judge_sequence`'s settings
        (``benchmarks/results/consistency.md``). With ``track``, ``sides`` and ``skeleton``
        all off, None means False: the per-frame results as the estimator gave them.
    support : bool, optional
        Record each frame's ``diagnostics["unexplained"]`` (:mod:`topopose.frame.support`),
        which the consistency reads; None (default): with ``consistency`` (on by default) or
        ``support_test``.
    support_test : bool or "replace"
        Per frame (also runs of unrelated poses): a matched frame whose silhouette is left
        unexplained by the placed model above
        :data:`topopose.sequence.consistency.MAX_UNEXPLAINED` is rejected
        (:func:`topopose.sequence.consistency.judge_support`, ``run --support``); ``"replace"``:
        the test replaces the confidence gate (frames the gate alone rejected are matched when
        they pass). Off by default (``benchmarks/results/applications_detection.md``).
    follow : FollowOptions, optional
        Sequences with the skeleton: the subject's capsule body tracked through every frame
        from the confident ones (:mod:`topopose.sequence.follow`; statuses ``matched``,
        ``tracked``, ``lost``, every tracked frame's joints and ``fit``); None: the defaults
        (on); ``FollowOptions(enabled=False)``: off.

    Returns
    -------
    RunResult
        ``.exit_status`` is 1 when some frames failed.
    """
    from topopose import _paths
    from topopose.capture import Capture, load_capture

    # ---- every argument and output checked before any work or any write
    if workers is None or isinstance(workers, bool) or int(workers) < 1:
        raise InputError(f"--workers: must be at least 1, got {workers}")
    resolution = _paths.check_resolution(resolution)
    threshold = _paths.check_threshold(threshold)
    m = load_model(model, constraints=constraints)
    cap = capture if isinstance(capture, Capture) else load_capture(capture)
    tolerance = _paths.check_tolerance(tolerance, len(cap.cameras))
    if gate is None:
        from topopose.frame.estimate import default_gate
        gate = default_gate(cap)
    options = {"betweenness": betweenness, "relation": relation, "max_missing": max_missing,
               "thinning": thinning, "tolerance": tolerance, "gate": gate}
    if refocus:
        options["refocus"] = True
    if thickness is not None:
        options["thickness"] = float(thickness)
    from topopose.sequence.motion import consistency_settings
    if consistency is None and not (track or sides or skeleton):
        consistency = False               # no sequence stage asked for: per-frame results
    try:
        judged = consistency_settings(consistency) is not None
    except ValueError as e:
        raise InputError(str(e)) from None
    if support or (support is None and (judged or support_test)):   # read by them
        options["support"] = True
    if CENTRE if centre is None else centre:
        options["centre"] = True
    todo = select_frames(cap, frames)
    if c3d is not None:
        from topopose.pose.export import require_c3d
        require_c3d()
    if trc is not None or c3d is not None:
        from topopose.pose.export import metres_per_unit
        metres_per_unit(cap.units)
    if bvh is not None and not (skeleton and m.joints):
        raise InputError(f"--bvh: model {m.name!r} has no [[joint]] (or --no-skeleton): no "
                         "skeleton to export")
    exports = {k: _paths.writable_output(v, f"--{k}") for k, v in
               (("trc", trc), ("csv", csv), ("c3d", c3d), ("bvh", bvh)) if v is not None}
    out = _paths.writable_output(output, "--output") if output is not None else None
    header = run_header(cap, m, resolution, threshold, options)
    done = {}
    partial = out.with_name(out.name + ".partial") if out is not None else None
    if out is not None and resume:
        for f in (out, partial):         # the .partial file of a killed run holds its frames
            if f.exists():
                check_resume(f, header, m)
                for p in read_poses(f, strict=False):
                    done[p.frame] = p
    skipped = [f for f in todo if f in done]
    todo = [f for f in todo if f not in done]

    # ---- the run: frames appended (and flushed) to a temporary file beside the output, which
    # replaces the output at the end — also on Ctrl-C or an error, so nothing computed is lost;
    # a killed process leaves the existing output as it was (and the partial file beside it)
    results = dict(done)
    t0 = time.perf_counter()
    fh = None
    if partial is not None:
        fh = open(partial, "w")
        fh.write(json.dumps(header, separators=(",", ":")) + "\n")
        for p in sorted(done.values(), key=lambda p: p.frame):
            fh.write(p.to_json() + "\n")
        fh.flush()
    bar = _progress(len(todo), progress and len(todo) > 0, f"{m.name} @ {resolution}³")
    first = [True]

    def finish(pose: Pose):
        results[pose.frame] = pose
        if fh is not None:
            fh.write(pose.to_json() + "\n")
            fh.flush()
        if bar is not None:
            bar.update(1)
            if first[0]:        # the ETA counts from the end of the first frame, which pays
                first[0] = False          # the first run's compilation and tables
                bar.start_t = bar.last_print_t = bar._time()
                bar.initial = bar.n
            bar.set_postfix(status=pose.status[:7], refresh=False)
        if on_pose is not None:
            on_pose(pose)

    def note(message):
        if bar is not None:
            bar.set_postfix_str(message)

    from topopose import _coldstart

    try:
        with _coldstart.notices(note):
            if todo and (workers > 1 or scheduler):
                _run_dask(cap, m, resolution, threshold, options, todo, workers, scheduler, finish)
            elif todo:
                from topopose.capture import prefetch

                warm = _coldstart.start_warmup()     # first run: a helper process
                try:
                    est = FrameEstimator(cap, m, resolution, threshold, **options)
                    est.warmup = warm
                    with prefetch(cap, todo):        # decoding + silhouettes run ahead in a thread
                        for f in todo:
                            finish(est.estimate(f))
                finally:
                    warm.close()
    finally:
        if bar is not None:
            bar.close()
        from topopose.frame.confidence import temporal_confidence      # time factors need the whole run
        temporal_confidence(list(results.values()), {f: i for i, f in enumerate(cap.frames)},
                            gate=gate and m.name == "human")
        if support_test:                  # per frame, on the statuses the gate gave
            from topopose.sequence.consistency import judge_support
            judge_support(results.values(), gate=support_test != "replace")
        if fh is not None:
            fh.close()
            if len(results) > len(done) or not out.exists() or resume:
                write_poses(out, results.values(), header)   # sorted, atomic replace
            partial.unlink(missing_ok=True)
    seconds = time.perf_counter() - t0
    poses = [results[k] for k in sorted(results)]
    motion = None
    # a resume with nothing to do keeps the file
    if (track or sides or skeleton or judged) and todo:
        from topopose.sequence.motion import process_sequence
        motion = process_sequence(poses, m, cap.up_vector, track=track, sides=sides,
                                  skeleton=skeleton, smooth=smooth, consistency=consistency,
                                  trim=trim, fps=cap.fps)
        poses = motion.poses
        from topopose.sequence.follow import follow_run
        poses = follow_run(poses, motion, m, cap, resolution, threshold, options, follow)
        if out is not None:
            write_poses(out, poses, header)
    counts = {s: sum(p.status == s for p in poses)
              for s in ("matched", "tracked", "rejected", "lost", "failed")}
    res = RunResult(poses, out, computed=len(todo), skipped=len(skipped), seconds=seconds,
                    counts=counts)
    units = cap.units
    fps = cap.fps or 25.0
    from topopose.pose.export import OPENSIM_LABELS, marker_names, write_c3d, write_csv, write_trc
    markers = marker_names(poses, m.parts)
    writers = {"trc": lambda t: write_trc(t, poses, markers, fps=fps, units=units, up=cap.up,
                                          labels=OPENSIM_LABELS),
               "csv": lambda t: write_csv(t, poses, markers),
               "c3d": lambda t: write_c3d(t, poses, markers, fps=fps, units=units,
                                          labels=OPENSIM_LABELS),
               "bvh": lambda t: write_motion_bvh(t, poses, motion, m, fps=fps, units=units,
                                                 up=cap.up)}
    for k, path in exports.items():
        with _paths.atomic_output(path) as t:
            writers[k](t)
    return res


def _hash(obj) -> str:
    import hashlib

    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def run_header(cap, model, resolution, threshold, options) -> dict:
    """The poses file's first line: what made it (``--resume`` refuses another model,
    resolution, capture or setting)."""
    from topopose import __version__

    calib = None
    if cap.path is not None:
        f = Path(cap.path) / "calibration.toml"
        if f.is_file():
            import hashlib
            calib = hashlib.sha256(f.read_bytes()).hexdigest()[:16]
    return {"topopose": __version__, "model": model.name, "model_hash": _hash(model.to_dict()),
            "resolution": int(resolution),
            "capture": str(Path(cap.path).resolve()) if cap.path is not None else None,
            "calibration_hash": calib, "up": cap.up, "threshold": threshold,
            "settings": {k: v for k, v in sorted(options.items())}}


def check_resume(out, header, model):
    """Refuse to resume ``out`` when it was made with another model, resolution, capture or
    setting (its header says so; a file without a header must at least hold the model's parts)."""
    from topopose.pose.pose import read_header

    old = read_header(out)
    if old is None:
        from topopose.sequence.chirality import numbered                  # left_/right_ names → the model's

        for p in read_poses(out, strict=False)[:1]:
            if set(numbered(p, model).parts) != set(model.parts):
                raise InputError(f"--resume: {out} holds poses of other parts "
                                 f"({', '.join(sorted(p.parts))}), not of model {model.name!r}; "
                                 "use another --output")
        return
    for key, name in (("model_hash", "model"), ("resolution", "resolution"),
                      ("capture", "capture"), ("calibration_hash", "calibration"),
                      ("threshold", "threshold"), ("settings", "settings")):
        a, b = old.get(key), header.get(key)
        if key == "capture" and (a is None or b is None):
            continue
        if a != b:
            shown = {"model_hash": (old.get("model"), header.get("model"))}.get(key, (a, b))
            raise InputError(f"--resume: {out} was made with another {name} ({shown[0]!r}, now "
                             f"{shown[1]!r}); use another --output or run without --resume")


def write_motion_bvh(path, poses, motion, model, fps=25.0, units="m", up="+z"):
    """BVH of the fitted skeleton. Joints carry their side names in the mirror order
    (``left_elbow`` is ``elbow_1``'s name when ``hand_1`` → ``left_hand``); a frame where the
    side was not decided uses the numbered joint in its place. Frames without a skeleton repeat
    the last one (BVH has no gaps; poses.jsonl says which frames were fitted)."""
    import numpy as np

    from topopose.sequence.chirality import joint_renaming
    from topopose.pose.export import write_bvh

    if motion is None or motion.tree is None:
        raise InputError("--bvh: no skeleton fitted (the model declares no [[joint]], or "
                         "--no-skeleton)")
    tree = motion.tree
    mapping = {pp: n for parts, names in model.mirrors for pp, n in zip(parts, names)}
    ren = joint_renaming(model, mapping, tree.names)
    names = [ren.get(n, n) for n in tree.names]
    P = np.full((len(poses), len(names), 3), np.nan)
    for i, p in enumerate(poses):
        for j, (nm, num) in enumerate(zip(names, tree.names)):
            v = p.joints.get(nm, p.joints.get(num))
            if v is not None:
                P[i, j] = v
    return write_bvh(path, names, tree.parents, P, fps=fps, units=units, up=up)


def _run_dask(cap, model, resolution, threshold, options, todo, workers, scheduler, finish):
    from dask.distributed import Client, LocalCluster, as_completed

    spec = _spec(cap, model, resolution, threshold, options)
    key = _key(spec)
    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise InputError(f"--scheduler: cannot reach Dask scheduler {scheduler!r} ({exc})") from None
        cluster = None
    else:
        # the worker processes ignore Ctrl-C (inherited SIG_IGN): only this process gets the
        # KeyboardInterrupt, and closes the cluster quietly, instead of every worker and nanny
        # printing its own traceback
        import signal

        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=50)   # CRITICAL only: a
                                   # worker heartbeat that outlives the scheduler on Ctrl-C logs ERROR
        finally:
            signal.signal(signal.SIGINT, old)
        client = Client(cluster)
    try:
        spec_f = client.scatter([spec], broadcast=True)[0] if "capture" in spec else spec
        futures = {client.submit(_worker_estimate, key, spec_f, f, pure=False): f for f in todo}
        for fut in as_completed(list(futures)):
            try:
                pose = Pose.from_dict(fut.result())
            except Exception as exc:       # worker died: that frame failed, the run goes on
                frame = futures[fut]
                pose = Pose(frame, "failed", None, {p: None for p in model.parts},
                            f"worker: {type(exc).__name__}: {exc}")
            finish(pose)
    except KeyboardInterrupt:
        import logging

        for name in ("distributed", "tornado", "asyncio"):   # shutting down mid-task: quiet
            logging.getLogger(name).setLevel(logging.CRITICAL)
        raise
    finally:
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        except Exception:       # noqa: BLE001  a cluster closing mid-task may complain
            pass


#: ``topopose run --workers N`` uses N local processes only for at least this many frames per
#: worker. benchmarks/workers.py (2 cores, load ~2, 100³): one process 10 ms per frame (its
#: prefetch thread already uses the second core); two workers cost ~1.5 s to start and then run
#: at ~9.6 ms per frame, so they win only from ~2,500 frames (40 frames: 4× slower, 200: 1.6×).
#: Workers pay off with more cores or on a cluster (``--scheduler``).
MIN_FRAMES_PER_WORKER = 1000


def run_cli(a) -> int:
    """``topopose run``: prints a summary; exit 1 when some frames failed."""
    workers = a.workers
    if workers and workers > 1 and not a.scheduler:
        from topopose.capture import load_capture

        n = len(select_frames(load_capture(a.capture), getattr(a, "frames", None)))
        if n < MIN_FRAMES_PER_WORKER * workers:
            print(f"topopose: note: --workers {workers}: {n} frames run faster in this process "
                  f"(starting {workers} worker processes costs more than they save below "
                  f"{MIN_FRAMES_PER_WORKER * workers} frames)", file=sys.stderr)
            workers = 1
    if getattr(a, "rerun", None):
        from topopose._paths import writable_output
        from topopose.viz.rerun import require_rerun
        require_rerun()                      # fail before the run, not after
        writable_output(a.rerun, "--rerun")
    res = run(a.capture, model=a.model, resolution=a.resolution, threshold=a.threshold,
              output=a.output, frames=getattr(a, "frames", None), workers=workers,
              scheduler=a.scheduler, resume=a.resume, progress=True, trc=a.trc, csv=a.csv,
              c3d=getattr(a, "c3d", None),
              constraints=not getattr(a, "no_constraints", False),
              tolerance=getattr(a, "tolerance", None),
              refocus=getattr(a, "refocus", False),
              on_pose=None, gate={"on": True, "off": False}.get(getattr(a, "confidence_gate", "auto")),
              thickness=getattr(a, "thickness", None), track=getattr(a, "track", True),
              sides=getattr(a, "sides", True), skeleton=getattr(a, "skeleton", True),
              smooth=getattr(a, "smooth", None), bvh=getattr(a, "bvh", None),
              consistency=getattr(a, "consistency", None),
              support_test=getattr(a, "support", None) or False, trim=getattr(a, "trim", None),
              centre=getattr(a, "centre", None))
    if getattr(a, "rerun", None):
        from topopose.viz.rerun import record_run
        record_run(a.rerun, a.capture, res.poses, model=a.model, resolution=a.resolution,
                   tolerance=getattr(a, "tolerance", None))
        print(f"recorded {a.rerun} (open it with `rerun {a.rerun}`)")
    print(summary_text(res))
    for p in res.failed[:10]:
        print(f"  failed {p.frame}: {p.error}")
    if len(res.failed) > 10:
        print(f"  ... {len(res.failed) - 10} more failed frames (see {a.output})")
    extra = [x for x in (a.trc, a.csv, getattr(a, "c3d", None), getattr(a, "bvh", None)) if x]
    if extra:
        print("exports: " + ", ".join(str(x) for x in extra))
    return res.exit_status


def summary_text(res: RunResult) -> str:
    c = res.counts
    n = len(res.poses)
    comp = [p for p in res.poses if p.status != "failed" and p.timings_ms.get("total")]
    fps = ""
    if res.computed and res.seconds > 0:      # the real rate: frames over wall time
        rate = res.computed / res.seconds
        fps = f" ({rate:.{1 if rate >= 1 else 3}f} frames/s"
        if comp:
            import numpy as np

            t = float(np.median([p.timings_ms["total"] for p in comp]))
            fps += f"; median {t:.1f} ms/frame in the estimator"
        fps += ")"
    where = f" → {res.output}" if res.output else ""
    skipped = f" ({res.skipped} resumed)" if res.skipped else ""
    out = [p for p in res.poses if p.diagnostics.get("temporal_outlier")]
    off = ""
    if out:                                   # kinematic_fit.neighbourhood, bridge_outliers
        k, b = len(out), sum(bool(p.diagnostics.get("interpolated")) for p in out)
        off = (f"; {k} skeleton{'s' if k > 1 else ''} off the motion around "
               f"{'them' if k > 1 else 'it'} (diagnostics.temporal_outlier"
               + (f", {b} interpolated from the frames either side" if b else "") + ")")
    k = sum(bool(p.diagnostics.get("despiked_joints")) for p in res.poses)
    if k:                                     # kinematic_fit.despike
        off += (f"; {k} frame{'s' if k > 1 else ''} with a bone far off the frames around, "
                "replaced by theirs (diagnostics.despiked_joints)")
    tracked = "".join(f", {c[k]} {k}" for k in ("tracked", "lost") if c.get(k))
    return (f"{n} frames{skipped}: {c.get('matched', 0)} matched{tracked}, "
            f"{c.get('rejected', 0)} rejected, {c.get('failed', 0)} failed in {res.seconds:.1f} s{fps}{where}{off}")
