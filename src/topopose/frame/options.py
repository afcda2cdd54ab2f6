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
    """Every option of the per-frame estimator, by stage. By name (the keyword arguments of
    :class:`~topopose.frame.estimate.FrameEstimator` and :meth:`with_`):

    constraints : bool
        False drops coordinate constraints (acrobatics).
    betweenness : bool
        Apply the model's betweenness constraints (§12.2.2.3).
    max_missing : int
        A matching with more unmatched parts than this is rejected (the partial and
        no-matching classes of §13.2.2, which the method detects itself).
    thinning : str
        Thinning method (D6I1D, the thesis' choice for the pipeline, §12.1).
    relation : str, optional
        Betweenness relation overriding the model's (``"b"`` or ``"i"``, §13.2.2.2).
    fill : bool
        Fill the hull's cavities (background pockets enclosed by the subject) before thinning.
        A solid subject has none; they come from silhouette noise and would force closed
        surfaces into the curve skeleton (topology preservation keeps every cavity).
    tolerance : int or None
        Visual-hull tolerance: keep the voxels seen as subject by at least C − tolerance cameras.
        None (default): 1 with 6 cameras or more, else 0 — one camera's silhouette error (a
        hole, a missed limb) then no longer carves tunnels through the hull, which would give
        the skeleton spurious loops (measured in ``benchmarks/quality.py``).
    repair : int or None
        With ``tolerance > 0``, keep the tolerant hull's voxels only within ``repair`` voxels
        (26-neighbourhood) of the strict hull (tolerance 0): the tolerance then only mends the
        strict hull where a camera's silhouette has a hole or an eroded border, and no longer
        adds *phantom volume* — regions that all cameras but one see as subject, which with a
        ring of cameras stick out of the subject by up to ~20 cm and become skeleton branches
        matched as a head or a hand (the consensus hull: ``visual_hull(..., consensus=repair)``,
        both hulls from one carve). ``None`` (default): 1; a
        negative value: off. Measured in ``benchmarks/quality.py`` (``hull-tol0`` rows).
    thickness : float or None
        Weight of the thickness term of the arc cost (:func:`thickness_arc_cost`, the model's
        :data:`THICKNESS` profile; models without one: off). None: ``DEFAULT_THICKNESS_WEIGHT``
        (1.0); 0: off. A head is thick, a hand thin: a bent arm as short as the neck+head branch
        no longer takes the head. It chooses the alignment; the reported AHA distance (judged
        by T_d) is without it (``diagnostics["thickness_cost"]``). Measured in
        :data:`THICKNESS`; cost 1–3 ms a frame at 100³ (×1.3–1.4, ``benchmarks/quality.py``).
    thickness_profile : dict, optional
        ``{part stem: (lo, hi)}`` relative radii overriding the model's.
    tips : sequence of str
        Leaf parts (by name stem) placed where their skeleton branch, prolonged, leaves the hull
        (:func:`topopose.frame.tips.extremity_tips`) rather than at the branch's end, which
        thinning leaves about one limb radius inside (complete models). Default ``("head",)``:
        a head's branch ends near the ball's centre, 0.10–0.15 m below the crown; the ends of
        thin hands and feet are within 2 cm of their tips, and prolonging them to the hull's
        border lands 1–2 cm further on the real recording and on the ``body`` subject
        (``benchmarks/real.py``, ``benchmarks/quality.py``). ``()``: off. ``("head", "hand")``
        is measured by ``benchmarks/quality.py --only body`` ("hand-tips" rows).
    prune : float or None
        Remove the skeleton's bumps before the data tree (:func:`topopose.skeleton.prune.
        prune_bumps`, scale-axis ball containment): leaf branches whose inscribed balls stay
        inside the junction's ball scaled by ``prune``. None: the model's entry in
        :data:`PRUNE` (human: 2.0, measured there; other models: off); 0: off.
    junction_centroid : bool or None
        Place each junction part (model degree > 1) at the centroid of its co-optimal data
        vertices next to the chosen one (:func:`junction_position`) instead of the chosen
        vertex alone. ``None`` (default): on for complete models, off for incomplete ones
        (not measured there yet).
    leaf_axis : float or None
        Leave a leaf part unplaced when it leaves its junction across the body axis
        (:func:`off_axis_leaf`) and every other part is placed: the model's entry in
        :data:`LEAF_AXIS` (human: the head must continue the axis crotch → torso; 0.7, within
        45°, is measured there) with this minimum cosine. None: the model's entry (off for
        every built-in model: it costs the real recording half its right frames); 0: off.
    tip_fraction : float
        Move a tip part (``tips``) only this fraction of the way from its skeleton end to the
        hull's border (1, default: all the way; measured in :data:`LEAF_AXIS`).
    spine : None, bool, float or dict
        Move the body-axis parts (torso, crotch, head) back from the hull's medial axis onto
        the spine (:mod:`topopose.frame.anatomy`): against the body's front, which the feet's
        end directions give, by a share of the hull's largest inscribed-ball radius. None
        (default): the model's entry of :data:`topopose.frame.anatomy.SPINE_SHIFT` (human;
        complete models only; no front, no shift); False or 0: off; a number scales the
        model's shares; a dict ``{part: share}`` replaces them. Measured in ``anatomy.py`` and
        ``benchmarks/quality.py`` (quality_body.md, "no-spine" rows).
    trunk : None, bool or tuple
        Put the torso back on the trunk line when the alignment slid it down towards the
        crotch (:func:`topopose.frame.anatomy.torso_on_trunk`). None or True (default): the
        model's entry of :data:`topopose.frame.anatomy.TORSO_ON_TRUNK` (human; complete models
        only); False: off; a tuple ``(part, lower, upper, min_fraction, fraction)`` replaces it.
        Measured there and in ``benchmarks/quality.py`` (quality_body.md, "no-trunk" rows).
    crotch_drop : None, bool or tuple
        With the spine shift, move the crotch further down (along the up vector) and back by
        shares of the hull's largest inscribed radius (:func:`topopose.frame.anatomy.
        crotch_drop`): the legs' junction rises into the mass of flexed hips. True: the
        model's entry of :data:`topopose.frame.anatomy.CROTCH_DROP` (human; complete models
        only), and None (default) too — the drop stops above the hull's gap between the legs;
        False: off; a tuple ``(part, down, back[, floor])`` replaces it. Measured there and in
        ``benchmarks/quality.py`` (quality_body.md, "no-crotch-drop" rows).
    matched_distance : bool or None
        T_d judges the AHA distance without what the unmatched leaf parts cost
        (:func:`missing_cost`; at most ``max_missing`` of them): a frame whose only defect is a
        missing limb (§13.2.2 counts it right) is no longer rejected for its deleted arm's
        cost. None: the model's entry of :data:`MATCHED_DISTANCE` (human: on); ``Pose.distance``
        stays the whole distance. Measured there.
    tip_anchor : None, bool or dict
        Prolong these tip leaves away from an anchor part's data vertex rather than along their
        branch's end direction (``{leaf: (anchor, max_radii)}``,
        :data:`topopose.frame.tips.TIP_ANCHOR`). None or True: the model's entry, without the
        leaf that ``head_from_hull`` places (human without coordinate constraints: the head,
        from the torso, at most 3 radii); False: off; a dict replaces it. Measured there.
    head_from_hull : float or None
        Place the head part from the hull rather than from the alignment
        (:func:`topopose.frame.tips.head_from_hull`, :data:`HEAD_FROM_HULL`): the highest hull
        point thicker than this fraction of the hull's largest inscribed radius, prolonged
        away from the torso to the hull's border. None: the model's entry when its head has
        an "above" coordinate constraint (human, upright subjects: 0.4), else off; 0: off.
    trunk_blend : None, bool, float or tuple
        Draw the torso ``weight`` of the way towards its place on the trunk line crotch → head
        (:func:`topopose.frame.anatomy.trunk_blend`, after ``trunk``): arms folded on the chest
        pull the skeleton's shoulder junction forward and sideways. None or True (default): the
        model's entry of :data:`topopose.frame.anatomy.TRUNK_BLEND` (human; complete models
        only); False or 0: off; a number: that weight with the model's entry; a tuple replaces
        it. Measured there.
    placed_missing : bool or None
        ``max_missing`` counts the parts left without a position once placed — a head the
        alignment left unmatched but placed from the hull (``head_from_hull``) is placed — rather
        than the alignment's unmatched parts (:data:`PLACED_MISSING`; ``diagnostics["missing"]``
        stays the alignment's). None: the model's entry (human: on); False: off.
    short_arm : float or None
        Leave a hand unplaced when its data path from the torso is shorter than this fraction
        of the longest leg path (crotch → foot) and every other part is placed
        (:func:`short_limb`, :data:`SHORT_ARM`): a forearm folded onto the body ends the arm's
        skeleton branch at the elbow, where the hand was placed. None: the model's entry
        (human: 0.35, measured there); 0: off.
    hand_trunk : float or None
        Leave a hand unplaced when it lies closer than this many hull radii to the trunk's
        thick core and every other part is placed (:func:`topopose.frame.anatomy.hand_on_trunk`,
        :data:`topopose.frame.anatomy.HAND_ON_TRUNK`): a forearm folded onto the body ends the
        arm's branch at the elbow or runs it on inside the trunk's surface. None: the model's
        entry (human: 1.3, measured there); 0: off.
    head_ball : float or None
        With ``head_from_hull``, the hull's top must hold a ball of this fraction of the hull's
        largest inscribed radius within 1.5 of those radii (:func:`topopose.frame.tips.
        thick_top`, :data:`topopose.frame.tips.HEAD_BALL`), else the next highest thick point
        is tried: a raised fist is as thick as ``head_from_hull``'s fraction. With it the head
        comes from the hull on coarser grids too (down to 1.2 voxels of thickness rather than
        1.5). None: the model's entry (human: 0.46 with 6 cameras or more, measured there);
        0: off.
    head_axis : bool or None
        Without an up for the head (``head_from_hull`` off: no coordinate constraints,
        acrobatic and inverted subjects), place the head from the hull along the body's own
        axis crotch → torso (:func:`topopose.frame.tips.head_along_axis`,
        :data:`topopose.frame.tips.HEAD_AXIS`): the thick point farthest along it, prolonged
        from the torso to the hull's border, unless it lies more than 6 hull radii from the
        head placed so far. None (default): on where the model's head has no "above"
        coordinate constraint (where ``head_from_hull`` is off by default); False: off.
    keep_junctions : bool or None
        Never contract a constrained model arc between two junctions (the human trunk, torso
        above crotch) — unless only the contracted alignment passes T_d (a data tree with one
        junction; flagged ``junctions_contracted`` in the alignment's diagnostics):
        on when None or True. Measured in
        ``benchmarks/real_align.py``, ``docs/real_alignment.md``.
    refocus : bool
        Visual hull on a grid refocused on the subject every frame (``visual_hull(...,
        refocus=True)``, thesis §13.2.2.1).
    gate : bool or None
        ``matched`` is decided by the gate (``gate_rule``). None (default): :func:`default_gate`
        (on), off with ``constraints=False`` (the gate was chosen on upright subjects).
    gate_rule : GateOptions, False or None
        The gate (:class:`topopose.frame.confidence.GateOptions`, its models only): the AHA
        distance within T_d, or the silhouettes explained with the arcs in proportion. None
        (default): :data:`topopose.frame.confidence.GATE`. False: the fitted confidence
        ≥ ``min_confidence`` instead (with per-part trust and head doubt).
    part_trust : bool or None
        Per-part trust (:func:`topopose.frame.confidence.judge_frame`): a frame the gate alone
        rejects is matched without the one extremity (head, hand, foot) whose removal makes
        the confidence reach the minimum; that part is unplaced, its guess kept in
        ``diagnostics["untrusted_guess"]``. None (default) or True: on; False: off.
    head_doubt : bool, str or None
        With per-part trust, a head the alignment left unmatched (placed from the hull alone)
        is the untrusted part when the frame with a typical head reaches the minimum
        (:func:`topopose.frame.confidence.head_doubt`). None (default) or True: on;
        False: off; ``"any"``: a matched head too (opt-in: it also lets through frames with a
        spurious limb at the chest, ``benchmarks/results/confidence.md``).
    junction_core : bool or None
        A junction part's centroid (``junction_centroid``) over the data vertices of its
        cluster that are not leaves of the data tree (:func:`junction_position`): a branch the
        alignment contracted into the junction — a forearm lying on the belly — is no part of
        it. None: the model's entry in :data:`JUNCTION_CORE` (human: on); False: every vertex.
    support : bool or None
        Record ``diagnostics["unexplained"]``: the largest share of a camera's silhouette the
        placed model leaves unexplained (:mod:`.support`). None (default): off (``run
        --consistency`` turns it on).
    trim : bool or None
        Record ``diagnostics["trim"]``: the hands' skeleton curves cut back where the
        silhouettes' evidence ends (:mod:`.trim`; the sequence stage applies them). None
        (default): on.
    centre : bool or None
        Record ``diagnostics["centred"]`` (and ``"centred_trim"``): the offsets moving the
        limbs' curve samples onto the silhouettes' centre lines (:mod:`.centre`; the kinematic
        fit applies them, nothing else changes). None (default): off.
    mask_resolution : MaskResolution, bool or None
        Masks read reduced to the resolution the fixed grid's silhouette test needs
        (:class:`topopose.hull.hull.MaskResolution`, :func:`topopose.capture.io.reduce_mask`;
        True: its defaults). None (default) or False: full resolution — the hull is carved
        from each silhouette's bounding box (:class:`topopose.hull.HullCarver`), as fast, and
        the reduction moves a few boundary voxels (``docs/decisions.md``).
    """

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
