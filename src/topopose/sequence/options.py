"""Options of the sequence stage (:func:`topopose.sequence.motion.process_sequence`): which
stages run and how the full kinematic skeleton is fitted, its gaps filled and its motion
smoothed (:mod:`.kinematic_fit`, thesis §13.3.1).

Every option is a field of a small frozen dataclass with the default the stage uses; a variant
is ``dataclasses.replace(SequenceOptions(), gaps=replace(GapOptions(), hints=False))`` or, by
field name alone, ``SequenceOptions.of(hints=False)``. The reason for each default is one line
of ``docs/decisions.md``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np


@dataclass(frozen=True)
class SkeletonFitOptions:
    """The initial placement of the joints, their bone lengths and the fit of each frame.

    Attributes
    ----------
    spine : float
        The trunk's joints moved back by this × the frame's spine shift (:func:`.frame_curves`;
        0: off).
    centred : bool
        The limbs' curves moved onto the silhouettes' centre lines when the frame recorded the
        offsets (``diagnostics["centred"]``, :mod:`topopose.frame.centre`).
    raised_shoulder : float or None
        Trunk lengths: a raised arm's shoulder moved down the trunk by this
        (:func:`.initial_placement`; None: off).
    seen_hull_shoulder : bool
        A hanging seen arm's shoulder placed from the hull's cross-section below the neck.
    hanging_width : (float, float) or None
        Hull radii (along the trunk, outward): the ``width`` of a joint whose limb hangs
        (None: the model's width).
    hip_feet : bool
        A joint with a ``width`` (hips) placed outward along the mean of the direction from
        its mate's curve point and the trunk's side from the front the feet tell (the spine
        shift; :func:`.lateral_direction`; False: the curve points' direction alone).
    bend : float or None
        A limb's middle joint at its curve's bend when the bend is deeper than this × the
        chord (:func:`.bend_joints`; None: off, :data:`.BEND_DEPTH` its measured depth).
    from_end : dict
        (limb end part's stem, joint base name) → percentile: the joint placed by its distance
        from its curve's far end (:func:`.from_end`).
    from_end_weight : float
        The share of that place from the far end.
    from_start : frozenset
        (limb end part's stem, joint base name): a hanging arm's joints placed by the bones'
        lengths from the curve's start (:func:`.from_start`).
    from_start_weight : float
        The share of the way to that place.
    width_radius : str or None
        ``"sequence"``: the joints' ``width`` scales with the sequence's median hull radius
        (None: each frame's own).
    quantile : float
        Percentile of each bone's lengths over the frames (:func:`.bone_lengths`).
    limb_quantile : dict
        Limb end part's stem → percentile of that limb's bones.
    slide : bool
        The model's ``slide`` bones take each frame's length (False: every bone constant).
    slide_quantile : float or None
        Percentile of a ``slide`` bone's constant length.
    shoulder_quantile : float or None
        Percentile of a bone from the root to a joint beside the curve (a shoulder's).
    tip_turn : dict
        Tip joint → degrees its target is turned away from the bone above (:func:`.tip_targets`).
    tip_stretch : dict
        Tip joint → factor its target is moved away from its parent.
    girdle : bool
        The joints a model declares as one girdle kept level (:func:`.girdle_targets`).
    inner_weight : float
        Weight of the initial placement of the joints inside an arc against the curve term
        (:func:`.fit_frame`).
    """

    spine: float = 0.15
    centred: bool = True
    raised_shoulder: float | None = 0.08
    seen_hull_shoulder: bool = True
    hanging_width: tuple | None = (-0.15, 0.7)
    hip_feet: bool = True
    bend: float | None = None
    from_end: dict = field(default_factory=lambda: ({("foot", "knee"): 40}))
    from_end_weight: float = 0.5
    from_start: frozenset = frozenset({("hand", "elbow"), ("hand", "wrist")})
    from_start_weight: float = 0.5
    width_radius: str | None = "sequence"
    quantile: float = 70
    limb_quantile: dict = field(default_factory=lambda: ({"foot": 80}))
    slide: bool = False
    slide_quantile: float | None = 50
    shoulder_quantile: float | None = 50
    tip_turn: dict = field(default_factory=lambda: ({"toe": 15.0}))
    tip_stretch: dict = field(default_factory=lambda: ({"fingertip": 1.08}))
    girdle: bool = True
    inner_weight: float = 1.0


@dataclass(frozen=True)
class GapOptions:
    """Frames and joints the per-frame results do not give.

    Attributes
    ----------
    max_gap : int
        Longest run of unfitted frames filled by interpolation (0: none).
    hold_frames : int
        A joint a frame does not see is held from the last fitted frame at most this many
        frames before, when that frame is the same motion (:func:`._continues`).
    hold_max : float
        Metres: the same motion moved the joints seen in both frames less than this on
        average (:func:`._continues`).
    hold_age : int or None
        Frames: a joint is held from the last fitted frame only when a frame placed it at most
        this many frames before (None: always).
    held_shoulder : float or None
        Radians: an unseen arm's shoulder raised this much from the plane across the trunk,
        opposite its mate (:func:`.rest_fill`; None: mirrored about the trunk axis).
    hints : bool
        An unseen arm bent to reach its hand hint's end (:func:`.hint_fill`).
    evidence : bool
        An unseen arm's elbow turned towards the hull's remainder
        (:func:`topopose.frame.unseen.evidence_fill`).
    shoulders : bool
        An unseen arm moved towards the shoulder from the hull's cross-section
        (:func:`.shoulder_fill`).
    """

    max_gap: int = 5
    hold_frames: int = 5
    hold_max: float = 0.15
    hold_age: int | None = 8
    held_shoulder: float | None = float(np.radians(30.0))
    hints: bool = True
    evidence: bool = True
    shoulders: bool = True


@dataclass(frozen=True)
class SmoothingOptions:
    """The skeleton's motion over runs of continuing motion.

    Attributes
    ----------
    smooth : int or None
        Savitzky–Golay window (frames, order 2); None: :func:`.smooth_window` of the capture's
        frame rate (9 frames at 25 frames/s: 0.36 s); 0: off.
    move : float or None
        Metres: a frame whose joints lie this far from its neighbours' median is off the
        motion around it (``diagnostics["temporal_outlier"]``, a run's end; None: off).
    despike : (float, float) or None
        (k, floor in degrees) of :func:`.despike`, the bones' spikes replaced (None: off).
    bridge : bool
        A temporal outlier between two frames of the same motion replaced by their
        interpolation (:func:`.bridge_outliers`).
    """

    smooth: int | None = None
    move: float | None = 0.15
    despike: tuple | None = (3.0, 15.0)
    bridge: bool = True


@dataclass(frozen=True)
class SequenceOptions:
    """What :func:`topopose.sequence.motion.process_sequence` runs, and how.

    Attributes
    ----------
    track : bool
        Numbered parts keep their identity over time (:mod:`.track`).
    sides : bool
        Mirror pairs named left / right (:mod:`.chirality`).
    skeleton : bool
        The full kinematic skeleton fitted (:mod:`.kinematic_fit`).
    trim : bool
        The hands' trim each frame recorded applied (:func:`topopose.frame.trim.apply_trim`).
    consistency : bool, "union", dict or None
        Sequences of one subject (a run of unrelated poses is left as it is): ``matched``
        decided with the run's own consistency (:mod:`topopose.sequence.consistency`,
        :func:`topopose.sequence.motion.consistency_settings`). None (default): ``"union"`` — a
        frame the confidence gate matched stays matched (unless a part of it was held at its
        tracked prediction) and a frame the gate alone rejected is matched when consistent
        with the run; True (``run --consistency``): the consistency instead of the gate; False
        (``--no-consistency``): the gate alone; a dict gives
        :func:`~topopose.sequence.consistency.judge_sequence`'s settings.
    skeleton_fit, gaps, smoothing
        The kinematic fit's options.
    """

    track: bool = True
    sides: bool = True
    skeleton: bool = True
    trim: bool = True
    consistency: object = None
    skeleton_fit: SkeletonFitOptions = field(default_factory=SkeletonFitOptions)
    gaps: GapOptions = field(default_factory=GapOptions)
    smoothing: SmoothingOptions = field(default_factory=SmoothingOptions)

    def with_(self, **flat) -> SequenceOptions:
        """A copy with options changed by field name, whatever group holds them
        (``max_gap=0``, ``girdle=False``, ``smooth=5``); an unknown name is a TypeError.
        ``track``, ``sides``, ``skeleton`` or ``trim`` None: unchanged."""
        top = {k: v for k, v in flat.items() if k in _TOP and (v is not None or k == "consistency")}
        groups = {}
        for k, v in flat.items():
            if k in _TOP:
                continue
            g = _GROUP_OF.get(k)
            if g is None:
                raise TypeError(f"sequence options: no option {k!r}")
            groups.setdefault(g, {})[k] = v
        return replace(self, **top, **{g: replace(getattr(self, g), **kw)
                                       for g, kw in groups.items()})

    @classmethod
    def of(cls, **flat) -> SequenceOptions:
        """The default options with these changed by field name (see :meth:`with_`)."""
        return cls().with_(**flat)


_TOP = {"track", "sides", "skeleton", "trim", "consistency"}
_GROUP_OF = {f.name: g for g, c in (("skeleton_fit", SkeletonFitOptions), ("gaps", GapOptions),
                                    ("smoothing", SmoothingOptions)) for f in fields(c)}

#: the defaults, shared (frozen)
DEFAULT = SequenceOptions()
