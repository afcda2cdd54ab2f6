"""Limb skeleton curves moved onto the silhouettes' centre lines (thesis §13.3.1).

With few cameras the visual hull keeps phantom volume (thesis §4.1) and its curve skeleton is
pulled off a limb's axis, while each silhouette is exact. Per frame, for every sample of the
skeleton curve (``diagnostics["curves"]``, :mod:`.curves`) of a limb arc (:data:`STEMS`), in
each camera the sample and its local curve direction are projected, and the silhouette is
scanned across the projected curve (perpendicular to it, both ways) to the limb's two contour
crossings. Their midpoint is that view's 2D centre observation when the limb is seen alone
there: both crossings found within :data:`SCAN` × the hull's inscribed radius at the sample
(projected), and the width (in capture units at the sample's depth) at most :data:`HULL_WIDTH` ×
twice that radius and :data:`VIEW_WIDTH` × the narrowest view's — a limb crossing the trunk or
another limb in a view is wider there and gives no observation.

An observation says the limb's axis lies in the plane through the camera centre and the 2D
line along the projected curve through the centre point; with the projection linearised at the
sample (its Jacobian ``J``, lens distortion included), the image normal ``n`` of the projected
curve and the centre's offset ``c`` along it: ``nᵀ J δ = c``. The sample moves by the
least-squares ``δ`` over its views' planes, perpendicular to the curve only, bounded by
:data:`MAX_SHIFT` × the local radius; a sample seen by fewer than :data:`MIN_VIEWS` (two)
views stays, one seen by views whose planes are nearly parallel (:data:`MIN_SPREAD`) moves
only along the one direction they constrain. :data:`ITERATIONS` such steps.

Samples thicker than :data:`LIMB_RADIUS` × the hull's largest inscribed radius (the trunk's;
a hand's curve begins at the chest) are left. The result is recorded per frame by
:class:`~.estimate.FrameEstimator` (``centre=True``; ``topopose run`` by default,
:data:`topopose.batch.run.CENTRE`) as ``diagnostics["centred"]``: per limb
part, the offsets (n, 3) of its curve's samples (the frame's parts, statuses, confidence and
``curves`` unchanged), and ``diagnostics["centred_trim"]`` for the hands' trimmed curves
(:mod:`.trim`); the kinematic fit adds them to the curves (:func:`topopose.sequence.kinematic_fit.
frame_curves`, :data:`~topopose.sequence.kinematic_fit.CENTRED`).
"""
from __future__ import annotations

import numpy as np

from topopose.pose.model import part_stem

STEMS = ("hand", "foot")     # limb arcs whose curves are centred
SCAN = 3.0                   # × the projected inscribed radius: how far the scan looks each way
HULL_WIDTH = 1.3             # a view's width ≤ this × 2 × the hull's inscribed radius (+ 2 px)
VIEW_WIDTH = 1.5             # … and ≤ this × the narrowest accepting view's width
LIMB_RADIUS = 0.6            # samples thicker than this × the largest inscribed radius: trunk
MAX_SHIFT = 1.0              # × the local inscribed radius: the largest move of a sample
MIN_SPREAD = 0.1             # smallest eigenvalue of the views' normal matrix (unit normals)
ITERATIONS = 1               # steps (each from the moved samples; see the figures below)
MIN_VIEWS = 2                # fewer views observing a sample: it stays (1: moved along the one
                             # direction its views constrain)
STEP = 0.5                   # px along the scan
PAD = 2.0                    # px of width tolerance (pixel rounding of the contour)
# The constants' figures: docs/decisions.md (limbs' curves on the silhouettes' centre lines).


def tangents(curve) -> np.ndarray:
    """Unit tangents (n, 3) of a polyline (central differences, one-sided at its ends)."""
    c = np.asarray(curve, float)
    if len(c) < 2:
        return np.zeros_like(c)
    t = np.gradient(c, axis=0)
    n = np.linalg.norm(t, axis=1, keepdims=True)
    return np.where(n > 0, t / np.where(n > 0, n, 1.0), 0.0)


