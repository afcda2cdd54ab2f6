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
