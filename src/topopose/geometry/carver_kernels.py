"""Numba kernels of the hierarchical visual-hull carver (see :mod:`topopose.geometry.carver`).

Packed inputs (built by :class:`~topopose.geometry.carver.HullCarver`):

- ``geo`` (C, 12): per camera, camera coordinates of voxel (0, 0, 0)'s centre (3), then the
  camera-coordinate steps of +1 voxel along i, j, k (3 × 3).
- ``intr`` (C, 16): fx, fy, cx, cy, skew, d0..d4 (distortion coefficients), model (0 pinhole,
  1 OpenCV radial-tangential, 2 fisheye), r2max (largest valid squared normalized radius),
  w, h, S (the image row stride of :func:`_pixel`'s flat index), unused.
- masks: one flat uint8 array, camera c's mask crop at ``moff[c]`` with rows of its width
  ``crop[c, 2]``; summed-area tables: one flat int32 array, camera c's table at ``soff[c]`` with
  rows of ``crop[c, 2] + 1``.
- rects: int32 (n, 4) inclusive pixel rectangles (x0, y0, x1, y1), one per (block, camera), for
  block levels ``lmin..lmax``; level ``l`` block (a, b, c) of camera ``q`` is row
  ``loff[l - lmin] + ((a * dims[.., 1] + b) * dims[.., 2] + c) * C + q``. ``x0 == INVALID``: the
  block's projection is unknown for that camera (a corner behind it or outside its valid lens
  field), so the camera cannot decide the block.

:func:`carve` takes them as three bundles, :class:`Cameras`, :class:`Silhouettes` and
:class:`Blocks`, passed as plain tuples in the named tuple's field order (Numba's dispatcher
types a plain tuple on its fast path).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

INVALID = -(2**31)


class Cameras(NamedTuple):
    """The cameras, packed: ``geo`` (C, 12) and ``intr`` (C, 16)."""

    geo: np.ndarray
    intr: np.ndarray


class Silhouettes(NamedTuple):
    """One frame's masks and summed-area tables: the flat buffers with each camera's offset,
    and per camera its mask's reduction factors ``fac`` (C, 2) and crop ``crop`` (C, 4)."""

    mflat: np.ndarray
    moff: np.ndarray
    sflat: np.ndarray
    soff: np.ndarray
    fac: np.ndarray
    crop: np.ndarray


class Blocks(NamedTuple):
    """The block rectangles of levels ``lmin..lmax``: ``rects``, each level's first row
    ``loff`` and its block grid ``ldims`` (levels, 3)."""

    rects: np.ndarray
    loff: np.ndarray
    ldims: np.ndarray
    lmin: int
    lmax: int


@njit(cache=True, inline="always")
def _distort(a, b, r2, intr, c):
    """Lens distortion of normalized coordinates (a, b), r2 = a² + b², for camera c:
    ``intr[c, 10]`` = 0 none, 1 OpenCV radial-tangential (k1, k2, p1, p2, k3 in ``intr[c, 5:10]``),
    2 fisheye (k1..k4 in ``intr[c, 5:9]``) — the model of ``Camera.project``."""
    model = intr[c, 10]
    if model == 1.0:
        k1 = intr[c, 5]
        k2 = intr[c, 6]
        p1 = intr[c, 7]
        p2 = intr[c, 8]
        k3 = intr[c, 9]
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a),
                b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b)
    if model == 2.0:
        r = math.sqrt(r2)
        if r > 1e-12:
            th = math.atan(r)
            t2 = th * th
            thd = th * (1.0 + t2 * (intr[c, 5] + t2 * (intr[c, 6] + t2 * (intr[c, 7] + t2 * intr[c, 8]))))
            s = thd / r
            return a * s, b * s
    return a, b


@njit(cache=True, inline="always")
def _pixel(geo, intr, c, fi, fj, fk):
    """Pixel index (row · S + column) of voxel (fi, fj, fk)'s centre in camera c, or -1 when not
    in the image."""
    u, v = _pixel_uv(geo, intr, c, fi, fj, fk)
    return -1 if u < 0 else v * int(intr[c, 14]) + u


