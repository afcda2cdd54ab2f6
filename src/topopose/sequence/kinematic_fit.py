"""Full skeleton: a kinematic model fitted to the skeleton curves of each frame (thesis §13.3.1:
the per-frame result initializes a kinematic model — extremities placed, then a fit to the
skeleton).

The model TOML declares joints at relative positions along its arcs (``[[joint]]``,
:class:`~topopose.pose.model.JointSpec`); joined in order along the arcs from the model root
they form a kinematic tree (:func:`kinematic_tree`). Per sequence:

1. **Initial placement** — every joint at its relative arc length ``at`` on the skeleton curve
   of its arc (:mod:`.curves`); ``at = 1`` is the arc's end part. A joint beside the curve
   (``offset``: shoulders and hips lie beside the curve's path from the chest junction) is moved
   along the trunk and away from its mirror partner by the declared fractions of the trunk.
   A joint at a part (``at = 0``, or ``at = 1`` without ``beyond``) whose arc has no curve in
   the frame (the far part missing, e.g. no head) is at that part. The trunk's curves and the
   joints beside them move back by ``SkeletonFitOptions.spine`` × the frame's spine shift (the spine
   lies behind the medial axis, :func:`frame_curves`); a joint with a ``width`` (hips) sits
   beside its arc's junction by ``width`` × the hull radius (the sequence's median); a joint
   with an ``at_raised`` (elbows, wrists) is there when its limb is raised, a raised arm's
   shoulder lower by ``SkeletonFitOptions.raised_shoulder``; a hanging arm's shoulder is the hull's
   (``diagnostics["hull_shoulders"]``: the trunk's cross-section below the neck,
   :func:`topopose.frame.unseen.hull_shoulders`; ``SkeletonFitOptions.seen_hull_shoulder``). A bent limb's
   middle joint (elbow, wrist, knee, ankle) is at its curve's bend (:func:`bend_joints`,
   ``SkeletonFitOptions.bend``). The knees are then placed by their distance from the leg curve's far end
   (sequence stage, :func:`from_end`, ``SkeletonFitOptions.from_end``): a 4-camera hull's leg junction
   wanders, the foot end does not. A hanging arm's elbow and wrist then move half-way to
   their places by the sequence's bone lengths from the shoulder along the curve
   (:func:`from_start`, ``SkeletonFitOptions.from_start``): the arm's curve ends short where the masks lose
   the hand, and its start slides with the chest junction. The tips' targets are corrected
   for the thinned branch end (sequence stage, :func:`tip_targets`): the toe turned away from
   the shank (``SkeletonFitOptions.tip_turn``), the fingertip moved out along the hand (``SkeletonFitOptions.tip_stretch``).
   A joint declared with a ``girdle`` (the neck with the shoulders) and that mirror pair are
   then placed as one symmetric rigid body (sequence stage, :func:`girdle_targets`,
   ``SkeletonFitOptions.girdle``).
2. **Bone lengths** — each bone's ``SkeletonFitOptions.quantile`` percentile over the matched frames of
   the initial placement, a mirror pair's bones (``elbow_1``, ``elbow_2``) sharing one length;
   constant over the sequence; a ``slide`` bone (the neck's) at its median
   (``SkeletonFitOptions.slide_quantile``: its length varies with the junction, no curve cuts it short), a
   shoulder's bone from the junction at ``SkeletonFitOptions.shoulder_quantile`` (with
   ``SkeletonFitOptions.slide`` on, off by default, a joint declared
   ``slide`` — the neck: its parent, the chest, is the skeleton curves' junction, which slides
   along the spine — takes each frame's initial-placement length, :func:`frame_lengths`).
3. **Fit** — per matched frame, the root at its initial placement (the model root part) and one
   direction per bone (``P_child = P_parent + L · d/|d|``, so lengths stay exactly constant),
   arc chain by arc chain from the root down, by :func:`scipy.optimize.least_squares` on: the
   distance of every curve sample to the chain of joints along its arc (the kinematic chain
   follows the skeleton curve), the distance of each joint to its initial placement (weight 1
   for joints on parts and joints with an offset, ``inner_weight`` for the others) and a gauge
   term ``|d| - 1``; then the root is moved by the mean offset of the other joints from their
   placements and the chains fitted again (``ROOT_STEPS``). An arc with neither a curve nor a
   placed joint in the frame keeps the bone directions of the last fitted frame when that is
   at most ``hold_frames`` (5) before and the same motion (``_continues``) and a frame placed
   the joint at most ``GapOptions.hold_age`` (8) frames before, else takes a rest pose
   (:func:`rest_fill`: a limb merged with the body hangs along the trunk, an arm's shoulder
   opposite its mate raised ``GapOptions.held_shoulder``, its forearm folded up and across the
   trunk's front); its joints are
   listed in ``diagnostics["held_joints"]``, so a frame that lost one part still has a
   skeleton. On unrelated random poses the last frame's arm was 11.6 cm off (median MPJPE of
   the frames holding joints, development seeds 21–33), the rest pose 8.7 cm. An unseen arm
   whose hand the per-frame stage left unplaced while its branch was matched (a short arm,
   a hand on the trunk's core, an untrusted hand: ``diagnostics["hand_hints"]``, the branch's
   curve) is then bent to reach the hint's end with its wrist (:func:`hint_fill`,
   ``GapOptions.hints``; ``fit_sequence(hints=False)``: off).
   Before the hints, an unseen arm's elbow is turned about its shoulder → wrist line towards
   the hull the matched curves leave unexplained (``diagnostics["arm_evidence"]``,
   :mod:`topopose.frame.unseen`, ``GapOptions.evidence``; ``fit_sequence(evidence=False)``: off).
   Last, an unseen arm moves half-way towards the nearer shoulder from the hull
   (:func:`shoulder_fill`, ``GapOptions.shoulders``; ``fit_sequence(shoulders=False)``: off, for
   the seen arms too).
4. **Gaps** — stretches of at most ``max_gap`` unfitted frames between fitted ones are filled
   by interpolating the root position and the bone directions (normalized linear), flagged
   ``diagnostics["interpolated"] = true``; never silently. Savitzky–Golay smoothing
   (:func:`scipy.signal.savgol_filter`, window :data:`SMOOTH`: 9 frames at 25 frames/s, the
   same 0.36 s at the capture's rate, :func:`smooth_window`; 0: off) of the root and bone
   directions over runs of fitted frames of one continuing motion (:func:`motion_runs`:
   consecutive frame numbers, each frame within ``SmoothingOptions.move`` of its neighbours' median,
   broken where the motion jumps and stays — a capture of unrelated poses makes no run),
   flagged ``diagnostics["smoothed"]``; the bones keep their constant lengths. Before the
   filter a bone direction far off its window's median (one frame's limb on a wrong branch)
   is replaced by that median (:func:`despike`, a Hampel filter, ``SmoothingOptions.despike``), listed in
   ``diagnostics["despiked_joints"]``. Each frame
   records its distance from its neighbours' median (``diagnostics["neighbour_distance"]``,
   :func:`neighbourhood`), ``diagnostics["temporal_outlier"]`` when it is ``SmoothingOptions.move``
   or more: a skeleton off the motion around it, most likely wrong. A stretch of at most
   ``max_gap`` such frames between two frames of one motion is *bridged*: its joints and
   parts interpolated from them as a gap, flagged ``interpolated`` too
   (:func:`bridge_outliers`, :func:`bridged_parts`, ``SmoothingOptions.bridge``).
"""
from __future__ import annotations

