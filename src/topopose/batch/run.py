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
from dataclasses import asdict, dataclass, field, is_dataclass, replace
from pathlib import Path

from topopose.batch.options import RunOptions
from topopose.errors import InputError
from topopose.frame.estimate import FrameEstimator
from topopose.frame.options import EstimatorOptions
from topopose.frames import sort_frames, sort_poses
from topopose.pose.model import load_model
from topopose.pose.pose import Pose, read_poses, write_poses


@dataclass
class RunResult:
    """What a run produced (all frames of the output file, including resumed ones).
    ``written``: the output and exports were written (False when every frame failed and an
    existing output was kept)."""

    poses: list
    output: Path | None
    computed: int = 0
    skipped: int = 0
    seconds: float = 0.0
    counts: dict = field(default_factory=dict)
    written: bool = True

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
        if not math.isfinite(sec):
            raise InputError(f"--frames: {whole!r}: {t!r} is not a finite time")
        return max(0, math.ceil(sec * cap.fps - 1e-9))
    return int(t)


def select_frames(cap, frames) -> list:
    """Frame names from None (all), a list, a ``slice`` of indices, or a text: ``"a:b"`` /
    ``"a:b:s"`` (indices, Python slice rules), ``"0.5s:1.2s"`` (times in seconds: the frames i
    with 0.5 ≤ i / fps < 1.2; the step, if any, is in frames; times and indices mix, e.g.
    ``"2s:"``), or ``"f1,f2"``."""
    if frames is None:
        return list(cap.frames)
    given = frames
    if isinstance(frames, slice):
        frames = list(cap.frames)[frames]
    elif isinstance(frames, str):
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
            if sl.step is not None and sl.step <= 0:
                raise InputError(f"--frames: {frames!r}: the step must be a positive number of "
                                 "frames")
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


def _spec(cap, model, resolution, threshold, options, keep=False):
    """A small, picklable description from which each worker builds its estimator once
    (``keep``: a :class:`KeepingEstimator`)."""
    spec = {"model": model.to_dict(), "resolution": resolution, "threshold": threshold,
            "options": options, "keep": bool(keep)}
    if cap.path is not None and cap.masks is None:
        spec["capture_path"] = str(cap.path)
    else:
        spec["capture"] = cap          # in-memory capture: shipped once per worker
    return spec


def _key(spec) -> str:
    d = {k: v for k, v in spec.items() if k != "capture"}
    d["capture_id"] = id(spec.get("capture")) if "capture" in spec else None
    return json.dumps(d, sort_keys=True, default=str)


