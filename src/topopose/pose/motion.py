"""From pose initialization to motion capture: the sequence stages after the per-frame result.

numbered parts → identities over time (:mod:`.track`) → hands trimmed out of the hull's phantom
volume (:mod:`.trim`, as each frame recorded it) → full kinematic skeleton with constant
bone lengths (:mod:`.kinematic_fit`) → left and right (:mod:`.chirality`) → optionally
``matched`` decided by the run's own consistency (:mod:`.consistency`). Every stage reads
only the poses (their parts and the skeleton curves in ``diagnostics["curves"]``), so it runs
after a parallel or resumed run as well.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .chirality import assign_sides, numbered
from .kinematic_fit import fit_sequence
from .track import track as track_identities


TRIM = True  # hands trimmed back where the silhouettes' evidence ends (:mod:`.trim`)


@dataclass
class Motion:
    """The processed sequence: poses, the kinematic tree and its bone lengths (or None)."""

    poses: list
    tree: object = None
    lengths: object = None
    stages: list = field(default_factory=list)


def process_sequence(poses, model, up, track=True, sides=True, skeleton=True, max_gap=5,
                     smooth=None, consistency=False, trim=None) -> Motion:
    """Run the sequence stages on the poses of one capture (sorted by frame).

    Parameters
    ----------
    poses : list of Pose
    model : Model
    up : the capture's up vector
    track, sides, skeleton : which stages to run (each needs what the model declares:
        interchangeable parts, ``[[mirror]]`` + ``[facing]``, ``[[joint]]``)
    max_gap, smooth : gap filling and smoothing of the skeleton (:func:`.fit_sequence`)
    consistency : bool or dict
        Last, on the poses as written: ``matched`` decided by the run's own consistency
        (:func:`.consistency.judge_sequence`; a dict gives its keyword arguments) when the run
        is a coherent sequence; off by default (``results/consistency.md``).
    trim : bool, optional
        Whether to apply the hands' trim each frame recorded (``diagnostics["trim"]``,
        :func:`.trim.apply_trim`) after the identities (default :data:`TRIM`).
    """
    poses = sorted((numbered(p, model) for p in poses), key=lambda p: p.frame)
    out = Motion(poses)
    if track and len(poses) > 1 and model.interchangeable():
        out.poses = track_identities(out.poses, model, max_gap=max_gap)
        out.stages.append("track")
    if (TRIM if trim is None else trim) and any(p.diagnostics.get("trim") for p in out.poses):
        from .trim import apply_trim

        out.poses = [apply_trim(p) for p in out.poses]
        out.stages.append("trim")
    if skeleton and model.joints:
        out.poses, out.tree, out.lengths = fit_sequence(out.poses, model, max_gap=max_gap,
                                                        smooth=smooth)
        out.stages.append("skeleton")
    if sides and model.mirrors and model.facing:
        out.poses = assign_sides(out.poses, model, up, use_time=track)
        out.stages.append("sides")
    if consistency and len(out.poses) > 2:
        from .consistency import judge_sequence, mirror_groups
        from .track import frame_index

        settings = consistency if isinstance(consistency, dict) else {}
        if judge_sequence(out.poses, model, frame_index(out.poses), groups=mirror_groups(model),
                          **settings):
            out.stages.append("consistency")
    return out
