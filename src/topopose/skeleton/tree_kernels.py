"""Numba kernels of the data-tree construction (thesis §7.3.3, Alg. 13).

Everything here works on the *voxel list* of a curve skeleton (a few hundred
voxels for a 100³ human), never on the whole grid, except :func:`find_voxels`,
which scans the grid once eight bytes at a time.

Voxel classes (thesis §7.3.3): 0 = E (0 or 1 skeleton neighbour), 1 = B
(exactly 2), 2 = I (more than 2), all under 26-adjacency.
"""
from __future__ import annotations

import numpy as np
from numba import njit

E_CLASS, B_CLASS, I_CLASS = 0, 1, 2


@njit(cache=True)
def find_voxels(flat, words):
    """Sorted linear (C-order) indices of the non-zero bytes of ``flat``.

    ``words`` is ``flat[:8 * len(words)]`` viewed as uint64: zero words (eight
    background voxels) are skipped with one comparison.
    """
    nw = words.shape[0]
    n = 0
    for w in range(nw):
        if words[w] != 0:
            base = w * 8
            for t in range(8):
                if flat[base + t] != 0:
                    n += 1
    for p in range(nw * 8, flat.shape[0]):
        if flat[p] != 0:
            n += 1
    out = np.empty(n, np.int64)
    m = 0
    for w in range(nw):
        if words[w] != 0:
            base = w * 8
            for t in range(8):
                if flat[base + t] != 0:
                    out[m] = base + t
                    m += 1
    for p in range(nw * 8, flat.shape[0]):
        if flat[p] != 0:
            out[m] = p
            m += 1
    return out


@njit(cache=True)
def voxel_graph(flat, idx, nx, ny, nz):
    """26-adjacency of the skeleton voxels.

    Returns
    -------
    coords : (n, 3) int64 voxel indices.
    nbr : (n, 26) int32, the neighbours' positions in ``idx`` (first ``deg`` entries).
    deg : (n,) int32 number of skeleton neighbours.
    """
    n = idx.shape[0]
    sx = ny * nz
    coords = np.empty((n, 3), np.int64)
    nbr = np.full((n, 26), -1, np.int32)
    deg = np.zeros(n, np.int32)
    for a in range(n):
        p = idx[a]
        i = p // sx
        r = p - i * sx
        j = r // nz
        k = r - j * nz
        coords[a, 0] = i
        coords[a, 1] = j
        coords[a, 2] = k
        for di in range(-1, 2):
            ii = i + di
            if ii < 0 or ii >= nx:
                continue
            for dj in range(-1, 2):
                jj = j + dj
                if jj < 0 or jj >= ny:
                    continue
                for dk in range(-1, 2):
                    if di == 0 and dj == 0 and dk == 0:
                        continue
                    kk = k + dk
                    if kk < 0 or kk >= nz:
                        continue
                    q = p + di * sx + dj * nz + dk
                    if flat[q] != 0:
                        # binary search of q in the sorted voxel list
                        lo = 0
                        hi = n - 1
                        while lo < hi:
                            mid = (lo + hi) >> 1
                            if idx[mid] < q:
                                lo = mid + 1
                            else:
                                hi = mid
                        nbr[a, deg[a]] = lo
                        deg[a] += 1
    return coords, nbr, deg


@njit(cache=True)
def _find(parent, a):
    r = a
    while parent[r] != r:
        r = parent[r]
    while parent[a] != r:  # path compression
        nxt = parent[a]
        parent[a] = r
        a = nxt
    return r


@njit(cache=True)
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra < rb:  # the smallest voxel index stays the root
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@njit(cache=True)
def _relabel(parent):
    """Component ids 0..C-1 numbered in the order of each component's first voxel."""
    n = parent.shape[0]
    lab = np.full(n, -1, np.int64)
    comp = np.empty(n, np.int64)
    c = 0
    for a in range(n):
        r = _find(parent, a)
        if lab[r] < 0:
            lab[r] = c
            c += 1
        comp[a] = lab[r]
    return comp, c


