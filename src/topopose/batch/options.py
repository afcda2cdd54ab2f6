"""Options of a batch run (:func:`topopose.batch.run.run`, ``topopose run``): which frames,
resume, progress, parallel workers, exports, and the per-frame and sequence stages' options.

A variant is ``dataclasses.replace`` of a group, or by name alone
``RunOptions.of(workers=2, trc="motion.trc", constraints=False, smooth=0)`` (the names of
:func:`~topopose.batch.run.run`'s keyword arguments, of :class:`~topopose.frame.options.
EstimatorOptions` and of :class:`~topopose.sequence.options.SequenceOptions`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from topopose.frame.options import EstimatorOptions
from topopose.sequence.options import SequenceOptions


@dataclass(frozen=True)
class ExportOptions:
    """Exports of the matched frames: ``trc`` (OpenSim, metres), ``csv`` (wide), ``c3d``
    (optional extra) and ``bvh`` (the fitted skeleton); paths or None."""

    trc: object = None
    csv: object = None
    c3d: object = None
    bvh: object = None


@dataclass(frozen=True)
class ParallelOptions:
    """``workers`` local processes (Dask ``LocalCluster``; 1: this process) or a Dask
    ``scheduler`` address (``"tcp://host:8786"``)."""

    workers: int = 1
    scheduler: str | None = None


@dataclass(frozen=True)
class RunOptions:
    """Every option of a run.

    Attributes
    ----------
    frames : None, list, slice or str
        The frames: None (all), a list, a slice of indices, ``"a:b"`` / ``"0.5s:1.2s"`` /
        ``"f1,f2"`` (:func:`~topopose.batch.run.select_frames`).
    resume : bool
        Skip the frames already in the output (an interrupted run continues).
    progress : bool
        A progress bar on stderr.
    on_pose : callable or None
        Called with each :class:`~topopose.pose.pose.Pose` as it finishes (e.g. a live viewer).
    support : bool or None
        Record each frame's ``diagnostics["unexplained"]`` (:mod:`topopose.frame.support`),
        which the consistency reads; None (default): with the consistency (on by default) or
        ``support_test``.
    support_test : bool or "replace"
        Per frame (also runs of unrelated poses): a matched frame whose silhouette is left
        unexplained by the placed model above
        :data:`topopose.sequence.consistency.MAX_UNEXPLAINED` is rejected
        (:func:`topopose.sequence.consistency.judge_support`, ``run --support``); ``"replace"``:
        the test replaces the confidence gate (frames the gate alone rejected are matched when
        they pass). Off by default.
    centre : bool
        Record per frame the limbs' curves moved onto the silhouettes' centre lines
        (:mod:`topopose.frame.centre`, ``diagnostics["centred"]``; the kinematic fit uses
        them, ``SkeletonFitOptions.centred``); default on. Recorded in the poses file's header.
    exports : ExportOptions
    parallel : ParallelOptions
    estimator : EstimatorOptions
        The per-frame options (:class:`~topopose.frame.estimate.FrameEstimator`); ``gate``
        None: :func:`~topopose.frame.rules.default_gate`, with the confidence's time factors
        computed over the run at the end.
    sequence : SequenceOptions
        The sequence stage's options; for a sequence (more than one frame) ``track`` rewrites
        the output file with stable identities.
    follow : FollowOptions or None
        Sequences with the skeleton: the subject's capsule body tracked through every frame
        from the confident ones (:mod:`topopose.sequence.follow`; statuses ``matched``,
        ``tracked``, ``lost``, every tracked frame's joints and ``fit``); None: the defaults
        (on); ``FollowOptions(enabled=False)``: off.
    """

    frames: object = None
    resume: bool = False
    progress: bool = True
    on_pose: object = None
    support: bool | None = None
    support_test: object = False
    centre: bool = True
    exports: ExportOptions = field(default_factory=ExportOptions)
    parallel: ParallelOptions = field(default_factory=ParallelOptions)
    estimator: EstimatorOptions = field(default_factory=EstimatorOptions)
    sequence: SequenceOptions = field(default_factory=SequenceOptions)
    follow: object = None

    def with_(self, **flat) -> RunOptions:
        """A copy with options changed by name, whatever group holds them; ``centre`` None:
        unchanged; an unknown name is a TypeError."""
        top, groups, est, seq = {}, {}, {}, {}
        for k, v in flat.items():
            if k in _TOP:
                if not (k == "centre" and v is None):
                    top[k] = v
            elif k in _GROUP_OF:
                groups.setdefault(_GROUP_OF[k], {})[k] = v
            elif k in _ESTIMATOR:
                est[k] = v
            else:
                seq[k] = v           # SequenceOptions.with_ names the unknown
        out = replace(self, **top, **{g: replace(getattr(self, g), **kw)
                                      for g, kw in groups.items()})
        if est:
            out = replace(out, estimator=out.estimator.with_(**est))
        if seq:
            out = replace(out, sequence=out.sequence.with_(**seq))
        return out

    @classmethod
    def of(cls, **flat) -> RunOptions:
        """The default options with these changed (see :meth:`with_`)."""
        return cls().with_(**flat)


_TOP = {f.name for f in fields(RunOptions)} - {"exports", "parallel", "estimator", "sequence"}
_GROUP_OF = {f.name: g for g, c in (("exports", ExportOptions), ("parallel", ParallelOptions))
             for f in fields(c)}
_ESTIMATOR = set(EstimatorOptions().flat()) - {"support", "centre", "trim"}   # trim: the sequence's
