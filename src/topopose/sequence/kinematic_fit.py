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
   at most ``HOLD_FRAMES`` (5) before and the same motion (``_continues``) and a frame placed
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

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from topopose.errors import InputError
from topopose.frame.curves import arc_lengths, model_arcs
from topopose.pose.model import part_stem
from topopose.sequence.options import DEFAULT, SequenceOptions, SkeletonFitOptions
from topopose.sequence.track import frame_index

FIT, GAPS, SMOOTHING = DEFAULT.skeleton_fit, DEFAULT.gaps, DEFAULT.smoothing


@dataclass
class KinematicTree:
    """Joint instances of a model: ``names[i]`` (``elbow_1``), ``base[i]`` (``elbow``),
    ``parents[i]`` (index, -1 for the root), ``arc[i]`` = (parent part, child part) of the model
    arc it lies on, ``at[i]`` its relative position along it."""

    names: list
    base: list
    parents: list
    arc: list
    at: list
    offset: list = None            # (along the trunk, outward) per joint, in trunk lengths
    trunk: tuple = ()              # (from part, to part)
    beyond: list = None            # tip joints: past the end part, × the curve length
    limbs: frozenset = frozenset()  # the model's limb parts (``[[mirror]]`` parts)
    width: list = None             # (along the trunk, outward) × hull radius, from the junction
    at_raised: list = None         # at when the arc's end part is past its start along the trunk
    slide: list = None             # the bone from its parent takes the frame's length (slide)
    girdle: list = None            # (pair's joint name, height) or None: one rigid body with it

    @property
    def root(self) -> int:
        return self.parents.index(-1)

    def order(self) -> list:
        """Joint indices, parents before children."""
        out, todo = [], [self.root]
        while todo:
            j = todo.pop(0)
            out.append(j)
            todo.extend(c for c, p in enumerate(self.parents) if p == j)
        return out

    def chains(self) -> dict:
        """Model arc (u, v) → joint indices along it in order, with the joint at its start."""
        out = {}
        for j, (u, v) in enumerate(self.arc):
            out.setdefault((u, v), []).append(j)
        for key, js in out.items():
            js.sort(key=lambda j: self.at[j])
            first = js[0]
            p = self.parents[first]
            if p >= 0 and self.at[first] > 0:
                js.insert(0, p)
        return out


def kinematic_tree(model) -> KinematicTree:
    """Expand the model's ``[[joint]]`` declarations over its arcs into one kinematic tree."""
    if not model.joints:
        raise InputError(f"model {model.name!r}: no [[joint]] declared; the full skeleton needs "
                         "joints along the arcs (see topopose.pose.model)")
    names, base, arc, at, offset, beyond, width, raised, slide, girdle = ([] for _ in range(10))
    arcs = model_arcs(model)
    for u, v in arcs:
        for js in model.joints:
            a, b = js.arc
            r = None if js.at_raised is None else float(js.at_raised)
            if a in (u, part_stem(u)) and b in (v, part_stem(v)):
                t = float(js.at)
            elif b in (u, part_stem(u)) and a in (v, part_stem(v)):
                t = 1.0 - float(js.at)
                r = None if r is None else 1.0 - r
            else:
                continue
            suffix = ""
            for decl, part in ((a, u), (b, v), (a, v), (b, u)):
                if decl not in (u, v) and decl == part_stem(part) and part != decl:
                    suffix = "_" + str(part).rpartition("_")[2]
                    break
            names.append(js.name + suffix)
            offset.append(tuple(float(x) for x in js.offset))
            width.append(tuple(float(x) for x in js.width))
            raised.append(r)
            slide.append(bool(js.slide))
            girdle.append(None if js.girdle is None else (str(js.girdle[0]),
                                                          float(js.girdle[1])))
            beyond.append(float(js.beyond) if t == 1.0 else 0.0)
            base.append(js.name)
            arc.append((u, v))
            at.append(t)
    if len(set(names)) != len(names):
        raise InputError(f"model {model.name!r}: two joints share a name ({names})")
    for g in {g for g in girdle if g is not None}:
        if base.count(g[0]) != 2:
            raise InputError(f"model {model.name!r}: field 'girdle' names joint {g[0]!r}, which "
                             f"the arcs make {base.count(g[0])} joints, not a mirror pair of 2")
    anchor = {}
    for j, ((u, v), t) in enumerate(zip(arc, at)):
        if t == 0.0:
            anchor.setdefault(u, j)
        elif t == 1.0:
            anchor.setdefault(v, j)
    parents = [None] * len(names)
    for u, v in arcs:
        js = sorted((j for j in range(len(names)) if arc[j] == (u, v)), key=lambda j: at[j])
        prev = anchor.get(u)
        for j in js:
            if j == prev:
                continue
            if at[j] == 0.0 and anchor.get(u) not in (None, j):
                prev = anchor[u]
                continue
            parents[j] = -1 if prev is None else prev
            prev = j
    for part, j in anchor.items():
        if parents[j] is None:            # an anchor at the start of its arc: link it upwards
            into = [a for a in arcs if a[1] == part]
            up = None
            if into:
                cands = [k for k in range(len(names)) if arc[k] == into[0]]
                if cands:
                    up = max(cands, key=lambda k: at[k])
            parents[j] = -1 if up is None else up
    parents = [-1 if p is None else p for p in parents]
    if sum(p == -1 for p in parents) != 1:
        roots = [names[j] for j, p in enumerate(parents) if p == -1]
        raise InputError(f"model {model.name!r}: the joints form {len(roots)} trees (roots "
                         f"{roots}); put a joint at at = 0 or 1 where arcs meet")
    return KinematicTree(names, base, parents, arc, at, offset,
                         tuple(model.facing.get("trunk", ())), beyond,
                         frozenset(x for parts, _names in model.mirrors for x in parts), width,
                         raised, slide, girdle)


TIP_DIRECTION = 0.1      # the tip direction: along the curve's last 10 % (see _along)


def _along(curve, t, beyond=0.0):
    """The point at relative arc length ``t`` of a curve; with ``beyond`` (t = 1), past its end
    by ``beyond`` × its length along its last direction (the chord of its last
    ``TIP_DIRECTION``): thinning stops a skeleton branch short of the limb's tip."""
    c = np.asarray(curve, dtype=float)
    s = arc_lengths(c)
    if s[-1] <= 0:
        return c[0]
    x = t * s[-1]
    out = np.array([np.interp(x, s, c[:, k]) for k in range(3)])
    if beyond:
        d = _end_direction(c, s)
        if d is not None:
            out = out + beyond * s[-1] * d
    return out


def _end_direction(c, s):
    """The unit direction of curve ``c`` (cumulative lengths ``s``) at its end: the chord of
    its last :data:`TIP_DIRECTION` of length; None when that is a point."""
    back = np.array([np.interp((1 - TIP_DIRECTION) * s[-1], s, c[:, k]) for k in range(3)])
    d = c[-1] - back
    n = float(np.linalg.norm(d))
    return d / n if n > 0 else None


# SkeletonFitOptions.spine = 0.15: the trunk's joints moved back by this × the frame's spine shift (see
                    # :func:`frame_curves`; development seeds 41–43 walks, 21–24 random, MPJPE
                    # median with the shoulders and hips moved too: 0 → 0.15 → 0.25 → 0.35:
                    # walks 5.47 → 5.31 → 5.31 → 5.41, random 7.34 → 7.12 → 7.22 → 7.13 cm)


# SkeletonFitOptions.centred = True: the limbs' curves moved onto the silhouettes' centre lines when the frame
                   # recorded them (``diagnostics["centred"]``, :mod:`.centre`)


def centred_curves(curves, offsets, limbs) -> dict:
    """``curves`` with the limbs' (``limbs``) samples moved by their recorded ``offsets``
    (:func:`topopose.frame.centre.centre_offsets`); a curve whose offsets do not match its
    samples (replaced since) is kept as it is."""
    out = dict(curves)
    for v, o in offsets.items():
        c = out.get(v)
        if v in limbs and c is not None:
            o = np.asarray(o, float)
            c = np.asarray(c, float)
            if o.shape == c.shape:
                out[v] = c + o
    return out


def frame_curves(pose, tree: KinematicTree, spine=None, fit: SkeletonFitOptions = FIT) -> dict:
    """The frame's skeleton curves, those of the trunk's arcs (arcs not ending at a limb, a
    ``[[mirror]]`` part: head, crotch) moved back by ``spine`` × ``diagnostics["spine_shift"]``
    (:mod:`topopose.frame.anatomy`: the hull's largest inscribed radius against the front the
    feet tell; absent when the feet tell none: no move). The skeleton curve runs through the
    hull's middle, the rig's spine, neck, pelvis, shoulder and hip joints lie behind it: after
    the fit they sat 2–4 cm in front of the truth (development seeds, medians: neck 2.5–3.7,
    pelvis 2.7–4.4, hips 3.5–3.7 cm). The joints with an ``offset`` (shoulders, hips) move
    back by the same amount (:func:`initial_placement`). With ``SkeletonFitOptions.centred``, the limbs'
    curves first moved onto the silhouettes' centre lines the frame recorded
    (``diagnostics["centred"]``, :func:`centred_curves`)."""
    curves = pose.diagnostics.get("curves") or {}
    if fit.centred and pose.diagnostics.get("centred"):
        curves = centred_curves(curves, pose.diagnostics["centred"], tree.limbs)
    spine = fit.spine if spine is None else spine
    s = pose.diagnostics.get("spine_shift")
    if not spine or s is None or not tree.limbs:
        return curves
    s = spine * np.asarray(s, float)
    return {v: np.asarray(c, float) + s if v not in tree.limbs else c for v, c in curves.items()}


def _beside(tree, j) -> bool:
    """Whether joint ``j`` lies beside its curve (an ``offset`` or a ``width``)."""
    return any(tree.offset[j]) or bool(tree.width and any(tree.width[j]))


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
HANG_COS = 0.9     # a limb hangs when its curve (junction → end) lies within arccos(0.9) = 26°
                   # of straight down the trunk (see HANGING_WIDTH)
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
HULL_GATE = 0.2    # m: a shoulder from the hull farther than this from the joint's place: unused


