"""Extremity tips: where a limb's skeleton branch, prolonged, leaves the visual hull.

A curve skeleton obtained by thinning stops inside the shape: the end of a limb's branch lies
about one inscribed-ball radius short of the surface (thesis §4.3: a ball thins to its centre;
an end point survives only where the shape is at its thinnest across). The model's extremities
(a head's crown, fingertips, toes) are on the surface, so a leaf part is placed where the
branch's end direction, prolonged from the skeleton end, leaves the hull. Measured on the real
recording (``benchmarks/real.py``, 100³): the skeleton end of the head lies 0.10–0.15 m below
Pose2Sim's head-top marker (head median error 0.22 m); the tip brings the median to 0.12 m and
the frames with head, hands and feet within 0.15 m from 8 % to 30 %. The end direction from
the last 4 voxels of the branch does better there than the whole branch's (26 %). On the
``body`` subject, whose ground truth accepts anything from the neck base to the crown, the
head's median error grows from 5.1 to 6.4 cm (a skeleton end off the head's axis is sent
sideways), which costs 2 of 32 separated frames at 0.08 × height.
"""
from __future__ import annotations

import numpy as np


def end_direction(skeleton_points: np.ndarray, end: np.ndarray, reach: float) -> np.ndarray | None:
    """Unit direction in which a branch ends at ``end``: from the mean of the skeleton points
    within ``reach`` of it (one side only, at an end point) to ``end``; None when too few."""
    d = np.linalg.norm(skeleton_points - end, axis=1)
    near = skeleton_points[(d > 0) & (d <= reach)]
    if len(near) < 2:
        return None
    v = end - near.mean(axis=0)
    n = float(np.linalg.norm(v))
    return None if n == 0 else v / n


def exit_point(volume: np.ndarray, origin, voxel_size: float, start, direction,
               max_length: float) -> np.ndarray:
    """The last point inside ``volume`` (bool grid) on the ray ``start + t·direction``,
    0 ≤ t ≤ ``max_length``, marched in steps of half a voxel (world units)."""
    org = np.asarray(origin, float)
    start = np.asarray(start, float)
    n = max(int(np.ceil(2 * max_length / voxel_size)), 1)
    t = np.linspace(0.0, max_length, n + 1)
    pts = start[None] + t[:, None] * np.asarray(direction, float)[None]
    ijk = np.round((pts - org) / voxel_size).astype(int)
    inside = np.all((ijk >= 0) & (ijk < np.array(volume.shape)), axis=1)
    inside[inside] = volume[tuple(ijk[inside].T)]
    out = np.flatnonzero(~inside)
    last = (out[0] - 1) if out.size else n
    return pts[max(last, 0)]


def inscribed_radius(volume: np.ndarray, ijk, limit: int) -> float:
    """Distance (voxels) from voxel ``ijk`` to the nearest voxel outside ``volume`` (or outside
    the grid), looked for within ``limit`` voxels (``limit`` when none is nearer)."""
    ijk = np.asarray(ijk, int)
    lo = ijk - limit
    hi = ijk + limit + 1
    pad_lo = np.maximum(-lo, 0)
    pad_hi = np.maximum(hi - np.array(volume.shape), 0)
    sub = volume[tuple(slice(max(a, 0), b) for a, b in zip(lo, hi))]
    sub = np.pad(sub, list(zip(pad_lo, pad_hi)), constant_values=False)
    out = np.argwhere(~sub)
    if not len(out):
        return float(limit)
    return float(min(np.sqrt(((out - limit) ** 2).sum(axis=1)).min(), limit))


def hull_box(vol):
    """The hull's bounding box as ``(lo, hi)`` voxel arrays (``hi`` exclusive):
    ``vol.diagnostics["bbox"]`` (inclusive, left by :func:`topopose.visual_hull`) when there
    is one, else from the axis projections of ``vol.data``; None when the hull is empty."""
    bb = (getattr(vol, "diagnostics", None) or {}).get("bbox")
    if bb:
        return np.asarray(bb[0], int), np.asarray(bb[1], int) + 1
    return _box(vol.data)


def _box(volume: np.ndarray):
    axes = [np.flatnonzero(volume.any(axis=tuple(k for k in range(3) if k != a))) for a in range(3)]
    if not len(axes[0]):
        return None
    return np.array([a[0] for a in axes]), np.array([a[-1] + 1 for a in axes])