import numpy as np

from topopose.frames import sort_poses
from topopose.sequence.gap_filling import (ACROSS, FOLD, HINT_END,  # noqa: F401
                                           SHOULDER_BLEND, _below, _continues,
                                           _interpolate, _outward, held_gaps, hint_fill,
                                           rest_fill, shoulder_fill)
from topopose.sequence.joint_placement import (BEND_DEPTH, HANG_COS, HULL_GATE,  # noqa: F401
                                               REACH_PAST, _arc_position, _hangs, _limb_joints,
                                               _raised, _reach, bend_joints, centred_curves,
                                               frame_curves, from_end, from_start,
                                               girdle_targets, initial_placement, tip_targets)
from topopose.sequence.options import DEFAULT, SequenceOptions
from topopose.sequence.skeleton_fit import (ROOT_STEPS, TIP_DIRECTION,  # noqa: F401
                                            KinematicTree, _along, _beside, _directions,
                                            _end_direction, _seg_dist, _seg_nearest,
                                            bone_lengths, chain_joints, chain_residuals,
                                            fit_frame, forward, frame_lengths, kinematic_tree)
from topopose.sequence.smoothing import (SMOOTH, SMOOTH_RATE, _apart,  # noqa: F401
                                         bridge_outliers, bridged_parts, despike, motion_runs,
                                         neighbourhood, smooth_window)
from topopose.sequence.track import frame_index

FIT, GAPS, SMOOTHING = DEFAULT.skeleton_fit, DEFAULT.gaps, DEFAULT.smoothing


# SkeletonFitOptions.spine = 0.15: the trunk's joints moved back by this × the frame's spine shift (see
                    # :func:`frame_curves`; development seeds 41–43 walks, 21–24 random, MPJPE
                    # median with the shoulders and hips moved too: 0 → 0.15 → 0.25 → 0.35:
                    # walks 5.47 → 5.31 → 5.31 → 5.41, random 7.34 → 7.12 → 7.22 → 7.13 cm)


# SkeletonFitOptions.centred = True: the limbs' curves moved onto the silhouettes' centre lines when the frame
                   # recorded them (``diagnostics["centred"]``, :mod:`.centre`)


# SkeletonFitOptions.raised_shoulder = 0.08: trunk lengths: a raised arm's shoulder (its hand past the chest junction
                        # along the trunk, as ``at_raised``) moved down the trunk by this; None
                        # or 0: off. Its curve rises with the arm, and the offsets calibrated on
                        # all arms left it high: after the fit the seen shoulders of raised arms
                        # were 4.1 cm too high (rig shoulder frame, median; hanging arms 2.1;
                        # development seeds 21–32 random, 269 raised arms). 0 / 0.04 / 0.08 /
                        # 0.12 / 0.16: random shoulders 7.6 / 7.1 / 7.0 / 6.9 / 7.0 cm, MPJPE
                        # 6.03 / 6.05 / 5.97 / 6.06 / 6.10 cm; walks (41–46: no raised arm)
                        # 4.85 cm either way


# SkeletonFitOptions.seen_hull_shoulder = True: a hanging seen arm's shoulder (its hand below the chest junction
                           # along the trunk) at the nearer of the frame's shoulders from the
                           # hull (``diagnostics["hull_shoulders"]``: the trunk's cross-section
                           # below the neck, :func:`topopose.frame.unseen.hull_shoulders`) when
                           # within HULL_GATE of its place on the curve. Development seeds
                           # 21–28 random, 41–45 walks (gate on; the seen shoulders' initial
                           # placement, median): hanging arms 6.8 → 3.6 (random, 155 arms),
                           # 6.0 → 2.4 cm (walks, 221); raised arms 6.4 → 8.5 cm (the slab's
                           # lateral extreme is the arm: not used). MPJPE of the fit (unseen
                           # arms' shoulders from the hull as well), without → with: random
                           # 5.76 → 5.63, walks 4.84 → 4.46 cm; shoulders 6.6 → 6.3 / 6.0 →
                           # 4.4 cm. Weighting the hull's shoulders ×3 / ×10 in the fit brought
                           # the shoulders to 5.9 / 3.9 cm but bent the elbows off (random
                           # 5.5 → 6.1 / 6.3 cm): MPJPE 5.70 / 5.77, not kept; only arms whose
                           # upper arm hangs within 30° / 45° / 60° of the trunk axis: 5.73 /
                           # 5.70 / 5.64, walks 4.85 / 4.67 / 4.47; bone lengths from the
                           # placement without the hull: 5.67 / 4.51 cm. ``tracking.py --dev``
                           # (random 21–32, walks 41–46, 60 / 40 frames), without → with:
                           # MPJPE random 5.6 → 5.6 (shoulders 6.9 → 6.5, elbows 5.6 → 5.8),
                           # walks 4.8 → 4.5 cm (shoulders 6.5 → 4.4); the real recording
                           # (``real_motion.py``) 10.6 → 10.3 cm, shoulders 15.6 → 13.2 cm
