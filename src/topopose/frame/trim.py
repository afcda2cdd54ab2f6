"""Limb ends in phantom volumes of the visual hull, trimmed back to where the silhouettes'
evidence ends (a sequence stage).

A visual hull is the largest volume consistent with the silhouettes (thesis §4.1): with few
cameras it keeps *phantom* volume, and a limb's skeleton branch can run past the real hand
into it — on the real 4-camera recording the right arm's branch passes the hand and continues
through a tube in front of the chest that the two cameras seeing the hand against the
background look along, and that the other two see inside the trunk (``studies/real_hands.py``);
on the synthetic 4-camera walks a hand's branch often continues down a thigh or along a ray
(``studies/phantom.py``). Such an extension is inside every silhouette but *explains nothing*:
the skeleton without it covers the same silhouette pixels. Per frame and per limb end of
:data:`STEMS`, in every camera the skeleton curves (``diagnostics["curves"]``) are projected
with, at each curve point, the disk of its silhouette depth (the distance to the silhouette's
border at its image: the medial-axis disks of the silhouette that curve point reaches). Walking
back from the limb end, a curve point is *explained* when, in every camera, its disk lies inside
(up to :data:`SLACK` projected voxels) the disk of a point of another curve or of the same curve
at least :data:`GAP` voxels before it along the curve. The end moves back to the last point that
is not explained (at most to :data:`MIN_FRACTION` of the curve) plus its disk's radius (the
limb's end lies one radius past its last maximal disk; its smallest over the views, in space),
when that is more than a voxel back; the curve is cut there, and the part is listed in
``diagnostics["trimmed"]``. A point along the rays of the cameras that see it
against the background and inside the trunk in the others is explained (its disk is the same as
the one before it, or inside the trunk's); a real hand is not, in a camera that sees it beside
the body (its disk reaches pixels no earlier point reaches).

The silhouettes are at hand only while a frame is estimated: :class:`~.estimate.FrameEstimator`
records the trimmed curves (``diagnostics["trim"]``, :func:`trimmed_curves`; the frame's parts
and confidence are unchanged), and the sequence stage applies them after the identities
(:func:`apply_trim`, :func:`topopose.sequence.motion.process_sequence`), so a resumed or parallel
run trims as well. Development seeds 41–50, ``studies/phantom.py``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from topopose.frame.curves import N_SAMPLES, arc_lengths, resample
from topopose.pose.model import part_stem

STEMS = ("hand",)      # limb ends whose branch is trimmed; the feet too: no better (below)
SLACK = 1.5            # projected voxels: a disk inside another up to this is inside it
GAP = 2.0              # voxels along the curve: a point is not explained by its own neighbours
# SLACK / GAP: a stretch of curve within asin(SLACK / GAP) = 49° of a camera's rays adds no disk in
# that view. Its figures: docs/decisions.md.
MIN_FRACTION = 0.5     # the end moves back at most to this fraction of its curve
UPSAMPLE = 4           # curve points per stored sample while walking back


def _at_end(part, curves, parts) -> bool:
    """Whether ``part`` is placed at its curve's end (not held or snapped elsewhere)."""
    return (part in curves and parts.get(part) is not None
            and np.linalg.norm(np.asarray(curves[part][-1], float)
                               - np.asarray(parts[part], float)) < 1e-4)


def voxel_size(pose) -> float | None:
    """The hull's voxel edge from the frame's diagnostics (``hull_litres`` over ``hull_voxels``,
    litres of a capture in metres; None when they are missing)."""
    d = pose.diagnostics
    lit, n = d.get("hull_litres"), d.get("hull_voxels")
    if not lit or not n:
        return None
    return float((float(lit) / 1000.0 / float(n)) ** (1.0 / 3.0))


