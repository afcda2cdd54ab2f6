"""Options of the per-frame estimator (:class:`topopose.frame.estimate.FrameEstimator`,
thesis §12.1), grouped by stage: hull, thinning, alignment, placement, confidence and what
each frame records for the sequence stage.

Every field's meaning and default are those of the :class:`FrameEstimator` parameter of the
same name (None: the model's own rule or the capture's default). A variant is
``dataclasses.replace`` of a group, or by field name alone ``EstimatorOptions.of(spine=False)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace


@dataclass(frozen=True)
class HullOptions:
    """Visual hull: ``tolerance`` (None: 1 with ≥ 6 cameras, else 0), ``repair`` (consensus
    hull reach, None: 1, negative: off), ``fill`` (cavities filled), ``refocus``,
    ``mask_resolution`` (None: full masks; a :class:`topopose.hull.hull.MaskResolution`, or
    True for its defaults: masks reduced to the resolution the grid needs)."""

    tolerance: int | None = None
    repair: int | None = None
    fill: bool = True
    refocus: bool = False
    mask_resolution: object = None


@dataclass(frozen=True)
class ThinningOptions:
    """Curve skeleton: the thinning ``method`` and ``prune`` (bump removal scale; None: the
    model's entry of :data:`topopose.frame.rules.PRUNE`; 0: off)."""

    method: str = "d6i1d"
    prune: float | None = None


@dataclass(frozen=True)
class AlignmentOptions:
    """AHA alignment and its judgement: coordinate ``constraints``, ``betweenness`` and its
    ``relation``, ``max_missing``, the ``thickness`` term (weight, ``thickness_profile``),
    ``keep_junctions``, ``matched_distance`` and ``placed_missing``."""

    constraints: bool = True
    betweenness: bool = True
    relation: str | None = None
    max_missing: int = 1
    thickness: float | None = None
    thickness_profile: dict | None = None
    keep_junctions: bool | None = None
    matched_distance: bool | None = None
    placed_missing: bool | None = None


@dataclass(frozen=True)
class PlacementOptions:
    """Where the parts go once aligned: junction centroids, tips, the spine, trunk and crotch
    rules, the rules that leave a part unplaced and the head from the hull."""

    junction_centroid: bool | None = None
    junction_core: bool | None = None
    tips: tuple = ("head",)
    tip_fraction: float = 1.0
    tip_anchor: object = None
    leaf_axis: float | None = None
    spine: object = None
    trunk: object = None
    trunk_blend: object = None
    crotch_drop: object = None
    short_arm: float | None = None
    hand_trunk: float | None = None
    head_from_hull: float | None = None
    head_ball: float | None = None
    head_axis: bool | None = None


@dataclass(frozen=True)
class ConfidenceOptions:
    """How far to trust the frame: the ``gate`` (None: :func:`~.estimate.default_gate`, off
    without coordinate constraints); ``gate_rule`` (:class:`~topopose.frame.confidence.GateOptions`
    deciding ``matched``; None: :data:`~topopose.frame.confidence.GATE`; False: the fitted
    confidence ≥ ``min_confidence`` instead, with ``part_trust`` and ``head_doubt``);
    ``min_share``."""

    gate: bool | None = None
    gate_rule: object = None
    min_confidence: float | None = None
    min_share: float = 0.8
    part_trust: bool | None = None
    head_doubt: object = None


@dataclass(frozen=True)
class RecordOptions:
    """What each frame records for the sequence stage, nothing else changing: skeleton
    ``curves``, free ``leaves``, ``arm_evidence``, ``support`` (the unexplained silhouette),
    ``trim`` and ``centre`` offsets."""

    curves: bool = True
    leaves: bool = True
    arm_evidence: bool = True
    support: bool = False
    trim: bool = True
    centre: bool = False


@dataclass(frozen=True)
class EstimatorOptions:
    """Every option of the per-frame estimator, by stage."""

    hull: HullOptions = field(default_factory=HullOptions)
    thinning: ThinningOptions = field(default_factory=ThinningOptions)
    alignment: AlignmentOptions = field(default_factory=AlignmentOptions)
    placement: PlacementOptions = field(default_factory=PlacementOptions)
    confidence: ConfidenceOptions = field(default_factory=ConfidenceOptions)
    records: RecordOptions = field(default_factory=RecordOptions)

    def with_(self, **flat) -> EstimatorOptions:
        """A copy with options changed by the :class:`~.estimate.FrameEstimator` parameter
        names (``thinning`` is ``thinning.method``); an unknown name is a TypeError.
        ``support``, ``trim`` or ``centre`` None: unchanged."""
        groups = {}
        for k, v in flat.items():
            if k in ("support", "trim", "centre") and v is None:
                continue
            g, f = _WHERE.get(k, (None, None))
            if g is None:
                raise TypeError(f"estimator options: no option {k!r}")
            groups.setdefault(g, {})[f] = v
        return replace(self, **{g: replace(getattr(self, g), **kw) for g, kw in groups.items()})

    @classmethod
    def of(cls, **flat) -> EstimatorOptions:
        """The default options with these changed (see :meth:`with_`)."""
        return cls().with_(**flat)

    def flat(self) -> dict:
        """``{parameter name: value}`` of every option (the inverse of :meth:`of`)."""
        return {k: getattr(getattr(self, g), f) for k, (g, f) in _WHERE.items()}


_GROUPS = {"hull": HullOptions, "thinning": ThinningOptions, "alignment": AlignmentOptions,
           "placement": PlacementOptions, "confidence": ConfidenceOptions,
           "records": RecordOptions}
_WHERE = {f.name: (g, f.name) for g, c in _GROUPS.items() for f in fields(c)}
_WHERE["thinning"] = ("thinning", "method")
del _WHERE["method"]

#: the defaults, shared (frozen)
DEFAULT = EstimatorOptions()
