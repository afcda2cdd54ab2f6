"""Numba kernels of the visual-hull flooding (thesis §13.3.1.1), driven by :mod:`.segment`.

Arrays are flat C-order views of a grid padded with one background voxel on every side, so a
neighbour offset never leaves the array.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def depth(mask, offsets):
    """Steps of the adjacency ``offsets`` from each mask voxel to the nearest background voxel
    (1 on the mask's border; 0 outside): the local thickness of the hull, by breadth-first
    search from the border inwards."""
    n = mask.size
    dist = np.zeros(n, np.int32)
    queue = np.empty(n, np.int64)
    tail = 0
    for i in range(n):
        if mask[i]:
            for o in offsets:
                j = i + o
                if j >= 0 and j < n and not mask[j]:
                    dist[i] = 1
                    queue[tail] = i
                    tail += 1
                    break
    head = 0
    while head < tail:
        i = queue[head]
        head += 1
        for o in offsets:
            j = i + o
            if mask[j] and dist[j] == 0:
                dist[j] = dist[i] + 1
                queue[tail] = j
                tail += 1
    return dist


@njit(cache=True)
def flood(mask, labels, start, offsets):
    """Multi-source breadth-first flooding of ``mask`` from the voxels with ``labels > 0``.

    In place on ``labels`` (int32): every mask voxel reachable from a seed gets the label of
    the seed s minimizing ``start[s] + steps(s, voxel)`` (steps of the adjacency inside the
    mask; ``start`` ≥ 0 delays a seed), ties to the smallest label. The queue is processed
    level by level; seeds enter at their start level, and a voxel reached at the same level by
    a smaller label takes it before its own turn to propagate. A seed already reached at an
    earlier level by another label is overrun. Labels outside the mask are cleared. Returns
    the number of voxels labelled.
    """
    n = mask.size
    ns = 0
    for i in range(n):
        if labels[i] > 0:
            if mask[i]:
                ns += 1
            else:
                labels[i] = 0
    seeds = np.empty(ns, np.int64)
    key = np.empty(ns, np.int64)
    k = 0
    for i in range(n):
        if labels[i] > 0:
            seeds[k] = i
            key[k] = start[i]
            k += 1
    order = np.argsort(key, kind="mergesort")
    own = labels.copy()
    for i in range(n):
        labels[i] = 0
    dist = np.full(n, -1, np.int32)
    queue = np.empty(n, np.int64)
    head = 0
    tail = 0
    s = 0
    level = 0
    while head < tail or s < ns:
        if head == tail:                       # nothing at this level: jump to the next seed
            level = max(level, key[order[s]])
        while s < ns and key[order[s]] <= level:
            i = seeds[order[s]]
            s += 1
            if dist[i] < 0:
                dist[i] = level
                labels[i] = own[i]
                queue[tail] = i
                tail += 1
            elif dist[i] == level and own[i] < labels[i]:
                labels[i] = own[i]
        while head < tail and dist[queue[head]] == level:
            i = queue[head]
            head += 1
            lab = labels[i]
            d = level + 1
            for o in offsets:
                j = i + o
                if mask[j]:
                    if dist[j] < 0:
                        dist[j] = d
                        labels[j] = lab
                        queue[tail] = j
                        tail += 1
                    elif dist[j] == d and lab < labels[j]:
                        labels[j] = lab
        level += 1
    return tail


@njit(cache=True)
def neighbours(mask, offsets):
    """The mask's voxels as a graph: ``idx`` (flat index of each mask voxel, in order) and
    ``nb`` (m, k): position in ``idx`` of each voxel's neighbour along ``offsets[k]``, or -1."""
    n = mask.size
    pos = np.full(n, -1, np.int64)
    m = 0
    for i in range(n):
        if mask[i]:
            pos[i] = m
            m += 1
    idx = np.empty(m, np.int64)
    for i in range(n):
        if mask[i]:
            idx[pos[i]] = i
    nb = np.full((m, offsets.size), -1, np.int32)
    for a in range(m):
        i = idx[a]
        for k in range(offsets.size):
            j = i + offsets[k]
            if j >= 0 and j < n and mask[j]:
                nb[a, k] = pos[j]
    return idx, nb


@njit(cache=True)
def flood_weighted(nb, steps, seeds, start, allow):
    """Multi-source shortest paths on the graph of :func:`neighbours` with integer step costs
    (Dial's bucket queue): every vertex reachable from a seed (``seeds > 0``) gets the label of
    the seed s minimizing ``start[s] + Σ steps[k]`` over the steps of a path, ties to the
    smallest label. ``steps`` (int, ≥ 1): the cost of each neighbour offset, e.g. the chamfer
    3, 4, 5 for face, edge and corner steps (÷ 3: a Euclidean distance within 4 %);
    ``start`` (int, ≥ 0) delays a seed; the paths stay on the vertices where ``allow`` is true
    (and the seeds). Returns ``(labels, dist)``: label 0 and dist -1 where no seed reaches."""
    m, K = nb.shape
    big = np.iinfo(np.int64).max
    dist = np.full(m, big, np.int64)
    lab = np.zeros(m, np.int32)
    smax = 0
    for a in range(m):
        if seeds[a] > 0:
            smax = max(smax, start[a])
    kmax = 1
    for k in range(K):
        kmax = max(kmax, steps[k])
    nbuck = smax + kmax * (m + 1) + 1
    head = np.full(nbuck, -1, np.int64)
    cap = m * (K + 1) + 1
    node_v = np.empty(cap, np.int64)
    node_next = np.empty(cap, np.int64)
    c = 0
    top = 0
    for a in range(m):
        L = seeds[a]
        if L > 0:
            d = start[a]
            if d < dist[a] or (d == dist[a] and L < lab[a]):
                dist[a] = d
                lab[a] = L
                node_v[c] = a
                node_next[c] = head[d]
                head[d] = c
                c += 1
                top = max(top, d)
    done = np.zeros(m, np.bool_)
    d = 0
    while d <= top:
        e = head[d]
        while e != -1:
            v = node_v[e]
            e = node_next[e]
            if done[v] or dist[v] != d:
                continue
            done[v] = True
            for k in range(K):
                w = nb[v, k]
                if w < 0 or done[w] or not allow[w]:
                    continue
                nd = d + steps[k]
                if nd < dist[w] or (nd == dist[w] and lab[v] < lab[w]):
                    dist[w] = nd
                    lab[w] = lab[v]
                    node_v[c] = w
                    node_next[c] = head[nd]
                    head[nd] = c
                    c += 1
                    if nd > top:
                        top = nd
        d += 1
    for a in range(m):
        if not done[a]:
            lab[a] = 0
            dist[a] = -1
    return lab, dist


@njit(cache=True)
def bone_distance(X, A, B, label, nlab):
    """(nlab, m) distance of each point of ``X`` (m, 3) to the nearest segment A[k]–B[k] of
    each label (``label[k]`` in 1..nlab; inf for a label without a segment)."""
    m = X.shape[0]
    out = np.full((nlab, m), np.inf)
    for k in range(A.shape[0]):
        L = label[k] - 1
        d0, d1, d2 = B[k, 0] - A[k, 0], B[k, 1] - A[k, 1], B[k, 2] - A[k, 2]
        dd = max(d0 * d0 + d1 * d1 + d2 * d2, 1e-12)
        for i in range(m):
            x0, x1, x2 = X[i, 0] - A[k, 0], X[i, 1] - A[k, 1], X[i, 2] - A[k, 2]
            t = min(1.0, max(0.0, (x0 * d0 + x1 * d1 + x2 * d2) / dd))
            e0, e1, e2 = x0 - t * d0, x1 - t * d1, x2 - t * d2
            e = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if e < out[L, i]:
                out[L, i] = e
    return out


@njit(cache=True)
def flood_parts(nb, steps, seeds, start, bd, weight, band):
    """Each label's own flood mixed with its distance to its bones (:func:`.segment.flood_labels`).

    For each label L with seeds, the shortest paths of :func:`flood_weighted` from L's seeds
    alone give T_L (``start`` plus chamfer ``steps``; ÷ 3 in voxels); each vertex takes the
    label minimizing ``(1 − weight) · T_L / 3 + weight · bd[L − 1]`` (``bd``: (nlab, m)
    distances to each label's bones, voxels; a label whose row is all inf scores T_L / 3).
    L's flood runs only on the vertices whose distance to L's bones is within ``band`` of
    the nearest bone's (and on its seeds): where L can win (``band`` inf: everywhere).
    Returns the labels (0 where no label reaches)."""
    m = nb.shape[0]
    nl = bd.shape[0]
    bmin = np.full(m, np.inf)
    for L in range(nl):
        for a in range(m):
            bmin[a] = min(bmin[a], bd[L, a])
    best = np.full(m, np.inf)
    lab = np.zeros(m, np.int32)
    own = np.zeros(m, np.int32)
    allow = np.zeros(m, np.bool_)
    for L in range(1, nl + 1):
        n_own = 0
        for a in range(m):
            own[a] = L if seeds[a] == L else 0
            n_own += own[a] > 0
        if n_own == 0:
            continue
        plain = True
        for a in range(m):
            if np.isfinite(bd[L - 1, a]):
                plain = False
                break
        for a in range(m):
            allow[a] = plain or own[a] > 0 or bd[L - 1, a] <= bmin[a] + band
        _, t = flood_weighted(nb, steps, own, start, allow)
        for a in range(m):
            if t[a] < 0:
                continue
            sc = t[a] / 3.0 if plain else (1 - weight) * t[a] / 3.0 + weight * bd[L - 1, a]
            if sc < best[a]:
                best[a] = sc
                lab[a] = L
    return lab