def silhouette_depth(mask):
    """The silhouette's depth map (distance to the background, px; exact Euclidean) over its
    bounding box and one pixel of background around it, and the box's corner ``(x0, y0)``:
    ``(depth, (x0, y0))``. Equal to the whole image's map inside the box (a pixel's nearest
    background outside the box is no nearer than the ring around it) at a fraction of its cost.
    """
    import cv2

    from topopose.geometry.masks import mask_box

    x, y, w, h = mask_box(mask)
    m = np.asarray(mask).view(np.uint8) if np.asarray(mask).dtype == bool else \
        np.asarray(mask, np.uint8)
    if w == 0:
        return np.zeros((0, 0), np.float32), (0, 0)
    x0, y0 = max(x - 1, 0), max(y - 1, 0)
    x1, y1 = min(x + w + 1, m.shape[1]), min(y + h + 1, m.shape[0])
    crop = np.ascontiguousarray(m[y0:y1, x0:x1])
    return cv2.distanceTransform(crop, cv2.DIST_L2, cv2.DIST_MASK_PRECISE), (x0, y0)


def disks(points, camera, depth):
    """Image positions (n, 2) of ``points`` in ``camera`` and their disks' radii (n,): the
    silhouette depth map ``depth`` (distance to the background, px; an array, or
    :func:`silhouette_depth`'s ``(map, corner)``) at the nearest pixel; 0 outside it, NaN
    positions behind the camera."""
    depth, (x0, y0) = depth if isinstance(depth, tuple) else (depth, (0, 0))
    uv = camera.project(np.asarray(points, float))
    rad = np.zeros(len(uv))
    ok = np.isfinite(uv).all(axis=1)
    x = np.full(len(uv), -1)
    y = np.full(len(uv), -1)
    x[ok] = np.rint(uv[ok, 0]).astype(int) - x0
    y[ok] = np.rint(uv[ok, 1]).astype(int) - y0
    inside = ok & (x >= 0) & (y >= 0) & (x < depth.shape[1]) & (y < depth.shape[0])
    rad[inside] = depth[y[inside], x[inside]]
    return uv, rad


def evidence_end(curve, others, cameras, depths, voxel, slack=None, gap=None,
                 min_fraction=None) -> tuple:
    """Index into ``curve`` of its last point not explained (module docstring), and that
    point's radius (capture units: its smallest disk over the views, in voxels × ``voxel``).

    Parameters
    ----------
    curve : (n, 3) the limb's curve, from its junction to the limb end
    others : list of (m, 3) the frame's other curves
    cameras : list of Camera
    depths : list of silhouette depth maps (px to the background), one per camera: arrays of
        the image's size or :func:`silhouette_depth`'s ``(map, corner)``
    voxel : the hull's voxel edge (capture units)

    Returns
    -------
    (int, float) : the index is ``n - 1`` when the end is explained by nothing else.
    """
    slack = SLACK if slack is None else slack
    gap = GAP if gap is None else gap
    min_fraction = MIN_FRACTION if min_fraction is None else min_fraction
    c = np.asarray(curve, float)
    n = len(c)
    s = arc_lengths(c)
    rest = [np.asarray(o, float) for o in others if len(o)]
    rest = np.concatenate(rest) if rest else np.zeros((0, 3))
    views = []
    for cam, dep in zip(cameras, depths):
        uv, rad = disks(c, cam, dep)
        z = cam.to_camera(c)[:, 2]
        px = float(cam.matrix[0, 0]) * voxel / np.maximum(z, 1e-9)   # a voxel, in px
        ouv, orad = disks(rest, cam, dep) if len(rest) else (np.zeros((0, 2)), np.zeros(0))
        keep = np.isfinite(ouv).all(axis=1)
        views.append((uv, rad, px, ouv[keep], orad[keep]))

    def radius(j):
        r = [rad[j] / px[j] for uv, rad, px, _, _ in views if rad[j] > 0]
        return float(min(r) * voxel) if r else 0.0

    j = n - 1
    stop = int(min_fraction * (n - 1))
    while j > stop:
        before = int(np.searchsorted(s, s[j] - gap * voxel, side="right"))
        for uv, rad, px, ouv, orad in views:
            if not np.isfinite(uv[j]).all() or rad[j] <= 0:
                return j, radius(j)               # outside a view: evidence we cannot judge
            lim = rad[j] - slack * px[j]
            d = np.linalg.norm(uv[:before] - uv[j], axis=1) + lim
            if not (before and np.any(d <= rad[:before])):
                d = np.linalg.norm(ouv - uv[j], axis=1) + lim
                if not np.any(d <= orad):
                    return j, radius(j)
        j -= 1
    return j, radius(j)


