"""The per-frame estimator's rules per built-in model and its capture defaults: which model
each placement rule applies to and with what constants (the ``None`` options of
:class:`~topopose.frame.estimate.FrameEstimator` take these)."""
from __future__ import annotations



# Scale-axis pruning of skeleton bumps (topopose.skeleton.prune.prune_bumps) per model: the ratio;
# models not listed: off. Its figures: docs/decisions.md.
PRUNE = {"human": 2.0}


# A leaf part that must continue the body axis (model: (leaf, its junction, the junction's other
# axis end, minimum cosine)): the leaf's data vertex must lie within acos(cos) of the direction axis
# end → junction, seen from the junction (data vertices of the alignment), else the leaf is left
# unplaced — a missing limb: the frame stays usable when the rest is right. Only in frames with
# every other part placed (a second missing part would make the frame partial, rejected). On `body`
# the skeleton often has no head branch — a raised arm merges with the head in the hull, or the head
# is absorbed into the shoulders' junction — and the head then takes a shoulder spur or a bend of an
# arm path, sideways of the neck (0.08–0.33 × height off). Its figures: docs/decisions.md.
LEAF_AXIS = {"human": ("head", "torso", "crotch", 0.0)}


# A hand whose arm branch ends at the elbow is left unplaced (short_limb, FrameEstimator(
# short_arm=...)): model name → (hands, arm base, leg base, feet, min ratio). With a forearm folded
# onto the chest or the belly (elbow bent 100–120°, the arm rotated inwards) the hull fuses forearm
# and trunk, the arm's skeleton branch ends at the elbow and the alignment puts the hand there
# (0.1–0.2 of the normalized tree against 0.18 for the model's arm; deleting the arm would cost
# 0.18): "hand at the elbow" was the commonest misplaced all-pose frame
# (benchmarks/diagnose_body.py). Only when every other part is placed (a second missing part would
# make the frame partial), the shorter hand. Its figures: docs/decisions.md.
SHORT_ARM = {"human": (("hand_1", "hand_2"), "torso", "crotch", ("foot_1", "foot_2"), 0.35)}


# max_missing on the parts placed (FrameEstimator(placed_missing=...)): model name → on. With an arm
# on the body the alignment often leaves the head unmatched as well (a short head branch pruned or
# absorbed into the shoulders); the head from the hull (HEAD_FROM_HULL) places it, yet the frame was
# rejected for two unmatched parts although only the arm's hand is without a position — a "missing
# limb" frame, right by §13.2.2. Its figures: docs/decisions.md.
PLACED_MISSING = {"human": True}


# The head from the hull (pose/tips.py, head_from_hull): (head, anchor, min_fraction) — the head
# part is put where the direction anchor → the hull's highest point whose inscribed radius is ≥
# min_fraction × the hull's largest leaves the hull, whatever the alignment gave the head (the
# status stays the alignment's: ``missing`` lists the parts it left unmatched;
# ``diagnostics["from_hull"]`` names the head). On for models whose head carries an "above"
# coordinate constraint (upright subjects). Its figures: docs/decisions.md.
HEAD_FROM_HULL = {"human": ("head", "torso", 0.4)}


# T_d on the distance of the matched parts only (FrameEstimator(matched_distance=...)): model name →
# on. An arm lying on the body has no skeleton branch: the alignment deletes the model's arm (γ(w,
# 0) = w: 0.18 of the human's normalized weight) and the frame — a right one, a missing limb of
# §13.2.2 — lands at 0.40–0.70, above T_d = 0.4, with 0.22–0.52 for the rest. Its figures:
# docs/decisions.md.
MATCHED_DISTANCE = {"human": True}


# A junction's centroid (junction_position) without the data leaves of its co-optimal cluster: model
# name → on. Its figures: docs/decisions.md.
JUNCTION_CORE = {"human": True}


def default_tolerance(cap) -> int:
    """Visual-hull tolerance used by default: 1 with ≥ 6 cameras, else 0."""
    return 1 if len(cap.cameras) >= 6 else 0


def default_gate(cap) -> bool:
    """Confidence gate used by default: on, whatever the number of cameras.

    The gate (:class:`topopose.frame.confidence.GateOptions`) decides ``matched``; its reason
    is in ``docs/decisions.md`` ("confidence gate on"). ``cap`` is kept for callers.
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