def _hangs(c, ax) -> bool:
    """Whether the curve ``c`` (junction → limb end) runs within :data:`HANG_COS` of straight
    down the unit trunk axis ``ax`` (which points up)."""
    c = np.asarray(c, float)
    v = c[-1] - c[0]
    n = float(np.linalg.norm(v))
    return n > 0 and float(np.dot(v, -ax)) > HANG_COS * n


def initial_placement(pose, tree: KinematicTree, spine=None, radius=None,
                      hull=None, fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """(n_joints, 3) joints at their relative arc length on the frame's curves (NaN: no curve);
    the trunk's curves and the offset joints moved back by ``spine`` (default
    ``SkeletonFitOptions.spine``) × the frame's spine shift (:func:`frame_curves`). A joint with a
    ``width`` (hips), when the hull radius is known (``radius``, else the length of the frame's
    spine shift) and its mirror mate placed: at its arc's start (the junction) moved along the
    trunk and outward (the direction from its mate's curve point to its own, across the trunk)
    by ``width`` (``SkeletonFitOptions.hanging_width`` when its limb hangs) × the radius — the hull's largest inscribed radius scales with girth, the
    trunk's length does not (development seeds: half shoulder width / radius 1.16–1.46 over
    four builds, / trunk length 0.39–0.76); otherwise as its ``offset`` says. A joint with an
    ``at_raised`` (elbows, wrists) is there instead of ``at`` when its arc's end part lies past
    its first part along the trunk (a hand above the chest junction: the arm's curve runs
    up through the shoulder's mass before the arm leaves it); such a raised arm's joint with
    an offset (its shoulder) moves down the trunk by ``SkeletonFitOptions.raised_shoulder`` trunk lengths.
    A hanging arm's shoulder (hand below the chest junction) is the nearer of the frame's
    ``diagnostics["hull_shoulders"]`` when within :data:`HULL_GATE` (``hull``, default
    ``SkeletonFitOptions.seen_hull_shoulder``)."""
    curves = frame_curves(pose, tree, spine)
    out = np.full((len(tree.names), 3), np.nan)
    used = np.full(len(tree.names), np.nan)      # the relative arc length each joint took
    for j, ((u, v), t) in enumerate(zip(tree.arc, tree.at)):
        c = curves.get(v)
        if tree.at_raised and tree.at_raised[j] is not None and _raised(pose, tree, j):
            t = tree.at_raised[j]              # a raised limb (see the model's at_raised)
        beyond = tree.beyond[j] if tree.beyond else 0.0
        used[j] = t
        if c is not None:
            out[j] = _along(c, t, beyond)
        elif t == 0.0 or (t == 1.0 and not beyond):   # a joint at a part: the part (no curve
            x = pose.parts.get(u if t == 0.0 else v)  # when the arc's far part is missing)
            if x is not None:
                out[j] = np.asarray(x, dtype=float)
    out = bend_joints(out, used, curves, tree, fit.bend)     # a bent limb's middle joints at the bend
    if tree.trunk and any(_beside(tree, j) for j in range(len(tree.names))):
        a, b = (pose.parts.get(x) for x in tree.trunk)
        if a is None or b is None:
            return out
        ax = np.asarray(b, float) - np.asarray(a, float)
        S = float(np.linalg.norm(ax))
        if S <= 0:
            return out
        ax /= S
        moved = out.copy()
        s = pose.diagnostics.get("spine_shift")
        radius = radius if radius is not None else (
            float(np.linalg.norm(s)) if s is not None else None)
        for j, (along, outward) in enumerate(tree.offset):
            if not _beside(tree, j) or np.isnan(out[j]).any():
                continue
            mates = [k for k in range(len(tree.names)) if k != j and tree.base[k] == tree.base[j]]
            c = curves.get(tree.arc[j][1])
            if (radius and tree.width and any(tree.width[j]) and len(mates) == 1
                    and c is not None and not np.isnan(out[mates[0]]).any()):
                lat = out[j] - out[mates[0]]
                lat -= np.dot(lat, ax) * ax
                n = np.linalg.norm(lat)
                if n > 0:
                    w_al, w_out = tree.width[j]
                    if fit.hanging_width is not None and _hangs(c, ax):
                        w_al, w_out = fit.hanging_width
                    moved[j] = (np.asarray(c, float)[0] + w_al * radius * ax
                                + w_out * radius * lat / n)
                    continue
            moved[j] = out[j] + along * S * ax
            if fit.raised_shoulder and tree.arc[j][1] in tree.limbs and \
                    tree.arc[j][0] == tree.trunk[1] and _raised(pose, tree, j):
                moved[j] -= fit.raised_shoulder * S * ax              # a raised arm's shoulder
            if outward and len(mates) == 1 and not np.isnan(out[mates[0]]).any():
                lat = out[j] - out[mates[0]]
                lat -= np.dot(lat, ax) * ax
                n = np.linalg.norm(lat)
                if n > 0:
                    moved[j] += outward * S * lat / n
        spine = fit.spine if spine is None else spine
        if spine and pose.diagnostics.get("spine_shift") is not None and tree.limbs:
            moved[[_beside(tree, j) for j in range(len(tree.names))]] += spine * np.asarray(
                pose.diagnostics["spine_shift"], float)
        H = pose.diagnostics.get("hull_shoulders")
        if (fit.seen_hull_shoulder if hull is None else hull) and H is not None:
            H = np.asarray(H, float).reshape(-1, 3)
            for j in range(len(tree.names)):          # a hanging arm's shoulder from the hull
                u, v = tree.arc[j]
                if not _beside(tree, j) or np.isnan(moved[j]).any() or v not in tree.limbs \
                        or u != tree.trunk[1] or pose.parts.get(v) is None or \
                        _raised(pose, tree, j):
                    continue
                h = H[int(np.argmin(np.linalg.norm(H - moved[j], axis=1)))]
                if np.linalg.norm(h - moved[j]) <= HULL_GATE:
                    moved[j] = h
        out = moved
    return out


BEND_DEPTH = 0.2   # a limb's middle joint (elbow, wrist, knee, ankle) at its curve's bend when the
             # bend's depth (the curve's farthest point from the chord between the joints either
             # side) exceeds this × the chord: 0.2 ≈ a joint angle of 136° (two equal bones).
             # None / 0: off (the joint at its ``at``). A bent limb's curve cuts the corner and
             # the fixed relative arc length put the bent elbow 9.0 cm off (initial placement;
             # 4.4 cm inside and 3.1 cm forward of the true one, median; development seeds 21–32
             # random, 223 bent arms). Development seeds (``tracking.py --dev``'s sequences:
             # random 21–32, walks 41–46; the fit on their gate-on per-frame poses, MPJPE median
             # over frames) off → 0.1 / 0.15 / 0.2 / 0.25: random 5.68 → 6.75 / 6.03 / 5.49 /
             # 5.49, walks 4.41 → 5.89 / 4.72 / 4.37 / 4.43 cm (below 0.2 a barely bent curve's
             # farthest point wanders along it and drags the bone lengths and knees off); with
             # the bone lengths from the placement without it 5.50 / 4.36 (not kept: the same);
             # the joint pushed out of the corner by 1.5 / 3 cm: 5.52 / 5.61
# SkeletonFitOptions.bend = None: off by default (``bend=BEND_DEPTH`` switches it on). Held out with 8 cameras it
             # adds nothing to the median (random poses 5.3 cm either way; elbows 5.5 → 5.2, ankles
             # 3.4 → 3.1 cm), and on the real 4-camera recording (benchmarks/real_motion.py) it
             # hurts: all frames 8.4 → 8.9 cm, the right frames 7.7 either way — a noisy 4-camera
             # hull's wrong curves bend where no limb does


def bend_joints(out, used, curves, tree: KinematicTree, bend=None) -> np.ndarray:
    """``out`` with each middle joint of a bent limb at its curve's bend (thesis §13.3.1: the
    kinematic model initialized from the skeleton curves).

    A middle joint is one on an arc ending at a limb part (``tree.limbs``) with its parent and
    its one child on the same arc (elbow between shoulder and wrist, wrist between elbow and
    fingertip, knee between hip and ankle, ankle between knee and toe). Between the curve points of its parent and child (their relative arc lengths in
    ``used``), the curve's point farthest from the chord joining those two points is the bend;
    when it lies farther than ``bend`` (default ``SkeletonFitOptions.bend``) × the chord's length from the
    chord, the joint is placed there — a bent limb's curve turns at the joint, and the fixed
    relative arc length ``at`` falls short of or past the turn.

    Parameters
    ----------
    out : (n, 3) the joints at their relative arc lengths (NaN: none)
    used : (n,) the relative arc length each joint took (NaN: none)
    curves : part → (k, 3) curve of the arc ending at the part
    tree : KinematicTree
    bend : the least depth of the bend over the chord (None: ``SkeletonFitOptions.bend``, off by default;
        :data:`BEND_DEPTH` when on)

    Returns
    -------
    (n, 3) array, a copy of ``out``.
    """
    out = out.copy()
    if not bend:
        return out
    for j, p in enumerate(tree.parents):
        u, v = tree.arc[j]
        kids = [k for k, q in enumerate(tree.parents) if q == j and tree.arc[k] == (u, v)]
        c = curves.get(v)
        if v not in tree.limbs or p < 0 or tree.arc[p] != (u, v) or len(kids) != 1 \
                or c is None or np.isnan(used[[j, p, kids[0]]]).any():
            continue
        c = np.asarray(c, float)
        s = arc_lengths(c)
        inside = (s > used[p] * s[-1]) & (s < used[kids[0]] * s[-1])
        A, B = _along(c, used[p]), _along(c, used[kids[0]])
        n = float(np.linalg.norm(B - A))
        if not inside.any() or n <= 0:
            continue
        X = c[inside] - A
        t = (B - A) / n
        dist = np.linalg.norm(X - np.outer(X @ t, t), axis=1)
        i = int(np.argmax(dist))
        if dist[i] > bend * n:
            out[j] = c[inside][i]
    return out


# SkeletonFitOptions.from_end = {("foot", "knee"): 40}: (limb end part's stem, joint base name) → percentile: that
    # middle joint placed by its distance from its curve's far end (the human's foot; not the
    # spider's legs, unmeasured), the reference length the percentile of the sequence's
    # leg-curve lengths (see from_end); {}: off (the fraction ``at`` from the junction). Issue 15,
    # development seeds (walks 41–44, random motion 51–53, 40 frames, the centred curves;
    # benchmarks/knee_dev.py, MPJPE median over the good frames, 4p / 4pd / 8 cameras): off
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


def _arc_position(c, s, x) -> float:
    """The arc length (``s``: the curve's cumulative lengths) of the point of curve ``c``
    nearest ``x``, on its segments."""
    A, D = c[:-1], np.diff(c, axis=0)
    dd = np.maximum((D * D).sum(axis=1), 1e-12)
    u = np.clip(((x - A) * D).sum(axis=1) / dd, 0.0, 1.0)
    k = int(np.argmin(np.linalg.norm(A + u[:, None] * D - x, axis=1)))
    return float(s[k] + u[k] * np.sqrt(dd[k]))


def _limb_joints(tree: KinematicTree, keys) -> list:
    """The joints inside a limb's arc (``0 < at < 1``, on its curve, not beside it) whose
    (limb end part's stem, base name) is in ``keys``, in tree order (parents first)."""
    return [j for j, b in enumerate(tree.base) if (part_stem(tree.arc[j][1]), b) in keys
            and tree.arc[j][1] in tree.limbs and not _beside(tree, j) and 0.0 < tree.at[j] < 1.0]


def from_end(init, poses, tree: KinematicTree, spine=None, ends=None,
             weight=None, fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """``init`` with each ``ends`` joint ((its limb end part's stem, its base name) →
    percentile, default ``SkeletonFitOptions.from_end``) placed by its distance from its curve's far end, not
    only at its fraction from the start.

    A limb's curve starts at the hull's junction, which wanders (a 4-camera hull's phantom
    volume between the legs moves the legs' junction: development seeds, the leg curves'
    median length 110 cm with 4 cameras, 101 cm with 8, the knee's distance from the foot end
    50 / 49 cm); its far end (the thinned foot or hand) wanders less. The joint's fraction
    ``t`` of its curve (the curve point nearest its initial place) is read against the
    sequence's reference length ``L`` of that limb's curves (their ``percentile`` % over the
    frames, mirror limbs pooled: a curve cut short lies below it): from the end, the joint's arc length is
    ``s_end − (1 − t) L`` (at least 0) — where it would be on a curve of the full length ending
    at the same place; it goes to ``weight`` × that + (1 − ``weight``) × ``t s_end`` (its place
    from the start: the far end wanders too, the two errors partly cancel). Thesis §13.3.1
    (the kinematic model initialized from the skeleton curves).

    Parameters
    ----------
    init : (n_frames, n_joints, 3) the joints' initial placement (NaN: none)
    poses : the frames' poses (their curves)
    tree : KinematicTree
    spine : as :func:`frame_curves`
    ends : (limb end part's stem, joint base name) → percentile (None: ``SkeletonFitOptions.from_end``)
    weight : the share of the place from the far end (None: ``SkeletonFitOptions.from_end_weight``)

    Returns
    -------
    (n_frames, n_joints, 3) array, a copy of ``init``.
    """
    ends = fit.from_end if ends is None else ends
    w = fit.from_end_weight if weight is None else weight
    init = np.array(init, dtype=float, copy=True)
    key = [(part_stem(tree.arc[j][1]), b) for j, b in enumerate(tree.base)]
    js = _limb_joints(tree, ends)
    if not js:
        return init
    curves = [frame_curves(p, tree, spine) if p.matched else {} for p in poses]
    lengths = {}
    for cs in curves:
        for v, c in cs.items():
            if v in tree.limbs:
                c = np.asarray(c, float)
                lengths.setdefault(part_stem(v), []).append(
                    float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum()))
    for i, cs in enumerate(curves):
        for j in js:
            v = tree.arc[j][1]
            c = cs.get(v)
            if c is None or np.isnan(init[i, j]).any() or part_stem(v) not in lengths:
                continue
            c = np.asarray(c, float)
            s = arc_lengths(c)
            if s[-1] <= 0:
                continue
            L = float(np.percentile(lengths[part_stem(v)], ends[key[j]]))
            t = _arc_position(c, s, init[i, j]) / s[-1]
            x = max(0.0, s[-1] - (1.0 - t) * L)
            x = w * x + (1.0 - w) * t * s[-1]
            init[i, j] = _along(c, x / s[-1])
    return init


# SkeletonFitOptions.from_start = {("hand", "elbow"), ("hand", "wrist")}: (limb end part's stem, joint base
    # name): those joints of a hanging limb (its end part below its first along the trunk)
    # also placed by the sequence's bone lengths from their parent (see from_start); set():
    # off. Issue 15, session 35: on the real recording the hanging left arm's curve ends 2–11
    # cm past the wrist from frame to frame (the masks lose part of the hand) and its start,
    # the chest junction, slides, so the fraction ``at`` put the elbow 10.4 cm and the wrist
    # 9.4 cm off (median over the right frames; the fits either side of a short frame within
    # 3 cm). Development seeds, with DESPIKE (benchmarks/knee_dev.py, good frames, 8 / 4p /
    # 4pd): 3.50 / 8.90 / 8.34 → 3.40 / 8.72 / 8.21 cm (elbows 4.0 / 9.3 / 11.5 → 3.5 / 8.4 /
    # 10.1); benchmarks/fps_dev.py (8 cameras 25 / 60 frames/s, 4p 25 / 60): 4.25 / 3.70 /
    # 9.75 / 9.27 → 4.16 / 3.64 / 9.55 / 9.28 cm. Not kept (docs/tried.md): weight 1 (4pd
    # 8.49: the fat hulls' bone lengths are 1.2–1.3 × the truth's), raised arms too, the
    # fingertips too, the knees and ankles (by arc length: the real recording 6.6 → 7.6 cm)
# SkeletonFitOptions.from_start_weight = 0.5: the joint goes this share of the way from its place at ``at`` to its
    # place by the bone length (as FROM_END_WEIGHT; 0.7: 8 / 4p / 4pd 3.44 / 8.63 / 8.39 cm)
REACH_PAST = 0.1   # m: a joint placed by its bone's length at most this far past its curve's
    # end (a hand lost in the masks shortens the arm's curve by a few cm; a curve much shorter
    # is no lost hand): beyond, its place at ``at`` is kept


def _raised(pose, tree: KinematicTree, j) -> bool:
    """Whether joint ``j``'s arc ends past its first part along the trunk (a hand above the
    chest junction: a raised arm, as ``at_raised``)."""
    if not tree.trunk:
        return False
    a, b = (pose.parts.get(x) for x in tree.trunk)
    pu, pv = (pose.parts.get(x) for x in tree.arc[j])
    if a is None or b is None or pu is None or pv is None:
        return False
    return float(np.dot(np.asarray(pv, float) - np.asarray(pu, float),
                        np.asarray(b, float) - np.asarray(a, float))) > 0


def _reach(c, s, x0, origin, length):
    """The first point of curve ``c`` (cumulative lengths ``s``) past arc length ``x0`` at
    distance ``length`` from ``origin``; past the curve's end along its last direction
    (:data:`TIP_DIRECTION`, as :func:`_along`) when the curve ends nearer, by at most
    :data:`REACH_PAST`. None when it cannot reach."""
    d = np.linalg.norm(c - origin, axis=1)
    k0 = int(np.searchsorted(s, x0, side="right"))
    for k in range(max(k0, 1), len(c)):
        if d[k] >= length > d[k - 1]:
            a, b = c[k - 1], c[k]
            # |a + u (b - a) - origin| = length on the segment, u in [0, 1]
            ab, ao = b - a, a - origin
            A, B, C = ab @ ab, 2 * ab @ ao, ao @ ao - length ** 2
            u = (-B + np.sqrt(max(B * B - 4 * A * C, 0.0))) / (2 * A) if A > 0 else 0.0
            return a + np.clip(u, 0.0, 1.0) * ab
    e = _end_direction(c, s)
    if e is None:
        return None
    ao = c[-1] - origin
    B, C = 2 * e @ ao, ao @ ao - length ** 2
    disc = B * B - 4 * C
    if disc < 0:
        return None
    u = (-B + np.sqrt(disc)) / 2
    return c[-1] + u * e if 0 <= u <= REACH_PAST else None


def from_start(init, poses, tree: KinematicTree, L, joints=None, weight=None,
               spine=None, fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """``init`` with each ``joints`` joint of a hanging limb (its end part below its first part
    along the trunk, :func:`_raised`) moved towards the point of its curve at its bone's
    length ``L`` from its parent (the parent placed first; the first such point past the
    parent's own place on the curve, :func:`_reach`).

    The fraction ``at`` reads a joint's place against the frame's curve, whose two ends wander
    (the chest junction slides; a hand lost in the masks cuts the arm's curve short); the
    bones' lengths are the sequence's (:func:`bone_lengths`). The joint goes ``weight``
    (default ``SkeletonFitOptions.from_start_weight``) of the way; a curve that ends short is continued along
    its last direction by at most :data:`REACH_PAST`. Thesis §13.3.1 (the kinematic model
    initialized from the skeleton curves).

    Parameters
    ----------
    init : (n_frames, n_joints, 3) the joints' initial placement (NaN: none)
    poses : the frames' poses (their curves and parts)
    tree : KinematicTree
    L : (n_joints,) the sequence's bone lengths
    joints : (limb end part's stem, joint base name) pairs (None: ``SkeletonFitOptions.from_start``)
    weight : the share of the way to the place by the bone length
    spine : as :func:`frame_curves`

    Returns
    -------
    (n_frames, n_joints, 3) array, a copy of ``init``.
    """
    joints = fit.from_start if joints is None else joints
    w = fit.from_start_weight if weight is None else weight
    init = np.array(init, dtype=float, copy=True)
    js = _limb_joints(tree, joints)
    if not js:
        return init
    for i, p in enumerate(poses):
        if not p.matched:
            continue
        cs = frame_curves(p, tree, spine)
        for j in js:                                   # in tree order: parents first
            c = cs.get(tree.arc[j][1])
            a = tree.parents[j]
            if c is None or np.isnan(init[i, j]).any() or a < 0 or np.isnan(init[i, a]).any() \
                    or np.isnan(L[j]) or _raised(p, tree, j):
                continue
            c = np.asarray(c, float)
            s = arc_lengths(c)
            if s[-1] <= 0:
                continue
            x = _reach(c, s, _arc_position(c, s, init[i, a]), init[i, a], L[j])
            if x is not None:
                init[i, j] = w * x + (1.0 - w) * init[i, j]
    return init


# SkeletonFitOptions.width_radius = "sequence": the hull radius of the joints' ``width``: the sequence's median
                            # (a subject's girth is constant) or "frame" (each frame's own)
# SkeletonFitOptions.quantile = 70: percent; see bone_lengths (development seeds as SPINE_BACK, with it
                     # 50 → 70 walks 5.31 → 5.12, random 7.12 → 7.00 cm)


def bone_lengths(init: np.ndarray, tree: KinematicTree, quantile=None,
                 fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """Length of each bone (child joint index): the ``quantile`` (default
    ``SkeletonFitOptions.quantile``) % of its lengths over the frames, mirror bones pooled. The joints
    at fixed relative arc lengths shorten a bone when its curve is cut short (the junction of
    a raised arm, a bent limb's curve cutting the corner): the median upper arm was 10 % short
    on walks, 20–25 % on random poses (development seeds). A ``slide`` bone (the neck's) takes
    ``SkeletonFitOptions.slide_quantile``, a bone from the root to a joint beside the curve (a shoulder's)
    ``SkeletonFitOptions.shoulder_quantile``: neither has a corner to make up for; the bones along a limb
    named in ``SkeletonFitOptions.limb_quantile`` (the legs') take its percentile."""
    limb = fit.limb_quantile if quantile is None else {}     # a quantile given: every bone's
    quantile = fit.quantile if quantile is None else quantile
    L = np.full(len(tree.names), np.nan)
    pooled = {}
    for j, p in enumerate(tree.parents):
        if p < 0:
            continue
        d = np.linalg.norm(init[:, j] - init[:, p], axis=1)
        pooled.setdefault((tree.base[j], tree.base[p]), []).extend(d[~np.isnan(d)])
    for j, p in enumerate(tree.parents):
        if p >= 0:
            v = pooled[(tree.base[j], tree.base[p])]
            q = (fit.slide_quantile if tree.slide and tree.slide[j] and fit.slide_quantile
                 else quantile)
            if fit.shoulder_quantile and p == tree.root and _beside(tree, j):
                q = fit.shoulder_quantile            # from the junction to a joint beside it
            if tree.arc[p] == tree.arc[j] and part_stem(tree.arc[j][1]) in limb:
                q = limb[part_stem(tree.arc[j][1])]   # along a limb ending at that part
            L[j] = float(np.percentile(v, q)) if v else np.nan
    return L


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


def frame_lengths(target, L, tree: KinematicTree, slide=None,
                  fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """The frame's bone lengths: ``L``, except the bones of the joints declared ``slide``
    (when ``slide``, default ``SkeletonFitOptions.slide``): the distance of the joint's initial placement
    ``target`` from its parent's, when both are placed."""
    slide = fit.slide if slide is None else slide
    out = L.copy()
    if not slide or not tree.slide:
        return out
    for j, p in enumerate(tree.parents):
        if tree.slide[j] and p >= 0 and not np.isnan(target[[j, p]]).any():
            out[j] = float(np.linalg.norm(target[j] - target[p]))
    return out


def forward(root, dirs, L, tree: KinematicTree, order=None) -> np.ndarray:
    """Joint positions from the root position and one direction per bone (normalized here)."""
    order = tree.order() if order is None else order
    P = np.zeros((len(tree.names), 3))
    P[tree.root] = root
    for j in order[1:]:
        d = dirs[j]
        P[j] = P[tree.parents[j]] + L[j] * d / max(np.linalg.norm(d), 1e-12)
    return P


def _seg_dist(q, A, B):
    """Distance of points q (m, 3) to the nearest of segments A→B (k, 3)."""
    return _seg_nearest(q, A, B)[0]


def _seg_nearest(q, A, B):
    """Distance of points q (m, 3) to the nearest of segments A→B (k, 3), that segment's
    index and the parameter (0 at A, 1 at B) of the nearest point on it."""
    ab = B - A
    t = np.einsum("mkc,kc->mk", q[:, None, :] - A[None], ab) / np.maximum(
        np.einsum("kc,kc->k", ab, ab), 1e-12)
    t = np.clip(t, 0.0, 1.0)
    proj = A[None] + t[..., None] * ab[None]
    d = np.linalg.norm(q[:, None, :] - proj, axis=2)
    s = d.argmin(axis=1)
    rows = np.arange(len(q))
    return d[rows, s], s, t[rows, s]


def chain_joints(x, p0, L):
    """The joints ``Q_b = p0 + sum_{j <= b} L_j u_j`` of one arc chain for the bone directions
    ``x`` (flattened (m, 3)), with the unit directions ``u`` and their norms ``|d_j|``."""
    d = x.reshape(-1, 3)
    nd = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    u = d / nd[:, None]
    return p0 + np.cumsum(L[:, None] * u, axis=0), u, nd


def chain_residuals(x, p0, L, target, weight, curve=None, curve_weight=1.0, jac=False):
    """Residuals of one arc chain (:func:`fit_frame`) and, with ``jac``, their Jacobian.

    The chain's joints are ``Q_b = p0 + sum_{j <= b} L_j d_j / |d_j|`` for the bone
    directions ``x = (d_0, ..., d_{m-1})`` (m, 3 flattened). Residuals: each joint's weighted
    offset from its target (``weight`` (m, 1), 0 for a joint without one), the gauge
    ``0.1 (|d_j| - 1)``, and, with a curve (k, 3), every sample's distance to the nearest
    segment of the polyline ``p0, Q_0 … Q_{m-1}`` × ``curve_weight / sqrt(k)``.

    The Jacobian is exact where the nearest segment does not change (the envelope of the
    distance to a segment: its derivative moves the segment's two ends by (1 - t) and t);
    ``dQ_b / dd_j = L_j (I - u_j u_j^T) / |d_j|`` for j <= b, ``u_j = d_j / |d_j|``.

    Returns
    -------
    r : (3m + m [+ k],) residuals; with ``jac``, (r, J) with J of shape (len(r), 3m)
    """
    Q, u, nd = chain_joints(x, p0, L)
    m = len(u)
    r = [((Q - target) * weight).ravel(), 0.1 * (nd - 1.0)]
    if curve is not None:
        A = np.vstack([p0, Q])
        dist, seg, t = _seg_nearest(curve, A[:-1], A[1:])
        k = curve_weight / np.sqrt(len(curve))
        r.append(k * dist)
    r = np.concatenate(r)
    if not jac:
        return r
    # G[j] = L_j (I - u_j u_j^T) / |d_j|: the move of every joint from bone j on per unit of d_j
    G = L[:, None, None] * (np.eye(3)[None] - u[:, :, None] * u[:, None, :]) / nd[:, None, None]
    J = np.zeros((len(r), 3 * m))
    for b in range(m):
        for j in range(b + 1):
            J[3 * b:3 * b + 3, 3 * j:3 * j + 3] = weight[b, 0] * G[j]
        J[3 * m + b, 3 * b:3 * b + 3] = 0.1 * u[b]
    if curve is not None:
        P = A[seg] + t[:, None] * (A[seg + 1] - A[seg])
        nrm = np.where(dist[:, None] > 1e-12, (P - curve) / np.maximum(dist, 1e-12)[:, None], 0.0)
        rows = 4 * m + np.arange(len(curve))
        for j in range(m):
            # segment s runs from A_s (moved by the bones j < s) to A_{s+1} (by the bones j <= s)
            f = np.where(j < seg, 1.0, np.where(j == seg, t, 0.0))
            J[rows, 3 * j:3 * j + 3] = k * f[:, None] * (nrm @ G[j])
    return r, J


ROOT_STEPS = 1      # root refinements (development seeds 21–33 random poses, MPJPE median of
                    # the fit: 0 → 1 → 2 steps 7.03 → 6.92 → 6.86 cm; walks 41–46 4.80 →
                    # 4.78 → 4.78 cm; each step costs one more fit)


def fit_frame(target, curves, L, tree: KinematicTree, start=None, inner_weight=1.0,
              curve_weight=1.0, root_steps=None, root=None):
    """Fit the kinematic tree to one frame (see the module docstring), one arc chain at a time
    from the root down: each chain's first joint is fixed by the chains above it, its bone
    directions are fitted (a dozen unknowns per :func:`least_squares`). Then ``root_steps``
    times: the root moved by the mean offset of the other joints from their targets, and the
    chains fitted again (alternating minimization over the root's position: the root, the
    chest junction, is the frame's least steady point).

    Returns (positions (n, 3), rms of the curve distances) or (None, None) without targets.
    """
    root_steps = ROOT_STEPS if root_steps is None else root_steps
    ok = ~np.isnan(target).any(axis=1)
    if not ok[tree.root] or ok.sum() < 2:
        return None, None
    init = target if start is None else np.where(np.isnan(start), target, start)
    n = len(tree.names)
    P = np.full((n, 3), np.nan)
    P[tree.root] = target[tree.root] if root is None else root
    w = np.where(np.array([t in (0.0, 1.0) or _beside(tree, j) for j, t in enumerate(tree.at)]),
                 1.0, inner_weight)
    rms = []
    for (u, v), js in tree.chains().items():
        if np.isnan(P[js[0]]).any():
            continue
        bones = js[1:]
        c = curves.get(v)
        c = None if c is None else np.asarray(c, float)
        tgt = target[bones]
        has = ~np.isnan(tgt).any(axis=1)
        if c is None and not has.any():
            if start is not None:      # nothing seen on this arc: the start's directions (held)
                d = np.diff(np.vstack([start[js[0]], start[bones]]), axis=0)
                d /= np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
                P[bones] = P[js[0]] + np.cumsum(L[bones][:, None] * d, axis=0)
            continue
        x0 = []
        prev = P[js[0]]
        for j in bones:
            d = init[j] - prev if not np.isnan(init[j]).any() else np.array([0.0, 0.0, -1.0])
            d = d / max(np.linalg.norm(d), 1e-9)
            x0.append(d)
            prev = prev + L[j] * d
        x0 = np.concatenate(x0)
        Lb = L[bones]
        wb = (w[bones] * has)[:, None]
        tgt0 = np.nan_to_num(tgt)
        p0 = P[js[0]]

        args = (p0, Lb, tgt0, wb, c, curve_weight)
        sol = least_squares(chain_residuals, x0, jac=lambda x, *a: chain_residuals(
            x, *a, jac=True)[1], args=args, method="lm", max_nfev=200)
        Q = chain_joints(sol.x, p0, Lb)[0]
        P[bones] = Q
        if c is not None:
            A = np.vstack([p0, Q])
            rms.append(float(np.sqrt(np.mean(_seg_dist(c, A[:-1], A[1:]) ** 2))))
    if np.isnan(P).any():
        return None, None
    if root_steps > 0:
        seen = ok.copy()
        seen[tree.root] = False
        return fit_frame(target, curves, L, tree, start, inner_weight, curve_weight,
                         root_steps - 1, P[tree.root] + np.mean(target[seen] - P[seen], axis=0))
    return P, float(np.mean(rms)) if rms else None


def _directions(P, tree):
    D = np.zeros_like(P)
    for j, p in enumerate(tree.parents):
        if p >= 0:
            d = P[j] - P[p]
            D[j] = d / max(np.linalg.norm(d), 1e-12)
    return D


HOLD_MAX = 0.15     # m: mean move of the seen joints from the last fitted frame
HOLD_FRAMES = 5     # the last fitted frame at most this many frames before (3 → 5: random
                    # motion, development seeds 51–56, MPJPE median 6.21 → 6.12 cm, frames
                    # holding joints 7.28 → 7.22; 10 / 15 the same as 5: a part lost across 4–5
                    # unmatched frames took the rest pose; walks 41–46 4.29 → 4.29, unrelated
                    # random poses 21–32 unchanged: they fail the motion check)


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


def _continues(prev, start, dt):
    """Whether the last fitted frame ``prev``, ``dt`` frames before, is the same motion: the
    joints seen in both moved (relative to the first of them, the root when seen) less than
    ``HOLD_MAX`` on average (unrelated random poses: the hands move 0.5–1.5 m; development
    seeds 21–33 with ``HOLD_MAX · dt``: frames holding joints 8.6 → 8.9 cm)."""
    if prev is None or not 1 <= dt <= HOLD_FRAMES:
        return False
    ok = np.flatnonzero(~np.isnan(start).any(axis=1))
    if len(ok) == 0:
        return False
    d = (start[ok] - start[ok[0]]) - (prev[ok] - prev[ok[0]])
    return float(np.linalg.norm(d, axis=1).mean()) < HOLD_MAX


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
                 # one held frame between two similar poses through; benchmarks/held_dev.py)


def held_gaps(P, held, t, tree: KinematicTree, L, max_gap=5):
    """Fill the joints a frame did not see (``held``) from the frames either side that saw
    them (issue 15: gap filling of short stretches, flagged, never silent).

    A run of at most ``max_gap`` consecutive frames holding joint ``j``, between two fitted
    frames ``a`` and ``b`` seeing it, the same motion (consecutive frame numbers, and the
    joints both see moved less than :data:`HOLD_MAX` per frame relative to the root, as
    :func:`_continues`): the bone directions of ``j``'s chain held there are interpolated
    linearly between ``a``'s and ``b``'s, the joints below re-placed with the frame's bone
    lengths ``L`` (n_frames, n_joints). Unrelated poses (random-motion captures) fail the
    motion check and keep their fill.

    Parameters
    ----------
    P : (n_frames, n_joints, 3) fitted joints (NaN rows: unfitted frames)
    held : (n_frames, n_joints) bool, the joints each frame did not see
    t : (n_frames,) frame numbers

    Returns
    -------
    P : a copy, filled; filled : (n_frames, n_joints) bool, the joints interpolated.
    """
    P = P.copy()
    n_f = len(P)
    filled = np.zeros(held.shape, dtype=bool)
    fitted = ~np.isnan(P).any(axis=(1, 2))
    seen = fitted[:, None] & ~held
    order = tree.order()
    for j in order[1:]:
        i = 0
        while i < n_f:
            if not (fitted[i] and held[i, j]):
                i += 1
                continue
            k = i
            while k + 1 < n_f and fitted[k + 1] and held[k + 1, j]:
                k += 1
            a, b = i - 1, k + 1
            i = k + 1
            if a < 0 or b >= n_f or not (seen[a, j] and seen[b, j]) or b - a - 1 > max_gap \
                    or t[b] - t[a] != b - a or filled[a + 1:b, j].any():
                continue
            both = np.flatnonzero(seen[a] & seen[b])
            both = both[both != tree.root]
            if len(both) == 0:
                continue
            move = np.linalg.norm((P[b, both] - P[b, tree.root]) - (P[a, both] - P[a, tree.root]),
                                  axis=1).mean()
            if move >= HOLD_MAX * (b - a):
                continue
            # the held joints of j's chain from j down (those the frames a and b both saw)
            sub = [j] + [c for c in order if c != j and _below(tree, c, j)]
            sub = [c for c in sub if held[a + 1:b, c].all() and seen[a, c] and seen[b, c]]
            Da, Db = _directions(P[a], tree), _directions(P[b], tree)
            for f in range(a + 1, b):
                s = (t[f] - t[a]) / (t[b] - t[a])
                D = _directions(P[f], tree)
                D[sub] = (1 - s) * Da[sub] + s * Db[sub]
                below = [c for c in order if c in sub or any(_below(tree, c, x) for x in sub)]
                for c in below:
                    d = D[c] / max(np.linalg.norm(D[c]), 1e-12)
                    P[f, c] = P[f, tree.parents[c]] + L[f, c] * d
                filled[f, sub] = True
    return P, filled


def _below(tree, c, j):
    """Whether joint ``c`` lies below joint ``j`` in the tree."""
    p = tree.parents[c]
    while p >= 0:
        if p == j:
            return True
        p = tree.parents[p]
    return False


FOLD = np.radians(130.0)  # an unseen arm's forearm and hand: folded forward and up by this angle
                          # from hanging, and turned ACROSS the body (towards the other side)
ACROSS = np.radians(30.0)  # by this angle about the trunk axis: a hand merged with the body lies
                          # against the trunk's front (development seeds 21–28, 8 × 40 random
                          # poses, gate on, the true unseen arm from its shoulder (down, out,
                          # forward): elbow (19, 7, 10), wrist (−8, −10, 15) cm; MPJPE median of
                          # the fit, FOLD / ACROSS: 90° / 0° 6.45, 110° / 0° 6.28, 110° / 30°
                          # 6.20, 130° / 0° 6.20, 130° / 30° 6.13, 130° / 50° 6.19, 130° / 70°
                          # 6.26 cm; frames holding joints 7.8 → 7.1 cm; walks 41–45 4.85 cm
                          # either way: they hold the last frame's arm. Earlier, seeds 31–35
                          # without ACROSS: 0° 7.14, 60° 7.05, 90° 6.80, 120° 6.85, 150° 7.05 cm;
                          # the upper arm tilted forward and out: no gain, 6.11–6.29 cm)


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


def _outward(P, tree, j, ax):
    """Unit vector from the chest to the shoulder of joint j's arm (its arc's first joint),
    across the trunk axis ``ax`` (zero when not defined)."""
    s = j
    while tree.parents[s] >= 0 and tree.arc[tree.parents[s]] == tree.arc[j]:
        s = tree.parents[s]
    c = tree.parents[s]
    if c < 0:
        return np.zeros(3)
    v = P[s] - P[c]
    v = v - np.dot(v, ax) * ax
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.zeros(3)


def rest_fill(start, pose, tree: KinematicTree, L, limbs, held_shoulder=GAPS.held_shoulder
              ) -> np.ndarray:
    """Unseen joints placed in a rest pose (an unseen limb is mostly one merged with the body):
    a joint whose mirror mate hangs from the same parent joint mirrored about the trunk axis
    (a half turn: hips; an arm's shoulder, with a forward known: opposite its mate across
    the trunk axis, raised ``GapOptions.held_shoulder`` from the plane across it), the other bones
    along the trunk axis — down for the limbs (arcs ending at a ``[[mirror]]`` part), up for
    the others (the head) — except an arm's (a limb from the trunk's upper part) bones below
    its first one: folded forward by ``FOLD`` and turned ``ACROSS`` the body (a hand merged
    with the body lies against the trunk's front), forward being the seen lower limbs' tip directions (the toes) across the
    trunk axis, across the direction from the arm's shoulder to the chest; without a forward,
    down."""
    out = start.copy()
    if not tree.trunk:
        return out
    a, b = (pose.parts.get(x) for x in tree.trunk)
    if a is None or b is None or np.isnan(out[tree.root]).any():
        return out
    ax = np.asarray(b, float) - np.asarray(a, float)
    if np.linalg.norm(ax) <= 0:
        return out
    ax /= np.linalg.norm(ax)
    fwd = []                       # forward: the tips of the limbs from the trunk's first part
    for j, p in enumerate(tree.parents):
        if tree.beyond and tree.beyond[j] and tree.arc[j][0] == tree.trunk[0] and \
                not np.isnan(start[j]).any() and not np.isnan(start[p]).any():
            v = start[j] - start[p]
            fwd.append(v - np.dot(v, ax) * ax)
    fwd = np.sum(fwd, axis=0) if fwd else None
    fwd = fwd / np.linalg.norm(fwd) if fwd is not None and np.linalg.norm(fwd) > 0 else None
    for j in tree.order()[1:]:
        if not np.isnan(out[j]).any():
            continue
        p = tree.parents[j]
        mates = [k for k in range(len(tree.names)) if k != j and tree.base[k] == tree.base[j]
                 and tree.parents[k] == p and not np.isnan(start[k]).any()]
        pp = tree.parents[p]
        arm = fwd is not None and tree.arc[j][1] in limbs and tree.arc[j][0] == tree.trunk[1]
        if mates and arm and held_shoulder is not None:
            v = start[mates[0]] - out[p]
            lat = v - np.dot(v, ax) * ax
            lat /= max(np.linalg.norm(lat), 1e-12)
            d = np.sin(held_shoulder) * ax - np.cos(held_shoulder) * lat
        elif mates:
            v = start[mates[0]] - out[p]
            d = 2 * np.dot(v, ax) * ax - v
        elif arm and pp >= 0 and tree.arc[pp] == tree.arc[j]:     # an arm below its elbow
            lat = _outward(out, tree, j, ax)
            d = -np.cos(FOLD) * ax + np.sin(FOLD) * (np.cos(ACROSS) * fwd - np.sin(ACROSS) * lat)
        else:
            d = -ax if tree.arc[j][1] in limbs else ax
        out[j] = out[p] + L[j] * d / max(np.linalg.norm(d), 1e-12)
    return out


# GapOptions.hints = True: an unseen arm bent to reach its hand hint's end (:func:`hint_fill`)
HINT_END = "wrist"  # the hint's end taken as the wrist ("wrist") or the elbow's direction
                    # ("elbow": the upper arm towards it, the forearm as it was). Development
                    # seeds 21–28 random, 41–43 walks (gate on, 80 hints): the end lies 18–29 cm
                    # from the true elbow (median per rule and motion; none within 5 cm) but
                    # 7–13 cm from the true wrist (the folded forearm's branch runs on to the
                    # hand); MPJPE median, off → "elbow" → "wrist": random 6.50 → 6.56 → 6.29,
                    # walks 5.05 → 5.00 → 5.00 cm; the held arms' mean shoulder/elbow/wrist
                    # error, off → "wrist": random 17.1 → 15.6 (140 arms, 41 hinted), walks
                    # 14.0 → 9.7 cm (42 arms). Benchmark seeds (tracking.py, gate on, same
                    # run, without → with): walks MPJPE 4.76 → 4.69 cm, hinted arms 12.1 → 8.8
                    # cm (101 arms); random 5.84 → 5.86 (mean 6.55 → 6.42; 13 frames better,
                    # 10 worse), hinted arms 16.6 → 13.5 cm (23 arms). Gating the hint by its
                    # reach (end beyond 1.0 / 1.2 × the arm, or within 0.3 / 0.5 of it): no gain


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
SHOULDER_BLEND = 0.5  # the fraction of the way to the hull's shoulder an unseen arm moves
# (Issue 15, hips branch: the unseen random arms after these fills sit inside the truth's body
# frame by 3.3 / 4.0 / 3.4 cm (shoulder / elbow / wrist; forward +2.8 / +1.4 / −0.3, up +1.8 /
# +0.1 / +0.9; median over 256 arms, development seeds 21–32, 60 frames; their errors 8.7 /
# 10.5 / 11.8 cm: scatter, not bias). Not kept: the unseen elbow and wrist moved out by 3 / 6
# cm after shoulder_fill: arms 12.0 → 11.6 / 11.8 cm, MPJPE 5.50 → 5.51 / 5.55 cm;
# HELD_SHOULDER 20° 5.53, ACROSS 15° 5.58 cm.)


def shoulder_fill(start, pose, tree: KinematicTree, unseen) -> np.ndarray:
    """``start`` with each unseen arm (an arc from the trunk's upper part to a limb part, all
    its joints ``unseen``) moved whole, its shoulder :data:`SHOULDER_BLEND` of the way to the
    nearer of the frame's two shoulders from the hull (``diagnostics["hull_shoulders"]``: the
    lateral extremes of the trunk's cross-section below the neck,
    :func:`topopose.frame.unseen.hull_shoulders`) when that lies within :data:`HULL_GATE`. The
    fit then keeps the chest → shoulder bone's length, taking its direction."""
    H = pose.diagnostics.get("hull_shoulders")
    out = start.copy()
    if H is None or not tree.trunk:
        return out
    H = np.asarray(H, float).reshape(-1, 3)
    for (u, v), js in tree.chains().items():
        arm = js[1:]
        if u != tree.trunk[1] or v not in tree.limbs or not arm or not unseen[arm].all() \
                or np.isnan(out[arm]).any():
            continue
        h = H[int(np.argmin(np.linalg.norm(H - out[arm[0]], axis=1)))]
        if np.linalg.norm(h - out[arm[0]]) > HULL_GATE:
            continue
        h = out[arm[0]] + SHOULDER_BLEND * (h - out[arm[0]])
        out[arm] += h - out[arm[0]]
    return out


def hint_fill(start, pose, tree: KinematicTree, L, unseen) -> np.ndarray:
    """``start`` with each unseen arm that has a hand hint (``diagnostics["hand_hints"]``:
    the curve of the branch of a hand the per-frame stage left unplaced — an arm branch
    ending at the elbow (``short_arm``), a hand on the trunk's core (``hand_on_trunk``) or an
    untrusted hand — from the chest junction to the branch end) bent at the hint. With
    :data:`HINT_END` ``"wrist"`` (default; the end lies near the wrist, not the elbow): the
    shoulder kept (as ``start`` has it), the elbow and wrist by the law of cosines so that the
    wrist is at the hint's end (on the line towards it, the arm straight, when out of reach),
    bent in the plane of ``start``'s elbow (the rest pose's hanging upper arm or the last
    frame's); with ``"elbow"``: the elbow a bone length from the shoulder towards the end.
    The joints below keep ``start``'s bone directions. Only arcs whose joints are all
    ``unseen`` (bool per joint: not placed by the frame)."""
    hints = pose.diagnostics.get("hand_hints") or {}
    out = start.copy()
    for (u, v), js in tree.chains().items():
        c = hints.get(v)
        arm = js[1:]
        if c is None or len(arm) < 2 or np.isnan(out[arm[0]]).any():
            continue
        end = np.asarray(c, float)[-1]
        d = end - out[arm[0]]
        if np.linalg.norm(d) <= 0 or np.isnan(out[arm]).any() or not unseen[arm].all():
            continue
        if HINT_END == "elbow" or len(arm) < 3:
            e = out[arm[0]] + L[arm[1]] * d / np.linalg.norm(d)
            out[arm[1:]] += e - out[arm[1]]
            continue
        # the end as the wrist: two bones (law of cosines), bent as ``start`` bends them
        a, b, r = L[arm[1]], L[arm[2]], float(np.linalg.norm(d))
        t = d / r
        n = out[arm[1]] - out[arm[0]]
        n = n - np.dot(n, t) * t
        n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-9 else np.zeros(3)
        ca = np.clip((a * a + r * r - b * b) / (2 * a * r), -1.0, 1.0) if r < a + b else 1.0
        e = out[arm[0]] + a * (ca * t + np.sqrt(1 - ca * ca) * n)
        w = end - e
        w = e + b * w / max(np.linalg.norm(w), 1e-12)
        out[arm[3:]] += w - out[arm[2]]
        out[arm[1]], out[arm[2]] = e, w
    return out


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


def tip_targets(init, tree: KinematicTree, turn=None, stretch=None,
                fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """The tip joints' targets (a joint past its arc's end part, ``beyond``: fingertips, toes)
    corrected for the skeleton curve's end (thesis §13.3.1: the kinematic model initialized
    from the skeleton curves). Thinning stops a branch short of the limb's tip and rounds the
    corner at its last joint, so the tip's target, extrapolated along the curve's last
    direction, lies short and turned towards the bone above.

    Per frame and tip joint ``j`` with parent ``p`` (wrist, ankle) and grandparent ``g``
    (elbow, knee), all placed: the vector ``x_j - x_p`` is turned by ``turn[base]`` degrees
    away from ``x_p - x_g`` in the plane of the two (the angle between them grows; left as it
    is when they are parallel), then scaled by ``stretch[base]``.

    Parameters
    ----------
    init : (n_frames, n_joints, 3) initial placements (NaN: not placed)
    tree : KinematicTree
    turn : {base name: degrees} (default ``SkeletonFitOptions.tip_turn``)
    stretch : {base name: factor} (default ``SkeletonFitOptions.tip_stretch``)

    Returns
    -------
    (n_frames, n_joints, 3) array, a copy of ``init``.
    """
    turn = fit.tip_turn if turn is None else turn
    stretch = fit.tip_stretch if stretch is None else stretch
    out = np.array(init, dtype=float, copy=True)
    for j, p in enumerate(tree.parents):
        if p < 0 or not (tree.beyond and tree.beyond[j] > 0):
            continue
        th, k = turn.get(tree.base[j]), stretch.get(tree.base[j])
        if not th and not k:
            continue
        g = tree.parents[p]
        for f in range(len(out)):
            x, a = out[f, j], out[f, p]
            if np.isnan(x).any() or np.isnan(a).any():
                continue
            v = x - a
            r = float(np.linalg.norm(v))
            if r <= 0:
                continue
            v = v / r
            if th and g >= 0 and not np.isnan(out[f, g]).any():
                u = a - out[f, g]
                n = u - np.dot(u, v) * v           # ⊥ v in the plane of u and v, towards u
                nn = float(np.linalg.norm(n))
                if nn > 1e-9:
                    t = np.radians(th)
                    v = np.cos(t) * v - np.sin(t) * n / nn     # away from u
            out[f, j] = a + (k or 1.0) * r * v
    return out


# SkeletonFitOptions.girdle = True: the joints a model declares as one girdle (``girdle = [pair, height]`` on a
               # joint: the neck with the shoulders) placed as one symmetric rigid body
               # (:func:`girdle_targets`); False: each joint alone. Development seeds (walks
               # 41–46, random motion 51–56, unrelated random poses 21–32; gate off, cached
               # per-frame results, benchmarks/trunk_dev.py's measure; MPJPE median over the
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


def girdle_targets(init, tree: KinematicTree, on=None,
                   fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """The targets of each declared girdle as one symmetric rigid body (sequence stage).

    A joint declared with ``girdle = [pair, h]`` (the neck with ``shoulder``) and the two
    joints of that mirror pair are placed by the rigid template that fits their three
    targets best (:meth:`scipy.spatial.transform.Rotation.align_vectors`, the Kabsch
    solution): the pair ``W`` apart, ``W`` the sequence's median distance between their
    targets, the joint on the pair's mid-plane ``h W`` from their midpoint. Each frame's three
    targets come from separate skeleton curves and junctions, which with few cameras scatter
    apart (the neck beside the shoulders' midpoint); the template shares their evidence.
    Frames where any of the three is unplaced keep their targets.

    Parameters
    ----------
    init : (n_frames, n_joints, 3) targets (NaN: not placed)
    tree : KinematicTree
    on : bool (default ``SkeletonFitOptions.girdle``)

    Returns
    -------
    (n_frames, n_joints, 3) array, a copy of ``init``.
    """
    from scipy.spatial.transform import Rotation

    out = np.array(init, dtype=float, copy=True)
    if not (fit.girdle if on is None else on) or not tree.girdle:
        return out
    for c, g in enumerate(tree.girdle):
        if g is None:
            continue
        pair = [j for j, b in enumerate(tree.base) if b == g[0]]      # two: kinematic_tree
        js = [c, *pair]
        ok = ~np.isnan(out[:, js]).any(axis=(1, 2))
        if not ok.any():
            continue
        W = float(np.median(np.linalg.norm(out[ok, pair[0]] - out[ok, pair[1]], axis=1)))
        T = np.array([[0.0, 0.0, g[1] * W], [0.5 * W, 0.0, 0.0], [-0.5 * W, 0.0, 0.0]])
        T -= T.mean(axis=0)
        for f in np.flatnonzero(ok):
            X = out[f, js]
            m = X.mean(axis=0)
            with warnings.catch_warnings():      # three targets in a line: any turn about it
                warnings.simplefilter("ignore", UserWarning)
                R, _ = Rotation.align_vectors(X - m, T)
            out[f, js] = m + R.apply(T)
    return out


SMOOTH = 9          # frames: the default Savitzky–Golay window (order 2) over the runs of
                    # continuing motion (:func:`motion_runs`); 0 / None given to fit_sequence as 0:
                    # off. Per-frame fits jitter (each frame's curves alone) while a body moves
                    # smoothly. Development seeds (random motion 51–56, walks 41–46, unrelated
                    # random poses 21–32; gate on, HOLD_AGE 8; MPJPE median over the pooled
                    # matched frames): off 5.91 / 4.29 / 5.60 cm; 7: 5.21 / 3.60; 9: 5.07 /
                    # 3.59 / 5.60; 11: 5.10 / 3.51; 13: 5.09 / 3.59 cm. Without the motion check
                    # (SMOOTH_MOVE None) unrelated poses are averaged together: window 5 / 7 / 9
                    # random poses 36.3 / 46.9 / 51.6 cm
SMOOTH_RATE = 25.0  # frames/s SMOOTH was chosen at: at another rate the default window keeps
                    # its duration, 0.36 s (:func:`smooth_window`). Development motions at 60
                    # frames/s (benchmarks/fps_dev.py, results/fps_dev.md: walks 41–43, random
                    # motion 51–53, 1.6 s each, 8 cameras; MPJPE median over the matched frames):
                    # window 0 / 9 / 15 / 21 / 27 frames: 4.86 / 4.02 / 3.85 / 3.73 / 3.76 cm
                    # (at 25 frames/s: 4.97 / 4.20 / 4.31 / 4.68 / 4.93): 9 frames at 60 frames/s
                    # (0.15 s) was too short, 21 (0.35 s) is 9 at 25
# SmoothingOptions.move = 0.15: m: a frame whose joints (from the root) lie this far from its
                    # neighbourhood's median is an outlier, and a run breaks where successive
                    # neighbourhoods lie this far apart (mean over the joints; :func:`motion_runs`).
                    # Until session 33 each frame was compared with the one before (window 9:
                    # 0.1 / 0.15 / 0.25 m: random motion 5.31 / 5.07 / 5.11, walks 3.59 / 3.59 /
                    # 3.60 cm, unrelated random poses 5.60 at each): a 4-camera fit's per-frame
                    # jitter broke the runs, the real recording had 27 of 100 frames smoothed.
                    # Against the neighbourhood (benchmarks/fps_dev.py, results/fps_dev_runs.md):
                    # development 8 cameras 4.20 → 4.23 cm at 25 frames/s, 3.73 → 3.71 at 60;
                    # 4p 10.04 → 9.89 / 9.74 → 9.74 cm; unrelated random poses (seeds 21–24)
                    # 5.44 cm, no frame smoothed, either way


def _apart(a, b) -> float:
    """Mean distance between two sets of joints (n_joints, 3)."""
    return float(np.linalg.norm(a - b, axis=1).mean())


def neighbourhood(P, t, tree: KinematicTree, reach, seen) -> tuple:
    """Per frame the fit saw (``seen``): the per-joint median ``M`` of its neighbourhood (the
    seen frames at most ``reach`` frame numbers away, itself included), joints taken from the
    root, and the frame's distance from it (m, mean over the joints); NaN for the other
    frames and for a frame with fewer than 3 seen frames in reach (:func:`motion_runs`)."""
    Q = P - P[:, tree.root:tree.root + 1]
    M = np.full_like(Q, np.nan)
    dist = np.full(len(P), np.nan)
    idx = np.flatnonzero(seen)
    for i in idx:
        near = idx[np.abs(t[idx] - t[i]) <= reach]
        if len(near) >= 3:
            M[i] = np.median(Q[near], axis=0)
            dist[i] = _apart(Q[i], M[i])
    return M, dist


def motion_runs(P, t, tree: KinematicTree, win, max_move=None, seen=None, near=None) -> list:
    """Runs ``(a, b)`` (frames ``a`` … ``b - 1``) of at least ``win`` fitted frames with
    consecutive frame numbers ``t`` along which the motion continues. Each frame the fit saw
    (``seen``, default every fitted frame; not one interpolated between two others) is
    compared with its neighbourhood: the per-joint median, joints taken from the root, of the
    seen frames at most ``win // 2`` frame numbers away (itself included). A frame at least
    ``max_move`` (m, mean over the joints; None: no check) from its neighbourhood, or with
    fewer than 3 seen frames in it, is an *outlier*: it belongs to no run (a single wrong
    frame among right ones). Between two successive seen frames that are not outliers, a run
    breaks where both the frames and their neighbourhoods lie ``max_move`` apart (the motion
    jumped and stayed; the frames interpolated between them belong to none). Unrelated poses
    (a random-pose capture) make no run: each frame is far from its neighbours' median, or
    the frames and the medians jump.
    Per-frame jitter does not break a run, as it did when each frame was compared with the
    one before (the real recording's 4-camera fits: 27 of 100 frames smoothed, now 59; see
    ``SmoothingOptions.move``).

    Parameters
    ----------
    P : (n_frames, n_joints, 3) joints (NaN: frame not fitted)
    t : (n_frames,) frame numbers
    win : the least run length (frames); ``win // 2`` the neighbourhood's reach
    max_move : the largest mean distance of a frame's joints from its neighbourhood's, and
        between two successive neighbourhoods (m)
    seen : (n_frames,) bool, the frames the fit saw (None: every fitted frame)
    near : ``(M, dist)`` of :func:`neighbourhood` for these frames and ``win // 2``, if
        already computed

    Returns
    -------
    list of (a, b) index pairs.
    """
    n_f = len(P)
    t = np.asarray(t)
    ok = ~np.isnan(P).reshape(n_f, -1).any(axis=1)
    seen = ok if seen is None else ok & np.asarray(seen, bool)
    outlier = np.zeros(n_f, dtype=bool)
    M = Q = None
    if max_move is not None:
        Q = P - P[:, tree.root:tree.root + 1]
        M, dist = near if near is not None else neighbourhood(P, t, tree, win // 2, seen)
        outlier = seen & ~(dist < max_move)         # NaN: too few neighbours to judge
    runs, start, last = [], None, None

    def close(end):
        if start is not None and end - start >= win:
            runs.append((start, end))

    for i in range(n_f):
        if not ok[i] or outlier[i] or (start is not None and t[i] - t[i - 1] != 1):
            close(i)
            start, last = None, None
            if not ok[i] or outlier[i]:
                continue
        if start is None:
            start, last = i, (i if seen[i] else None)
            continue
        if not seen[i]:
            continue
        if M is not None and last is not None and _apart(Q[i], Q[last]) >= max_move \
                and _apart(M[i], M[last]) >= max_move:
            close(last + 1)
            start = i
        last = i
    close(n_f)
    return runs


# SmoothingOptions.despike = (3.0, 15.0): (k, floor in degrees) of :func:`despike`, the bones' spikes replaced
    # before the smoothing; None: off. A frame whose matched curves put one limb on a wrong
    # branch (the real recording's frames 36 and 42: the left arm's curve on another branch,
    # its hand 0.6 m off) keeps the rest of its skeleton near its neighbours', so it stays in
    # its run, and the Savitzky–Golay window averaged the wrong arm into the 20 frames around
    # it (left elbow 7 cm off where the fits either side had it within 3 cm). Real recording
    # (real_motion.py, session 34's poses): all / right frames 6.80 / 6.44 → 6.61 / 6.26 cm
    # (k 2 / 5 with floor 10 / 15°: 6.66 / 6.42, 6.75 / 6.33; floor 8 / 25°: 6.56 / 6.26,
    # 6.61 / 6.26). Development seeds: neutral (fps_dev.py, 8 cameras 25 / 60 frames/s, 4p 25
    # / 60: 4.23 / 3.71 / 9.75 / 9.27 → 4.25 / 3.70 / 9.75 / 9.27 cm; knee_dev.py, 8 / 4p /
    # 4pd: 3.43 / 8.97 / 8.34 → 3.50 / 8.90 / 8.34); unrelated random poses untouched (no run)


def despike(D, half, k, floor):
    """A Hampel filter on bone directions: each frame's direction of each bone more than
    ``max(med + k × MAD, floor)`` degrees from the median direction of its window (the frames
    at most ``half`` away, itself included; ``med``, ``MAD``: the median and the scaled median
    absolute deviation of the window's angles to it) is replaced by that median direction.

    Parameters
    ----------
    D : (n_frames, n_joints, 3) unit bone directions (:func:`_directions`; the root's zero)
    half : the window's half-width (frames)
    k, floor : the threshold's MAD factor and its least value (degrees)

    Returns
    -------
    (D with the spikes replaced, (n_frames, n_joints) bool: the bones replaced)

    Examples
    --------
    >>> D = np.tile([0.0, 0.0, -1.0], (7, 1, 1))
    >>> D[3, 0] = [1.0, 0.0, 0.0]                  # one frame's bone swung out 90 degrees
    >>> out, bad = despike(D, 3, 3.0, 15.0)
    >>> bad[:, 0].tolist(), out[3, 0].tolist()
    ([False, False, False, True, False, False, False], [0.0, 0.0, -1.0])
    """
    n = len(D)
    out = D.copy()
    bad = np.zeros(D.shape[:2], dtype=bool)
    for i in range(n):
        W = D[max(0, i - half):i + half + 1]
        m = np.median(W, axis=0)
        norm = np.linalg.norm(m, axis=1)
        m = m / np.maximum(norm, 1e-12)[:, None]
        ang = np.degrees(np.arccos(np.clip(np.einsum("wjk,jk->wj", W, m), -1.0, 1.0)))
        med = np.median(ang, axis=0)
        mad = 1.4826 * np.median(np.abs(ang - med), axis=0)
        a_i = np.degrees(np.arccos(np.clip(np.einsum("jk,jk->j", D[i], m), -1.0, 1.0)))
        bad[i] = (a_i > np.maximum(med + k * mad, floor)) & (norm > 1e-9)
        out[i, bad[i]] = m[bad[i]]
    return out, bad


def smooth_window(fps=None) -> int:
    """The default smoothing window (frames) at ``fps`` frames/s: the odd number of frames
    nearest :data:`SMOOTH` / :data:`SMOOTH_RATE` seconds (at least 3); :data:`SMOOTH` itself
    when the rate is unknown, :data:`SMOOTH` is off or :data:`SMOOTH_RATE` is None (the
    window in frames at any rate, as before session 33).

    Examples
    --------
    >>> smooth_window(25), smooth_window(60), smooth_window(None), smooth_window(10)
    (9, 21, 9, 3)
    """
    if not SMOOTH or not fps or not SMOOTH_RATE:
        return SMOOTH or 0
    return max(3, 2 * int(round((SMOOTH * float(fps) / SMOOTH_RATE - 1) / 2)) + 1)


def _interpolate(P, t, L, tree: KinematicTree, a, b) -> None:
    """Frames ``a + 1 … b - 1`` of ``P`` (in place) interpolated between frames ``a`` and ``b``
    by their frame numbers ``t``: the root position and the bone directions linearly
    (normalized), the bone lengths ``L`` (per frame) too."""
    Da, Db = _directions(P[a], tree), _directions(P[b], tree)
    for k in range(a + 1, b):
        s = (t[k] - t[a]) / (t[b] - t[a])
        root = (1 - s) * P[a, tree.root] + s * P[b, tree.root]
        P[k] = forward(root, (1 - s) * Da + s * Db, (1 - s) * L[a] + s * L[b], tree)


# SmoothingOptions.bridge = True: a temporal outlier between two frames of the same motion is replaced by their
    # interpolation (:func:`bridge_outliers`); False: it keeps its own fit, flagged only.
    # Development seeds (benchmarks/fps_dev.py, results/fps_dev_bridge.md; MPJPE median over
    # the good frames, the default window): 4p 9.89 → 9.75 cm at 25 frames/s (15 frames
    # bridged), 9.74 → 9.27 at 60 (37); 8 cameras 4.23 / 3.71 cm, no frame bridged; unrelated
    # random poses (seeds 21–24) none bridged. Without the majority rule 4p 9.37 / 8.90 cm,
    # but held-out unrelated random poses were bridged (s12: 4.8 → 5.1 cm)


def bridge_outliers(P, t, tree: KinematicTree, L, dist, max_gap, max_move, M=None, reach=None):
    """``P`` with short stretches of *outlier* frames (a skeleton ``max_move`` or more from its
    neighbours' median, :func:`neighbourhood`) replaced by the interpolation of the frames
    either side (root position and bone directions, as the gap filling) — the issue's "gap
    filling of short rejected stretches" for frames the per-frame stage matched but the
    motion around them rejects (issue 15). A stretch is bridged when

    * it has at most ``max_gap`` frames, consecutive frame numbers to the two frames either
      side, and those two were judged and are not outliers;
    * the two are of one motion: less than ``max_move`` apart (mean over the joints, from the
      root), or their neighbourhoods' medians ``M`` are (a 4-camera fit jitters; as
      :func:`motion_runs`);
    * its pose does not recur: no other judged frame within ``reach`` frame numbers lies less
      than ``max_move`` from one of its frames (two poses taken in turn are the capture's);
    * most judged frames within ``reach`` of it (itself included) are not outliers: a wrong
      frame among right ones. In a capture of unrelated poses most frames are outliers, and
      the few near their neighbours' median are typical poses, not one motion.

    Parameters
    ----------
    P : (n_frames, n_joints, 3) joints (NaN: frame not fitted)
    t : (n_frames,) frame numbers
    L : (n_frames, n_joints) bone lengths per frame
    dist : (n_frames,) each frame's distance from its neighbours' median (m; NaN: not
        judged: not fitted, interpolated, or too few neighbours)
    max_gap : longest stretch bridged (frames)
    max_move : m, the outliers' distance and the ends' largest one
    M : (n_frames, n_joints, 3) the neighbourhood medians (:func:`neighbourhood`), or None
    reach : frames around a stretch looked at (None: ``max_gap``)

    Returns
    -------
    P : a copy, bridged; bridged : (n_frames,) bool

    Examples
    --------
    A chain whose middle frame jumped away (the root stays, the bones point elsewhere):

    >>> from topopose.pose.model import load_model
    >>> tree = kinematic_tree(load_model("human"))
    >>> rng = np.random.default_rng(0)
    >>> P = np.stack([np.cumsum(rng.normal(0, 0.1, (len(tree.names), 3)), 0)] * 3)
    >>> P[1] += rng.normal(0, 0.5, P[1].shape)
    >>> L = np.ones((3, len(tree.names)))
    >>> Q, done = bridge_outliers(P, np.arange(3), tree, L, np.array([0, 1, 0]), 5, 0.15)
    >>> done.tolist(), bool(np.allclose(Q[1] - Q[1, tree.root], forward(
    ...     np.zeros(3), _directions(P[0], tree), L[0], tree)))
    ([False, True, False], True)
    """
    P = np.array(P, dtype=float, copy=True)
    t = np.asarray(t)
    dist = np.asarray(dist, float)
    outlier, end = dist >= max_move, dist < max_move          # NaN: neither
    judged = np.flatnonzero(np.isfinite(dist))
    reach = max_gap if reach is None else reach
    Q = P - P[:, tree.root:tree.root + 1]
    done = np.zeros(len(P), dtype=bool)

    def bridgeable(i, j):
        a, b = i - 1, j + 1
        if a < 0 or b >= len(P) or not (end[a] and end[b]) or j - i + 1 > max_gap \
                or t[i] - t[a] != 1 or t[b] - t[j] != 1:
            return False
        if _apart(Q[a], Q[b]) >= max_move and (M is None or _apart(M[a], M[b]) >= max_move):
            return False
        around = judged[(t[judged] >= t[i] - reach) & (t[judged] <= t[j] + reach)]
        if 2 * np.count_nonzero(outlier[around]) >= len(around):
            return False
        others = around[(around < i) | (around > j)]
        return not any(_apart(Q[k], Q[m]) < max_move for m in range(i, j + 1) for k in others
                       if abs(t[k] - t[m]) <= reach)

    i = 0
    while i < len(P):
        if not outlier[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(P) and outlier[j + 1] and t[j + 1] - t[j] == 1:
            j += 1
        if bridgeable(i, j):
            _interpolate(P, t, L, tree, i - 1, j + 1)
            done[i:j + 1] = True
        i = j + 1
    return P, done


def bridged_parts(poses, t, bridged, i) -> tuple:
    """The parts of bridged frame ``i`` (:func:`bridge_outliers`): each part placed in both
    frames either side of its stretch interpolated between them by frame number, the others
    as the frame had them; returns (parts, the names interpolated)."""
    a, b = i - 1, i + 1
    while bridged[a]:
        a -= 1
    while bridged[b]:
        b += 1
    s = (t[i] - t[a]) / (t[b] - t[a])
    pa, pb = poses[a].parts, poses[b].parts
    done = sorted(k for k in pa if pa[k] is not None and pb.get(k) is not None)
    parts = dict(poses[i].parts)
    for k in done:
        parts[k] = (1 - s) * np.asarray(pa[k], float) + s * np.asarray(pb[k], float)
    return parts, done


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
    poses = sorted(poses, key=lambda p: p.frame)
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
            if miss.any() and _continues(prev, start, t[i] - t_prev if prev is not None else 0):
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
    held = np.isnan(init).any(axis=2)
    filled = np.zeros_like(held)
    if max_gap and gap.gaps:
        P, filled = held_gaps(P, held, t, tree, Lf, max_gap)
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
    return out, tree, L