def skeleton_voxels(skeleton: np.ndarray, box=None) -> np.ndarray:
    """``np.argwhere(skeleton)`` (same rows, same order), scanning only ``box`` = ``(lo, hi)``
    (:func:`hull_box`: the skeleton lies in its hull) when given. One per frame serves
    :func:`extremity_tips`, :func:`topopose.frame.anatomy.front_direction` and
    :func:`topopose.frame.curves.arc_curves`."""
    if box is None:
        return np.argwhere(skeleton)
    lo, hi = box
    return np.argwhere(skeleton[tuple(slice(a, b) for a, b in zip(lo, hi))]) + np.asarray(lo)


def extremity_tips(vol, skeleton, data, mapping: dict, leaf_parts, reach: float = 4.0,
                   max_radii: float = 1.5, voxels=None, anchors=None) -> dict:
    """Tip of each leaf part matched to a data leaf (see module docstring).

    Parameters
    ----------
    vol : Volume
        The hull (``data``, ``origin``, ``voxel_size``).
    skeleton : ndarray of bool
        The curve skeleton on the same grid.
    data : Tree
        The data tree (vertex positions in world units).
    mapping : dict
        Model part → data vertex.
    leaf_parts : iterable of str
        The model's leaf parts.
    reach : float
        Radius (voxels) of the skeleton neighbourhood that gives the end direction.
    max_radii : float
        Longest prolongation, in inscribed-ball radii of the hull at the skeleton end (a branch
        ending in a phantom volume, or whose direction is off, is not followed far).
    voxels : ndarray, optional
        :func:`skeleton_voxels` of ``skeleton`` if already computed.
    anchors : dict, optional
        ``{leaf part: (anchor part, max_radii)}`` (:data:`TIP_ANCHOR`): that leaf is prolonged
        in the direction from the anchor part's data vertex to its branch end, at most that
        many inscribed radii, rather than along its branch's own end direction (as
        :func:`head_from_hull` goes on from the torso). Leaves whose anchor is unmatched or
        sits on the end fall back to the end direction and ``max_radii``.

    Returns
    -------
    dict
        part → tip position (world units) for the parts that have one.
    """
    vs = float(vol.voxel_size)
    org = np.asarray(vol.origin, float)
    pts = (np.argwhere(skeleton) if voxels is None else voxels) * vs + org
    if not len(pts):
        return {}
    out = {}
    for p in leaf_parts:
        v = mapping.get(p)
        if v is None or data.degree(v) != 1:
            continue
        end = data.positions.get(v)
        if end is None:
            continue
        end = np.asarray(end, float)
        d, radii = _anchor_direction(data, mapping, end, (anchors or {}).get(p))
        if d is None:
            d, radii = end_direction(pts, end, reach * vs), max_radii
        if d is None:
            continue
        r = inscribed_radius(vol.data, np.round((end - org) / vs).astype(int), 16)
        out[p] = exit_point(vol.data, org, vs, end, d, radii * max(r, 1.0) * vs)
    return out


#: Leaf parts prolonged away from an anchor part (:func:`extremity_tips` ``anchors``), per model:
#: ``{leaf: (anchor, max_radii)}``. The head's branch often bends at its end (thinning leaves a spur
#: towards a cheek or the back of the skull), so its own end direction sends the tip sideways and
#: 1.5 radii stop short; the direction torso → branch end is the body's axis through the head
#: (thesis §4.3: the branch ends one inscribed radius inside, the crown is on the surface beyond
#: it). Used where the head is not placed from the hull (no coordinate constraints: inverted,
#: acrobatic subjects). Its figures: docs/decisions.md.
TIP_ANCHOR = {"human": {"head": ("torso", 3.0)}}
#: The head from the hull must hold a head-sized ball (:func:`thick_top` ``ball``, ``reach``), per
#: model: ``(ball, reach, min_voxels, min_cameras)``; ball and reach × the hull's largest inscribed
#: radius. A raised fist above the head is as thick as the ``min_fraction`` 0.4 of
#: :data:`topopose.frame.rules.HEAD_FROM_HULL` and was taken for the head (the commonest wrong head
#: of the ``body`` subject's separated frames once the head came from the hull). Its figures:
#: docs/decisions.md.
HEAD_BALL = {"human": (0.46, 1.5, 1.2, 6)}