# SkeletonFitOptions.hanging_width = (-0.15, 0.7): hull radii (along the trunk, outward): the ``width`` of a joint
                   # whose limb hangs (:func:`_hangs`; a standing leg) instead of the model's
                   # (``human``: [-0.3, 0.7], a raised or spread leg); None: the model's always.
                   # The hips sat 2.6 cm low and 2.4 cm inside on walks, 0.7 cm high and 3.0 cm
                   # inside on random poses (width [-0.3, 0.7], median bias in the truth's body
                   # frame): the crotch junction lies lower against the hips when the legs hang.
                   # Development seeds (random 21–32, 60 frames, walks 41–46, 40 frames, gate
                   # on, the per-frame poses of one run; MPJPE median over frames, walks /
                   # random): one width for all [-0.3, 0.7] 4.38 / 5.50 cm (hips 6.4 / 5.4),
                   # [-0.3, 0.85] 4.41 / 5.42, [-0.3, 1.0] 4.52 / 5.45, [-0.15, 0.7] 4.28 /
                   # 5.67, [-0.15, 0.85] 4.30 / 5.57, [-0.2, 0.85] 4.32 / 5.51; hanging
                   # [-0.15, 0.85] (cos 0.9 / 0.8 / 0.95) 4.32 / 5.42, 4.31 / 5.47, 4.36 / 5.41;
                   # hanging [-0.1, 0.85] 4.33 / 5.42; hanging [-0.15, 0.7] 4.30 / 5.40 (hips
                   # 6.1 / 5.1 cm), but the real recording (real_motion.py; balancing: a
                   # raised leg) 8.4 → 8.5 cm (hips 9.4 → 9.7, width 0.223 → 0.266 m against
                   # Pose2Sim's 0.209: its fat 4-camera hull's radius). Kept: hanging [-0.15,
                   # 0.7], the model's [-0.3, 0.7] 4.38 → 4.30 / 5.50 → 5.50 cm (hips 6.4 → 6.0
                   # / 5.5); real 8.4 → 8.4 cm (hips 9.4 → 8.7; its right frames 7.5 → 7.5,
                   # hips 8.0 → 7.7 cm; they sat 2.8 cm low). Held-out (tracking.md, once):
                   # walks 4.2 → 4.2 cm (hips 5.6 → 5.9: the heavy walks' 4.8 → 6.2, 5.7 → 7.0;
                   # the lean's 7.1 → 6.3, 8.0 → 7.0), random 5.2 → 5.2 (hips 4.9 → 4.7).
                   # Not kept either: a third tier,
                   # the outward width 0.85 for a leg more than arccos(0.8 / 0.7 / 0.5 / 0)
                   # from down: random 5.45 / 5.49 / 5.50 / 5.50 cm, the real recording (at
                   # 0.8) 8.4 → 8.5 cm (hips 8.7 → 9.8, width 0.265 m: its legs' curves lean
                   # more than 37° from down most of the time); the outward width from the
                   # sequence's shank length (its bone from the knee, 80th percentile: within
                   # 0–3 cm of the rig's) instead of the hull radius, × 0.289 (the MakeHuman
                   # rig's half hip-joint distance / shank, its default build) 4.44 / 5.48 cm,
                   # × 0.33 4.48 / 5.47 cm: the half hip distance spreads 0.26–0.45 shanks over
                   # the body's builds, 0.77–0.97 hull radii (the heavy build's hips are wide).


# SkeletonFitOptions.bend = None: off by default (``bend=BEND_DEPTH`` switches it on). Held out with 8 cameras it
             # adds nothing to the median (random poses 5.3 cm either way; elbows 5.5 → 5.2, ankles
             # 3.4 → 3.1 cm), and on the real 4-camera recording (benchmarks/real_motion.py) it
             # hurts: all frames 8.4 → 8.9 cm, the right frames 7.7 either way — a noisy 4-camera
             # hull's wrong curves bend where no limb does


# SkeletonFitOptions.from_end = {("foot", "knee"): 40}: (limb end part's stem, joint base name) → percentile: that
    # middle joint placed by its distance from its curve's far end (the human's foot; not the
    # spider's legs, unmeasured), the reference length the percentile of the sequence's
    # leg-curve lengths (see from_end); {}: off (the fraction ``at`` from the junction).
    # Development seeds (walks 41–44, random motion 51–53, 40 frames, the centred curves;
    # studies/knee_dev.py, MPJPE median over the good frames, 4p / 4pd / 8 cameras): off
    # 10.44 / 8.85 / 3.44 cm (knees 7.5 / 7.4 / 2.5); percentile 30: 10.38 / 8.92 / 3.45; 40:
    # 10.40 / 8.81 / 3.45 (knees 6.2 / 5.4 / 2.6); 50: 10.53 / 8.72 / 3.45 (knees 6.0 / 5.8 /
    # 2.6); 60: 10.52 / 8.75 / 3.41 — each from the end alone; half-way to the place at ``at``
    # (``SkeletonFitOptions.from_end_weight``), 40: 10.30 / 8.73 / 3.39 cm (knees 6.0 / 6.5 / 2.5), 50: 10.37 /
    # 8.78 / 3.40. Elbows from the hand's end as well: mixed (docs/tried.md).


# SkeletonFitOptions.from_end_weight = 0.5: the joint's arc length: this share of the one from the far end, the rest
    # of the one at its fraction ``at`` (1: from the end alone). From the end alone the knees
    # improve where the junction drops and worsen where it does not (development seeds,
    # percentile 40, knees per sequence 4p 4.7 → 5.6, 9.1 → 5.5, 5.1 → 7.0 ...); MPJPE 4p / 4pd
    # / 8 cameras with the weight 0.3 / 0.5 / 0.7 / 1: 10.31 / 10.30 / 10.28 / 10.40, 8.78 /
    # 8.73 / 8.75 / 8.81, 3.40 / 3.39 / 3.40 / 3.45 cm (off: 10.44 / 8.85 / 3.44)