@njit(cache=True, inline="always")
def _pixel_uv(geo, intr, c, fi, fj, fk):
    """Column and row of voxel (fi, fj, fk)'s centre in camera c (:func:`_pixel`'s), or
    (-1, -1) when not in the image."""
    x = geo[c, 0] + fi * geo[c, 3] + fj * geo[c, 6] + fk * geo[c, 9]
    y = geo[c, 1] + fi * geo[c, 4] + fj * geo[c, 7] + fk * geo[c, 10]
    z = geo[c, 2] + fi * geo[c, 5] + fj * geo[c, 8] + fk * geo[c, 11]
    if not z > 0.0:
        return -1, -1
    iz = 1.0 / z
    a = x * iz
    b = y * iz
    r2 = a * a + b * b
    if r2 > intr[c, 11]:
        return -1, -1
    a, b = _distort(a, b, r2, intr, c)
    u = intr[c, 0] * a + intr[c, 4] * b + intr[c, 2] + 0.5
    v = intr[c, 1] * b + intr[c, 3] + 0.5
    w = intr[c, 12]
    h = intr[c, 13]
    if not (u >= 0.0 and u < w and v >= 0.0 and v < h):
        return -1, -1
    return int(u), int(v)


@njit(cache=True)
def project_voxels(geo, intr, ijk):
    """Flat pixel index (or -1) of each voxel centre ``ijk`` (n, 3) in every camera → (n, C)."""
    n = ijk.shape[0]
    C = geo.shape[0]
    out = np.empty((n, C), dtype=np.int64)
    for p in range(n):
        for c in range(C):
            out[p, c] = _pixel(geo, intr, c, ijk[p, 0], ijk[p, 1], ijk[p, 2])
    return out


@njit(cache=True)
def _rect_state(rects, row, sflat, soff, w, h, W, fx=1, fy=1, ox=0, oy=0, cw=1 << 30,
                ch=1 << 30):
    """0: all outside the silhouette, 1: all inside, 2: undecided (mixed or unknown).
    ``fx``, ``fy`` > 1: the summed-area table is that of a mask ``fx`` × ``fy`` times smaller
    whose nearest-neighbour upsampling (pixel (u, v) → (u // fx, v // fy)) is the silhouette:
    the rectangle covers exactly the small pixels ``x0 // fx`` … ``x1 // fx`` (rows alike), so
    the answer is the one the full-size table gives. The table covers the mask's crop
    ``ox … ox + cw − 1`` × ``oy … oy + ch − 1`` (mask pixels), outside which no pixel is set:
    the rectangle's count is that of its part in the crop, and it is all inside only when that
    count fills the whole rectangle — the answers of the whole mask's table."""
    x0 = rects[row, 0]
    if x0 == INVALID:
        return 2
    y0 = rects[row, 1]
    x1 = rects[row, 2]
    y1 = rects[row, 3]
    cx0 = max(x0, 0)
    cy0 = max(y0, 0)
    cx1 = min(x1, w - 1)
    cy1 = min(y1, h - 1)
    if cx0 > cx1 or cy0 > cy1:
        return 0
    sx0, sx1, sy0, sy1 = cx0, cx1, cy0, cy1
    if fx != 1:
        sx0 = cx0 // fx
        sx1 = cx1 // fx
    if fy != 1:
        sy0 = cy0 // fy
        sy1 = cy1 // fy
    ix0 = max(sx0, ox) - ox
    ix1 = min(sx1, ox + cw - 1) - ox
    iy0 = max(sy0, oy) - oy
    iy1 = min(sy1, oy + ch - 1) - oy
    if ix0 > ix1 or iy0 > iy1:
        return 0
    s = (sflat[soff + (iy1 + 1) * W + ix1 + 1] - sflat[soff + iy0 * W + ix1 + 1]
         - sflat[soff + (iy1 + 1) * W + ix0] + sflat[soff + iy0 * W + ix0])
    if s == 0:
        return 0
    if (s == (sx1 - sx0 + 1) * (sy1 - sy0 + 1) and cx0 == x0 and cy0 == y0
            and cx1 == x1 and cy1 == y1):
        return 1
    return 2