class KeepingEstimator(FrameEstimator):
    """The run's :class:`FrameEstimator`, keeping of each frame it carves what the tracking
    stage reads (:class:`~topopose.sequence.kept.KeptFrame`, in :attr:`kept` by frame name),
    so that stage carves, decodes and segments nothing again."""

    def __init__(self, *args, kept=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.kept = {} if kept is None else kept

    def hull(self, frame):
        from topopose.sequence.follow import estimator_views
        from topopose.sequence.kept import KeptFrame

        vol = super().hull(frame)
        self.kept[frame] = KeptFrame.keep(vol, estimator_views(self, frame))
        return vol


def _build(spec) -> FrameEstimator:
    from topopose.capture import load_capture
    from topopose.pose.model import model_from_dict

    cap = spec["capture"] if "capture" in spec else load_capture(spec["capture_path"])
    model = model_from_dict(spec["model"], source="model")
    kind = KeepingEstimator if spec.get("keep") else FrameEstimator
    return kind(cap, model, spec["resolution"], spec["threshold"], spec["options"])


def _worker_estimate(spec_key, spec, frame) -> tuple:
    """Runs on a Dask worker: estimate one frame with the worker's cached estimator; returns
    the pose as a dict and what the tracker keeps of the frame (None unless ``spec["keep"]``)."""
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
    pose = est.estimate(frame).to_dict()
    return pose, est.kept.pop(pose["frame"], None) if spec.get("keep") else None


def _progress(total, enabled, desc):
    if not enabled:
        return None
    from tqdm import tqdm

    # smoothing 0: the rate is frames over time since the end of the first frame (see run)
    return tqdm(total=total, unit="frame", desc=desc, dynamic_ncols=True, file=sys.stderr,
                smoothing=0)


def run(capture, model="human", resolution=100, threshold=None, output=None,
        options: RunOptions | None = None, **flat) -> RunResult:
    """Estimate the pose in every frame of a capture (thesis §12.1), writing as it goes.

    Parameters
    ----------
    capture : Capture or path
    model : Model, built-in name or TOML path
    resolution, threshold : see :class:`FrameEstimator`
    output : path, optional
        JSON Lines output; each frame is appended and flushed as soon as it is done.
    options : RunOptions, optional
        Every option, grouped (:class:`~topopose.batch.options.RunOptions`, which documents
        them; default: the defaults).
    **flat
        Options changed by name (:meth:`~topopose.batch.options.RunOptions.with_`): ``frames``,
        ``resume``, ``progress``, ``on_pose``, ``support``, ``support_test``, ``centre``; the
        exports ``trc``, ``csv``, ``c3d``, ``bvh``; ``workers`` or a Dask ``scheduler``; any
        per-frame option of :class:`FrameEstimator` (``constraints``, ``betweenness``,
        ``relation``, ``max_missing``, ``thinning``, ``tolerance``, ``refocus``, ``gate``,
        ``thickness``, ...); any option of the sequence stage
        (:class:`~topopose.sequence.options.SequenceOptions`: ``track``, ``sides``,
        ``skeleton``, ``smooth``, ``trim``, ``consistency``, ...). With ``track``, ``sides``
        and ``skeleton`` all off, ``consistency`` None means False: the per-frame results as
        the estimator gave them.

    Every output is checked before any work (:func:`topopose._paths.check_outputs`) against
    the capture's files, the model file and the other outputs; the output replaces an existing
    file only when the run completes, and not at all when every frame failed (exit status 1,
    the old file kept).

    Returns
    -------
    RunResult
        ``.exit_status`` is 1 when some frames failed.
    """
    from topopose import _paths
    from topopose.capture import Capture, load_capture

    o = (options or RunOptions()).with_(**flat)
    resume, support, support_test = o.resume, o.support, o.support_test
    workers, scheduler = o.parallel.workers, o.parallel.scheduler
    eo, seq = o.estimator, o.sequence
    track, sides, skeleton, consistency = seq.track, seq.sides, seq.skeleton, seq.consistency
    # ---- every argument and output checked before any work or any write
    if workers is None or isinstance(workers, bool) or int(workers) < 1:
        raise InputError(f"--workers: must be at least 1, got {workers}")
    resolution = _paths.check_resolution(resolution)
    threshold = _paths.check_threshold(threshold)
    _paths.check_number(eo.alignment.thickness, "--thickness", low=0)
    _paths.check_number(seq.smoothing.smooth, "--smooth", low=0, integer=True)
    m = load_model(model, constraints=eo.alignment.constraints)
    cap = capture if isinstance(capture, Capture) else load_capture(capture)
    eo = _checked_estimator(eo, cap)
    gate = eo.confidence.gate
    from topopose.sequence.motion import consistency_settings
    if consistency is None and not (track or sides or skeleton):
        consistency = False               # no sequence stage asked for: per-frame results
    try:
        judged = consistency_settings(consistency) is not None
    except ValueError as e:
        raise InputError(str(e)) from None
    if support or (support is None and (judged or support_test)):   # read by them
        eo = eo.with_(support=True)
    eo = eo.with_(centre=bool(o.centre))
    todo = select_frames(cap, o.frames)
    out, exports = _checked_outputs(output, o.exports, cap, m, skeleton, model)
    if scheduler and todo:
        probe_scheduler(scheduler)                # before any write
    header = run_header(cap, m, resolution, threshold, run_settings(eo))
    partial = out.with_name(out.name + ".partial") if out is not None else None
    done = _resumed(out, partial, header, m) if out is not None and resume else {}
    skipped = [f for f in todo if f in done]
    todo = [f for f in todo if f not in done]

    # ---- the run: frames appended (and flushed) to a temporary file beside the output, which
    # replaces the output when the run completes. Interrupted (Ctrl-C, an error), it replaces
    # only a missing output or a resumed one (which it extends): an existing file of another run
    # is left as it was and the frames computed stay in the partial file, which --resume reads;
    # a killed process leaves the existing output as it was (and the partial file beside it)
    results = dict(done)
    # what the tracking stage reads of each frame, kept as the frames are computed
    kept = ({} if (o.follow is None or o.follow.enabled) and skeleton and m.joints
            and len(todo) > 2 else None)
    existed = out is not None and out.exists()
    t0 = time.perf_counter()
    fh = _open_partial(partial, out, header, done) if partial is not None else None
    bar = _progress(len(todo), o.progress and len(todo) > 0, f"{m.name} @ {resolution}³")
    finish = _frame_sink(results, fh, bar, o.on_pose)
    complete = False
    written = True
    motion = None
    poses = []
    try:
        try:
            _compute_frames(cap, m, resolution, threshold, eo, todo, o.parallel, finish, bar,
                            kept)
        finally:
            if bar is not None:
                bar.close()
            from topopose.frame.confidence import temporal_confidence   # time factors: the whole run
            temporal_confidence(list(results.values()), {f: i for i, f in enumerate(cap.frames)},
                                gate=gate and m.name == "human")
            if support_test:                  # per frame, on the statuses the gate gave
                from topopose.sequence.consistency import judge_support
                judge_support(results.values(), gate=support_test != "replace")
            if fh is not None:
                fh.close()
        seconds = time.perf_counter() - t0
        poses = [results[k] for k in sort_frames(results)]
        if todo and existed and not resume and all(results[f].status == "failed" for f in todo):
            # nothing worth keeping: the complete result already there stays
            partial.unlink(missing_ok=True)
            print(f"topopose: note: every frame failed; {out} left as it was", file=sys.stderr)
            written, exports = False, {}
        else:
            # a resume with nothing to do keeps the file
            if (track or sides or skeleton or judged) and todo:
                motion = _sequence_stage(poses, m, cap, resolution, threshold, eo,
                                         replace(seq, consistency=consistency), o.follow, kept)
                poses = motion.poses
            if out is not None and (todo or not existed or resume):
                write_poses(out, poses, header)                   # sorted, atomic replace
            if partial is not None:
                partial.unlink(missing_ok=True)
        complete = True
    except BaseException as exc:
        if not complete and partial is not None and partial.exists():
            if existed and not resume:        # another run's file: never replaced by a part
                if len(results) > len(done) and isinstance(exc, KeyboardInterrupt):
                    exc.add_note(f"{out} left as it was; the {len(results) - len(done)} frames "
                                 f"computed are in {partial} (--resume continues from them)")
                elif len(results) == len(done):
                    partial.unlink(missing_ok=True)
            else:                              # nothing computed is lost
                write_poses(out, results.values(), header)
                partial.unlink(missing_ok=True)
        raise
    counts = {s: sum(p.status == s for p in poses)
              for s in ("matched", "tracked", "rejected", "lost", "failed")}
    res = RunResult(poses, out, computed=len(todo), skipped=len(skipped), seconds=seconds,
                    counts=counts, written=written)
    write_exports(exports, poses, motion, m, cap)
    return res


def _open_partial(partial, out, header, done):
    """The partial file beside ``out``, opened with the header and the resumed frames."""
    try:
        fh = open(partial, "w")
    except OSError as exc:
        raise InputError(f"--output: cannot write beside {out} ({exc.strerror or exc})") from None
    fh.write(json.dumps(header, separators=(",", ":")) + "\n")
    for p in sort_poses(done.values()):
        fh.write(p.to_json() + "\n")
    fh.flush()
    return fh


def _frame_sink(results, fh, bar, on_pose):
    """The callback each finished frame goes through: kept in ``results``, appended (and
    flushed) to the partial file ``fh``, counted on the progress ``bar``, given to ``on_pose``."""
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
            bar.set_postfix(status=f"{pose.status:8}", refresh=False)   # whole, fixed width
        if on_pose is not None:
            on_pose(pose)

    return finish


def _compute_frames(cap, m, resolution, threshold, eo, todo, parallel, finish, bar, kept=None):
    """Every frame of ``todo`` estimated and given to ``finish``: in worker processes or on a
    Dask cluster (``parallel``), else here with the first run's warm-up helper and the frames
    decoded ahead in threads; first-run notices on the progress ``bar``. ``kept``: a dict
    that receives what the tracking stage reads of each frame (:class:`KeepingEstimator`)."""
    from topopose import _notices
    from topopose.batch import warmup

    def note(message):
        if bar is not None:
            bar.set_postfix_str(message)

    workers, scheduler = parallel.workers, parallel.scheduler
    with _notices.notices(note):
        if todo and (workers > 1 or scheduler):
            _run_dask(cap, m, resolution, threshold, eo, todo, workers, scheduler, finish, kept)
        elif todo:
            from topopose.capture import prefetch

            warm = warmup.start_warmup()     # first run: a helper process
            try:
                est = (FrameEstimator(cap, m, resolution, threshold, eo) if kept is None else
                       KeepingEstimator(cap, m, resolution, threshold, eo, kept=kept))
                est.warmup = warm
                # decoding + silhouettes run ahead in threads (at the resolution the grid
                # needs, when the masks are reduced)
                with prefetch(cap, todo, factors=est.mask_factors()):
                    for k, f in enumerate(todo):
                        finish(est.estimate(f))
                        if k == 0 and kept is not None:
                            _import_ahead(SEQUENCE_MODULES)
            finally:
                warm.close()


#: what the sequence stage and the tracker import (SciPy's signal module alone takes ~0.5 s),
#: imported while the frames are computed
SEQUENCE_MODULES = ("scipy.signal", "scipy.optimize", "topopose.sequence.motion",
                    "topopose.sequence.follow")


def _import_ahead(names):
    """Import the modules ``names`` in a background thread."""
    import importlib
    import threading

    def work():
        for n in names:
            try:
                importlib.import_module(n)
            except Exception:       # noqa: BLE001  imported again (and raising) where used
                pass

    threading.Thread(target=work, name="topopose-import-ahead", daemon=True).start()


def _sequence_stage(poses, m, cap, resolution, threshold, eo, seq, follow, kept=None):
    """The sequence stage of a run (:func:`topopose.sequence.motion.process_sequence`), then
    the subject's body followed through every frame (:func:`topopose.sequence.follow.follow_run`,
    on the frames ``kept`` by the frame loop); the returned motion's ``poses`` are the run's.

    When the frames that passed the confidence gate give the tracker no start (none passed,
    or too few to learn the body from), and ``FollowOptions.unconfirmed``, the stage runs
    again on the next most trusted alignments (:func:`~topopose.sequence.track.ungated`):
    those the gate alone rejected, else every rejected one, which then start the track; their
    frames keep their status, and of that run only the tracker's fits are kept."""
    from topopose.sequence.follow import FollowOptions, follow_run
    from topopose.sequence.motion import process_sequence
    from topopose.sequence.track import ungated

    def followed(p):                    # a frame the tracker fitted
        return "track_body" in p.diagnostics

    fo = follow or FollowOptions()
    motion = process_sequence(poses, m, cap.up_vector, seq, fps=cap.fps)
    motion.poses = follow_run(motion.poses, motion, m, cap, resolution, threshold, eo, follow,
                              kept=kept)
    if any(map(followed, motion.poses)) or not (fo.enabled and fo.unconfirmed) \
            or motion.tree is None or len(poses) < 3:    # tracked, or nothing to track with
        return motion
    strict, tried = {p.frame: p for p in motion.poses}, None
    for lift in (False, True):
        lifted = ungated(poses, lift)
        more = [q.matched for q in lifted]
        if more == tried or not any(q.matched and not p.matched for p, q in zip(poses, lifted)):
            continue                    # no alignment more to start from
        tried = more
        loose = process_sequence(lifted, m, cap.up_vector, seq, fps=cap.fps)
        back = [replace(q, status=strict[q.frame].status, error=strict[q.frame].error)
                if q.matched else q for q in loose.poses]
        back = follow_run(back, loose, m, cap, resolution, threshold, eo, follow, kept=kept,
                          starts=[q.matched for q in loose.poses])
        if any(map(followed, back)):
            loose.poses = [q if followed(q) else strict[q.frame] for q in back]
            return loose
    return motion


def _checked_estimator(eo, cap) -> EstimatorOptions:
    """``eo`` with the hull tolerance checked against the cameras and the gate's default for
    the capture (:func:`~topopose.frame.rules.default_gate`)."""
    from topopose import _paths

    tolerance = _paths.check_tolerance(eo.hull.tolerance, len(cap.cameras))
    gate = eo.confidence.gate
    if gate is None:
        from topopose.frame.rules import default_gate
        gate = default_gate(cap)
    return eo.with_(tolerance=tolerance, gate=gate)


def run_inputs(capture_path, model) -> list:
    """What a run reads, which no output may replace: the capture's files (``capture_path``:
    its folder, or None for a capture in memory) and a model file."""
    from topopose import _paths

    return [("--model", _paths.file_input(model)),
            *(_paths.capture_inputs(capture_path) if capture_path is not None else [])]


def _checked_outputs(output, ex, cap, m, skeleton, model) -> tuple:
    """``(output, {kind: path})``: the poses file and the exports asked for
    (:class:`~topopose.batch.options.ExportOptions`), checked together before any work
    (:func:`topopose._paths.check_outputs`: writable, none an input of the run nor the file of
    another output), C3D's extra installed, the capture's units known, a skeleton for BVH."""
    from topopose import _paths

    trc, csv, c3d, bvh = ex.trc, ex.csv, ex.c3d, ex.bvh
    if c3d is not None:
        from topopose.pose.export import require_c3d
        require_c3d()
    if trc is not None or c3d is not None:
        from topopose.pose.export import metres_per_unit
        metres_per_unit(cap.units)
    if bvh is not None and not (skeleton and m.joints):
        raise InputError(f"--bvh: model {m.name!r} has no [[joint]] (or --no-skeleton): no "
                         "skeleton to export")
    checked = _paths.check_outputs({"--output": output, "--trc": trc, "--csv": csv, "--c3d": c3d,
                                    "--bvh": bvh}, run_inputs(cap.path, model))
    return checked.get("--output"), {k[2:]: checked[k] for k in ("--trc", "--csv", "--c3d", "--bvh")
                                     if k in checked}


def write_exports(exports, poses, motion, m, cap):
    """Write each export of ``{kind: path}`` (TRC, CSV, C3D of the matched frames; BVH of the
    fitted skeleton), each to a temporary file renamed at the end."""
    from topopose import _paths

    units = cap.units
    fps = cap.fps or 25.0
    from topopose.pose.export import OPENSIM_LABELS, marker_names, write_c3d, write_csv, write_trc
    markers = marker_names(poses, m.parts)
    writers = {"trc": lambda t: write_trc(t, poses, markers, fps=fps, units=units, up=cap.up,
                                          labels=OPENSIM_LABELS, name=exports["trc"].name),
               "csv": lambda t: write_csv(t, poses, markers),
               "c3d": lambda t: write_c3d(t, poses, markers, fps=fps, units=units,
                                          labels=OPENSIM_LABELS),
               "bvh": lambda t: write_motion_bvh(t, poses, motion, m, fps=fps, units=units,
                                                 up=cap.up)}
    for k, path in exports.items():
        with _paths.atomic_output(path, f"--{k}") as t:
            writers[k](t)


def _resumed(out, partial, header, model) -> dict:
    """``{frame: Pose}`` already in ``out`` or in the ``.partial`` file of a killed run,
    refused when made with other settings (:func:`check_resume`)."""
    done = {}
    for f in (out, partial):         # the .partial file of a killed run holds its frames
        if f.exists():
            check_resume(f, header, model)
            for p in read_poses(f, strict=False):
                done[p.frame] = p
    return done


def _hash(obj) -> str:
    import hashlib

    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def run_settings(options: EstimatorOptions) -> dict:
    """The per-frame options a poses file's header records (``--resume`` refuses others):
    alignment, thinning, hull tolerance and gate always; refocus, the thickness weight and
    the support and centre records when on; any other option that is not its default (but
    ``constraints``, which the model's hash records)."""
    a, r = options.alignment, options.records
    out = {"betweenness": a.betweenness, "relation": a.relation, "max_missing": a.max_missing,
           "thinning": options.thinning.method, "tolerance": options.hull.tolerance,
           "gate": options.confidence.gate}
    if options.hull.refocus:
        out["refocus"] = True
    if a.thickness is not None:
        out["thickness"] = float(a.thickness)
    if r.support:
        out["support"] = True
    if r.centre:
        out["centre"] = True
    default = EstimatorOptions().flat()
    for k, v in options.flat().items():
        if k not in out and k not in ("refocus", "thickness", "support", "centre", "constraints") \
                and v != default[k]:
            out[k] = _plain(v)
    return out


def _plain(v):
    """An option's value as the JSON header holds it (a dataclass as its fields)."""
    if is_dataclass(v) and not isinstance(v, type):
        return json.loads(json.dumps(asdict(v)))
    return v


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


#: seconds a Dask scheduler has to answer (connection and first reply) before ``--scheduler``
#: is refused: a cluster on a network answers in well under a second
SCHEDULER_TIMEOUT = 20.0


def probe_scheduler(address, timeout: float = SCHEDULER_TIMEOUT) -> None:
    """Ask ``address`` who it is, within ``timeout`` seconds, before a ``Client`` connects:
    an address that does not parse, a server that accepts and never replies, or one that
    speaks another protocol (an HTTP server) raises InputError naming ``--scheduler``."""
    import asyncio

    from distributed.comm import connect

    async def ask():
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout))
    except (TimeoutError, asyncio.TimeoutError):
        raise InputError(f"--scheduler: {address!r} did not answer within {timeout:g} s "
                         "(not a Dask scheduler, or unreachable)") from None
    except Exception as exc:            # noqa: BLE001  bad address, refused, another protocol
        raise InputError(f"--scheduler: no Dask scheduler at {address!r} "
                         f"({type(exc).__name__}: {str(exc)[:200]})") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise InputError(f"--scheduler: {address!r} answered, but is not a Dask scheduler")