# SkeletonFitOptions.from_start = {("hand", "elbow"), ("hand", "wrist")}: (limb end part's stem, joint base
    # name): those joints of a hanging limb (its end part below its first along the trunk)
    # also placed by the sequence's bone lengths from their parent (see from_start); set():
    # off. On the real recording the hanging left arm's curve ends 2–11
    # cm past the wrist from frame to frame (the masks lose part of the hand) and its start,
    # the chest junction, slides, so the fraction ``at`` put the elbow 10.4 cm and the wrist
    # 9.4 cm off (median over the right frames; the fits either side of a short frame within
    # 3 cm). Development seeds, with DESPIKE (studies/knee_dev.py, good frames, 8 / 4p /
    # 4pd): 3.50 / 8.90 / 8.34 → 3.40 / 8.72 / 8.21 cm (elbows 4.0 / 9.3 / 11.5 → 3.5 / 8.4 /
    # 10.1); studies/fps_dev.py (8 cameras 25 / 60 frames/s, 4p 25 / 60): 4.25 / 3.70 /
    # 9.75 / 9.27 → 4.16 / 3.64 / 9.55 / 9.28 cm. Not kept (docs/decisions.md): weight 1 (4pd
    # 8.49: the fat hulls' bone lengths are 1.2–1.3 × the truth's), raised arms too, the
    # fingertips too, the knees and ankles (by arc length: the real recording 6.6 → 7.6 cm)
# SkeletonFitOptions.from_start_weight = 0.5: the joint goes this share of the way from its place at ``at`` to its
    # place by the bone length (as FROM_END_WEIGHT; 0.7: 8 / 4p / 4pd 3.44 / 8.63 / 8.39 cm)
    # end (a hand lost in the masks shortens the arm's curve by a few cm; a curve much shorter
    # is no lost hand): beyond, its place at ``at`` is kept


# SkeletonFitOptions.width_radius = "sequence": the hull radius of the joints' ``width``: the sequence's median
                            # (a subject's girth is constant) or "frame" (each frame's own)
# SkeletonFitOptions.quantile = 70: percent; see bone_lengths (development seeds as SPINE_BACK, with it
                     # 50 → 70 walks 5.31 → 5.12, random 7.12 → 7.00 cm)


# SkeletonFitOptions.limb_quantile = {"foot": 80}: percent, by the limb's end part (its stem): the constant length
                             # of the bones along a limb's arc (thigh, shank, foot; not the bone
                             # from the junction) instead of ``SkeletonFitOptions.quantile`` (only when no
                             # quantile is given). A leg's curve is cut short and cuts the bent
                             # knee's corner as an arm's does: at the 70th percentile the legs sat
                             # short. Development seeds (random 21–32, 60 frames, walks 41–46, 40
                             # frames, gate on; MPJPE median over frames), legs at 70 → 80: random
                             # 5.66 → 5.58 cm (hips 5.6 → 5.5, knees 3.8 → 3.7, ankles 3.5 →
                             # 3.4), walks 4.40 → 4.33 cm; the real recording (real_motion.py) 8.4
                             # → 8.4 cm (its right frames 7.7 → 7.5, hips 8.4 → 8.0). Not kept:
                             # legs at 90 (random 5.51 vs 5.48 at 80, both with hips 0.85 below),
                             # arms at 60 / 80 (random 5.58 / 5.66: shoulders 6.3 at 80), every
                             # bone at 80 (5.59); the hips' outward ``width`` 0.7 → 0.85 hull
                             # radii (the hips sat 3.0 / 2.2 cm inside on random / walks): random
                             # 5.58 → 5.48, walks 4.33 → 4.29 cm, but the real recording 8.4 →
                             # 8.5 cm (hips 10.1 → 10.5: its fat 4-camera hull's radius widens
                             # them; already 0.225 m against Pose2Sim's 0.209)


# SkeletonFitOptions.slide = False: the model's ``slide`` bones take each frame's length (False: every bone constant).
               # Off by default: issue 15 asks for bone lengths constant over the sequence and a
               # BVH (constant offsets, :func:`~.export.write_bvh`) whose re-read joints equal
               # the fit's. On, the neck's bone from the chest (the curves' junction, not a
               # joint: it slides along the spine, a raised arm pulls it up) takes each frame's
               # length (development seeds 21–28 random, 41–45 walks, gate on; fit, median over
               # frames, neck / MPJPE: random 6.2 / 6.13 → 5.2 / 6.03 cm, the initial
               # placement's neck 5.2; walks 3.9 / 4.85 → 3.5 / 4.83 cm; benchmark in
               # ``tracking.md``). Tried too: the neck's 30th/50th percentile, no gain; the
               # pelvis sliding: hips 6.0 → 5.7, pelvis 5.9 → 6.6 cm


# SkeletonFitOptions.slide_quantile = 50: percent: the constant length of a ``slide`` bone (the neck's, from the chest
                     # junction) when SLIDE is off; None: ``SkeletonFitOptions.quantile`` as the others.
                     # The 70th percentile makes up for a limb's curve cutting corners; the
                     # neck's curve cuts none — its length from the junction only varies as the
                     # junction slides: at the 70th percentile the neck bone was 16.0 cm long
                     # on random poses against 13.9 cm from the junction to the true neck
                     # (median; initial placement 13.5; development seeds 21–32 random, 41–46
                     # walks, gate on), so the fit pushed the neck 1.2 cm further off than its
                     # initial placement. Median: random neck 6.4 → 6.0, MPJPE 6.22 → 6.20 cm;
                     # walks neck 3.8 → 3.8, MPJPE 4.89 → 4.86 cm (40th: random neck 5.7, walks
                     # 3.9; every trunk bone at the median: random pelvis 5.3 → 5.9 cm)