def _anchor_direction(data, mapping, end, rule):
    """(unit direction anchor vertex → ``end``, max radii) for ``rule = (anchor part,
    max_radii)``, or (None, None) when there is no rule, no anchor position or no distance."""
    if rule is None:
        return None, None
    v = mapping.get(rule[0])
    a = None if v is None else data.positions.get(v)
    if a is None:
        return None, None
    d = end - np.asarray(a, float)
    n = float(np.linalg.norm(d))
    return (None, None) if n == 0 else (d / n, float(rule[1]))


def squared_distances(volume: np.ndarray, box=None):
    """Squared Euclidean distance transform of ``volume`` (bool grid) on its bounding box
    padded by one empty voxel: ``(dt², lo)``, voxel ``ijk`` of the grid at ``dt²[ijk - lo + 1]``
    (whole numbers, float32); None when the volume is empty. ``box``: the bounding box
    ``(lo, hi)`` if known (:func:`hull_box`). Its square root is :func:`inscribed_distances`;
    at a voxel it is :func:`topopose.skeleton.prune.ball_radius` squared (the padding is
    background, nearer than any background beyond it)."""
    import edt

    box = _box(volume) if box is None else box
    if box is None:
        return None
    lo, hi = box
    sub = volume[tuple(slice(a, b) for a, b in zip(lo, hi))]
    sub = np.pad(sub.view(np.uint8) if sub.dtype == bool else sub.astype(np.uint8), 1)
    return edt.edtsq(sub, black_border=False, parallel=1), lo     # = scipy's, 2–6× faster


def inscribed_distances(volume: np.ndarray, box=None, squared=None):
    """Euclidean distance transform of ``volume`` (bool grid) on its bounding box padded by one
    empty voxel: ``(dt, lo)``, voxel ``ijk`` of the grid at ``dt[ijk - lo + 1]``; None when the
    volume is empty. ``box``: the bounding box ``(lo, hi)`` if known (:func:`hull_box`);
    ``squared``: :func:`squared_distances` of ``volume`` if already computed. One per frame
    serves :func:`thick_top` and :func:`topopose.frame.anatomy.hull_radius`."""
    sq = squared_distances(volume, box) if squared is None else squared
    return None if sq is None else (np.sqrt(sq[0]), sq[1])   # = edt.edt, bit for bit


def thick_top(volume: np.ndarray, origin, voxel_size: float, up, min_fraction: float,
              min_voxels: float = 1.5, edt=None, ball: float = 0.0, reach: float = 1.5,
              tries: int = 4):
    """The highest point (along ``up``) of ``volume`` (bool grid) whose inscribed ball radius
    is at least ``min_fraction`` × the largest one (the trunk's), and that radius (world units);
    None when the volume is empty or that radius is below ``min_voxels`` voxels (a coarse grid
    cannot tell a head from an arm by thickness: body subject at 50³, ``HEAD_FROM_HULL``).
    ``edt``: :func:`inscribed_distances` of ``volume`` if already computed.

    The head of an upright subject is the highest *thick* part: hands and forearms raised
    beside or above it are thinner (see :func:`head_from_hull`). With ``ball`` > 0 the top
    must also have a ball of radius ≥ ``ball`` × the largest within ``reach`` × the largest
    radius (the head's centre below its crown): a raised fist as thick as ``min_fraction``
    has none (:data:`HEAD_BALL`); such a top and its neighbourhood are set aside and the next
    highest tried, ``tries`` times at most (then None)."""
    edt = inscribed_distances(volume) if edt is None else edt
    if edt is None:
        return None
    dt, lo = edt
    rmax = dt.max()
    if min_fraction * rmax < min_voxels:
        return None
    ijk = np.argwhere(dt >= min_fraction * rmax)
    pts = (ijk - 1 + lo) * voxel_size + np.asarray(origin, float)
    rad = dt[tuple(ijk.T)]
    h = pts @ np.asarray(up, float)
    keep = np.ones(len(pts), bool)
    for _ in range(max(1, tries) if ball > 0 else 1):
        if not keep.any():
            return None
        top = keep & (h >= h[keep].max() - voxel_size)   # the top layer's thick voxels: centroid
        c = pts[top].mean(axis=0)
        if ball <= 0:
            return c, float(rad[top].mean()) * voxel_size
        near = ((pts - c) ** 2).sum(axis=1) <= (reach * float(rmax) * voxel_size) ** 2
        if near.any() and rad[near].max() >= ball * rmax:
            return c, float(rad[top].mean()) * voxel_size
        keep &= ~near if near.any() else ~top    # a top of two clumps: centroid near neither
    return None


