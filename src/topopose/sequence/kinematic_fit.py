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
                                           SHOULDER_BLEND, _continues, _interpolate,
                                           _outward, hint_fill, rest_fill, shoulder_fill)
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


# SkeletonFitOptions.spine = 0.15: the trunk's joints moved back by this × the frame's spine shift.
# Its figures: docs/decisions.md.


# SkeletonFitOptions.centred = True: the limbs' curves moved onto the silhouettes' centre lines when the frame
                   # recorded them (``diagnostics["centred"]``, :mod:`.centre`)


# SkeletonFitOptions.raised_shoulder = 0.08: trunk lengths: a raised arm's shoulder (its hand past
# the chest junction along the trunk, as ``at_raised``) moved down the trunk by this; None or 0:
# off. Its figures: docs/decisions.md.


# SkeletonFitOptions.seen_hull_shoulder = True: a hanging seen arm's shoulder (its hand below the
# chest junction along the trunk) at the nearer of the frame's shoulders from the hull
# (``diagnostics["hull_shoulders"]``: the trunk's cross-section below the neck,
# :func:`topopose.frame.unseen.hull_shoulders`) when within HULL_GATE of its place on the curve. Its
# figures: docs/decisions.md.


# SkeletonFitOptions.bend = None: off by default (``bend=BEND_DEPTH`` switches it on). Its figures:
# docs/decisions.md.


# SkeletonFitOptions.from_end = {("foot", "knee"): 40}: (limb end part's stem, joint base name) →
# percentile: that middle joint placed by its distance from its curve's far end (the human's foot;
# not the spider's legs, unmeasured), the reference length the percentile of the sequence's
# leg-curve lengths (see from_end); {}: off (the fraction ``at`` from the junction). Its figures:
# docs/decisions.md.


# SkeletonFitOptions.from_end_weight = 0.5: the joint's arc length: this share of the one from the
# far end, the rest of the one at its fraction ``at`` (1: from the end alone). Its figures:
# docs/decisions.md.


# SkeletonFitOptions.from_start = {("hand", "elbow"), ("hand", "wrist")}: (limb end part's stem,
# joint base name): those joints of a hanging limb (its end part below its first along the trunk)
# also placed by the sequence's bone lengths from their parent (see from_start); set(): off. Its
# figures: docs/decisions.md.


# SkeletonFitOptions.width_radius = "sequence": the hull radius of the joints' ``width``: the
# sequence's median (a subject's girth is constant) or "frame" (each frame's own)
# SkeletonFitOptions.quantile = 70: percent; see bone_lengths. Its figures: docs/decisions.md.


# SkeletonFitOptions.limb_quantile = {"foot": 80}: percent, by the limb's end part (its stem): the
# constant length of the bones along a limb's arc (thigh, shank, foot; not the bone from the
# junction) instead of ``SkeletonFitOptions.quantile`` (only when no quantile is given). A leg's
# curve is cut short and cuts the bent knee's corner as an arm's does: at the 70th percentile the
# legs sat short. Its figures: docs/decisions.md.


# SkeletonFitOptions.slide = False: the model's ``slide`` bones take each frame's length (False:
# every bone constant). Its figures: docs/decisions.md.


# SkeletonFitOptions.slide_quantile = 50: percent: the constant length of a ``slide`` bone (the
# neck's, from the chest junction) when SLIDE is off; None: ``SkeletonFitOptions.quantile`` as the
# others. Its figures: docs/decisions.md.


# SkeletonFitOptions.shoulder_quantile = 50: percent: the constant length of a bone from the root
# (the curves' chest junction) to a joint beside the curve (a shoulder; ``offset``); None:
# ``SkeletonFitOptions.quantile``. As the neck's (``SkeletonFitOptions.slide_quantile``) its length
# only varies as the junction slides, and a hanging arm's shoulder is the hull's, not the curve's:
# no corner to make up for. Its figures: docs/decisions.md.


# GapOptions.hold_age = 8: frames: a joint is held from the last fitted frame only when a frame
# placed it at most this many frames before; older, it takes the rest pose and the fills (evidence,
# hints, hull shoulders) afresh. None: no limit. Its figures: docs/decisions.md.


# GapOptions.held_shoulder = np.radians(30.0): an unseen arm's shoulder: from the chest, opposite
# its mate across the trunk axis, raised by this angle from the plane across the trunk (None: the
# mate's position turned half about the trunk axis). Its figures: docs/decisions.md.


# GapOptions.evidence = True: an unseen arm's elbow turned towards the hull's remainder
# (topopose.frame.unseen.evidence_fill). Its figures: docs/decisions.md.


# GapOptions.shoulders = True: an unseen arm moved towards the shoulder from the hull's
# cross-section below the neck (``diagnostics["hull_shoulders"]``, :func:`topopose.pose.
# unseen.hull_shoulders`; :func:`shoulder_fill`), after the evidence and the hints. Its figures:
# docs/decisions.md.


# SkeletonFitOptions.tip_turn = {"toe": 15.0}: degrees, by tip joint: its target turned away from
# the bone above its parent (the toe from the shank, knee → ankle), in the plane of the two
# (:func:`tip_targets`). Its figures: docs/decisions.md.


# SkeletonFitOptions.girdle = True: the joints a model declares as one girdle (``girdle = [pair,
# height]`` on a joint: the neck with the shoulders) placed as one symmetric rigid body
# (:func:`girdle_targets`); False: each joint alone. Its figures: docs/decisions.md.


# SmoothingOptions.move = 0.15: m: a frame whose joints (from the root) lie this far from its
# neighbourhood's median is an outlier, and a run breaks where successive neighbourhoods lie this
# far apart (mean over the joints; :func:`motion_runs`). Its figures: docs/decisions.md.


# SmoothingOptions.despike = (3.0, 15.0): (k, floor in degrees) of :func:`despike`, the bones'
# spikes replaced before the smoothing; None: off. A frame whose matched curves put one limb on a
# wrong branch (the real recording's frames 36 and 42: the left arm's curve on another branch, its
# hand 0.6 m off) keeps the rest of its skeleton near its neighbours', so it stays in its run, and
# the Savitzky–Golay window averaged the wrong arm into the 20 frames around it (left elbow 7 cm off
# where the fits either side had it within 3 cm). Its figures: docs/decisions.md.


# SmoothingOptions.bridge = True: a temporal outlier between two frames of the same motion is
# replaced by their interpolation (:func:`bridge_outliers`); False: it keeps its own fit, flagged
# only. Its figures: docs/decisions.md.


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
        seen arms' hull shoulders off too), ... (:mod:`.options`)

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
        frames either side, :func:`bridged_parts`), ``["held_joints"]`` (not seen by the frame)
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
    out = _annotated(poses, P, tree, t, rms, held, interp, smoothed, spiked, bridged, apart,
                     move)
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


def _annotated(poses, P, tree: KinematicTree, t, rms, held, interp, smoothed, spiked, bridged,
               apart, move) -> list:
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