# SkeletonFitOptions.shoulder_quantile = 50: percent: the constant length of a bone from the root (the curves' chest
                        # junction) to a joint beside the curve (a shoulder; ``offset``); None:
                        # ``SkeletonFitOptions.quantile``. As the neck's (``SkeletonFitOptions.slide_quantile``) its length
                        # only varies as the junction slides, and a hanging arm's shoulder is the
                        # hull's, not the curve's: no corner to make up for. At the 70th
                        # percentile the fit lifted the seen hanging arms' shoulders off their
                        # placement (bent arms 5.8 → 7.2 cm, 3.0 cm too high; straight 3.4 →
                        # 5.2 cm; development seeds 21–32 random, gate on). Development seeds
                        # (as ``SkeletonFitOptions.bend``'s, with it), 70 → 40 / 50: MPJPE random
                        # 5.49 → 5.56 / 5.51 (mean over frames 6.27 → 6.20 / 6.21), walks 4.37
                        # → 4.33 / 4.31 cm; shoulders random 6.5 → 6.1, walks 4.1 → 3.6 cm


# GapOptions.hold_age = 8: frames: a joint is held from the last fitted frame only when a frame placed
                    # it at most this many frames before; older, it takes the rest pose and the
                    # fills (evidence, hints, hull shoulders) afresh. None: no limit. In random
                    # motion a lost arm stays lost 20–40 frames, and held from frame to frame it
                    # drifts with each frame's fills (development seeds 51–56, 204 lost arms:
                    # mean shoulder / elbow / wrist error 12.9 cm median, 15–17 cm after 4–7 and
                    # over 30 frames; with HOLD_AGE 8: 11.2 cm). Development seeds (random motion
                    # 51–56, walks 41–46, unrelated random poses 21–32; gate on, no smoothing;
                    # MPJPE median): None 6.12 / 4.29 / 5.60 cm; 0 (never held) 5.93 / 4.37;
                    # 1 / 3 / 5 / 8 / 12: random motion 5.90 / 5.93 / 5.95 / 5.91 / 5.93, walks
                    # 4.37 / 4.31 / 4.29 / 4.29 / 4.29 cm (walks' arms are lost for 1–7 frames
                    # and hang straight: holding them is right); unrelated poses 5.60 at each
                    # (they fail the motion check). With SMOOTH 9: None / 5 / 8 / 12: random
                    # motion 5.30 / 5.17 / 5.07 / 5.18, walks 3.58 / 3.57 / 3.59 / 3.59 cm


# GapOptions.gaps = False: an unseen (held) joint between two frames of the same motion that saw it
                 # interpolated (:func:`held_gaps`, ``fit_sequence(gaps=True)``); off: the rest
                 # pose / last frame's arm of the frame loop. Off by default: no gain measured.
                 # Random-motion captures are unrelated poses (the pelvis moves ~1 m between
                 # frames): never filled. Development walks 41–46 (gate on): MPJPE median 4.33 →
                 # 4.33 cm, frames holding joints 5.53 → 5.46 (per walk 3.67 / 5.43 / 4.17 /
                 # 4.10 / 4.50 / 3.97 → 3.67 / 5.43 / 4.17 / 4.29 / 4.21 / 3.84); the 144
                 # filled joints (37 frames; hips' width 0.85 then), error to the
                 # nearest rig joint of their kind, median / mean: last frame's 7.4 / 9.6 →
                 # interpolated 7.5 / 9.1 cm (the frames either side see the arm only partly).
                 # Random motion (random-smooth, development seeds 51–56; HOLD_FRAMES 5), runs up
                 # to 5 / 10 / 15 / 30 / 60 frames: 6.12 → 6.12 / 6.12 / 6.12 / 6.16 / 6.16 cm
                 # (a lost arm stays lost 20–40 frames, across rejected ones); walks 4.29 →
                 # 4.30–4.31; unrelated random poses 21–32 5.60 → 5.81 (HOLD_MAX · (b − a) lets
                 # one held frame between two similar poses through; studies/held_dev.py)


# GapOptions.held_shoulder = np.radians(30.0): an unseen arm's shoulder: from the chest, opposite its mate
                          # across the trunk axis, raised by this angle from the plane across the
                          # trunk (None: the mate's position turned half about the trunk axis).
                          # The half turn copied the mate's height, and a seen arm is often a
                          # raised one that pulls its shoulder up: the unseen arms' shoulders
                          # were 5.8 cm too high (12.7 cm off, median; the rig's 7.0 cm above
                          # the chest junction against our 12.7; development seeds 21–32 random,
                          # 185 unseen arms). Elevation 0° / 20° / 25° / 30° / 35° / 45°: MPJPE
                          # random 6.28 / 6.09 / 6.10 / 6.07 / 6.12 / 6.27 cm (half turn 6.22),
                          # unseen arms (mean shoulder / elbow / wrist error, median) 16.0 /
                          # 13.2 / 13.0 / 12.9 / 13.0 / 14.8 (14.8) cm; walks 41–46 4.87–4.98
                          # (4.89) cm. Tried on top: the hanging upper arm tilted outward by
                          # 10° / 20° / 30° (random 6.09 / 6.13 / 6.13 cm) and a hinted arm's
                          # elbow bent outward (no gain)


# GapOptions.evidence = True: an unseen arm's elbow turned towards the hull's remainder
                     # (topopose.frame.unseen.evidence_fill). Development seeds 21–28 random,
                     # 41–45 walks (gate on), without → with: MPJPE random 5.98 → 5.83, walks
                     # 4.86 → 4.86 cm; frames holding joints 6.85 → 6.40 / 6.22 → 6.15 cm;
                     # unseen arms (mean shoulder/elbow/wrist error, median) 12.2 → 10.2 cm
                     # (140 arms) / 7.9 → 7.2 cm (63 arms)


# GapOptions.shoulders = True: an unseen arm moved towards the shoulder from the hull's cross-section
                      # below the neck (``diagnostics["hull_shoulders"]``, :func:`topopose.pose.
                      # unseen.hull_shoulders`; :func:`shoulder_fill`), after the evidence and
                      # the hints. Development seeds 21–28 random, 41–45 walks (gate on, 181
                      # unseen arms): from the fit's chest the hull's shoulder is 3.6 cm from
                      # the true one, the rest pose's 8.2 cm (median), but 30 % of the time it
                      # is the worse one, and the arm moved with it then drags elbow and
                      # wrist off. MPJPE random / walks: without 5.83 / 4.86 cm; the whole
                      # arm moved before the evidence and hints 5.87 / 4.91, only the
                      # shoulder 5.85 / 4.88, the arm after them 5.81 / 4.86; within 0.1 m
                      # half-way (SHOULDER_BLEND) 5.76 / 4.84, within 0.2 m half-way 5.63 /
                      # 4.46 (with the seen arms' hull shoulders: SEEN_HULL_SHOULDER), 0.7 of
                      # the way 5.67 / 4.45. The rest pose's upper arm tilted out or forward
                      # by 20° on top: 5.96–6.07 / 4.84–4.86 cm