@njit(cache=True)
def carve(cams, sil, blocks, tolerance, levels, out, stats):
    """Hierarchical carving of the volumetric visual hull (thesis §2.3.2.2).

    A voxel is set in ``out`` (uint8, (nx, ny, nz), zeroed by the caller) when its centre
    projects inside the silhouette in at least C − ``tolerance`` cameras: to 1, or with ``levels`` to 2 when all C
    cameras see it as subject (the strict hull, tolerance 0) and 1 otherwise — the strict and
    the tolerant hull in one pass (an all-inside block's miss count is exact; an undecided
    voxel counts its misses exactly up to the early exit at ``tolerance + 1``). Blocks of 2^l voxels are classified per
    camera by their projected bounding rectangle against the summed-area table: all-outside
    (the camera rejects every voxel of the block), all-inside (it accepts every voxel), or
    undecided; undecided blocks are split in 8 down to level ``lmin``, whose voxels are tested
    one by one by exact projection (distortion included) with early exit.

    ``sil.fac`` (int64, (C, 2)): per camera, the integer factors (fx, fy) by which its mask and
    table are smaller than its image ((1, 1): full size); the silhouette is the mask's
    nearest-neighbour upsampling, pixel (u, v) reading mask pixel (u // fx, v // fy), so the
    hull is the one the upsampled mask gives, without building it (:func:`_rect_state`).

    ``sil.crop`` (int64, (C, 4)): per camera, the part of its mask (ox, oy, cw, ch, in the mask's
    own pixels) that the buffers hold (packed, rows of the crop's width), outside which the mask
    is empty: the silhouette's bounding box, so that a frame's buffers and tables cost its
    subject's pixels, not the image's.

    ``stats`` (int64, 12): block tests, voxel tests, projections, full blocks, empty blocks,
    set voxels, and the bounding box of set voxels is written to ``stats[6:12]`` (imin, jmin, kmin, imax,
    jmax, kmax; imin > imax when nothing is set).
    """
    nx, ny, nz = out.shape
    geo, intr = cams
    mflat, moff, sflat, soff, fac, crop = sil
    rects, loff, ldims, lmin, lmax = blocks
    C = geo.shape[0]
    nlev = lmax - lmin + 1
    tdims = ldims[nlev - 1]
    ntop = tdims[0] * tdims[1] * tdims[2]
    cap = ntop + 8 * (nlev + 1)
    st_l = np.empty(cap, np.int64)
    st_a = np.empty(cap, np.int64)
    st_b = np.empty(cap, np.int64)
    st_c = np.empty(cap, np.int64)
    st_act = np.empty(cap, np.int64)
    st_miss = np.empty(cap, np.int64)
    ws = np.empty(C, np.int64)
    hs = np.empty(C, np.int64)
    for c in range(C):
        ws[c] = int(intr[c, 12])
        hs[c] = int(intr[c, 13])
    allcams = (1 << C) - 1
    top = 0
    for a in range(tdims[0]):
        for b in range(tdims[1]):
            for cc in range(tdims[2]):
                st_l[top] = lmax
                st_a[top] = a
                st_b[top] = b
                st_c[top] = cc
                st_act[top] = allcams
                st_miss[top] = 0
                top += 1
    nblock = 0
    nvox = 0
    nproj = 0
    nfull = 0
    nempty = 0
    nset = 0
    bmin0 = nx
    bmin1 = ny
    bmin2 = nz
    bmax0 = -1
    bmax1 = -1
    bmax2 = -1
    while top > 0:
        top -= 1
        lev = st_l[top]
        a = st_a[top]
        b = st_b[top]
        cc = st_c[top]
        act = st_act[top]
        miss = st_miss[top]
        li = lev - lmin
        d1 = ldims[li, 1]
        d2 = ldims[li, 2]
        base = loff[li] + ((a * d1 + b) * d2 + cc) * C
        nblock += 1
        for c in range(C):
            if (act >> c) & 1:
                s = _rect_state(rects, base + c, sflat, soff[c], ws[c], hs[c], crop[c, 2] + 1,
                                fac[c, 0], fac[c, 1], crop[c, 0], crop[c, 1], crop[c, 2],
                                crop[c, 3])
                if s == 0:
                    miss += 1
                    act &= ~(1 << c)
                    if miss > tolerance:
                        break
                elif s == 1:
                    act &= ~(1 << c)
        if miss > tolerance:
            nempty += 1
            continue
        size = 1 << lev
        i0 = a * size
        j0 = b * size
        k0 = cc * size
        i1 = min(i0 + size, nx)
        j1 = min(j0 + size, ny)
        k1 = min(k0 + size, nz)
        if act == 0:
            nfull += 1
            val = 2 if (levels and miss == 0) else 1
            nset += (i1 - i0) * (j1 - j0) * (k1 - k0)
            for i in range(i0, i1):
                for j in range(j0, j1):
                    for k in range(k0, k1):
                        out[i, j, k] = val
            bmin0 = min(bmin0, i0)
            bmin1 = min(bmin1, j0)
            bmin2 = min(bmin2, k0)
            bmax0 = max(bmax0, i1 - 1)
            bmax1 = max(bmax1, j1 - 1)
            bmax2 = max(bmax2, k1 - 1)
            continue
        if lev > lmin:
            half = size >> 1
            for da in range(2):
                if i0 + da * half >= nx:
                    continue
                for db in range(2):
                    if j0 + db * half >= ny:
                        continue
                    for dc in range(2):
                        if k0 + dc * half >= nz:
                            continue
                        st_l[top] = lev - 1
                        st_a[top] = 2 * a + da
                        st_b[top] = 2 * b + db
                        st_c[top] = 2 * cc + dc
                        st_act[top] = act
                        st_miss[top] = miss
                        top += 1
            continue
        # finest block level: exact per-voxel test of the undecided cameras
        for i in range(i0, i1):
            for j in range(j0, j1):
                for k in range(k0, k1):
                    nvox += 1
                    m = miss
                    for c in range(C):
                        if (act >> c) & 1:
                            nproj += 1
                            pu, pv = _pixel_uv(geo, intr, c, float(i), float(j), float(k))
                            p = -1                      # not in the image, or outside the crop
                            if pu >= 0:
                                if fac[c, 0] != 1:
                                    pu //= fac[c, 0]
                                if fac[c, 1] != 1:
                                    pv //= fac[c, 1]
                                pu -= crop[c, 0]
                                pv -= crop[c, 1]
                                if pu >= 0 and pv >= 0 and pu < crop[c, 2] and pv < crop[c, 3]:
                                    p = pv * crop[c, 2] + pu
                            if p < 0 or mflat[moff[c] + p] == 0:
                                m += 1
                                if m > tolerance:
                                    break
                    if m <= tolerance:
                        out[i, j, k] = 2 if (levels and m == 0) else 1
                        nset += 1
                        bmin0 = min(bmin0, i)
                        bmin1 = min(bmin1, j)
                        bmin2 = min(bmin2, k)
                        bmax0 = max(bmax0, i)
                        bmax1 = max(bmax1, j)
                        bmax2 = max(bmax2, k)
    stats[0] = nblock
    stats[1] = nvox
    stats[2] = nproj
    stats[3] = nfull
    stats[4] = nempty
    stats[5] = nset
    stats[6] = bmin0
    stats[7] = bmin1
    stats[8] = bmin2
    stats[9] = bmax0
    stats[10] = bmax1
    stats[11] = bmax2


