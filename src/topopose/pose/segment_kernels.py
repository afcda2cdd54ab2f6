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
def _push(hk, hv, hl, size, k, v, lab):
    i = size
    hk[i] = k
    hv[i] = v
    hl[i] = lab
    while i > 0:
        p = (i - 1) >> 1
        if hk[p] < hk[i] or (hk[p] == hk[i] and hl[p] <= hl[i]):
            break
        hk[p], hk[i] = hk[i], hk[p]
        hv[p], hv[i] = hv[i], hv[p]
        hl[p], hl[i] = hl[i], hl[p]
        i = p
    return size + 1


@njit(cache=True)
def _pop(hk, hv, hl, size):
    k, v, lab = hk[0], hv[0], hl[0]
    size -= 1
    hk[0], hv[0], hl[0] = hk[size], hv[size], hl[size]
    i = 0
    while True:
        a = 2 * i + 1
        b = a + 1
        m = i
        if a < size and (hk[a] < hk[m] or (hk[a] == hk[m] and hl[a] < hl[m])):
            m = a
        if b < size and (hk[b] < hk[m] or (hk[b] == hk[m] and hl[b] < hl[m])):
            m = b
        if m == i:
            break
        hk[m], hk[i] = hk[i], hk[m]
        hv[m], hv[i] = hv[i], hv[m]
        hl[m], hl[i] = hl[i], hl[m]
        i = m
    return k, v, lab, size


@njit(cache=True)
def flood_weighted(mask, labels, start, offsets, steps, cost):
    """Multi-source Dijkstra flooding of ``mask`` from the voxels with ``labels > 0``.

    In place on ``labels`` (int32): every mask voxel reachable from a seed gets the label of
    the seed s minimizing ``start[s] + Σ steps[k] · (cost[a] + cost[b]) / 2`` over the steps
    a → b of a path inside the mask (``steps[k]``: the length of neighbour offset k, e.g. 1,
    √2, √3; ``cost``: a per-voxel price, 1 everywhere for the Euclidean geodesic distance),
    ties to the smallest label. Returns the distances (inf where not reached).
    """
    n = mask.size
    dist = np.full(n, np.inf)
    cap = 1
    for i in range(n):
        if mask[i]:
            cap += 1
    cap *= offsets.size + 1
    hk = np.empty(cap)
    hv = np.empty(cap, np.int64)
    hl = np.empty(cap, np.int32)
    size = 0
    own = labels.copy()
    for i in range(n):
        labels[i] = 0
    for i in range(n):
        if own[i] > 0 and mask[i]:
            size = _push(hk, hv, hl, size, start[i], i, own[i])
    while size > 0:
        d, i, lab, size = _pop(hk, hv, hl, size)
        if labels[i] != 0:
            continue
        labels[i] = lab
        dist[i] = d
        for k in range(offsets.size):
            j = i + offsets[k]
            if mask[j] and labels[j] == 0:
                nd = d + steps[k] * 0.5 * (cost[i] + cost[j])
                if nd <= dist[j]:
                    dist[j] = nd
                    size = _push(hk, hv, hl, size, nd, j, lab)
    return dist