def trimmed_curves(curves, parts, cameras, silhouettes, voxel, stems=None, **kw) -> dict:
    """Per limb end of ``stems`` (default :data:`STEMS`) whose curve ends in unexplained volume
    (module docstring): its curve cut back, ``N_SAMPLES`` points from the junction to the new
    end. Only parts placed at their curve's end are judged.

    Parameters
    ----------
    curves : {part: (n, 3)} the frame's skeleton curves (``diagnostics["curves"]``)
    parts : {part: (3,) or None} the placed parts
    cameras, silhouettes : the frame's cameras and boolean silhouettes, as compared
        (:func:`topopose.frame.support.compared_views`)
    voxel : the hull's voxel edge (capture units)

    Examples
    --------
    >>> trimmed_curves({}, {}, [], [], 0.02)
    {}
    """
    stems = STEMS if stems is None else stems
    todo = [q for q in curves if part_stem(q) in stems and _at_end(q, curves, parts)]
    if not todo or not voxel:
        return {}
    depths = [silhouette_depth(m) for m in silhouettes]
    up = {q: resample(np.asarray(c, float), UPSAMPLE * len(c)) for q, c in curves.items()}
    out = {}
    for q in todo:
        others = [c for r, c in up.items() if r != q and part_stem(r) != part_stem(q)]
        c = up[q]
        j, r = evidence_end(c, others, cameras, depths, voxel, **kw)
        s = arc_lengths(c)
        end = s[j] + r                  # the limb's end: its last disk's reach along the curve
        if end < s[-1] - voxel:
            cut = np.vstack([c[s < end], [np.interp(end, s, c[:, i]) for i in range(3)]])
            out[q] = np.round(resample(cut, N_SAMPLES), 5)
    return out


def apply_trim(pose):
    """``pose`` with each part of ``diagnostics["trim"]`` still at its curve's end moved to the
    trimmed curve's end, the curve replaced, and the part listed in ``diagnostics["trimmed"]``
    (the sequence stage); the pose itself when nothing moves. The curve's centre-line offsets
    (``diagnostics["centred"]``, :mod:`.centre`) become the trimmed curve's
    (``diagnostics["centred_trim"]``)."""
    trim = pose.diagnostics.get("trim") or {}
    curves = pose.diagnostics.get("curves") or {}
    parts, new_curves, moved = dict(pose.parts), dict(curves), []
    cen = dict(pose.diagnostics.get("centred") or {})
    cen_trim = pose.diagnostics.get("centred_trim") or {}
    for q, cut in trim.items():
        if _at_end(q, curves, parts):
            new_curves[q] = np.asarray(cut, float)
            parts[q] = new_curves[q][-1].copy()
            moved.append(q)
            cen.pop(q, None)            # the trimmed curve's own centre-line offsets, if any
            if q in cen_trim:
                cen[q] = cen_trim[q]
    if not moved:
        return pose
    diag = {**pose.diagnostics, "curves": new_curves, "trimmed": moved}
    if cen or "centred" in diag:
        diag["centred"] = cen
    return replace(pose, parts=parts, diagnostics=diag)


def trim_pose(pose, cameras, silhouettes, stems=None, **kw):
    """:func:`trimmed_curves` and :func:`apply_trim` at once, on a pose and its frame's views;
    the voxel edge from the pose's diagnostics (:func:`voxel_size`)."""
    d = pose.diagnostics
    cut = trimmed_curves(d.get("curves") or {}, pose.parts, cameras, silhouettes,
                         voxel_size(pose), stems, **kw)
    return apply_trim(replace(pose, diagnostics={**d, "trim": cut})) if cut else pose