def _run_dask(cap, model, resolution, threshold, options, todo, workers, scheduler, finish,
              kept=None):
    from dask.distributed import Client, LocalCluster, as_completed

    spec = _spec(cap, model, resolution, threshold, options, keep=kept is not None)
    key = _key(spec)
    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT}s")
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
    stop, old_sigint = _ctrl_c_noted()
    try:
        spec_f = client.scatter([spec], broadcast=True)[0] if "capture" in spec else spec
        futures = {client.submit(_worker_estimate, key, spec_f, f, pure=False): f for f in todo}
        for fut in as_completed(list(futures)):
            if stop.is_set():       # a Ctrl-C whose KeyboardInterrupt Dask's code swallowed
                raise KeyboardInterrupt
            try:
                got, frame_kept = fut.result()
                pose = Pose.from_dict(got)
                if kept is not None and frame_kept is not None:
                    kept[pose.frame] = frame_kept
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
        if old_sigint is not None:
            import signal

            signal.signal(signal.SIGINT, old_sigint)
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        except Exception:       # noqa: BLE001  a cluster closing mid-task may complain
            pass


def _ctrl_c_noted() -> tuple:
    """While Dask runs the frames, SIGINT both raises KeyboardInterrupt (where the main thread
    is) and is noted, so that the frame loop stops at the next frame even when library code
    caught the exception. Returns ``(event, previous handler or None)``: only in the main
    thread, with Python's own SIGINT handler, is the handler changed."""
    import signal
    import threading

    noted = threading.Event()
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return noted, None

    def on_sigint(signum, frame):
        noted.set()
        signal.default_int_handler(signum, frame)

    signal.signal(signal.SIGINT, on_sigint)
    return noted, signal.default_int_handler


