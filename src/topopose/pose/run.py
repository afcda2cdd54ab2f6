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

from ..errors import InputError
from .estimate import FrameEstimator
from .model import load_model
from .pose import Pose, read_poses, write_poses


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
        frames = [f for f in text.split(",") if f.strip()]
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
    from ..capture import load_capture
    from .model import model_from_dict

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

    return tqdm(total=total, unit="frame", desc=desc, dynamic_ncols=True, file=sys.stderr,
                smoothing=0.1)


def run(capture, model="human", resolution=100, threshold=None, output=None, *, frames=None,
        workers=1, scheduler=None, resume=False, progress=True, trc=None, csv=None, c3d=None,
        constraints=True, betweenness=True, relation=None, max_missing=1, thinning="d6i1d",
        tolerance=None, refocus=False, on_pose=None, gate=True, track=True, sides=True,
        skeleton=True, smooth=None, bvh=None) -> RunResult:
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
    gate : bool
        ``matched`` also needs the frame's confidence (:mod:`.confidence`, with the time
        factors computed over the run at the end) above its minimum; False: the confidence is
        reported only.
    track : bool
        Sequences (more than one frame): give the numbered parts stable identities over time
        (:func:`topopose.pose.track.track`); the output file is rewritten with them.
    sides : bool
        Name the model's mirror pairs left / right (:mod:`topopose.pose.chirality`).
    skeleton : bool
        Fit the full kinematic skeleton (:mod:`topopose.pose.kinematic_fit`): ``Pose.joints``.
    smooth : int, optional
        Savitzky–Golay window (frames) smoothing the skeleton.
    bvh : path, optional
        BVH export of the fitted skeleton (Blender).

    Returns
    -------
    RunResult
        ``.exit_status`` is 1 when some frames failed.
    """
    from ..capture import Capture, load_capture

    m = load_model(model, constraints=constraints)
    cap = capture if isinstance(capture, Capture) else load_capture(capture)
    options = {"betweenness": betweenness, "relation": relation, "max_missing": max_missing,
               "thinning": thinning, "tolerance": tolerance, "gate": gate}
    if refocus:
        options["refocus"] = True
    todo = select_frames(cap, frames)
    if workers is None or workers < 1:
        raise InputError(f"--workers: must be at least 1, got {workers}")
    if c3d is not None:
        from .export import require_c3d
        require_c3d()
    if bvh is not None and not (skeleton and m.joints):
        raise InputError(f"--bvh: model {m.name!r} has no [[joint]] (or --no-skeleton): no "
                         "skeleton to export")

    done = {}
    out = Path(output) if output is not None else None
    if out is not None:
        if out.parent and not out.parent.exists():
            out.parent.mkdir(parents=True, exist_ok=True)
        if resume and out.exists():
            for p in read_poses(out, strict=False):
                done[p.frame] = p
            write_poses(out, done.values())       # drops a half-written last line
        elif out.exists():
            out.unlink()
    skipped = [f for f in todo if f in done]
    todo = [f for f in todo if f not in done]

    results = dict(done)
    t0 = time.perf_counter()
    fh = open(out, "a") if out is not None else None
    bar = _progress(len(todo), progress and len(todo) > 0, f"{m.name} @ {resolution}³")

    def finish(pose: Pose):
        results[pose.frame] = pose
        if fh is not None:
            fh.write(pose.to_json() + "\n")
            fh.flush()
        if bar is not None:
            bar.update(1)
            bar.set_postfix(status=pose.status[:7], refresh=False)
        if on_pose is not None:
            on_pose(pose)

    try:
        if todo and (workers > 1 or scheduler):
            _run_dask(cap, m, resolution, threshold, options, todo, workers, scheduler, finish)
        elif todo:
            from ..capture import prefetch

            est = FrameEstimator(cap, m, resolution, threshold, **options)
            with prefetch(cap, todo):        # decoding + silhouettes run ahead in a thread
                for f in todo:
                    finish(est.estimate(f))
    finally:
        if bar is not None:
            bar.close()
        if fh is not None:
            fh.close()
    seconds = time.perf_counter() - t0
    from .confidence import temporal_confidence
    temporal_confidence(list(results.values()), {f: i for i, f in enumerate(cap.frames)},
                        gate=gate and m.name == "human")
    if out is not None:
        write_poses(out, results.values())
    poses = [results[k] for k in sorted(results)]
    motion = None
    if track or sides or skeleton:
        from .motion import process_sequence
        motion = process_sequence(poses, m, cap.up_vector, track=track, sides=sides,
                                  skeleton=skeleton, smooth=smooth)
        poses = motion.poses
        if out is not None:
            write_poses(out, poses)
    counts = {s: sum(p.status == s for p in poses) for s in ("matched", "rejected", "failed")}
    res = RunResult(poses, out, computed=len(todo), skipped=len(skipped), seconds=seconds,
                    counts=counts)
    units = cap.units
    fps = cap.fps or 25.0
    from .export import OPENSIM_LABELS, marker_names
    markers = marker_names(poses, m.parts)
    if trc is not None:
        from .export import write_trc
        write_trc(trc, poses, markers, fps=fps, units=units, up=cap.up, labels=OPENSIM_LABELS)
    if csv is not None:
        from .export import write_csv
        write_csv(csv, poses, markers)
    if c3d is not None:
        from .export import write_c3d
        write_c3d(c3d, poses, markers, fps=fps, units=units, labels=OPENSIM_LABELS)
    if bvh is not None:
        write_motion_bvh(bvh, poses, motion, m, fps=fps, units=units, up=cap.up)
    return res


def write_motion_bvh(path, poses, motion, model, fps=25.0, units="m", up="+z"):
    """BVH of the fitted skeleton. Joints carry their side names in the mirror order
    (``left_elbow`` is ``elbow_1``'s name when ``hand_1`` → ``left_hand``); a frame where the
    side was not decided uses the numbered joint in its place. Frames without a skeleton repeat
    the last one (BVH has no gaps; poses.jsonl says which frames were fitted)."""
    import numpy as np

    from .chirality import joint_renaming
    from .export import write_bvh

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
        cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
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
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_cli(a) -> int:
    """``topopose run``: prints a summary; exit 1 when some frames failed."""
    if getattr(a, "rerun", None):
        from ..viz.rerun import require_rerun
        require_rerun()                      # fail before the run, not after
    res = run(a.capture, model=a.model, resolution=a.resolution, threshold=a.threshold,
              output=a.output, frames=getattr(a, "frames", None), workers=a.workers,
              scheduler=a.scheduler, resume=a.resume, progress=True, trc=a.trc, csv=a.csv,
              c3d=getattr(a, "c3d", None),
              constraints=not getattr(a, "no_constraints", False),
              tolerance=getattr(a, "tolerance", None),
              refocus=getattr(a, "refocus", False),
              on_pose=None, gate=not getattr(a, "no_confidence_gate", False),
              track=getattr(a, "track", True),
              sides=getattr(a, "sides", True), skeleton=getattr(a, "skeleton", True),
              smooth=getattr(a, "smooth", None), bvh=getattr(a, "bvh", None))
    if getattr(a, "rerun", None):
        from ..viz.rerun import record_run
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
    if comp:
        import numpy as np

        t = float(np.median([p.timings_ms["total"] for p in comp]))
        fps = f"; median {t:.1f} ms/frame ({1000 / t:.0f} frames/s per core)"
    where = f" → {res.output}" if res.output else ""
    skipped = f" ({res.skipped} resumed)" if res.skipped else ""
    return (f"{n} frames{skipped}: {c.get('matched', 0)} matched, {c.get('rejected', 0)} rejected, "
            f"{c.get('failed', 0)} failed in {res.seconds:.1f} s{fps}{where}")
