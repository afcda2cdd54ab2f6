"""From pose initialization to motion capture: the sequence stages after the per-frame result.

numbered parts → identities over time (:mod:`.track`) → hands trimmed out of the hull's phantom
volume (:mod:`.trim`, as each frame recorded it) → full kinematic skeleton with constant
bone lengths (:mod:`.kinematic_fit`) → left and right (:mod:`.chirality`) → ``matched``
decided with the run's own consistency (:mod:`.consistency`; by default the union of the
confidence gate and the consistency, :data:`CONSISTENCY`). Every stage reads
only the poses (their parts and the skeleton curves in ``diagnostics["curves"]``), so it runs
after a parallel or resumed run as well.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from topopose.frames import sort_poses
from topopose.sequence.chirality import assign_sides, numbered
from topopose.sequence.kinematic_fit import fit_sequence
from topopose.sequence.options import DEFAULT, SequenceOptions
from topopose.sequence.track import track as track_identities

#: ``matched`` of a coherent sequence: the confidence gate's, plus the frames the gate alone
#: rejected that the run's own consistency finds consistent (:func:`.consistency.judge_sequence`
#: ``union=True``; development seeds: ``benchmarks/results/consistency.md``)
CONSISTENCY = "union"


def consistency_settings(consistency) -> dict | None:
    """:func:`.consistency.judge_sequence`'s keyword arguments for the ``consistency`` option of
    :func:`process_sequence` / ``run``: None → the default (:data:`CONSISTENCY`); False → off
    (None); True → the consistency replaces the gate (``run --consistency``, ``{}``);
    ``"union"`` → ``{"union": True}``; a dict is given as it is."""
    if consistency is None:
        consistency = CONSISTENCY
    if consistency is False:
        return None
    if consistency is True:
        return {}
    if consistency == "union":
        return {"union": True}
    if isinstance(consistency, dict):
        return dict(consistency)
    raise ValueError(f"consistency: False, True, 'union' or a dict, got {consistency!r}")


@dataclass
class Motion:
    """The processed sequence: poses, the kinematic tree and its bone lengths (or None)."""

    poses: list
    tree: object = None
    lengths: object = None
    stages: list = field(default_factory=list)


def process_sequence(poses, model, up, options: SequenceOptions | None = None, fps=None,
                     **flat) -> Motion:
    """Run the sequence stages on the poses of one capture (sorted by frame).

    Parameters
    ----------
    poses : list of Pose
    model : Model
    up : the capture's up vector
    options : SequenceOptions, optional
        What runs and how (default :data:`.options.DEFAULT`); ``**flat`` changes options by
        field name (:meth:`.SequenceOptions.with_`), e.g. ``skeleton=False, max_gap=0``.
    fps : the capture's frame rate (frames/s), which scales the default smoothing window
    track, sides, skeleton : which stages to run (each needs what the model declares:
        interchangeable parts, ``[[mirror]]`` + ``[facing]``, ``[[joint]]``)
    max_gap, smooth : gap filling and smoothing of the skeleton (:func:`.fit_sequence`)
    consistency : bool, "union", dict or None
        Last, on the poses as written, when the run is a coherent sequence: ``matched``
        decided with the run's own consistency (:func:`.consistency.judge_sequence`, see
        :func:`consistency_settings`): None (default): :data:`CONSISTENCY`, the union of the
        confidence gate and the consistency; True: the consistency instead of the gate;
        False: the gate alone.
    trim : bool
        Whether to apply the hands' trim each frame recorded (``diagnostics["trim"]``,
        :func:`.trim.apply_trim`) after the identities (default on).
    """
    o = (options or DEFAULT).with_(**flat)
    track, sides, skeleton, max_gap = o.track, o.sides, o.skeleton, o.gaps.max_gap
    poses = sort_poses(numbered(p, model) for p in poses)
    out = Motion(poses)
    if track and len(poses) > 1 and model.interchangeable():
        out.poses = track_identities(out.poses, model, max_gap=max_gap)
        out.stages.append("track")
    if o.trim and any(p.diagnostics.get("trim") for p in out.poses):
        from topopose.frame.trim import apply_trim

        out.poses = [apply_trim(p) for p in out.poses]
        out.stages.append("trim")
    if skeleton and model.joints:
        out.poses, out.tree, out.lengths = fit_sequence(out.poses, model, o, fps=fps)
        out.stages.append("skeleton")
    if sides and model.mirrors and model.facing:
        out.poses = assign_sides(out.poses, model, up, use_time=track)
        out.stages.append("sides")
    settings = consistency_settings(o.consistency)
    if settings is not None and len(out.poses) > 2:
        from topopose.sequence.consistency import judge_sequence, mirror_groups
        from topopose.sequence.track import frame_index

        if judge_sequence(out.poses, model, frame_index(out.poses), groups=mirror_groups(model),
                          **settings):
            out.stages.append("consistency")
    return out