def jacobians(camera, points, h) -> tuple:
    """Image positions (N, 2) of ``points`` and the projection's Jacobians (N, 2, 3), forward
    differences of step ``h`` (lens distortion included)."""
    P = np.asarray(points, float)
    uv = camera.project(P)
    J = np.empty((len(P), 2, 3))
    for k in range(3):
        Q = P.copy()
        Q[:, k] += h
        J[:, :, k] = (camera.project(Q) - uv) / h
    return uv, J


def scan_widths(mask, uv, normal, half) -> tuple:
    """Per point: the silhouette run through ``uv`` (N, 2) along ``normal`` (N, 2, unit),
    looked for within ``half`` (N,) px each way: its two crossings' signed distances
    ``(lo, hi)`` (px along ``normal``; NaN when the point is outside the silhouette or a
    crossing lies beyond ``half``). A crossing is halfway between the last inside and the
    first outside sample (steps of :data:`STEP` px)."""
    from topopose.frame.centre_kernels import scan_runs

    n = len(uv)
    lo = np.full(n, np.nan)
    hi = np.full(n, np.nan)
    if not n:
        return lo, hi
    K = int(np.ceil(np.nanmax(np.where(np.isfinite(half), half, 0)) / STEP)) + 1
    scan_runs(np.asarray(mask, bool).view(np.uint8), np.asarray(uv, float),
              np.asarray(normal, float), np.asarray(half, float), STEP, K, lo, hi)
    return lo, hi


