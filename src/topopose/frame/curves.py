"""Skeleton curves of the matched model arcs (thesis §13.3.1: the initialization's skeleton
branches are what a kinematic model is then fitted to).

The alignment maps each model arc to a data path (a chain of data-tree vertices, §12.1); the
curve of that arc is the voxel path of the curve skeleton through those vertices: shortest
paths (26-adjacency, Euclidean steps, :func:`scipy.sparse.csgraph.dijkstra`) between the skeleton
voxels nearest to consecutive waypoints — the parent part, the data path's inner vertices, the
child part. Each curve is resampled to ``n`` points equally spaced along its length, from the
parent part (the model root side) to the child part, and stored per frame in
``Pose.diagnostics["curves"]`` keyed by the child part, so the later stages (left and right,
:mod:`.chirality`; the kinematic fit, :mod:`.kinematic_fit`) need no volume.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

N_SAMPLES = 16


def model_arcs(model) -> list:
    """``(parent, child)`` for every model edge, oriented away from the model's root."""
    adj = model.tree.adjacency()
    out, seen, stack = [], {model.root}, [model.root]
    while stack:
        u = stack.pop()
        for v, _w in adj[u]:
            if v not in seen:
                seen.add(v)
                out.append((u, v))
                stack.append(v)
    return out


def arc_lengths(points) -> np.ndarray:
    """Cumulative arc length at each vertex of the polyline ``points`` (n, 3): 0 first.

    Examples
    --------
    >>> arc_lengths([[0, 0, 0], [3, 4, 0], [3, 4, 1]]).tolist()
    [0.0, 5.0, 6.0]
    """
    p = np.asarray(points, dtype=float)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def resample(points, n=N_SAMPLES) -> np.ndarray:
    """``n`` points equally spaced along the polyline ``points`` (its ends kept)."""
    p = np.asarray(points, dtype=float)
    if len(p) == 1:
        return np.repeat(p, n, axis=0)
    s = arc_lengths(p)
    if s[-1] <= 0:
        return np.repeat(p[:1], n, axis=0)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, p[:, c]) for c in range(3)], axis=1)


def arc_curves(skeleton, origin, voxel_size, data, alignment, model, parts, n=N_SAMPLES,
               voxels=None) -> dict:
    """Curve of each matched model arc (see the module docstring).

    Parameters
    ----------
    skeleton : ndarray of bool (the curve skeleton of the frame)
    origin, voxel_size : the volume's grid
    data : data Tree (positions of its vertices)
    alignment : Alignment (``alignment.arc(u, v)``: data path of model arc u–v)
    model : Model
    parts : dict part -> position or None (the frame's part positions)
    voxels : ndarray, optional (:func:`topopose.frame.tips.skeleton_voxels` of ``skeleton``)

    Returns
    -------
    dict child part -> ndarray (n, 3), from the parent part to the child part.
    """
    idx = np.argwhere(skeleton) if voxels is None else voxels
    if len(idx) < 2:
        return {}
    world = np.asarray(origin, float) + idx * float(voxel_size)
    kd = cKDTree(idx)
    pairs = kd.query_pairs(r=1.75, output_type="ndarray")
    w = np.linalg.norm(idx[pairs[:, 0]] - idx[pairs[:, 1]], axis=1)
    g = coo_matrix((w, (pairs[:, 0], pairs[:, 1])), shape=(len(idx), len(idx))).tocsr()
    wkd = cKDTree(world)
    ways = {}
    for u, v in model_arcs(model):
        if parts.get(u) is None or parts.get(v) is None:
            continue
        path = alignment.arc(u, v)
        if path is None:
            continue
        way = [parts[u]] + [data.positions[x] for x in path[1:-1]
                            if data.positions.get(x) is not None] + [parts[v]]
        nodes = [int(wkd.query(np.asarray(p, float))[1]) for p in way]
        ways[(u, v)] = [a for i, a in enumerate(nodes) if i == 0 or a != nodes[i - 1]]
    # the shortest paths from every source node at once (one graph validation, not one per pair)
    src = sorted({a for nodes in ways.values() for a in nodes[:-1]})
    row = {a: i for i, a in enumerate(src)}
    if src:
        _, preds = dijkstra(g, directed=False, indices=src, return_predecessors=True)
    out = {}
    for (u, v), nodes in ways.items():
        chain = [nodes[0]]
        ok = True
        for a, b in zip(nodes, nodes[1:]):
            pred = preds[row[a]]
            if pred[b] < 0:
                ok = False
                break
            seg = [b]
            while seg[-1] != a:
                seg.append(int(pred[seg[-1]]))
            chain.extend(seg[::-1][1:])
        if not ok:
            continue
        pts = np.vstack([np.asarray(parts[u], float), world[chain], np.asarray(parts[v], float)])
        out[v] = np.round(resample(pts, n), 5)
    return out