def head_from_hull(vol, up, anchor=None, min_fraction: float = 0.4, max_radii: float = 3.0,
                   edt=None, ball=None):
    """The head of an upright subject from the hull alone: from the highest thick point
    (:func:`thick_top`), where the direction from ``anchor`` (the torso part) through it leaves
    the hull (the crown), at most ``max_radii`` inscribed radii on; None for an empty hull or
    one too coarse (:func:`thick_top`).

    Thinning gives a head a branch only where the head stands out of the hull: with an arm
    raised beside a leaning head (and, with few cameras, the phantom volume between them) the
    head merges into the shoulder mass and the alignment puts the head part on the arm or on a
    phantom branch (real recording, frames 28–74: head errors 0.2–0.45 m, no data leaf within
    0.23 m of the head marker). Its figures: ``docs/decisions.md`` ("head from the hull").
    ``edt``: :func:`inscribed_distances` of the hull if already computed; ``ball``: ``(ball,
    reach, min_voxels)`` of :func:`thick_top` (:data:`HEAD_BALL`), None: off."""
    top = thick_top(vol.data, vol.origin, float(vol.voxel_size), up, min_fraction, edt=edt,
                    **({} if ball is None else {"ball": ball[0], "reach": ball[1],
                                                "min_voxels": ball[2]}))
    if top is None:
        return None
    c, r = top
    up = np.asarray(up, float)
    d = up / np.linalg.norm(up)
    if anchor is not None:
        v = c - np.asarray(anchor, float)
        if np.linalg.norm(v) > 0:
            d = v / np.linalg.norm(v)
    return exit_point(vol.data, vol.origin, float(vol.voxel_size), c, d, max_radii * r)


#: The head from the hull along the body's own axis, where no "up" is known (a model without
#: coordinate constraints: acrobatic, inverted subjects), per model: ``(head, anchor, lower end,
#: min_fraction, max_shift)``: the direction lower end → anchor (crotch → torso, junctions of the
#: alignment) replaces the up vector of :func:`head_from_hull` — the thick point of the hull
#: farthest along it, prolonged from the anchor to the hull's border — unless that point lies more
#: than ``max_shift`` × the hull's largest inscribed radius from the head placed so far (a torso on
#: the wrong part turns the axis). See :func:`head_along_axis`. Without it the head is the head
#: branch's tip (:data:`TIP_ANCHOR`), which falls short where the head's data vertex is no leaf (the
#: head merged with a raised arm: no tip at all) or the branch ends askew. Its figures:
#: docs/decisions.md.
HEAD_AXIS = {"human": ("head", "torso", "crotch", 0.4, 6.0)}


def head_along_axis(vol, parts: dict, rule, edt=None, ball=None):
    """The head of ``rule`` (:data:`HEAD_AXIS`) from the hull along the body's axis lower end →
    anchor (:func:`head_from_hull` with that axis as up), or None: anchor or lower end
    unplaced, no thick top, or farther than ``max_shift`` radii from ``parts``' head.
    ``edt``: :func:`inscribed_distances` of the hull."""
    head, anchor, lower, frac, max_shift = rule
    a, b = parts.get(anchor), parts.get(lower)
    if a is None or b is None:
        return None
    axis = np.asarray(a, float) - np.asarray(b, float)
    n = float(np.linalg.norm(axis))
    if n == 0:
        return None
    edt = inscribed_distances(vol.data) if edt is None else edt
    x = head_from_hull(vol, axis / n, a, frac, edt=edt, ball=ball)
    h = parts.get(head)
    if x is not None and h is not None and (
            np.linalg.norm(x - np.asarray(h, float))
            > max_shift * float(edt[0].max()) * float(vol.voxel_size)):
        return None
    return x


def free_leaves(data, mapping) -> list:
    """Positions (lists of 3 floats, rounded to 0.1 mm) of the data tree's leaves (degree-1
    vertices) that no model part was matched to: where a misplaced numbered part may really be
    (:func:`assign_identities`' ``candidates``)."""
    deg = {}
    for u, v, _ in data.edges:
        deg[u] = deg.get(u, 0) + 1
        deg[v] = deg.get(v, 0) + 1
    used = {v for v in mapping.values() if v is not None}
    return [[round(float(c), 4) for c in data.positions[v]] for v, d in sorted(deg.items())
            if d == 1 and v not in used and data.positions.get(v) is not None]