#: ``topopose run --workers N`` uses N local processes only for at least this many frames per
#: worker. benchmarks/workers.py (2 cores, load ~2, 100³): one process 10 ms per frame (its
#: prefetch thread already uses the second core); two workers cost ~1.5 s to start and then run
#: at ~9.6 ms per frame, so they win only from ~2,500 frames (40 frames: 4× slower, 200: 1.6×).
#: Workers pay off with more cores or on a cluster (``--scheduler``).
MIN_FRAMES_PER_WORKER = 1000


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
    where = f" → {res.output}" if res.output and res.written else ""
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
    k = sum((p.diagnostics.get("follow") or {}).get("confirmed") is False for p in res.poses)
    if k:                                     # FollowOptions.unconfirmed
        off += (f"; {k} frame{'s' if k > 1 else ''} tracked from alignments the run "
                "rejected, as no matched frame could start the track "
                "(diagnostics.follow.confirmed false)")
    kept = [p for p in res.poses if p.status != "failed"
            and (p.diagnostics.get("follow") or {}).get("before") == "failed"]
    if kept:                                  # the tracker fitted the hull a failed frame kept
        k = len(kept)
        off += (f"; {k} frame{'s' if k > 1 else ''} the per-frame stage failed, followed in "
                f"the hull {'they' if k > 1 else 'it'} kept (first {kept[0].frame}: "
                f"{kept[0].error})")
    if c.get("rejected") and not any(c.get(k) for k in ("matched", "tracked", "lost")):
        off += ("; no frame matched, so no motion was tracked (the body is followed from the "
                "matched frames; --confidence-gate off and a higher --threshold accept more)")
    return (f"{n} frames{skipped}: {c.get('matched', 0)} matched{tracked}, "
            f"{c.get('rejected', 0)} rejected, {c.get('failed', 0)} failed in {res.seconds:.1f} s{fps}{where}{off}")
