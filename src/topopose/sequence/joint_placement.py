"""Where each joint of a frame starts (thesis §13.3.1: the kinematic model initialized from the
skeleton curves): relative arc lengths on the curves, the trunk's joints behind the medial
axis, shoulders and hips beside it, bent limbs, knees from the far end, hanging arms from the
start, the tips' targets and the girdles."""
from __future__ import annotations

import warnings

import numpy as np

from topopose.frame.curves import arc_lengths
from topopose.pose.model import part_stem
from topopose.sequence.options import DEFAULT, SkeletonFitOptions
from topopose.sequence.skeleton_fit import (KinematicTree, _along, _beside, _end_direction)

FIT = DEFAULT.skeleton_fit

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


HANG_COS = 0.9     # a limb hangs when its curve (junction → end) lies within arccos(0.9) = 26°
                   # of straight down the trunk (see HANGING_WIDTH)


HULL_GATE = 0.2    # m: a shoulder from the hull farther than this from the joint's place: unused


def lateral_direction(x, mate, ax, shift=None) -> np.ndarray:
    """The outward direction (unit, across the unit trunk axis ``ax``; zero when none) of a
    joint at ``x`` from its mirror mate at ``mate``.

    Without ``shift``: from the mate's point to the joint's, across the trunk. With the frame's
    spine shift ``shift`` (:mod:`topopose.frame.anatomy`: back, against the front the feet
    tell), the mean of that unit direction and the trunk's side (``ax`` × the front, on the
    joint's side): the hips' points on the legs' curves turn with a leg lifted forward, the
    feet with a foot turned out — two estimates of the pelvis's left–right line whose errors
    do not follow each other.

    Parameters
    ----------
    x, mate : (3,) the joint's and its mate's places (on their limbs' curves)
    ax : (3,) the trunk's unit axis (up)
    shift : (3,) or None, the frame's ``diagnostics["spine_shift"]``

    Returns
    -------
    (3,) array, of length 1 or 0.
    """
    lat = np.asarray(x, float) - np.asarray(mate, float)
    lat = lat - np.dot(lat, ax) * ax
    n = float(np.linalg.norm(lat))
    if n <= 0:
        return np.zeros(3)
    lat = lat / n
    if shift is None:
        return lat
    side = np.cross(ax, -np.asarray(shift, float))
    m = float(np.linalg.norm(side))
    if m <= 0:
        return lat
    side = side / m * (1.0 if np.dot(side, lat) >= 0 else -1.0)
    d = lat + side
    k = float(np.linalg.norm(d))
    return d / k if k > 0 else lat


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
    trunk and outward (:func:`lateral_direction`: from its mate's curve point to its own,
    across the trunk, with ``SkeletonFitOptions.hip_feet`` turned half-way to the side the
    feet tell) by ``width`` (``SkeletonFitOptions.hanging_width`` when its limb hangs) × the
    radius — the hull's largest inscribed radius scales with girth, the trunk's length does
    not (development seeds: half shoulder width / radius 1.16–1.46 over four builds, / trunk
    length 0.39–0.76); otherwise as its ``offset`` says. A joint with an
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
                lat = lateral_direction(out[j], out[mates[0]], ax, s if fit.hip_feet else None)
                if lat.any():
                    w_al, w_out = tree.width[j]
                    if fit.hanging_width is not None and _hangs(c, ax):
                        w_al, w_out = fit.hanging_width
                    moved[j] = (np.asarray(c, float)[0] + w_al * radius * ax
                                + w_out * radius * lat)
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
             # side) exceeds this × the chord: 0.2 ≈ a joint angle of 136° (two equal bones). None /
             # 0: off (the joint at its ``at``). Its figures: docs/decisions.md.


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


REACH_PAST = 0.1   # m: a joint placed by its bone's length at most this far past its curve's


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
