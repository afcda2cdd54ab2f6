"""The per-frame estimator's rules per built-in model and its capture defaults: which model
each placement rule applies to and with what constants (the ``None`` options of
:class:`~topopose.frame.estimate.FrameEstimator` take these)."""
from __future__ import annotations



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