# (Issue 15, hips branch: the unseen random arms after these fills sit inside the truth's body
# frame by 3.3 / 4.0 / 3.4 cm (shoulder / elbow / wrist; forward +2.8 / +1.4 / −0.3, up +1.8 /
# +0.1 / +0.9; median over 256 arms, development seeds 21–32, 60 frames; their errors 8.7 /
# 10.5 / 11.8 cm: scatter, not bias). Not kept: the unseen elbow and wrist moved out by 3 / 6
# cm after shoulder_fill: arms 12.0 → 11.6 / 11.8 cm, MPJPE 5.50 → 5.51 / 5.55 cm;
# HELD_SHOULDER 20° 5.53, ACROSS 15° 5.58 cm.)


# SkeletonFitOptions.tip_turn = {"toe": 15.0}: degrees, by tip joint: its target turned away from the bone above its
                    # parent (the toe from the shank, knee → ankle), in the plane of the two
                    # (:func:`tip_targets`).
                    # The foot's skeleton curve cuts the heel's corner and its last 10 % still
                    # points along the shank: the ankle's bend (shank → foot) was 19–20° too
                    # small after the fit (28–30° in the initial placement; development seeds
                    # random 21–32, walks 41–46, 40 frames, gate on; median, the same at every
                    # true ankle angle), the toes 4.9 / 5.4 cm below the true foot's line
                    # (random / walks). Toes, median: 0 / 10 / 15 / 18 / 20 / 25 / 35°: random
                    # 6.2 / 4.6 / 4.3 / 4.4 / 4.7 / 5.3 / 7.2, walks 6.9 / 5.0 / 4.8 / 5.0 /
                    # 5.1 / 5.6 / 7.4 cm; MPJPE (no toe in it) random 5.67 → 5.67, walks 4.27 →
                    # 4.27 cm, ankles 3.5 / 3.1 → 3.5 / 3.1. Held out (tracking.py, once, with
                    # TIP_STRETCH; same run without both): toes random 5.8 → 4.0, walks 6.7 →
                    # 4.4 cm; MPJPE random 5.21 → 5.20, walks 4.20 → 4.16 cm (gate on); the real
                    # recording (real_motion.py, same per-frame poses) 8.37 → 8.37 cm, its right
                    # frames 7.50 → 7.54 cm; its toes against Pose2Sim's big toes 9.9 → 7.5 cm
                    # (right frames 9.1 → 7.0)
# SkeletonFitOptions.tip_stretch = {"fingertip": 1.08}: by tip joint: its target moved away from its parent by this
                    # factor (:func:`tip_targets`). The fingertips sat short along the true
                    # hand (wrist → fingertip 0.88 / 0.92 of the rig's after the fit, 3.1 / 2.4
                    # cm short; random / walks, development seeds as TIP_TURN; their direction
                    # unbiased, 2° / 5°). Fingertips, median, 1 / 1.05 / 1.08 / 1.1 / 1.15:
                    # random 7.0 / 6.8 / 6.7 / 6.7 / 6.7, walks 5.2 / 5.1 / 5.2 / 5.3 / 5.5 cm;
                    # MPJPE random 5.67 → 5.66, walks 4.27 → 4.26 cm. The hand's bone at a
                    # higher percentile instead, the target left: 80 / 90 / 97 %: fingertips
                    # random 6.8 / 6.7 / 6.9 cm, but the fit then pulls the wrist back (random
                    # wrists 4.5 → 4.5 / 4.7 / 5.1 cm). Held out: fingertips random 7.4 → 7.3,
                    # walks 5.6 → 5.6 cm (with TIP_TURN, see there)


# SkeletonFitOptions.girdle = True: the joints a model declares as one girdle (``girdle = [pair, height]`` on a
               # joint: the neck with the shoulders) placed as one symmetric rigid body
               # (:func:`girdle_targets`); False: each joint alone. Development seeds (walks
               # 41–46, random motion 51–56, unrelated random poses 21–32; gate off, cached
               # per-frame results, studies/trunk_dev.py's measure; MPJPE median over the
               # good frames, 4p / 4pd / 8 cameras): off 8.90 / 7.47 / 3.67 cm, neck and
               # shoulders at height 0 / 0.1 / 0.15 × the shoulder width 8.63 / 8.59 / – ,
               # 7.16 / 7.13 / – , 3.71 / 3.61 / – (necks 8.8 → 8.2, 6.8 → 5.7, 4.2 → 3.6;
               # shoulders 9.0 → 9.6, 9.0 → 9.1, 3.7 → 4.0 cm at 0.1); the neck alone moved
               # (0.1): 8.72 / 7.19 / 3.69; the neck weighted 0.5: 8.66 / 7.17 / 3.61; the
               # pelvis and hips as a girdle (height 0): 9.08 / 7.52 / 3.78 (worse). All
               # frames (most of them wrong per frame with 4 cameras) off → 0.1: 14.65 → 14.46,
               # 13.99 → 14.12, 4.54 → 4.47 cm. On the truth the neck lies 4–6 cm above the
               # shoulders' midpoint, on the mid-plane; the 4-camera fit put it 10 cm from it,
               # 1 cm up (development seeds)


# SmoothingOptions.move = 0.15: m: a frame whose joints (from the root) lie this far from its
                    # neighbourhood's median is an outlier, and a run breaks where successive
                    # neighbourhoods lie this far apart (mean over the joints; :func:`motion_runs`).
                    # Compared with the one frame before instead (window 9:
                    # 0.1 / 0.15 / 0.25 m: random motion 5.31 / 5.07 / 5.11, walks 3.59 / 3.59 /
                    # 3.60 cm, unrelated random poses 5.60 at each): a 4-camera fit's per-frame
                    # jitter broke the runs, the real recording had 27 of 100 frames smoothed.
                    # Against the neighbourhood (studies/fps_dev.py):
                    # development 8 cameras 4.20 → 4.23 cm at 25 frames/s, 3.73 → 3.71 at 60;
                    # 4p 10.04 → 9.89 / 9.74 → 9.74 cm; unrelated random poses (seeds 21–24)
                    # 5.44 cm, no frame smoothed, either way


