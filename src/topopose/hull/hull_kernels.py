"""Numba kernels of the visual hull's clean-up: tolerant consensus, cavity filling, largest part."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def consensus_near(lab, lo0, lo1, lo2, hi0, hi1, hi2, r, sub, idx):
    """Tolerant voxels near the strict hull, in the box ``lo..hi`` (inclusive) of ``lab``.

    ``lab`` holds the labels of :func:`carve` with ``levels`` (2 strict, 1 tolerant only).
    ``sub`` (box-shaped uint8) gets 1 where ``lab >= 1`` and some voxel within Chebyshev
    distance ``r`` (``r`` steps in the 26-neighbourhood; clipped to the box, which holds every
    labelled voxel) has label 2, else 0. The flat box indices of the labelled voxels go to
    ``idx`` (at least as long as their number). Returns (tolerant voxels, strict voxels).
    """
    ntol = 0
    nstrict = 0
    s1 = hi1 - lo1 + 1
    s2 = hi2 - lo2 + 1
    for i in range(lo0, hi0 + 1):
        for j in range(lo1, hi1 + 1):
            rowf = ((i - lo0) * s1 + (j - lo1)) * s2
            for k in range(lo2, hi2 + 1):
                v = lab[i, j, k]
                if v == 0:
                    sub[i - lo0, j - lo1, k - lo2] = 0
                    continue
                idx[ntol] = rowf + k - lo2
                ntol += 1
                if v == 2:
                    nstrict += 1
                    sub[i - lo0, j - lo1, k - lo2] = 1
                    continue
                near = 0
                for a in range(max(i - r, lo0), min(i + r, hi0) + 1):
                    for b in range(max(j - r, lo1), min(j + r, hi1) + 1):
                        for c in range(max(k - r, lo2), min(k + r, hi2) + 1):
                            if lab[a, b, c] == 2:
                                near = 1
                                break
                        if near:
                            break
                    if near:
                        break
                sub[i - lo0, j - lo1, k - lo2] = near
    return ntol, nstrict


@njit(cache=True)
def consensus_select(lab, cl, ncomp, lo0, lo1, lo2, idx, ntol, max_removed, state, res, dropped):
    """Largest 26-component of the consensus, and the tolerant hull's largest component,
    written back into ``lab`` (box at ``lo``, shape of ``cl``) as 1 / 0.

    ``cl``: 26-connected labels (1..``ncomp``) of the tolerant-and-near voxels in the box;
    ``idx[:ntol]``: flat box indices of the tolerant voxels (:func:`consensus_near`);
    ``state``: the box-shaped uint8 array ``sub`` of :func:`consensus_near` (0 at every
    non-tolerant voxel; reused as scratch). Let L be the largest component of ``cl`` (lowest
    label among equals). When |L| > ``ntol`` / 2, L lies in the largest 26-component T of the
    whole tolerant hull (the component holding L has more than half of its voxels) and is
    therefore the largest component of T ∩ near. The tolerant voxels outside L are then
    grouped into 26-components (breadth-first, over those voxels only): the groups adjacent
    to L make up T minus L, the others are exactly the tolerant hull's other components. So |T|
    follows without labelling the tolerant hull. When more than ``max_removed`` · |T| voxels
    would go, T is written instead of L (skipped). Work: O(tolerant voxels).

    ``res`` (int64, 12): status (0 done, -1 the shortcut does not apply: ``lab`` and
    ``state`` untouched), |L|, |T|, removed, skipped, number of ``dropped`` sizes (the other
    tolerant components, unsorted), the bounding box of the written voxels (imin, jmin, kmin,
    imax, jmax, kmax).
    """
    s0, s1, s2 = cl.shape
    clf = cl.reshape(-1)
    stf = state.reshape(-1)
    sizes = np.zeros(ncomp + 1, np.int64)
    for p in range(ntol):
        sizes[clf[idx[p]]] += 1
    best = 0
    nL = 0
    for q in range(1, ncomp + 1):
        if sizes[q] > nL:
            nL = sizes[q]
            best = q
    res[:] = 0
    if 2 * nL <= ntol:
        res[0] = -1
        return
    # state: 2 = L, 1 = other tolerant voxel (unvisited), 3 = visited, 0 = background
    for p in range(ntol):
        f = idx[p]
        stf[f] = 2 if clf[f] == best else 1
    nR = ntol - nL
    order = np.empty(max(nR, 1), np.int64)
    cstart = np.empty(nR + 1, np.int64)
    ctouch = np.zeros(nR + 1, np.bool_)
    ncomp_r = 0
    tail = 0
    nT = nL
    nd = 0
    for p in range(ntol):
        f0 = idx[p]
        if stf[f0] != 1:
            continue
        start = tail
        stf[f0] = 3
        order[tail] = f0
        tail += 1
        head = start
        touch = False
        while head < tail:
            f = order[head]
            head += 1
            x = f // (s1 * s2)
            y = (f // s2) % s1
            z = f % s2
            for a in range(max(x - 1, 0), min(x + 1, s0 - 1) + 1):
                for b in range(max(y - 1, 0), min(y + 1, s1 - 1) + 1):
                    for c in range(max(z - 1, 0), min(z + 1, s2 - 1) + 1):
                        t = state[a, b, c]
                        if t == 2:
                            touch = True
                        elif t == 1:
                            state[a, b, c] = 3
                            order[tail] = (a * s1 + b) * s2 + c
                            tail += 1
        cstart[ncomp_r] = start
        ctouch[ncomp_r] = touch
        ncomp_r += 1
        if touch:
            nT += tail - start
        else:
            dropped[nd] = tail - start
            nd += 1
    cstart[ncomp_r] = tail
    removed = nT - nL
    skipped = removed > max_removed * nT
    if skipped:
        for q in range(ncomp_r):
            if ctouch[q]:
                for p in range(cstart[q], cstart[q + 1]):
                    stf[order[p]] = 2
    bmin0, bmin1, bmin2 = s0, s1, s2
    bmax0, bmax1, bmax2 = -1, -1, -1
    for p in range(ntol):
        f = idx[p]
        x = f // (s1 * s2)
        y = (f // s2) % s1
        z = f % s2
        if stf[f] == 2:
            lab[lo0 + x, lo1 + y, lo2 + z] = 1
            bmin0 = min(bmin0, x)
            bmin1 = min(bmin1, y)
            bmin2 = min(bmin2, z)
            bmax0 = max(bmax0, x)
            bmax1 = max(bmax1, y)
            bmax2 = max(bmax2, z)
        else:
            lab[lo0 + x, lo1 + y, lo2 + z] = 0
    res[1] = nL
    res[2] = nT
    res[3] = removed
    res[4] = 1 if skipped else 0
    res[5] = nd
    res[6] = lo0 + bmin0
    res[7] = lo1 + bmin1
    res[8] = lo2 + bmin2
    res[9] = lo0 + bmax0
    res[10] = lo1 + bmax1
    res[11] = lo2 + bmax2


@njit(cache=True)
def fill_cavities(occ, lo0, lo1, lo2, hi0, hi1, hi2):
    """Fill the cavities of ``occ`` (uint8 0 / 1) in place; returns (cavities, voxels filled).

    A cavity is a background component (6-adjacency, the dual of the object's 26-adjacency)
    that does not reach the outside of the box ``lo..hi`` (inclusive), which must hold every
    object voxel. A background voxel with no object voxel on one side of its k-row (the
    contiguous axis) reaches the box face straight along k, so only the *candidates* — those
    between the first and the last object voxel of their k-row — can be in a cavity. Their
    6-components (over candidates only) are searched breadth-first: one with a background
    non-candidate 6-neighbour, or on an i / j face of the box, reaches the outside; the others
    are exactly the cavities. Work: one pass over the box's rows plus O(candidates).
    """
    s0 = hi0 - lo0 + 1
    s1 = hi1 - lo1 + 1
    s2 = hi2 - lo2 + 1
    # per row: first / last object k (box coordinates), -1 when the row is empty
    first = np.full((s0, s1), -1, np.int64)
    last = np.full((s0, s1), -1, np.int64)
    ncand = 0
    for i in range(s0):
        for j in range(s1):
            f = -1
            for k in range(s2):
                if occ[lo0 + i, lo1 + j, lo2 + k]:
                    f = k
                    break
            if f < 0:
                continue
            l = f
            for k in range(s2 - 1, f, -1):
                if occ[lo0 + i, lo1 + j, lo2 + k]:
                    l = k
                    break
            first[i, j] = f
            last[i, j] = l
            for k in range(f + 1, l):
                if not occ[lo0 + i, lo1 + j, lo2 + k]:
                    ncand += 1
    if ncand == 0:
        return 0, 0
    # candidate positions and a visited mark, as flat box indices in a dict-free way: the
    # candidates of row (i, j) are found again from first / last; visited marks go to occ
    # itself as value 2 (outside) / 3 (being searched)
    queue = np.empty(ncand, np.int64)
    ncav = 0
    nfill = 0
    for i0 in range(s0):
        for j0 in range(s1):
            if first[i0, j0] < 0:
                continue
            for k0 in range(first[i0, j0] + 1, last[i0, j0]):
                if occ[lo0 + i0, lo1 + j0, lo2 + k0] != 0:
                    continue
                # new candidate component
                occ[lo0 + i0, lo1 + j0, lo2 + k0] = 3
                queue[0] = (i0 * s1 + j0) * s2 + k0
                tail = 1
                head = 0
                outside = False
                while head < tail:
                    fl = queue[head]
                    head += 1
                    x = fl // (s1 * s2)
                    y = (fl // s2) % s1
                    z = fl % s2
                    for d in range(6):
                        a, b, c = x, y, z
                        if d == 0:
                            a = x - 1
                        elif d == 1:
                            a = x + 1
                        elif d == 2:
                            b = y - 1
                        elif d == 3:
                            b = y + 1
                        elif d == 4:
                            c = z - 1
                        else:
                            c = z + 1
                        if a < 0 or a >= s0 or b < 0 or b >= s1:
                            outside = True
                            continue
                        v = occ[lo0 + a, lo1 + b, lo2 + c]
                        if v == 1 or v == 3:
                            continue
                        if v == 2:
                            outside = True
                            continue
                        # background, unvisited: a candidate iff strictly inside its row's span
                        if first[a, b] < 0 or c <= first[a, b] or c >= last[a, b]:
                            outside = True
                            continue
                        occ[lo0 + a, lo1 + b, lo2 + c] = 3
                        queue[tail] = (a * s1 + b) * s2 + c
                        tail += 1
                mark = 2 if outside else 1
                for p in range(tail):
                    fl = queue[p]
                    occ[lo0 + fl // (s1 * s2), lo1 + (fl // s2) % s1, lo2 + fl % s2] = mark
                if not outside:
                    ncav += 1
                    nfill += tail
    # clear the outside marks
    for i in range(s0):
        for j in range(s1):
            if first[i, j] < 0:
                continue
            for k in range(first[i, j] + 1, last[i, j]):
                if occ[lo0 + i, lo1 + j, lo2 + k] == 2:
                    occ[lo0 + i, lo1 + j, lo2 + k] = 0
    return ncav, nfill


@njit(cache=True)
def keep_label(sub, lab, n):
    """Keep in ``sub`` (bool, in place) only the voxels of the largest label of ``lab`` (labels
    1 … ``n``, 0 background; the smallest label among equally large ones, as ``np.argmax``);
    returns the voxel count of every label (index 0 unused, set to 0) and the label kept, or
    (empty, -1) when a label exceeds ``n`` (nothing changed)."""
    sizes = np.zeros(n + 1, np.int64)
    s0, s1, s2 = lab.shape
    for i in range(s0):
        for j in range(s1):
            for k in range(s2):
                x = lab[i, j, k]
                if x > n:
                    return np.zeros(0, np.int64), -1
                sizes[x] += 1
    sizes[0] = 0
    best = 0
    for x in range(1, n + 1):
        if sizes[x] > sizes[best]:
            best = x
    for i in range(s0):
        for j in range(s1):
            for k in range(s2):
                if lab[i, j, k] != best:
                    sub[i, j, k] = False
    return sizes, best