@njit(cache=True)
def _uv(geo, intr, c, fi, fj, fk, out2):
    """Sub-pixel coordinates of the point (fi, fj, fk) (voxel index units) in camera c, written
    to ``out2``; False when the point is behind the camera or beyond the lens' valid field.
    Same model as :func:`_pixel` (and ``Camera.project``)."""
    x = geo[c, 0] + fi * geo[c, 3] + fj * geo[c, 6] + fk * geo[c, 9]
    y = geo[c, 1] + fi * geo[c, 4] + fj * geo[c, 7] + fk * geo[c, 10]
    z = geo[c, 2] + fi * geo[c, 5] + fj * geo[c, 8] + fk * geo[c, 11]
    if not z > 0.0:
        return False
    a = x / z
    b = y / z
    r2 = a * a + b * b
    if r2 > intr[c, 11]:
        return False
    a, b = _distort(a, b, r2, intr, c)
    out2[0] = intr[c, 0] * a + intr[c, 4] * b + intr[c, 2]
    out2[1] = intr[c, 1] * b + intr[c, 3]
    return True


@njit(cache=True)
def block_rects(geo, intr, c, block, nb0, nb1, nb2, margin, clamp, out):
    """Inclusive pixel rectangles of the blocks of ``block`` voxels in camera c → ``out``
    (nb0, nb1, nb2, 4) int64: the box of the projected corners of each block's voxel extents
    (indices a·block − ½ … (a + 1)·block − ½), widened by ``margin`` pixels; ``INVALID`` when a
    corner is not validly projected."""
    n0, n1, n2 = nb0 + 1, nb1 + 1, nb2 + 1
    u = np.empty((n0, n1, n2))
    v = np.empty((n0, n1, n2))
    ok = np.empty((n0, n1, n2), np.bool_)
    tmp = np.empty(2)
    for a in range(n0):
        fi = -0.5 + block * a
        for b in range(n1):
            fj = -0.5 + block * b
            for cc in range(n2):
                fk = -0.5 + block * cc
                good = _uv(geo, intr, c, fi, fj, fk, tmp)
                ok[a, b, cc] = good
                u[a, b, cc] = min(max(tmp[0], -clamp), clamp)
                v[a, b, cc] = min(max(tmp[1], -clamp), clamp)
    for a in range(nb0):
        for b in range(nb1):
            for cc in range(nb2):
                good = True
                umin = np.inf
                umax = -np.inf
                vmin = np.inf
                vmax = -np.inf
                for da in range(2):
                    for db in range(2):
                        for dc in range(2):
                            if not ok[a + da, b + db, cc + dc]:
                                good = False
                            uu = u[a + da, b + db, cc + dc]
                            vv = v[a + da, b + db, cc + dc]
                            umin = min(umin, uu)
                            umax = max(umax, uu)
                            vmin = min(vmin, vv)
                            vmax = max(vmax, vv)
                if good:
                    out[a, b, cc, 0] = int(math.floor(umin + 0.5)) - margin
                    out[a, b, cc, 1] = int(math.floor(vmin + 0.5)) - margin
                    out[a, b, cc, 2] = int(math.floor(umax + 0.5)) + margin
                    out[a, b, cc, 3] = int(math.floor(vmax + 0.5)) + margin
                else:
                    out[a, b, cc, 0] = INVALID
                    out[a, b, cc, 1] = 0
                    out[a, b, cc, 2] = 0
                    out[a, b, cc, 3] = 0