# SmoothingOptions.despike = (3.0, 15.0): (k, floor in degrees) of :func:`despike`, the bones' spikes replaced
    # before the smoothing; None: off. A frame whose matched curves put one limb on a wrong
    # branch (the real recording's frames 36 and 42: the left arm's curve on another branch,
    # its hand 0.6 m off) keeps the rest of its skeleton near its neighbours', so it stays in
    # its run, and the Savitzky–Golay window averaged the wrong arm into the 20 frames around
    # it (left elbow 7 cm off where the fits either side had it within 3 cm). Real recording
    # (real_motion.py): all / right frames 6.80 / 6.44 → 6.61 / 6.26 cm
    # (k 2 / 5 with floor 10 / 15°: 6.66 / 6.42, 6.75 / 6.33; floor 8 / 25°: 6.56 / 6.26,
    # 6.61 / 6.26). Development seeds: neutral (fps_dev.py, 8 cameras 25 / 60 frames/s, 4p 25
    # / 60: 4.23 / 3.71 / 9.75 / 9.27 → 4.25 / 3.70 / 9.75 / 9.27 cm; knee_dev.py, 8 / 4p /
    # 4pd: 3.43 / 8.97 / 8.34 → 3.50 / 8.90 / 8.34); unrelated random poses untouched (no run)


# SmoothingOptions.bridge = True: a temporal outlier between two frames of the same motion is replaced by their
    # interpolation (:func:`bridge_outliers`); False: it keeps its own fit, flagged only.
    # Development seeds (studies/fps_dev.py; MPJPE median over
    # the good frames, the default window): 4p 9.89 → 9.75 cm at 25 frames/s (15 frames
    # bridged), 9.74 → 9.27 at 60 (37); 8 cameras 4.23 / 3.71 cm, no frame bridged; unrelated
    # random poses (seeds 21–24) none bridged. Without the majority rule 4p 9.37 / 8.90 cm,
    # but held-out unrelated random poses were bridged (s12: 4.8 → 5.1 cm)


