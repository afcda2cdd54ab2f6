"""Pose initialization of one frame (thesis §12.1, Fig. 12.8).

silhouettes → visual hull → D6I1D curve skeleton (border constraint for incomplete models)
→ data tree → weight normalization → AHA of the model tree into the data tree, rooted as
§12.1.1 prescribes → threshold T_d → betweenness constraints → part positions.

:class:`FrameEstimator` holds everything that does not change between frames (the model,
its :class:`~topopose.match.Matcher` precomputation, the hull's projection tables for the
capture and resolution); :func:`estimate_pose` is the one-frame convenience wrapper.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from topopose.errors import InputError
from topopose.pose.model import Model, load_model
from topopose.pose.pose import Pose

STAGES = ("hull", "thinning", "tree", "alignment")


class FrameError(Exception):
    """A frame that cannot be processed (reported as status "failed", the run goes on)."""


@dataclass
class FrameDetail:
    """Intermediate results of one frame (for pictures and debugging)."""

    volume: object = None          # topopose.Volume (the visual hull)
    skeleton: np.ndarray | None = None
    data: object = None            # data Tree (normalized weights)
    alignment: object = None


def _border_vertex(data):
    bv = data.diagnostics.get("border_vertex") if data.diagnostics else None
    if isinstance(bv, (list, tuple)):
        bv = bv[0] if len(bv) == 1 else None
    return bv


class FrameEstimator:
    """Pose initialization for the frames of one capture with one model (thesis §12.1).

    Builds once what every frame shares: the normalized, rooted model tree and its
    :class:`~topopose.match.Matcher`, and the visual-hull carver of the capture's grid.

    Parameters
    ----------
    cap : Capture
    model : Model or str
        A :class:`Model`, a built-in name or a TOML path.
    resolution : int
        Voxels along the longest side of the capture volume (thesis: 100 is the compromise).
    threshold : float, optional
        T_d; default the model's own (None in the model: 2, i.e. reject nothing).
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
        negative value: off. Measured in ``benchmarks/quality.py`` (human, 100³, noise 1,
        2 × 40 frames): FP/match 0.05 / 0.13 → 0 / 0.05, TP median distance 0.20 → 0.11; hand
        (incomplete model, fingers a few mm apart, R_b, 100³, noise 1, 40 frames): TP rate
        0.07 → 0.28, FP/match 0.82 → 0.45 (phantom volume between the fingers fused them).
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
        on ``body`` (quality_body.md, "hand-tips" rows; TP rate / FP per match, gate on): held
        out (seeds 21, 22) separated 0.85 / 0.010 either way, all poses 0.60 / 0.053 either way
        (misplaced 24 → 23 over all frames; hands' median error 1.7 → 2.1 cm); dev seeds 41, 42
        separated 0.892 / 0.027 → 0.883 / 0.036, all poses 0.658 / 0.060 → 0.675 / 0.036 (it
        loses the separated frames it was meant for, cause not studied): not the default.
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
        :data:`topopose.match.align.KEEP_CONSTRAINED_JUNCTIONS` (on) when None. Measured in
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
        (:func:`topopose.frame.confidence.head_doubt`, issue 11). None (default) or True: on;
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
    """

    def __init__(self, cap, model="human", resolution=100, threshold=None, *, constraints=True,
                 betweenness=True, max_missing=1, thinning="d6i1d", tolerance=None,
                 relation=None, fill=True, repair=None, junction_centroid=None, refocus=False,
                 min_share=0.8, gate=None, min_confidence=None, thickness=None,
                 thickness_profile=None, tips=("head",), prune=None, leaf_axis=None,
                 tip_fraction=1.0, spine=None, tip_anchor=None,
                 head_from_hull=None, trunk=None, matched_distance=None, crotch_drop=None,
                 short_arm=None, trunk_blend=None, placed_missing=None, part_trust=None,
                 hand_trunk=None, head_ball=None, keep_junctions=None, head_doubt=None,
                 head_axis=None, junction_core=None, support=None, trim=None,
                 centre=None, gate_rule=None):
        from topopose.match import Matcher
        from topopose.frame.confidence import min_confidence_for

        self.min_share = float(min_share)
        if support is not None:
            self.support = bool(support)
        if trim is not None:
            self.trim = bool(trim)
        if centre is not None:
            self.centre = bool(centre)
        # the fitted confidence knows upright subjects only (its head features look up): without
        # the coordinate constraints (acrobatic poses) the default gate is off — on, it rejected
        # 105 of the 198 frames of benchmarks/applications.py's acrobatic sequence, every
        # inverted one
        self.gate = ((default_gate(cap) and constraints) if gate is None else bool(gate))
        self.min_confidence = None if min_confidence is None else float(min_confidence)
        # per-part trust (pose/confidence.py judge_frame, DROP_PARTS): None/True on, False off
        self.part_trust = part_trust is not False
        # head doubt (pose/confidence.py head_doubt): None/True an unmatched head, "any" any
        # head, False off
        self.head_doubt = True if head_doubt is None else head_doubt

        self.cap = cap
        self.model: Model = load_model(model, constraints=constraints)
        from topopose.frame.confidence import GATE
        rule = GATE if gate_rule is None else gate_rule
        self.gate_rule = rule if self.gate and rule and self.model.name in rule.models else None
        if support is None and self.gate_rule is not None:
            self.support = True           # the gate reads the silhouette support
        if self.min_confidence is None and self.model.name == "human":
            # calibrated for the human model only, per number of cameras
            self.min_confidence = min_confidence_for(len(cap.cameras))
        self.resolution = int(resolution)
        if self.resolution < 8:
            raise InputError(f"--resolution: {resolution} is too small (at least 8 voxels)")
        self.threshold = (float(threshold) if threshold is not None
                          else (self.model.threshold if self.model.threshold is not None else 2.0))
        self.betweenness = betweenness
        self.relation = relation
        self.max_missing = int(max_missing)
        self.thinning = thinning
        self.tolerance = default_tolerance(cap) if tolerance is None else int(tolerance)
        self.fill = bool(fill)
        self.refocus = bool(refocus)
        if repair is None:
            repair = 1
        self.repair = int(repair)
        self.pattern = self.model.pattern()
        if junction_centroid is None:
            junction_centroid = self.model.complete
        adj = self.model.tree.adjacency()
        self.junctions = ({p for p in self.model.parts if len(adj[p]) > 1}
                          if junction_centroid else set())
        self.junction_core = (JUNCTION_CORE.get(self.model.name, False) if junction_core is None
                              else bool(junction_core))
        self.up = np.asarray(cap.up_vector, dtype=float)
        from topopose.match.align import KEEP_CONSTRAINED_JUNCTIONS
        self.matcher = Matcher(self.pattern, method="aha", cut=False, up=self.up,
                               keep_junctions=(KEEP_CONSTRAINED_JUNCTIONS if keep_junctions is None
                                               else bool(keep_junctions)))
        self.warmup = None      # first run: the helper process of topopose.batch.warmup.start_warmup
        self.thickness_profile = (THICKNESS.get(self.model.name) if thickness_profile is None
                                  else dict(thickness_profile))
        if thickness is None:
            thickness = DEFAULT_THICKNESS_WEIGHT
        self.thickness = float(thickness) if self.thickness_profile else 0.0
        self.thickness_reach = max(1, round(THICKNESS_REACH * self.resolution))
        if prune is None:
            prune = PRUNE.get(self.model.name, 0.0)
        self.prune = float(prune)
        nb = [p for p in self.model.neighbours(self.model.root) if p in self.junctions
              or len(adj[p]) > 1]
        self._root_arc = nb[0] if nb else None
        # a leaf that must continue the body axis (LEAF_AXIS): (leaf, junction, axis end, cos)
        rule = LEAF_AXIS.get(self.model.name)
        cos = (rule[3] if rule else 0.0) if leaf_axis is None else float(leaf_axis)
        self.leaf_axis = (*rule[:3], cos) if rule and cos else None
        self.tip_fraction = float(tip_fraction)
        # the head from the hull's highest thick point (pose/tips.py), for upright subjects
        rule = HEAD_FROM_HULL.get(self.model.name)
        frac = ((rule[2] if rule and any(c.kind == "above" and rule[0] in c.parts
                                          for c in self.model.constraints) else 0.0)
                if head_from_hull is None else float(head_from_hull))
        self.head_from_hull = (rule[0], rule[1], frac) if rule and frac > 0 else None
        # leaf parts placed where their branch leaves the hull (pose/tips.py)
        stems = set(tips or ())
        self.tips = [p for p in self.model.parts if len(adj[p]) == 1 and self.model.complete
                     and p.rstrip("_0123456789") in stems]
        # tips prolonged away from an anchor part (TIP_ANCHOR), where the hull does not place them
        from topopose.frame.tips import TIP_ANCHOR
        if isinstance(tip_anchor, dict):
            self.tip_anchor = dict(tip_anchor)
        elif tip_anchor is None or tip_anchor is True:
            placed = {self.head_from_hull[0]} if self.head_from_hull else set()
            self.tip_anchor = {p: r for p, r in TIP_ANCHOR.get(self.model.name, {}).items()
                               if p not in placed}
        else:
            self.tip_anchor = {}
        self.spine = _spine_option(self.model, spine)
        self.matched_distance = (MATCHED_DISTANCE.get(self.model.name, False)
                                 if matched_distance is None else bool(matched_distance))
        from topopose.frame.anatomy import CROTCH_DROP, TORSO_ON_TRUNK, TRUNK_BLEND
        self.trunk = _rule_option(self.model, TORSO_ON_TRUNK, trunk, default=True)
        if isinstance(trunk_blend, (int, float)) and not isinstance(trunk_blend, bool):
            rule = TRUNK_BLEND.get(self.model.name) if self.model.complete else None
            self.trunk_blend = (*rule[:4], float(trunk_blend)) if rule and trunk_blend else None
        else:
            self.trunk_blend = _rule_option(self.model, TRUNK_BLEND, trunk_blend, default=True)
        self.crotch_drop = _rule_option(self.model, CROTCH_DROP, crotch_drop, default=True)
        self.placed_missing = (PLACED_MISSING.get(self.model.name, False)
                               if placed_missing is None else bool(placed_missing))
        # a hand whose branch ends at the elbow (SHORT_ARM): (hands, torso, crotch, feet, ratio)
        rule = SHORT_ARM.get(self.model.name) if self.model.complete else None
        ratio = (rule[4] if rule else 0.0) if short_arm is None else float(short_arm)
        self.short_arm = (*rule[:4], ratio) if rule and ratio > 0 else None
        # a hand next to the trunk's core (HAND_ON_TRUNK): (hands, core, reach)
        from topopose.frame.anatomy import HAND_ON_TRUNK
        rule = HAND_ON_TRUNK.get(self.model.name) if self.model.complete else None
        reach = (rule[2] if rule else 0.0) if hand_trunk is None else float(hand_trunk)
        self.hand_trunk = (*rule[:2], reach) if rule and reach > 0 else None
        # the head from the hull holds a head-sized ball (tips.HEAD_BALL): (ball, reach)
        from topopose.frame.tips import HEAD_BALL
        rule = HEAD_BALL.get(self.model.name)
        ball = ((rule[0] if rule and len(cap.cameras) >= rule[3] else 0.0) if head_ball is None
                else float(head_ball))
        self.head_ball = ((ball, *(rule[1:3] if rule else (1.5, 1.5))) if ball > 0 else None)
        # without coordinate constraints: the head from the hull along the body's own axis
        # (tips.HEAD_AXIS): (head, anchor, lower end, min_fraction, max_shift)
        from topopose.frame.tips import HEAD_AXIS
        rule = HEAD_AXIS.get(self.model.name) if self.model.complete else None
        on = (not any(c.kind == "above" and rule[0] in c.parts for c in self.model.constraints)
              if head_axis is None and rule else bool(head_axis))
        self.head_axis = tuple(rule) if rule and on else None

    def arc_cost(self, vol, data, radii=None):
        """The thickness arc cost of this frame (:func:`thickness_arc_cost`), or None when off.
        ``radii``: :func:`taxicab_radii` of ``vol`` if already computed."""
        if not self.thickness:
            return None
        return thickness_arc_cost(vertex_radii(vol, data, self.thickness_reach, radii),
                                  self.thickness_profile, self.thickness,
                                  root=self.model.root, root_arc=self._root_arc)

    curves = True    # record the skeleton curve of each matched arc (pose.curves)
    leaves = True    # record the data tree's unmatched leaves (pose.track: snapping)
    arm_evidence = True   # record the hull's remainder when a limb is unplaced (pose.unseen)
    # record the silhouette the placed model leaves unexplained (pose.support; used by
    # ``run --consistency``, which turns it on)
    support = False
    # record the hands' curves trimmed out of the hull's phantom volume (pose.trim; applied by
    # the sequence stage, nothing else changes)
    trim = True
    # record the limbs' curves moved onto the silhouettes' centre lines (pose.centre; applied
    # by the kinematic fit, nothing else changes)
    centre = False

    # ------------------------------------------------------------------ stages
    def hull(self, frame):
        """Visual hull of ``frame`` on the capture's grid.

        :func:`topopose.visual_hull` caches the grid's projection tables on the capture, so
        they are built once per capture and resolution (per process). With ``tolerance > 0``
        and ``repair ≥ 0`` it is the consensus hull (``visual_hull(..., consensus=repair)``:
        the strict and the tolerant hull from one carve, see
        :func:`topopose.hull.hull.consensus_hull_labels`).
        """
        from topopose.hull import visual_hull

        consensus = self.repair if self.tolerance > 0 and self.repair >= 0 else None
        masks = None
        if self.support or self.trim or self.centre:   # the silhouettes the hull is carved from
            from topopose.hull import uses_soft_fusion
            from topopose.frame.support import compared_views
            self._silhouettes = None
            if not uses_soft_fusion(self.cap):
                masks = self.cap.silhouettes(frame)
                self._silhouettes = compared_views(self.cap.cameras, masks)
        vol = visual_hull(self.cap, frame, resolution=self.resolution, tolerance=self.tolerance,
                          consensus=consensus, refocus=self.refocus, masks=masks)
        if (self.support or self.trim or self.centre) and self._silhouettes is None:  # cached
            from topopose.capture.background import foreground_maps, scaled_camera
            p = self.cap.options["silhouettes"]
            cut = int(255 * float(p.get("cut", 0.5)))
            self._silhouettes = ([scaled_camera(c, float(p["scale"])) for c in self.cap.cameras],
                                 [q > cut for q in foreground_maps(self.cap, frame)])
        return vol

    def estimate(self, frame, detail: bool = False):
        """Pose of one frame; never raises for a frame-level problem (status "failed").

        Returns a :class:`Pose`, or ``(Pose, FrameDetail)`` when ``detail`` is true.
        """
        from topopose.skeleton import data_tree
        from topopose.topology import thin

        name = self.cap.frame_name(frame)
        timings = {}
        det = FrameDetail()
        stage = "hull"
        t_all = time.perf_counter()
        try:
            t0 = time.perf_counter()
            vol = self.hull(name)
            timings["hull"] = (time.perf_counter() - t0) * 1e3
            det.volume = vol
            n_vox = vol.diagnostics.get("voxels")
            if n_vox is None:
                n_vox = int(np.count_nonzero(vol.data))
            if n_vox == 0:
                raise FrameError("empty visual hull: no voxel lies inside every silhouette "
                                 "(empty silhouette, or the subject is outside the capture volume)")
            touches = vol.diagnostics.get("touches_border")
            if touches is None:
                touches = _touches_border(vol.data)
            if self.model.complete and touches:
                raise FrameError("the subject crosses the border of the capture volume "
                                 "(visual hull touches the grid side); enlarge [capture.volume] "
                                 "or use an incomplete model")
            stage = "thinning"
            if self.fill:
                t0 = time.perf_counter()
                vol = fill_cavities(vol)
                det.volume = vol
                timings["fill"] = (time.perf_counter() - t0) * 1e3
            t0 = time.perf_counter()
            keep = None if self.model.complete else arm_keep(vol)
            if self.warmup is not None:
                self.warmup.wait_tables()
            skel = thin(vol, method=self.thinning, keep=keep)
            timings["thinning"] = (time.perf_counter() - t0) * 1e3
            det.skeleton = skel
            stage = "tree"
            if self.warmup is not None:       # its tree and alignment kernels are now cached
                self.warmup.wait_all()
                self.warmup = None
            t0 = time.perf_counter()
            # incomplete model: the skeleton end pinned where the infinite limb leaves the
            # grid is the border vertex (a mask, not "grid": fingertips touching the grid
            # side must not become infinite limbs too)
            sq = None
            if self.prune > 0:         # bumps of the surface are no limbs (skeleton.prune)
                from topopose.skeleton.prune import prune_bumps
                if self.spine or self.head_from_hull is not None:
                    # the distance transform the placement needs anyway gives the ball radii
                    from topopose.frame.tips import hull_box, squared_distances
                    sq = squared_distances(vol.data, hull_box(vol))
                skel, data, _ = prune_bumps(skel, vol.data, self.prune, vol.origin,
                                            vol.voxel_size,
                                            border=None if self.model.complete else keep,
                                            squared=sq)
                det.skeleton = skel
            else:
                data = data_tree(skel, origin=vol.origin, voxel_size=vol.voxel_size,
                                 border=None if self.model.complete else keep)
            data_root = None
            if not self.model.complete:
                data_root = _border_vertex(data)
                if data_root is None:
                    raise FrameError("no skeleton branch crosses the capture border, but the "
                                     f"model {self.model.name!r} is incomplete (its "
                                     f"{self.model.infinite_edge[0]!r} limb must leave the volume)")
            data = data.normalized()
            data.root = data_root
            timings["tree"] = (time.perf_counter() - t0) * 1e3
            det.data = data
            stage = "alignment"
            t0 = time.perf_counter()
            # once a frame: the thickness term and judge_frame (which computes it when None)
            radii = taxicab_radii(vol) if self.thickness else None
            arc_cost = self.arc_cost(vol, data, radii)
            al = self.matcher.align(data, data_root=data_root, arc_cost=arc_cost)
            thick = matched_arc_cost(al, arc_cost)
            if self.matcher.contractible is not None:
                # KEEP_CONSTRAINED_JUNCTIONS: the trunk contracted only when that alone passes T_d
                def judged(a, t):
                    return a.distance - t - (missing_cost(self.pattern, a)
                                             if self.matched_distance else 0.0)
                if judged(al, thick) > self.threshold:
                    al2 = self.matcher.contractible.align(data, data_root=data_root,
                                                          arc_cost=arc_cost)
                    thick2 = matched_arc_cost(al2, arc_cost)
                    if judged(al2, thick2) <= self.threshold:
                        al, thick = al2, thick2
                        al.diagnostics["junctions_contracted"] = True
            unordered = []
            if self.betweenness:
                for c in self.model.constraints:
                    if c.kind == "between":
                        if self.relation is not None:
                            from topopose.match.tree import Constraint
                            c = Constraint(c.kind, c.parts, c.axis, self.relation)
                        al = betweenness_by_lengths(al, self.pattern, data, c)
                        if (al.diagnostics or {}).get("betweenness") == "unsatisfied":
                            # no co-optimal order satisfies it: those parts stay unplaced, a
                            # partial matching the method rejects (§13.2.2.2, R_b)
                            unordered.extend(c.parts)
                            al.diagnostics.pop("betweenness", None)
            timings["alignment"] = (time.perf_counter() - t0) * 1e3
            det.alignment = al
        except FrameError as exc:
            pose = self._failed(name, f"{stage}: {exc}", timings, t_all)
            return (pose, det) if detail else pose
        except InputError as exc:
            pose = self._failed(name, f"{stage}: {exc}", timings, t_all)
            return (pose, det) if detail else pose
        except Exception as exc:  # a frame never stops a run
            pose = self._failed(name, f"{stage}: {type(exc).__name__}: {exc}", timings, t_all)
            return (pose, det) if detail else pose

        # T_d applies to the length distance of §12.1.1; the thickness term only chooses the
        # alignment (see THICKNESS for the measurement)
        t0 = time.perf_counter()       # "placement": parts, judgement and curves of the frame
        from topopose.frame.tips import hull_box, skeleton_voxels
        box = hull_box(vol)
        sk_vox = skeleton_voxels(skel, box)     # the skeleton's voxels, once a frame
        dist = float(al.distance) - thick
        parts = {}
        for p in self.model.parts:
            v = al.mapping.get(p)
            pos = None if v is None else data.positions.get(v)
            if pos is not None and p in self.junctions:
                pos = junction_position(al, data, p, v, leaves=not self.junction_core)
            parts[p] = None if pos is None or p in unordered else np.asarray(pos, dtype=float)
        dropped = []
        if (self.leaf_axis is not None and all(x is not None for x in parts.values())
                and off_axis_leaf(data, al.mapping, *self.leaf_axis)):
            dropped.append(self.leaf_axis[0])
            parts[self.leaf_axis[0]] = None
        short = []
        if self.short_arm is not None and all(x is not None for x in parts.values()):
            p = short_limb(data, al.mapping, *self.short_arm)
            if p is not None:
                short.append(p)
                parts[p] = None
        on_skeleton = dict(parts)      # the skeleton curves end at the branch ends
        if self.tips:
            from topopose.frame.tips import extremity_tips
            for p, x in extremity_tips(vol, skel, data, al.mapping, self.tips,
                                          voxels=sk_vox, anchors=self.tip_anchor).items():
                if parts.get(p) is not None:
                    parts[p] = (x if self.tip_fraction == 1.0
                                else parts[p] + self.tip_fraction * (x - parts[p]))
        edt = None
        if self.spine or self.head_from_hull is not None or self.hand_trunk is not None:
            from topopose.frame.tips import inscribed_distances      # inscribed radii, once a frame
            edt = inscribed_distances(vol.data, box, sq)
        detect_parts = {}
        if self.spine:      # the spine lies behind the medial axis (pose/anatomy.py)
            parts, diag_spine, detect_parts = self.spine_parts(vol, skel, data, al, parts, edt,
                                                               sk_vox)
        missing = [p for p, x in parts.items() if x is None]   # by the alignment: the status
        from_hull = []
        if self.head_from_hull is not None:
            from topopose.frame.tips import head_from_hull
            head, anchor, frac = self.head_from_hull
            x = head_from_hull(vol, self.up, parts.get(anchor), frac, edt=edt,
                               ball=self.head_ball)
            if x is not None:
                parts[head] = x
                from_hull.append(head)
        if self.head_axis is not None:       # no "up" for the head: the body's axis instead
            from topopose.frame.tips import head_along_axis
            x = head_along_axis(vol, parts, self.head_axis, edt, self.head_ball)
            if x is not None:
                parts[self.head_axis[0]] = x
                from_hull.append(self.head_axis[0])
        on_core = []      # after the head from the hull: a head it placed counts as placed
        if self.hand_trunk is not None and all(x is not None for x in parts.values()):
            from topopose.frame.anatomy import hand_on_trunk
            p = hand_on_trunk(parts, self.hand_trunk, vol, edt)
            if p is not None:
                on_core.append(p)
                parts[p] = None
                on_skeleton[p] = None      # no curve to the elbow either
                missing.append(p)
        on_trunk = False
        if self.trunk is not None:       # a torso slid down to the crotch (pose/anatomy.py)
            from topopose.frame.anatomy import torso_on_trunk
            parts, on_trunk = torso_on_trunk(parts, self.trunk)
        if self.trunk_blend is not None:     # arms on the chest pull the junction forward
            from topopose.frame.anatomy import trunk_blend
            parts = trunk_blend(parts, self.trunk_blend)
        status, error = "matched", None
        mcost = missing_cost(self.pattern, al)
        # T_d judges what the matched parts cost (MATCHED_DISTANCE): a missing limb is a right
        # frame (§13.2.2), its deleted arm's own cost no reason to reject it
        judged = dist - mcost if self.matched_distance else dist
        if not math.isfinite(dist) or judged > self.threshold:
            status = "rejected"
            error = f"AHA distance {dist:.3f} above threshold T_d = {self.threshold:g}"
            if judged != dist:
                error += f" ({judged:.3f} without the unmatched parts)"
        elif len(missing) > self.max_missing and (
                not self.placed_missing
                or sum(x is None for x in parts.values()) > self.max_missing):
            status = "rejected"
            error = f"{len(missing)} parts unmatched ({', '.join(missing)})"
            if unordered:
                error += "; no co-optimal alignment satisfies the betweenness constraint"
        # what the hull lost and how far to trust the frame (topopose.frame.confidence)
        from topopose.frame.confidence import DROP_PARTS, judge_frame

        status, error, extra = judge_frame(
            vol, n_vox, data, self.model, self.up, dist, self.threshold, len(missing), status,
            error, self.min_share,
            self.min_confidence if self.gate and self.gate_rule is None else None,
            self.cap.units, al=al, thickness_cost=thick, reach=self.thickness_reach,
            radius_map=radii, missing_cost=mcost, parts=parts,
            drop_parts=DROP_PARTS if self.part_trust and self.gate_rule is None else (),
            doubt_head=self.head_doubt)
        if extra.get("untrusted"):     # per-part trust: unplaced, its best guess kept
            extra["untrusted_guess"] = np.round(parts[extra["untrusted"]], 6).tolist()
            parts = {**parts, extra["untrusted"]: None}
            on_skeleton[extra["untrusted"]] = None      # no curve for it either
        diag = {"model": self.model.name, "resolution": self.resolution,
                "hull_tolerance": self.tolerance, "hull_voxels": n_vox,
                "skeleton_voxels": int(data.diagnostics.get("n_voxels", -1)),
                "data_vertices": data.n_vertices, "missing": missing, **extra}
        if arc_cost is not None:
            diag["thickness_cost"] = round(thick, 6)
        diag["missing_cost"] = round(mcost, 6)
        if self.prune > 0:
            diag["pruned_bumps"] = len(data.diagnostics.get("pruned_bumps", ()))
        if from_hull:
            diag["from_hull"] = from_hull
        if dropped:
            diag["off_axis"] = dropped
        if short:
            diag["short_arm"] = short
        if on_core:
            diag["hand_on_trunk"] = on_core
        if on_trunk:
            diag["on_trunk"] = self.trunk[0]
        if self.spine:
            diag["spine_shift"] = diag_spine
        detect_parts = {p: x for p, x in detect_parts.items() if parts.get(p) is not None}
        if detect_parts:
            # the crotch before the drop (pose/anatomy.py CROTCH_DROP): the pelvis, what the
            # pose descriptions compare (§13.3.2.1, topopose.apps.detect.description_parts)
            diag["detect_parts"] = detect_parts
        if unordered:
            diag["betweenness_unsatisfied"] = sorted(set(unordered), key=unordered.index)
        if self.curves:
            # skeleton curve of each matched arc, for left/right and the kinematic fit (§13.3.1)
            from topopose.frame.curves import arc_curves, model_arcs
            # hand hints: a hand unplaced by a rule (short_arm, hand_on_trunk, untrusted) whose
            # branch is matched keeps that branch's curve (its end: near the wrist, measured in
            # benchmarks/tracking.py) in diagnostics["hand_hints"] for the kinematic fit
            # (kinematic_fit.HAND_HINTS); parts, statuses and the other curves unchanged
            hinted = {p: data.positions.get(al.mapping.get(p)) for p in
                      short + on_core + ([extra["untrusted"]] if extra.get("untrusted") else [])
                      if al.mapping.get(p) is not None
                      and not any(u == p for u, _ in model_arcs(self.model))}     # leaves
            hinted = {p: np.asarray(x, float) for p, x in hinted.items() if x is not None}
            try:
                # (the model's [[joint]] positions along arcs are fractions of these curves)
                curves = arc_curves(skel, vol.origin, vol.voxel_size, data, al,
                                    self.model, {**on_skeleton, **hinted}, voxels=sk_vox)
                hints = {p: curves.pop(p) for p in hinted if p in curves}
                diag["curves"] = curves
                if hints:
                    diag["hand_hints"] = hints
                # the shoulders the trunk's cross-section below the neck tells (pose/unseen.py;
                # used by the kinematic fit, nothing else changes)
                if self.spine and diag.get("spine_shift") is not None:
                    from topopose.frame.unseen import frame_hull_shoulders
                    hs = frame_hull_shoulders(vol, curves, parts, self.model, diag["spine_shift"])
                    if hs is not None:
                        diag["hull_shoulders"] = np.round(hs, 4).tolist()
                # an unplaced limb: the hull the matched curves leave unexplained, where it
                # can lie (pose/unseen.py; used by the kinematic fit, nothing else changes)
                if self.arm_evidence and any(parts.get(x) is None for pair, _ in
                                             self.model.mirrors for x in pair):
                    from topopose.frame.unseen import hull_remainder
                    diag["arm_evidence"] = np.round(hull_remainder(
                        vol, curves, edt), 4).tolist()
            except Exception as exc:           # never costs the frame its pose
                diag["curves_error"] = f"{type(exc).__name__}: {exc}"
            if self.trim and diag.get("curves") and getattr(self, "_silhouettes", None):
                from topopose.frame.trim import trimmed_curves
                t1 = time.perf_counter()
                cut = trimmed_curves(diag["curves"], parts, *self._silhouettes, vol.voxel_size)
                if cut:
                    diag["trim"] = {q: c.tolist() for q, c in cut.items()}
                timings["trim"] = (time.perf_counter() - t1) * 1e3
            if self.centre and diag.get("curves") and getattr(self, "_silhouettes", None):
                # the limbs' curves onto the silhouettes' centre lines (§13.3.1)
                from topopose.frame.centre import frame_offsets
                t1 = time.perf_counter()
                cen, cen_trim = frame_offsets(diag["curves"], diag.get("trim"),
                                              *self._silhouettes, vol.data, vol.origin,
                                              vol.voxel_size, edt)
                if cen:
                    diag["centred"] = cen
                if cen_trim:
                    diag["centred_trim"] = cen_trim
                timings["centre"] = (time.perf_counter() - t1) * 1e3
            if self.support and diag.get("curves") and getattr(self, "_silhouettes", None):
                # analysis by synthesis: the silhouette the placed model leaves unexplained
                from topopose.frame.support import support_features
                t1 = time.perf_counter()
                sup = support_features(diag["curves"], parts, *self._silhouettes, vol.data,
                                       vol.origin, vol.voxel_size, edt, extras=False)
                diag["unexplained"] = round(sup["unexplained"], 4)
                timings["support"] = (time.perf_counter() - t1) * 1e3
        if self.leaves:      # candidates for a misplaced numbered part (pose.track)
            from topopose.frame.tips import free_leaves
            diag["free_leaves"] = free_leaves(data, al.mapping)
        if self.gate_rule is not None:   # the gate (topopose.frame.confidence.GateOptions)
            from topopose.frame.confidence import gate_decision
            status, error = gate_decision(status, error, diag, self.gate_rule,
                                          sum(x is None for x in parts.values()), self.max_missing)
        timings["placement"] = (time.perf_counter() - t0) * 1e3
        timings["total"] = (time.perf_counter() - t_all) * 1e3
        pose = Pose(name, status, dist, parts, error, timings, diag)
        return (pose, det) if detail else pose

    def spine_parts(self, vol, skel, data, al, parts, edt=None, voxels=None):
        """``parts`` with the body-axis parts moved back onto the spine
        (:mod:`topopose.frame.anatomy`), the shift applied (world units, or None) and the
        dropped part before its drop (``{part: position}``, {} without a drop): the legs'
        junction on the spine, the pelvis the pose descriptions compare (§13.3.2.1)."""
        from topopose.frame.anatomy import crotch_drop, front_direction, hull_radius, spine_shift

        feet = [p for p in self.model.parts if p.rstrip("_0123456789") == "foot"]
        front = front_direction(vol, skel, data, al.mapping, feet, self.up, voxels=voxels)
        if front is None:
            return parts, None, {}
        r = hull_radius(vol, edt)
        parts = spine_shift(parts, front, r, self.spine)
        before = {}
        if self.crotch_drop is not None:
            part = self.crotch_drop[0]
            if parts.get(part) is not None:
                before = {part: np.round(np.asarray(parts[part], float), 6).tolist()}
            parts = crotch_drop(parts, self.up, front, r, self.crotch_drop, vol)
        return parts, [round(float(x), 4) for x in -r * front], before

    def _failed(self, name, reason, timings, t_all):
        timings["total"] = (time.perf_counter() - t_all) * 1e3
        return Pose(name, "failed", None, {p: None for p in self.model.parts}, reason, timings,
                    {"model": self.model.name, "resolution": self.resolution,
                     "hull_tolerance": self.tolerance})


def path_length(adj, u, v):
    """Length of the path from ``u`` to ``v`` in a tree given as ``{vertex: [(neighbour,
    weight), ...]}`` (``Tree.adjacency()``), or None when they are not connected."""
    seen, stack = {u: 0.0}, [u]
    while stack:
        x = stack.pop()
        if x == v:
            return seen[x]
        for y, w in adj[x]:
            if y not in seen:
                seen[y] = seen[x] + w
                stack.append(y)
    return None


def betweenness_by_lengths(al, pattern, data, constraint):
    """Apply a betweenness constraint (thesis §12.2.2), choosing by limb lengths among the
    co-optimal alignments that satisfy it.

    :func:`topopose.match.apply_betweenness` returns the first co-optimal alignment that
    satisfies the constraint. A betweenness sequence (thumb, index, middle, ring, little) is
    satisfied by an order and by its reverse alike (R(P1, P2, P3) is symmetric in P1, P2), and
    the alignment often cannot tell them apart either: when every data finger is shorter
    (or longer) than every model finger, Σ|w − w′| is the same for every permutation of the
    fingers (on synthetic hands all 120 were co-optimal), so "first" was the little finger
    named thumb in most frames. Among the satisfying co-optimal alignments this keeps the one
    whose limb lengths, relative to their mean, are closest to the model's (Σ of absolute
    differences; the limb of a part is its tree path from the image of the part's model
    neighbour): the thumb is the short one. The mirror image of the chosen assignment is
    compared too (it may not be co-optimal); when it wins only ``mapping`` is swapped
    (``diagnostics["betweenness"] = "mirrored"``; distance and arcs stay the alignment's).
    Same return convention as ``apply_betweenness``.
    """
    from topopose.match import apply_betweenness
    from topopose.match.betweenness import cooptimal_alignments, satisfies

    parts = tuple(constraint.parts)
    ctx = getattr(al, "_ctx", None)
    if ctx is None:
        return apply_betweenness(al, pattern, data, constraint)
    rel = constraint.relation or "b"
    adj = pattern.adjacency()
    plen, base = {}, {}
    for p in parts:
        nb = [(n, w) for n, w in adj[p] if math.isfinite(w)]
        if len(nb) != 1:                  # not a limb end: plain betweenness
            return apply_betweenness(al, pattern, data, constraint)
        base[p], plen[p] = nb[0]
    pm = float(np.mean(list(plen.values())))
    dadj = data.adjacency()

    def tree_dist(u, v):
        return None if u is None or v is None else path_length(dadj, u, v)

    def score(cand, use):
        d = {p: tree_dist(cand.mapping.get(base[p]), cand.mapping.get(p)) for p in use}
        ok = [p for p in use if d[p] is not None and math.isfinite(d[p])]
        dm = float(np.mean([d[p] for p in ok])) if ok else 0.0
        pmu = float(np.mean([plen[p] for p in ok])) if ok else pm
        return sum(abs(d[p] / dm - plen[p] / pmu) for p in ok) if dm > 0 else math.inf

    cands = [ctx.make(ctx.top, np.array(ev, np.int64).reshape(-1, 3))
             for ev in cooptimal_alignments(al, parts)]
    best = None
    for cand in cands:
        if satisfies(cand.mapping, data.positions, parts, rel):
            s = score(cand, parts)
            if best is None or s < best[0]:
                best = (s, cand)
    if best is None:
        al.diagnostics["betweenness"] = "unsatisfied"
        return al
    cand = best[1]
    cand.diagnostics["betweenness"] = "applied"
    # the mirror image of the sequence satisfies the constraint as well (same triples); the
    # alignment may have kept only one orientation, so compare both by their lengths
    n = len(parts)
    mirror = SimpleNamespace(mapping={**cand.mapping, **{parts[i]: cand.mapping.get(parts[n - 1 - i])
                                                         for i in range(n)}})
    if score(mirror, parts) < best[0]:
        cand.mapping = mirror.mapping
        cand.diagnostics["betweenness"] = "mirrored"
    return cand


# Relative thickness of each part of a built-in model (thesis §12.3 gives lengths only): the
# hull's inscribed-ball radius (taxicab distance transform on the hull's box, 0.5 ms at 100³;
# the exact EDT took 9 ms for about the same figures) at the part's data vertex — the largest within
# ±THICKNESS_REACH × resolution voxels (2 at 100³: a skeleton end lies at the crown, the head's
# centre is a few voxels in) — over the largest radius of the hull (the chest). Ranges
# (lo, hi) = 5–95 % of the correctly placed parts of `body` frames (5 builds × 2 seeds, 400
# frames, 100³, noise 1), except the head's lower bound (5 %: 0.44), lowered to 0.30 for the
# capsule human, whose small head sphere measures 0.33 (at 0.44 it lost one of 40 separated
# frames to a head/hand swap); inside no cost, outside weight × the log of the excess
# (thickness_arc_cost). Keys: part name stems. The alignment's distance without the term is
# what T_d judges. Measured on those 200 separated + 200 all-pose frames (0.08 × height, every
# part; TP rate / FP per match, separated; all):
#   no thickness term                         0.85 / 0.128;  0.45  / 0.419
#   weight 1, reach 2 (default)               0.85 / 0.115;  0.525 / 0.103
#   the same, head lower bound 0.44           0.86 / 0.104;  0.535 / 0.085
#   weight 0.3 / 0.6, reach 2, T_d on total   0.86 / 0.104, 0.845 / 0.091;  0.51 / 0.143, 0.515 / 0.104
#   weight 1, reach 2, T_d on the total       0.835 / 0.092; 0.525 / 0.071
#   leaves only (no torso, crotch), w 0.3     0.86 / 0.109;  0.51  / 0.164
#   radius at the vertex only (reach 0), w .3 0.86 / 0.109;  0.505 / 0.263 (w 0.6, 1: worse)
#   two-sided log cost around the medians    0.855 / 0.100, 0.41 / 0.241 (w 0.05); worse at 0.1
# The held-out seeds of benchmarks/quality.py (quality_body.md) check it. Capsule human (40
# frames, noise 1, 100³): separated 1.00 / 0 either way; all poses 0.75 / 0.118 → 0.80 / 0.
# The dog, the spider and the hand have no profile (term off).
DEFAULT_THICKNESS_WEIGHT = 1.0
# Scale-axis pruning of skeleton bumps (topopose.skeleton.prune.prune_bumps) per model: the
# ratio; models not listed: off. Measured on `body` (5 builds x seeds 41, 42 x 12 frames, 100³,
# noise 1, 0.08 x height; TP rate / FP per match), separated; all poses:
#   off                                   0.833 / 0.123;  0.592 / 0.145
#   branch length < c x junction radius   c 1.0: 0.833 / 0.123, 0.600 / 0.143; c 1.5: 0.842 / 0.114,
#                                         0.617 / 0.129; c 2.0: 0.858 / 0.104, 0.608 / 0.120
#                                         (the head's short branch is pruned: missing limb 12 → 32)
#   ball containment (default) < c        c 1.6: 0.842 / 0.114, 0.592 / 0.155; c 2.0: 0.858 / 0.096,
#                                         0.617 / 0.129; c 2.4: 0.858 / 0.096, 0.600 / 0.163
# (before the head tips of pose/tips.py; with them, c 2.0 contain: off 0.817 / 0.140; 0.567 / 0.181
# → on 0.833 / 0.123; 0.592 / 0.165.) Held-out seeds: benchmarks/quality.py (quality_body.md,
# "no-prune" rows).
PRUNE = {"human": 2.0}
THICKNESS = {"human": {"head": (0.30, 0.85), "hand": (0.0, 0.40), "foot": (0.0, 0.43),
                       "crotch": (0.83, 9.0), "torso": (0.67, 9.0)}}
# A leaf part that must continue the body axis (model: (leaf, its junction, the junction's other
# axis end, minimum cosine)): the leaf's data vertex must lie within acos(cos) of the direction
# axis end → junction, seen from the junction (data vertices of the alignment), else the leaf is
# left unplaced — a missing limb: the frame stays usable when the rest is right. Only in frames
# with every other part placed (a second missing part would make the frame partial, rejected).
# On `body` the skeleton often has no head branch — a raised arm merges with the head in the
# hull, or the head is absorbed into the shoulders' junction — and the head then takes a
# shoulder spur or a bend of an arm path, sideways of the neck (0.08–0.33 × height off).
# Measured on `body` (builds average, heavy, child, lean, random × tuning seeds 41–44 × 8 frames,
# 100³, noise 1, 0.08 × height; TP rate / FP per match), separated (160 frames); all poses (160):
#   off                                       0.825 / 0.170;  0.644 / 0.127
#   cos 0.6 / 0.7 / 0.8, in every frame       0.875 / 0.114, 0.881 / 0.108, 0.887 / 0.101;
#                                             0.637 / 0.121, 0.631 / 0.106, 0.637 / 0.097
#   the same, only with nothing else missing  0.875 / 0.119, 0.881 / 0.113 (default: cos 0.7,
#                                             45°), 0.887 / 0.107;  0.650 / 0.119, 0.656 / 0.110,
#                                             0.662 / 0.102
#   the world's up axis instead (cos 0.7)     0.875 / 0.114 (0.875 / 0.119);  0.644 / 0.096
#                                             (0.662 / 0.102)
# Tip of the head (pose/tips.py) only half way (tip_fraction 0.5), on top of cos 0.7, seeds 41,
# 42: 0.912 / 0.076 → 0.938 / 0.051; all poses 0.675 / 0.115 → 0.688 / 0.098: the head's skeleton
# end lies 2–5 % of the height beside the neck → crown segment (the face's volume), and the tip
# moves it as far again sideways; the real recording's head-top marker wants the whole way
# (tips.py), so the default stays 1. Held-out seeds: benchmarks/quality.py (quality_body.md,
# "no-leaf-axis", "gate-off" and "tip-half" rows): without the confidence gate separated 0.86 /
# 0.096 → 0.88 / 0.070, all poses 0.55 / 0.185 either way; with the gate (pose/confidence.py,
# the default) nothing changes at status — the gate already rejects those frames. On the real
# recording (benchmarks/real.py, person silhouettes, a subject bending and balancing) cos 0.7
# leaves the head unplaced in 69 of 100 frames and the frames with head, hands and feet within
# 0.15 m fall from 31 % to 15 %: the default is off (0); ``leaf_axis=0.7`` turns it on.
LEAF_AXIS = {"human": ("head", "torso", "crotch", 0.0)}
# A hand whose arm branch ends at the elbow is left unplaced (short_limb, FrameEstimator(
# short_arm=...)): model name → (hands, arm base, leg base, feet, min ratio). With a forearm
# folded onto the chest or the belly (elbow bent 100–120°, the arm rotated inwards) the hull
# fuses forearm and trunk, the arm's skeleton branch ends at the elbow and the alignment puts the
# hand there (0.1–0.2 of the normalized tree against 0.18 for the model's arm; deleting the arm
# would cost 0.18): "hand at the elbow" was the commonest misplaced all-pose frame
# (benchmarks/diagnose_body.py). Only when every other part is placed (a second missing part
# would make the frame partial), the shorter hand. The ratio of the torso → hand path to the
# longest crotch → foot path, `body` dev seeds 41, 42 (5 builds × 12 frames, 100³, noise 1, gate
# off): right hands of separated frames 1 % / 5 % / median 0.39 / 0.49 / 0.69; 0.35 lies below.
# All-pose frames, TP rate / FP per match: off 0.800 / 0.086, ratio 0.25–0.45 0.817 / 0.067
# (the same 2 misplaced frames become "missing limb"); separated frames unchanged. The hand's
# inscribed radius and the path alone (normalized weights) did not separate wrong from right
# hands. Held out (benchmarks/quality.py, quality_body.md, "no-short-arm" rows; gate off): all
# poses 0.77 / 0.080 → 0.79 / 0.050 (misplaced 21 → 18), separated 0.93 / 0.067 either way.
SHORT_ARM = {"human": (("hand_1", "hand_2"), "torso", "crotch", ("foot_1", "foot_2"), 0.35)}
# max_missing on the parts placed (FrameEstimator(placed_missing=...)): model name → on. With an
# arm on the body the alignment often leaves the head unmatched as well (a short head branch
# pruned or absorbed into the shoulders); the head from the hull (HEAD_FROM_HULL) places it,
# yet the frame was rejected for two unmatched parts although only the arm's hand is without a
# position — a "missing limb" frame, right by §13.2.2. `body` dev seeds 41, 42 (5 builds × 12
# frames, 100³, noise 1, gate off; TP rate / FP per match, with SHORT_ARM and TRUNK_BLEND): all
# poses 0.825 / 0.057 → 0.842 / 0.056 (2 right frames more matched, no wrong one), separated
# 0.917 / 0.043 either way. Held out (benchmarks/quality.py, quality_body.md,
# "no-placed-missing" rows; gate off): all poses 0.78 / 0.051 → 0.79 / 0.050, separated 0.93 /
# 0.067 either way.
PLACED_MISSING = {"human": True}
# The head from the hull (pose/tips.py, head_from_hull): (head, anchor, min_fraction) — the head
# part is put where the direction anchor → the hull's highest point whose inscribed radius is
# ≥ min_fraction × the hull's largest leaves the hull, whatever the alignment gave the head
# (the status stays the alignment's: ``missing`` lists the parts it left unmatched;
# ``diagnostics["from_hull"]`` names the head). On for models whose head carries an "above"
# coordinate constraint (upright subjects). Real recording (benchmarks/real.py, person
# silhouettes, 4 cameras, 100³; cached hulls, frames with head, hands and feet within 0.15 m):
# off 32 → 0.4: 71 of 100 (0.3: 68, 0.35: 71, 0.45: 59, 0.5: 22); head median / p90 error
# 0.122 / 0.370 → 0.068 / 0.096 m. Body subject (benchmarks/quality.py's body set, seeds 21, 22,
# 100³, TP rate / FP per match, gate on | off): separated 0.79 / 0.031 | 0.86 / 0.096 → 0.81 /
# 0.010 | 0.89 / 0.061, all poses 0.46 / 0.083 | 0.55 / 0.185 → 0.47 / 0.067 | 0.56 / 0.173;
# head median error 5.6 → 2.1 cm. The window is narrow: on the body's 8-camera hulls raised
# arms count as thick below 0.4 (separated, gate on: 0.3 → 0.64 / 0.214, 0.35 → 0.78 / 0.051,
# 0.45 → 0.82 / 0.000); on the real recording's 4-camera hulls (a trunk inflated by phantom
# volume) the head no longer does above it (0.45 → 59 right frames). On a coarse grid the rule
# is skipped (thick radius below 1.5 voxels, :func:`~topopose.frame.tips.thick_top`): at 50³ the
# body's trunk is 3–3.5 voxels thick and the rule cost separated frames 0.53 / 0.190 → 0.48 /
# 0.266; at 100³ it is 5–6 voxels.
HEAD_FROM_HULL = {"human": ("head", "torso", 0.4)}
# T_d on the distance of the matched parts only (FrameEstimator(matched_distance=...)): model
# name → on. An arm lying on the body has no skeleton branch: the alignment deletes the model's
# arm (γ(w, 0) = w: 0.18 of the human's normalized weight) and the frame — a right one, a
# missing limb of §13.2.2 — lands at 0.40–0.70, above T_d = 0.4, with 0.22–0.52 for the rest.
# Measured on ``body`` (training seeds 41, 42, 5 builds × 12 frames, 100³, noise 1, gate off,
# torso on the trunk; TP rate / FP per match), all poses: whole distance 0.667 / 0.059 →
# matched parts 0.800 / 0.086 (T_d 0.35 on it: 0.767 / 0.052); separated 0.908 / 0.044 →
# 0.908 / 0.052. With the gate (the default) the fitted confidence decides instead of T_d and
# reports both distances (pose/confidence.py; only the whole one is fitted). Held-out seeds 21,
# 22 (benchmarks/quality.py, quality_body.md, "whole-distance" rows), gate off: separated 0.91 /
# 0.044 → 0.93 / 0.067, all poses 0.60 / 0.111 → 0.73 / 0.111; with the gate unchanged (0.85 /
# 0.010; 0.60 / 0.053).
MATCHED_DISTANCE = {"human": True}
THICKNESS_REACH = 0.02      # × resolution: the radius at a vertex is the largest within ± that


def taxicab_radii(vol):
    """The taxicab distance transform of the hull on its bounding box grown by one voxel
    (:func:`scipy.ndimage.distance_transform_cdt`'s, computed by
    :func:`topopose.frame.estimate_kernels.taxicab_distances`): ``(dt, lo)``, voxel ``ijk`` at
    ``dt[ijk - lo]``. One per frame serves every :func:`vertex_radii` of the frame."""
    from topopose.frame.estimate_kernels import taxicab_distances

    a = vol.data
    bbox = (vol.diagnostics or {}).get("bbox")
    if bbox is None:
        occ = [np.flatnonzero(a.any(axis=tuple(i for i in range(3) if i != ax))) for ax in range(3)]
        bbox = ([int(o[0]) for o in occ], [int(o[-1]) for o in occ])
    lo = [max(int(x) - 1, 0) for x in bbox[0]]
    hi = [min(int(x) + 2, n) for x, n in zip(bbox[1], a.shape)]
    return taxicab_distances(a[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]), lo


def vertex_radii(vol, data, reach: int = 0, radii=None) -> dict:
    """Inscribed-ball radius of the hull at every data vertex, relative to the hull's largest:
    the taxicab distance transform (:func:`scipy.ndimage.distance_transform_cdt`, 20× faster
    than the exact EDT) on the hull's bounding box, its largest value within ``reach`` voxels
    of the vertex (0: at the vertex; a vertex whose voxel is background — an I-component
    centroid off the hull — takes the largest of its 3×3×3 neighbourhood). ``radii``:
    :func:`taxicab_radii` of ``vol`` if already computed."""
    from topopose.frame.estimate_kernels import window_max

    dt, lo = taxicab_radii(vol) if radii is None else radii
    ref = float(dt.max()) or 1.0
    org, vs = np.asarray(vol.origin, float), float(vol.voxel_size)
    verts = [v for v in data.vertices if data.positions.get(v) is not None]
    if not verts:
        return {}
    # every vertex at once (the same arithmetic, element by element)
    pos = np.array([np.asarray(data.positions[v]) for v in verts])
    x = np.round((pos - org) / vs).astype(int) - np.asarray(lo)
    x = np.clip(x, 0, np.array(dt.shape) - 1)
    r = window_max(dt, x.astype(np.int64), int(max(reach, 0)))
    return {v: float(a) / ref for v, a in zip(verts, r.tolist())}


def thickness_arc_cost(radii: dict, profile: dict, weight: float, cap: float = 1.5,
                       root=None, root_arc=None):
    """Arc cost term (:meth:`topopose.match.Matcher.align`) of the parts' thickness.

    Resizing the model arc that ends at part ``p`` (its lower end, away from the root) to a
    data path ending at vertex ``v`` costs ``weight × min(max(0, log(lo / r), log(r / hi)),
    cap)``, with ``r`` the relative radius of :func:`vertex_radii` at ``v`` and ``(lo, hi)``
    the part's range (``profile``, by name stem, e.g. :data:`THICKNESS`; parts without one pay
    nothing): nothing inside the range, the log of the excess outside. The arc ``root`` →
    ``root_arc`` also pays for the root's own thickness at its upper end. A head is thick, a hand thin: a bent
    arm whose branch is as short as the neck+head branch no longer takes the head.
    """
    def stem(p):
        head, sep, tail = str(p).rpartition("_")
        return head if sep and tail.isdigit() else str(p)

    known = {}             # id of a vertex list → (list, its radii with NaN where unknown)
    # vertices numbered 0 … n - 1 (data trees): the radii as an array, read by index, and
    # each part's term computed once over all vertices (elementwise: the same values)
    ids = [v for v in radii if isinstance(v, (int, np.integer)) and not isinstance(v, bool)]
    table = None
    if ids and len(ids) == len(radii) and min(ids) >= 0 and max(ids) < 4 * len(ids) + 64:
        table = np.full(max(ids) + 1, np.nan)
        table[np.asarray(ids, np.int64)] = [radii[v] for v in ids]
    by_stem = {}           # stem → its term over ``table``

    def values(lo, hi, radius):
        r = np.maximum(np.where(np.isnan(radius), max(lo, 1e-3), radius), 1e-3)
        out = np.maximum(np.log(max(lo, 1e-3) / r), np.log(r / hi))
        return weight * np.clip(out, 0.0, cap)

    def term(part, verts):
        rho = profile.get(stem(part))
        if rho is None:
            return np.zeros(len(verts))
        got = known.get(id(verts))
        if got is None or got[0] is not verts:
            idx = None
            if table is not None and len(verts):
                idx = np.asarray(verts)
                if (idx.dtype.kind not in "iu" or idx.ndim != 1 or idx.min() < 0
                        or idx.max() >= len(table)):
                    idx = None
            got = known[id(verts)] = (verts, idx if idx is not None else np.array(
                [radii.get(v, np.nan) for v in verts], float))
        if got[1].dtype.kind in "iu":
            t = by_stem.get(stem(part))
            if t is None:
                t = by_stem[stem(part)] = values(*rho, table)
            return t[got[1]]
        return values(*rho, got[1])

    def cost(p_up, p_low, d_up, d_low):
        C = np.zeros((len(p_up), len(d_up)))
        low = {}
        up = {}
        for i, (pu, pl) in enumerate(zip(p_up, p_low)):
            if pl not in low:
                low[pl] = term(pl, d_low)
            C[i] = low[pl]
            if pu == root and pl == root_arc:
                if pu not in up:
                    up[pu] = term(pu, d_up)
                C[i] += up[pu]
        return C

    return cost


def matched_arc_cost(al, arc_cost) -> float:
    """The part of ``al.distance`` paid to ``arc_cost`` (0 when None): its value on every
    matched pair of arcs (``al.pairs``: pattern path, data path, upper ends first)."""
    if arc_cost is None or not math.isfinite(al.distance):
        return 0.0
    pairs = al.pairs or []
    if not pairs:
        return 0.0
    C = arc_cost([p[0] for p, _ in pairs], [p[-1] for p, _ in pairs],
                 [d[0] for _, d in pairs], [d[-1] for _, d in pairs])
    return float(np.trace(np.asarray(C)))


def missing_cost(pattern, al) -> float:
    """What the unmatched leaf parts of the alignment ``al`` cost it: the normalized weight of
    each model leaf arc whose leaf maps to no data vertex (a deleted arc costs γ(w, 0) = w)."""
    if not math.isfinite(al.distance):
        return 0.0
    adj = pattern.adjacency()
    return float(sum(adj[p][0][1] for p, v in (al.mapping or {}).items()
                     if v is None and len(adj.get(p, ())) == 1 and math.isfinite(adj[p][0][1])))


def arm_keep(vol) -> np.ndarray:
    """Keep mask of an incomplete model's thinning (thesis §12.1): one voxel where the
    infinite limb (the forearm) leaves the grid.

    The thesis keeps the object voxel nearest the centroid of the object voxels on the grid
    boundary (:func:`topopose.topology.border_constraint`). Two refinements make it the limb's
    exit point in every frame: the boundary voxels are split into 26-connected pieces and
    only the largest one (the limb's cut section; a fingertip grazing the grid side makes a
    small second piece) is used, and the kept voxel is taken among that piece's own voxels,
    so it always lies on the boundary — a limb leaving across an edge or a corner of the grid
    gives an L-shaped section whose centroid is inside the object, and the object voxel
    nearest it is then not on the boundary (no skeleton end touches the border, the frame
    fails). Empty mask when the object does not touch the boundary.
    """
    import cc3d

    a = vol.data
    onb = np.zeros(a.shape, dtype=bool)
    for ax in range(3):
        for end in (0, -1):
            idx = [slice(None)] * 3
            idx[ax] = end
            onb[tuple(idx)] = a[tuple(idx)]
    out = np.zeros(a.shape, dtype=bool)
    if not onb.any():
        return out
    lab, n = cc3d.connected_components(onb, connectivity=26, return_N=True)
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    pts = np.argwhere(lab == int(np.argmax(sizes)))
    c = pts.mean(axis=0)
    out[tuple(pts[int(np.argmin(((pts - c) ** 2).sum(axis=1)))])] = True
    return out


def off_axis_leaf(data, mapping, leaf, junction, axis_end, min_cos) -> bool:
    """Whether ``leaf``'s data vertex leaves the data vertex of ``junction`` at more than
    acos(``min_cos``) from the axis ``axis_end`` → ``junction`` (a head beside the neck: a
    shoulder spur or an arm's bend). False when one of the three is unmatched or two coincide."""
    pts = [data.positions.get(mapping.get(p)) if mapping.get(p) is not None else None
           for p in (leaf, junction, axis_end)]
    if any(x is None for x in pts):
        return False
    leaf_p, junc, end = (np.asarray(x, dtype=float) for x in pts)
    a, b = junc - end, leaf_p - junc
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na == 0 or nb == 0:
        return False
    return float(a @ b) / (na * nb) < min_cos


def short_limb(data, mapping, limbs, base, leg_base, legs, min_ratio):
    """The part of ``limbs`` (the hands) whose data path from ``base``'s vertex (the torso) is
    the shortest, when it is shorter than ``min_ratio`` × the longest data path from
    ``leg_base`` (the crotch) to one of ``legs`` (the feet); else None (also when ``base``,
    ``leg_base`` or every leg is unmatched). A real arm's branch, shoulder centre → hand, is
    about 0.7 of a leg's (``body``, median); one that ends at the elbow (a forearm folded onto the body, fused with
    it in the hull) is shorter than the upper arm, and the hand placed at its end is wrong."""
    adj = data.adjacency()

    def length(a, b):
        u, v = mapping.get(a), mapping.get(b)
        return None if u is None or v is None else path_length(adj, u, v)

    leg = max((x for x in (length(leg_base, f) for f in legs) if x is not None), default=None)
    if not leg:
        return None
    arms = [(x, p) for p, x in ((p, length(base, p)) for p in limbs) if x is not None]
    if not arms:
        return None
    x, p = min(arms)
    return p if x < min_ratio * leg else None


# A junction's centroid (junction_position) without the data leaves of its co-optimal cluster:
# model name → on. Measured on ``body`` (dev seeds 1, 11, 14, 5 builds × 12 frames, 100³, noise
# 1, gate off): 30 of 180 all-pose frames have a leaf in the torso's cluster (a forearm on the
# belly, its branch contracted into the junction), their torso error falls in 20 (e.g. 0.60 →
# 0.25, 1.00 → 0.67 × the tolerance), TP rate / FP per match 0.811 / 0.070 → 0.817 / 0.064;
# separated unchanged (0.978 / 0.022). Held out (benchmarks/quality.py, quality_body.md,
# "no-junction-core" rows, the confidence refit with the rule): gate on, all poses 0.808 / 0.020
# → 0.817 / 0.020, separated 0.975 / 0.008 either way; gate off unchanged (docs/body_accuracy.md).
# See FrameEstimator(junction_core=).
JUNCTION_CORE = {"human": True}


def junction_position(al, data, part, v, leaves: bool = True):
    """Position of the junction part ``part`` mapped to data vertex ``v``.

    Thinning seldom leaves one intersection voxel where several limbs meet (§7.3): the data tree
    holds a cluster of junction vertices joined by edges of a voxel or two, and the alignment
    can map the model junction to any of them at the same cost (its co-optimal
    ``alternatives``, §12.2.2). The chosen one is a tie-break; the cluster — the alternatives
    connected to ``v`` through alternatives in the data tree — is the junction, and its centroid
    the estimate. Measured in ``benchmarks/quality.py`` (spider, 100³, noise 1, 40 frames): the
    cephalothorax median error 0.053 → 0.020 (tolerance 0.082), misplaced frames 7 → 2; human
    torso 0.030 → 0.023. ``leaves`` False: the cluster's leaves of the data tree left out
    (unless it has nothing else) — the far end of a branch contracted into the junction
    (:data:`JUNCTION_CORE`).
    """
    alts = set((al.alternatives or {}).get(part) or ())
    if len(alts) <= 1 or v not in alts:
        return data.positions.get(v)
    adj = data.adjacency()
    seen, stack = {v}, [v]
    while stack:
        x = stack.pop()
        for y, _w in adj.get(x, ()):
            if y in alts and y not in seen:
                seen.add(y)
                stack.append(y)
    if not leaves:
        seen = [u for u in seen if len(adj.get(u, ())) > 1] or seen
    pts = [data.positions[u] for u in seen if data.positions.get(u) is not None]
    return np.mean(np.asarray(pts, dtype=float), axis=0) if pts else data.positions.get(v)


def fill_cavities(vol):
    """Fill the volume's cavities, in place: background components (6-adjacency, the dual of
    the object's 26-adjacency) that do not reach the outside become object. Returns ``vol``.

    :func:`topopose.hull.fill_cavities` (same result as ``scipy.ndimage.binary_fill_holes``)
    on the hull's bounding box ``vol.diagnostics["bbox"]`` when :func:`topopose.visual_hull`
    left one (it must still hold every voxel), else on the box it computes."""
    from topopose.hull import fill_cavities as fill

    if not vol.data.flags.c_contiguous:
        vol.data = np.ascontiguousarray(vol.data)
    n, _ = fill(vol.data, (vol.diagnostics or {}).get("bbox"))     # in place: the frame's own hull
    if n:
        vol.diagnostics["cavities_filled"] = n
    return vol


def default_tolerance(cap) -> int:
    """Visual-hull tolerance used by default: 1 with ≥ 6 cameras, else 0."""
    return 1 if len(cap.cameras) >= 6 else 0


def default_gate(cap) -> bool:
    """Confidence gate used by default: on, whatever the number of cameras.

    With the fitted confidence (:mod:`.confidence`, ``benchmarks/results/confidence.md``:
    held-out seeds of ``body`` (walk, random, separated and all poses) and the capsule human,
    noise 1, 100³, right = issue 11's TP, every placed part within 0.08 × height; matched
    frames, precision, recall of the right frames): 8 cameras 383, 0.859, 0.859 without the
    gate → 327, 0.936, 0.799 with it; 4 cameras 18, 0.67, 0.14 → 8, 0.88, 0.08. On the body
    benchmark's own frames (``quality.py --only body``, seeds 21, 22, 8 cameras; TP rate /
    FP per match) separated 0.86 / 0.096 → 0.79 / 0.031, all poses 0.55 / 0.185 → 0.46 /
    0.083. (The earlier product confidence halved the right frames with 8 cameras, so the
    gate was on with fewer than 6 cameras only.) ``cap`` is kept for callers.
    """
    return True


def _rule_option(model, table, option, default: bool):
    """A per-model rule option of :class:`FrameEstimator` (``trunk``, ``crotch_drop``): the
    model's entry of ``table`` (complete models only) when ``option`` is True, or None and
    ``default``; a tuple or list replaces it; anything else (False): off (None)."""
    if isinstance(option, (tuple, list)):
        return tuple(option)
    if option is True or (option is None and default):
        return table.get(model.name) if model.complete else None
    return None


def _spine_option(model, spine):
    """The spine shift shares of :class:`FrameEstimator` (``{part: share}``, empty: off):
    None: the model's entry of :data:`topopose.frame.anatomy.SPINE_SHIFT` (complete models
    only); False/0: off; a number: that multiple of the model's entry; a dict: the shares."""
    from topopose.frame.anatomy import SPINE_SHIFT

    base = SPINE_SHIFT.get(model.name, {}) if model.complete else {}
    if spine is None or spine is True:
        return dict(base)
    if isinstance(spine, dict):
        return {p: float(x) for p, x in spine.items() if p in model.parts}
    return {p: float(spine) * x for p, x in base.items()} if spine else {}


def _touches_border(a: np.ndarray) -> bool:
    return bool(a[0].any() or a[-1].any() or a[:, 0].any() or a[:, -1].any()
                or a[:, :, 0].any() or a[:, :, -1].any())


def estimate_pose(cap, frame, model="human", resolution=100, threshold=None, *,
                  constraints=True, betweenness=True, max_missing=1, thinning="d6i1d",
                  tolerance=None) -> Pose:
    """Estimate the pose of one frame (thesis §12.1, Fig. 12.8).

    For many frames build one :class:`FrameEstimator` (or use :func:`topopose.run`): it
    reuses the model precomputation and the hull's projection tables.

    Examples
    --------
    >>> import topopose as tp                                        # doctest: +SKIP
    >>> cap = tp.load_capture("CAPTURE")                             # doctest: +SKIP
    >>> pose = tp.estimate_pose(cap, "000012", "human")              # doctest: +SKIP
    >>> pose.status, pose.parts["head"]                              # doctest: +SKIP
    """
    est = FrameEstimator(cap, model, resolution, threshold, constraints=constraints,
                         betweenness=betweenness, max_missing=max_missing, thinning=thinning,
                         tolerance=tolerance)
    return est.estimate(frame)