@njit(cache=True)
def union_up(r):
    """Rectangles (m0, m1, m2, C, 4) of the parent level: union of the up-to-8 children of
    ``r`` (n0, n1, n2, C, 4); INVALID when a child is."""
    n0, n1, n2, C = r.shape[0], r.shape[1], r.shape[2], r.shape[3]
    m0, m1, m2 = (n0 + 1) // 2, (n1 + 1) // 2, (n2 + 1) // 2
    out = np.empty((m0, m1, m2, C, 4), np.int64)
    for a in range(m0):
        for b in range(m1):
            for cc in range(m2):
                for q in range(C):
                    x0 = np.int64(1) << 40
                    y0 = np.int64(1) << 40
                    x1 = -(np.int64(1) << 40)
                    y1 = -(np.int64(1) << 40)
                    bad = False
                    for da in range(2):
                        i = 2 * a + da
                        if i >= n0:
                            continue
                        for db in range(2):
                            j = 2 * b + db
                            if j >= n1:
                                continue
                            for dc in range(2):
                                k = 2 * cc + dc
                                if k >= n2:
                                    continue
                                if r[i, j, k, q, 0] == INVALID:
                                    bad = True
                                else:
                                    x0 = min(x0, r[i, j, k, q, 0])
                                    y0 = min(y0, r[i, j, k, q, 1])
                                    x1 = max(x1, r[i, j, k, q, 2])
                                    y1 = max(y1, r[i, j, k, q, 3])
                    if bad:
                        out[a, b, cc, q, 0] = INVALID
                        out[a, b, cc, q, 1] = 0
                        out[a, b, cc, q, 2] = 0
                        out[a, b, cc, q, 3] = 0
                    else:
                        out[a, b, cc, q, 0] = x0
                        out[a, b, cc, q, 1] = y0
                        out[a, b, cc, q, 2] = x1
                        out[a, b, cc, q, 3] = y1
    return out


@njit(cache=True)
def rect_misses(r, sat, w, h, fx, fy, misses):
    """``misses`` += 1 for each cell whose rectangle ``r`` (n0, n1, n2, 4: x0, y0, x1, y1, or
    ``x0 == INVALID``: unknown, never a miss) lies outside the image (w, h) or holds no set pixel
    of the summed-area table ``sat`` (of the mask, or of its small mask when it is reduced by
    (fx, fy): the rectangle's blocks)."""
    n0, n1, n2 = misses.shape
    for a in range(n0):
        for b in range(n1):
            for c in range(n2):
                rx0 = r[a, b, c, 0]
                if rx0 == INVALID:
                    continue
                ry0 = r[a, b, c, 1]
                rx1 = r[a, b, c, 2]
                ry1 = r[a, b, c, 3]
                if rx0 > w - 1 or rx1 < 0 or ry0 > h - 1 or ry1 < 0:
                    misses[a, b, c] += 1
                    continue
                x0 = min(max(rx0, 0), w - 1) // fx
                x1 = min(max(rx1, 0), w - 1) // fx
                y0 = min(max(ry0, 0), h - 1) // fy
                y1 = min(max(ry1, 0), h - 1) // fy
                s = sat[y1 + 1, x1 + 1] - sat[y0, x1 + 1] - sat[y1 + 1, x0] + sat[y0, x0]
                if s == 0:
                    misses[a, b, c] += 1