def fit_sequence(poses, model, options: SequenceOptions | None = None, fps=None, **flat):
    """Fit the full skeleton to every matched frame of a sequence (see the module docstring).

    Parameters
    ----------
    poses : list of Pose (curves in their diagnostics)
    model : Model with ``[[joint]]`` declarations
    options : SequenceOptions, optional
        Its ``skeleton_fit``, ``gaps`` and ``smoothing`` (default :data:`.options.DEFAULT`).
    fps : the capture's frame rate (frames/s) the default window is scaled to (None: 25)
    **flat : options changed by field name (:meth:`.SequenceOptions.with_`): ``max_gap``,
        ``smooth`` (an odd Savitzky–Golay window over the runs of continuing motion,
        :func:`motion_runs`; None: :func:`smooth_window` of ``fps``; 0: off), ``inner_weight``,
        ``spine``, ``quantile``, ``slide``, ``hints``, ``evidence``, ``shoulders`` (False: the
        seen arms' hull shoulders off too), ``gaps``, ... (:mod:`.options`)

    Returns
    -------
    poses : list of Pose with ``joints`` (numbered joint names, e.g. ``elbow_1``) and
        ``diagnostics["skeleton_rms"]`` (curve distance after the fit),
        ``["interpolated"]``, ``["smoothed"]``, ``["despiked_joints"]`` (the joints whose
        bone direction :func:`despike` replaced), ``["neighbour_distance"]`` (m: the frame's
        joints from its neighbours' median, :func:`neighbourhood`, when smoothing) and
        ``["temporal_outlier"]`` (that distance ≥ ``SmoothingOptions.move``: a frame off the motion
        around it, most likely wrong; ``["interpolated"]`` too when bridged,
        :func:`bridge_outliers`, and ``["interpolated_parts"]``, the parts it took from the
        frames either side, :func:`bridged_parts`), ``["held_joints"]`` (not seen by the frame),
        ``["interpolated_joints"]`` (those of them interpolated, :func:`held_gaps`)
    tree : KinematicTree
    lengths : ndarray, the bone length of each joint's bone (NaN for the root); a ``slide``
        bone's is its sequence length, used where the frame has none
    """
    o = (options or DEFAULT).with_(**flat)
    fit, gap, sm = o.skeleton_fit, o.gaps, o.smoothing
    max_gap, smooth, spine = gap.max_gap, sm.smooth, fit.spine
    hull = None if gap.shoulders else False     # off: the seen arms' hull shoulders too
    move = sm.move
    poses = sort_poses(poses)
    tree = kinematic_tree(model)
    radius = [np.linalg.norm(p.diagnostics["spine_shift"]) for p in poses
              if p.matched and p.diagnostics.get("spine_shift") is not None]
    radius = float(np.median(radius)) if radius and fit.width_radius == "sequence" else None
    init = np.stack([initial_placement(p, tree, spine, radius, hull, fit)
                     if p.matched
                     else np.full((len(tree.names), 3), np.nan) for p in poses]) \
        if poses else np.zeros((0, len(tree.names), 3))
    init = from_end(init, poses, tree, spine, fit=fit)     # limb middle joints from the far end
    init = tip_targets(init, tree, fit=fit)
    init = girdle_targets(init, tree, fit=fit)
    L = bone_lengths(init, tree, fit=fit)
    init = from_start(init, poses, tree, L, spine=spine, fit=fit)   # hanging arms by the bones' lengths
    P, Lf, rms, t = _fit_frames(poses, init, tree, L, fit, gap)
    n_f = len(poses)
    held = np.isnan(init).any(axis=2)
    filled = np.zeros_like(held)
    if max_gap and gap.gaps:
        P, filled = held_gaps(P, held, t, tree, Lf, max_gap, gap.hold_max)
    fitted = ~np.isnan(P).any(axis=(1, 2))
    interp = np.zeros(n_f, dtype=bool)
    idx = np.flatnonzero(fitted)
    if max_gap and len(idx) > 1:
        for a, b in zip(idx, idx[1:]):
            if 1 < b - a <= max_gap + 1:
                _interpolate(P, t, Lf, tree, a, b)
                interp[a + 1:b] = True
    smoothed = np.zeros(n_f, dtype=bool)
    spiked = np.zeros((n_f, len(tree.names)), dtype=bool)
    bridged = np.zeros(n_f, dtype=bool)
    apart = np.full(n_f, np.nan)
    smooth = smooth_window(fps) if smooth is None else smooth
    if smooth:
        from scipy.signal import savgol_filter

        win = int(smooth) | 1
        near = neighbourhood(P, t, tree, win // 2, fitted & ~interp)
        apart = near[1]
        if sm.bridge and max_gap and move is not None:
            P, bridged = bridge_outliers(P, t, tree, Lf, apart, max_gap, move, near[0],
                                         win // 2)
            if bridged.any():           # the runs go on through them (not judged again)
                interp |= bridged
                near = neighbourhood(P, t, tree, win // 2, fitted & ~interp)
        runs = motion_runs(P, t, tree, win, move, seen=~interp, near=near)
        for a, b in runs:
            D = np.stack([_directions(P[i], tree) for i in range(a, b)])
            R = P[a:b, tree.root]
            if sm.despike:
                D, spiked[a:b] = despike(D, win // 2, *sm.despike)
            D = savgol_filter(D, win, 2, axis=0)
            R = savgol_filter(R, win, 2, axis=0)
            for k, i in enumerate(range(a, b)):
                P[i] = forward(R[k], D[k], Lf[i], tree)
                smoothed[i] = True
    out = _annotated(poses, P, tree, t, rms, held, filled, interp, smoothed, spiked, bridged,
                     apart, move)
    return out, tree, L


def _fit_frames(poses, init, tree: KinematicTree, L, fit, gap):
    """Each matched frame's joints fitted from its initial placement (:func:`fit_frame`), the
    joints it does not see started from the last fitted frame, a rest pose, the arm evidence,
    the hand hint or the hull's shoulder (:mod:`.gap_filling`); returns ``(P, Lf, rms, t)``:
    joints (NaN: not fitted), each frame's bone lengths, the fits' curve distances and the
    frame numbers."""
    spine = fit.spine
    n_f = len(poses)
    Lf = np.tile(L, (n_f, 1))              # per frame: a sliding bone's length varies
    P = np.full_like(init, np.nan)
    rms = [None] * n_f
    prev, t_prev, t = None, None, frame_index(poses)
    seen_at = np.full(len(tree.names), -np.inf)   # the frame that last placed each joint
    limbs = tree.limbs
    if not np.isnan(L[[j for j in range(len(L)) if tree.parents[j] >= 0]]).any():
        for i, p in enumerate(poses):
            if not p.matched:
                continue
            start = init[i].copy()
            miss = np.isnan(start).any(axis=1)
            seen_at[~miss] = t[i]
            if miss.any() and _continues(prev, start, t[i] - t_prev if prev is not None else 0,
                                         gap):
                hold = miss.copy()
                if gap.hold_age is not None:      # only joints seen at most hold_age frames ago
                    hold &= t[i] - seen_at <= gap.hold_age
                start[hold] = prev[hold] - prev[tree.root] + np.nan_to_num(start[tree.root])
            if miss.any() and np.isnan(start).any():   # an unrelated pose before: the rest pose
                start = rest_fill(start, p, tree, L, limbs, gap.held_shoulder)
            if miss.any() and gap.evidence:
                from topopose.frame.unseen import evidence_fill
                start = evidence_fill(start, p, tree, L, miss, limbs)
            if miss.any() and gap.hints:
                start = hint_fill(start, p, tree, L, miss)
            if miss.any() and gap.shoulders:
                start = shoulder_fill(start, p, tree, miss)
            Lf[i] = frame_lengths(init[i], L, tree, fit=fit)
            Pi, r = fit_frame(init[i], frame_curves(p, tree, spine, fit), Lf[i], tree,
                              start=None if np.isnan(start).any() else start,
                              inner_weight=fit.inner_weight)
            if Pi is not None:
                P[i], rms[i], prev, t_prev = Pi, r, Pi, t[i]
    return P, Lf, rms, t


def _annotated(poses, P, tree: KinematicTree, t, rms, held, filled, interp, smoothed, spiked,
               bridged, apart, move) -> list:
    """The poses with their fitted ``joints`` and the fit's diagnostics (see
    :func:`fit_sequence`)."""
    out = []
    for i, p in enumerate(poses):
        if np.isnan(P[i]).any():              # no skeleton (joints of an earlier run dropped)
            out.append(type(p)(**{**p.__dict__, "joints": {}}) if p.joints else p)
            continue
        diag = dict(p.diagnostics)
        parts = p.parts
        if bridged[i]:                        # its parts too, from the same two frames
            parts, diag["interpolated_parts"] = bridged_parts(poses, t, bridged, i)
        if rms[i] is not None:
            diag["skeleton_rms"] = round(rms[i], 5)
        hj = [nm for j, nm in enumerate(tree.names) if held[i, j]]
        if hj and not interp[i]:
            diag["held_joints"] = hj
        if filled[i].any() and not interp[i]:
            diag["interpolated_joints"] = [nm for j, nm in enumerate(tree.names) if filled[i, j]]
        if interp[i]:
            diag["interpolated"] = True
        if smoothed[i]:
            diag["smoothed"] = True
        if spiked[i].any():
            diag["despiked_joints"] = [nm for j, nm in enumerate(tree.names) if spiked[i, j]]
        if np.isfinite(apart[i]):
            diag["neighbour_distance"] = round(float(apart[i]), 4)
            if move is not None and apart[i] >= move:
                diag["temporal_outlier"] = True
        q = type(p)(**{**p.__dict__, "diagnostics": diag, "parts": parts,
                       "joints": {nm: P[i, j].copy() for j, nm in enumerate(tree.names)}})
        out.append(q)
    return out