def centre_offsets(curves, cameras, silhouettes, radius, max_radius, voxel, stems=None,
                   iterations=None) -> dict:
    """Per limb part of ``stems`` (default :data:`STEMS`): the offsets (n, 3) that move its
    curve's samples onto the silhouettes' centre lines (module docstring); zero for a sample
    left where it was. Parts with no sample moved are left out.

    Parameters
    ----------
    curves : {part: (n, 3)} skeleton curves (``diagnostics["curves"]``)
    cameras, silhouettes : the frame's cameras and boolean silhouettes, as compared
        (:func:`topopose.frame.support.compared_views`)
    radius : callable (N, 3) → (N,) the hull's inscribed radius at points (capture units;
        :func:`topopose.frame.support.curve_radii`)
    max_radius : the hull's largest inscribed radius (capture units)
    voxel : the hull's voxel edge (capture units)

    Returns
    -------
    dict part → ndarray (n, 3)

    Examples
    --------
    >>> centre_offsets({}, [], [], lambda p: p[:, 0], 0.1, 0.02)
    {}
    """
    stems = STEMS if stems is None else stems
    its = ITERATIONS if iterations is None else iterations
    keys = [q for q, c in curves.items()
            if part_stem(q) in stems and c is not None and len(c) > 1]
    if not keys or not cameras or not voxel:
        return {}
    C = [np.asarray(curves[q], float) for q in keys]
    P0 = np.concatenate(C)
    T = np.concatenate([tangents(c) for c in C])
    R = np.asarray(radius(P0), float)
    use = (R > 0) & (R <= LIMB_RADIUS * max_radius) & (np.linalg.norm(T, axis=1) > 0)
    # a basis (N, 3, 2) of the plane perpendicular to each tangent
    a = np.where(np.abs(T[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    b1 = np.cross(T, a)
    b1 /= np.maximum(np.linalg.norm(b1, axis=1, keepdims=True), 1e-12)
    B = np.stack([b1, np.cross(T, b1)], axis=2)
    P = P0.copy()
    h = 0.1 * float(voxel)
    for _ in range(its):
        idx = np.flatnonzero(use)
        if not len(idx):
            break
        X, Tt, Rr, Bb = P[idx], T[idx], R[idx], B[idx]
        rows = []                     # per view: (normal rows (N, 2), rhs (N,), width (N,))
        for cam, S in zip(cameras, silhouettes):
            uv, J = jacobians(cam, X, h)
            d = np.einsum("nij,nj->ni", J, Tt)
            dn = np.linalg.norm(d, axis=1)
            z = cam.to_camera(X)[:, 2]
            f = float(cam.matrix[0, 0])
            ppu = f / np.where(z > 0, z, np.nan)                    # px per capture unit
            ok = np.isfinite(uv).all(axis=1) & (dn > 1e-9) & (z > 0)
            nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.where(dn > 1e-9, dn, 1.0)[:, None]
            half = np.where(ok, SCAN * Rr * ppu + PAD, 0.0)
            lo, hi = scan_widths(S, np.where(ok[:, None], uv, 0.0), nrm, half)
            width = (hi - lo) / ppu                                 # capture units
            centre = 0.5 * (hi + lo)                                # px along nrm
            good = ok & np.isfinite(width) & (width <= HULL_WIDTH * 2 * Rr + PAD / ppu)
            g = np.einsum("ni,nij->nj", nrm, J)                     # nᵀJ (N, 3), px per unit
            gn = np.linalg.norm(g, axis=1)
            good &= gn > 0
            gB = np.einsum("nj,njk->nk", g, Bb) / np.where(gn > 0, gn, 1.0)[:, None]
            rhs = centre / np.where(gn > 0, gn, 1.0)                 # capture units
            rows.append((good, gB, rhs, np.where(good, width, np.inf)))
        narrow = np.min([w for *_, w in rows], axis=0)
        A = np.zeros((len(idx), 2, 2))
        v = np.zeros((len(idx), 2))
        cnt = np.zeros(len(idx), int)
        for good, gB, rhs, w in rows:
            k = good & (w <= VIEW_WIDTH * narrow)
            A[k] += gB[k, :, None] * gB[k, None, :]
            v[k] += gB[k] * rhs[k, None]
            cnt += k
        lam = np.linalg.eigvalsh(A)[:, 0]
        solve = (cnt >= 2) & (lam >= MIN_SPREAD)
        # nearly parallel views (or, with MIN_VIEWS 1, one view): the move along the one
        # direction they constrain (the least-norm solution)
        part = (cnt >= MIN_VIEWS) & ~solve & (cnt > 0)
        if not (solve.any() or part.any()):
            break
        y = np.zeros((len(idx), 2))
        y[solve] = np.linalg.solve(A[solve], v[solve][..., None])[..., 0]
        if part.any():
            w, E = np.linalg.eigh(A[part])
            e = E[:, :, 1]                                         # the constrained direction
            y[part] = e * (np.einsum("ni,ni->n", e, v[part]) / np.maximum(w[:, 1], 1e-12))[:, None]
        step = np.einsum("nkj,nj->nk", Bb, y)
        P[idx] = X + step
        # bounded: at most MAX_SHIFT × the radius from the curve's own sample, across it
        off = P[idx] - P0[idx]
        off -= np.einsum("ni,ni->n", off, Tt)[:, None] * Tt
        n = np.linalg.norm(off, axis=1)
        cap = MAX_SHIFT * Rr
        off *= np.where(n > cap, cap / np.maximum(n, 1e-12), 1.0)[:, None]
        P[idx] = P0[idx] + off
    off = P - P0
    out, i = {}, 0
    for q, c in zip(keys, C):
        o = off[i:i + len(c)]
        i += len(c)
        if np.any(o != 0):
            out[q] = o
    return out


def frame_offsets(curves, trim, cameras, silhouettes, occ, origin, voxel, edt=None) -> tuple:
    """:func:`centre_offsets` of a frame's curves and of its hands' trimmed curves
    (``diagnostics["trim"]``), the radii from the hull ``occ`` (its inscribed distances
    ``edt``, :func:`topopose.frame.tips.inscribed_distances`, if already computed):
    ``(centred, centred_trim)`` dicts part → list of [x, y, z] offsets rounded to 0.1 mm."""
    from topopose.frame.support import curve_radii
    from topopose.frame.tips import inscribed_distances

    if edt is None:
        edt = inscribed_distances(occ)
    if edt is None:
        return {}, {}
    big = float(edt[0].max()) * float(voxel)

    def radius(p):
        return curve_radii(p, occ, np.asarray(origin, float), voxel, edt)

    def packed(d):
        return {q: np.round(o, 4).tolist() for q, o in d.items()}

    a = centre_offsets(curves, cameras, silhouettes, radius, big, voxel)
    b = (centre_offsets(trim, cameras, silhouettes, radius, big, voxel) if trim else {})
    return packed(a), packed(b)