@njit(cache=True)
def label_voxels(nbr, deg):
    """Classes and 26-components by union-find on the voxel list.

    Returns
    -------
    cls : (n,) int8 voxel class (0 E, 1 B, 2 I).
    comp : (n,) int64 component of the voxel among the voxels of its class.
    ncomp : number of class components.
    scomp : (n,) int64 26-component of the whole skeleton.
    nscomp : number of skeleton components.
    """
    n = deg.shape[0]
    cls = np.empty(n, np.int8)
    for a in range(n):
        d = deg[a]
        cls[a] = 0 if d <= 1 else (1 if d == 2 else 2)
    parent = np.arange(n)
    sparent = np.arange(n)
    for a in range(n):
        for t in range(deg[a]):
            b = nbr[a, t]
            if b > a:
                _union(sparent, a, b)
                if cls[a] == cls[b]:
                    _union(parent, a, b)
    comp, ncomp = _relabel(parent)
    scomp, nscomp = _relabel(sparent)
    return cls, comp, ncomp, scomp, nscomp


@njit(cache=True)
def branch_contacts(coords, nbr, deg, cls, comp, ncomp):
    """Where branches and vertex components touch, and the branch lengths.

    Returns
    -------
    bb : (ncomp,) float64 sum of the steps between consecutive voxels of each
        B component (in voxel units; 0 for other classes).
    contacts : (m, 4) int64 rows (B component, touched component, B voxel, touched voxel),
        one per adjacency between a B voxel and a non-B voxel.
    csteps : (m,) float64 length of each such step (1, √2 or √3).
    direct : (k, 4) int64 rows (E component, I component, E voxel, I voxel) for
        each E voxel adjacent to an I voxel (an edge with no B between).
    dsteps : (k,) float64.
    """
    n = deg.shape[0]
    bb = np.zeros(ncomp, np.float64)
    contacts = np.empty((2 * n, 4), np.int64)
    csteps = np.empty(2 * n, np.float64)
    direct = np.empty((n, 4), np.int64)
    dsteps = np.empty(n, np.float64)
    m = 0
    k = 0
    for a in range(n):
        ca = cls[a]
        if ca == 2:
            continue
        for t in range(deg[a]):
            b = nbr[a, t]
            d0 = coords[a, 0] - coords[b, 0]
            d1 = coords[a, 1] - coords[b, 1]
            d2 = coords[a, 2] - coords[b, 2]
            step = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if ca == 1:
                if cls[b] == 1:
                    bb[comp[a]] += 0.5 * step  # each B–B pair is seen from both ends
                else:
                    contacts[m, 0] = comp[a]
                    contacts[m, 1] = comp[b]
                    contacts[m, 2] = a
                    contacts[m, 3] = b
                    csteps[m] = step
                    m += 1
            elif cls[b] == 2:  # an E voxel touching an I voxel directly
                direct[k, 0] = comp[a]
                direct[k, 1] = comp[b]
                direct[k, 2] = a
                direct[k, 3] = b
                dsteps[k] = step
                k += 1
    return bb, contacts[:m], csteps[:m], direct[:k], dsteps[:k]


@njit(cache=True)
def thick_blocks(flat, coords, nx, ny, nz):
    """Count full 2×2 squares (in the three axis planes) and full 2×2×2 cubes.

    A 26-thin curve has none except, rarely, inside a junction; a surface or a
    solid is made of them (used to reject inputs that are not curve skeletons).
    """
    sx = ny * nz
    n = coords.shape[0]
    squares = 0
    cubes = 0
    for a in range(n):
        i = coords[a, 0]
        j = coords[a, 1]
        k = coords[a, 2]
        p = i * sx + j * nz + k
        ci = i + 1 < nx
        cj = j + 1 < ny
        ck = k + 1 < nz
        fi = ci and flat[p + sx] != 0
        fj = cj and flat[p + nz] != 0
        fk = ck and flat[p + 1] != 0
        fij = fi and fj and flat[p + sx + nz] != 0
        fik = fi and fk and flat[p + sx + 1] != 0
        fjk = fj and fk and flat[p + nz + 1] != 0
        squares += int(fij) + int(fik) + int(fjk)
        if fij and fik and fjk and flat[p + sx + nz + 1] != 0:
            cubes += 1
    return squares, cubes
