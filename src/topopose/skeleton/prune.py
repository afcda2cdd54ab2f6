"""Pruning of insignificant skeleton branches (bumps of the surface) before alignment.

A medial (curve) skeleton is unstable: a bump of the surface — silhouette noise dilating one
camera's border, a false blob the tolerant hull keeps, a heel or a thumb — grows a leaf branch
from the medial curve out to the bump (thesis §7.1 on the skeleton's sensitivity to boundary
noise). The *scale axis* idea (Giesen, Miklos, Pauly & Wormser, "The scale axis transform",
SoCG 2009) measures a branch against the thickness of the shape where it starts: a leaf branch
whose inscribed balls all stay inside the ball of the hull at its junction scaled by ``ratio``
is a bump, not a limb.

:func:`prune_bumps` removes such branches from the skeleton voxels, one per junction and round,
the shortest first, and rebuilds the data tree (:func:`~topopose.skeleton.data_tree`) after each
round: once a bump next to a wrist is gone, the wrist is no junction any more and the hand's
branch is long again, so it is never compared with the bump's.
"""
from __future__ import annotations

import math

import numpy as np

from topopose.errors import InputError
from topopose.skeleton.tree import data_tree


def ball_radius(hull: np.ndarray, voxel, start: int = 8) -> float:
    """Inscribed-ball radius (voxels) of ``hull`` at ``voxel``: the Euclidean distance from the
    voxel's centre to the nearest background voxel centre (outside the grid counts as
    background). Exact, found in a cube around the voxel grown until it holds the answer; 0
    when ``voxel`` itself is background."""
    x = np.asarray(voxel, dtype=np.int64)
    shape = np.asarray(hull.shape)
    if not hull[tuple(x)]:
        return 0.0
    k = int(start)
    while True:
        lo, hi = x - k, x + k + 1
        sub = hull[tuple(slice(max(a, 0), min(b, n)) for a, b, n in zip(lo, hi, shape))]
        bg = np.argwhere(~sub) + np.maximum(lo, 0) - x
        d = float(np.sqrt((bg * bg).sum(1).min())) if bg.size else math.inf
        # the grid's outside, just beyond its faces
        d = min(d, float(min(np.min(x + 1), np.min(shape - x))))
        if d <= k:
            return d
        k *= 2


def prune_bumps(skeleton: np.ndarray, hull: np.ndarray, ratio: float, origin=(0.0, 0.0, 0.0),
                voxel_size=1.0, border=None, max_rounds: int = 6, measure: str = "contain",
                squared=None, **tree_options):
    """Remove the leaf branches of ``skeleton`` that are bumps of ``hull`` (scale axis, see the
    module docstring); return ``(skeleton, tree, pruned)``.

    Parameters
    ----------
    skeleton : (nx, ny, nz) bool
        Curve skeleton of ``hull`` (not modified; a pruned copy is returned).
    hull : (nx, ny, nz) bool
        The volume the skeleton was thinned from.
    ratio : float
        0 prunes nothing. With ``measure="contain"`` (default, the scale axis) a leaf branch
        (leaf → junction of degree ≥ 3) is a bump when every inscribed ball along it (its
        voxels, the leaf's included: distance to the junction + radius) fits inside the
        junction's ball scaled by ``ratio`` (radius :func:`ball_radius` at the junction voxel
        nearest its centroid): a head — a big ball at the end of a short branch — reaches out
        of it where a bump of the same length does not. With ``measure="length"``: the
        branch's length (voxels, as :func:`~topopose.skeleton.data_tree` measures it) is below
        ``ratio`` × that radius.
    origin, voxel_size, border, **tree_options
        Passed to :func:`~topopose.skeleton.data_tree`. A leaf holding a ``border`` voxel
        (an incomplete model's infinite limb) is never pruned.
    measure : "contain" or "length"
    max_rounds : int
        Each round prunes at most one branch per junction (the shortest candidate), then the
        tree is rebuilt.
    squared : (ndarray, lo), optional
        :func:`topopose.frame.tips.squared_distances` of ``hull`` if already computed: the
        radii are read there (equal to :func:`ball_radius`) instead of searched.

    Returns
    -------
    skeleton : bool array, tree : Tree of the returned skeleton, pruned : list of dicts
        (``length`` and ``radius`` in voxels, ``position`` of the removed leaf, world units).
    """
    skel = np.array(skeleton, dtype=bool, copy=True)
    tree = data_tree(skel, origin=origin, voxel_size=voxel_size, border=border, **tree_options)
    pruned = []
    if measure not in ("contain", "length"):
        raise InputError(f"prune_bumps: measure must be \"contain\" or \"length\", got {measure!r}")
    if not ratio or ratio <= 0:
        tree.diagnostics["pruned_bumps"] = pruned
        return skel, tree, pruned
    vs = float(voxel_size)
    if squared is None:
        def radius_at(x):
            return ball_radius(hull, x)
    else:
        sq, off = squared[0], np.asarray(squared[1], np.int64) - 1

        def radius_at(x):
            return float(np.sqrt(float(sq[tuple(np.asarray(x, np.int64) - off)])))
    bmask = None if border is None or isinstance(border, str) else border.reshape(-1)
    for _ in range(int(max_rounds)):
        adj = tree.adjacency()
        leaves = [v for v in tree.vertices if len(adj[v]) == 1]
        if len(leaves) <= 2 or tree.voxels is None:
            break
        idx = tree.voxels["index"]
        vert, edge = tree.voxels["vertex"], tree.voxels["edge"]
        coords = np.stack(np.unravel_index(idx, skel.shape), 1)
        eindex = {frozenset((u, v)): j for j, (u, v, _w) in enumerate(tree.edges)}
        best = {}                 # junction → (length, leaf, edge index, radius)
        radius = {}
        for v in leaves:
            u, w = adj[v][0]
            if len(adj[u]) < 3 or not math.isfinite(w):
                continue
            mine = vert == v
            if bmask is not None and bmask[idx[mine]].any():
                continue
            length = w / vs
            if u not in radius:
                own = np.flatnonzero(vert == u)
                if own.size == 0:
                    radius[u] = 0.0
                else:
                    c = (np.asarray(tree.positions[u], float) - np.asarray(origin, float)) / vs
                    x = coords[own[np.argmin(((coords[own] - c) ** 2).sum(1))]]
                    radius[u] = radius_at(x)
            r = radius[u]
            sel = mine | (edge == eindex[frozenset((u, v))])
            if r <= 0 or not sel.any():
                bump = False
            elif measure == "length" or length >= 2 * ratio * r:
                # (a branch twice as long as the scaled ball's radius leaves it)
                bump = length < ratio * r
            else:
                # scale axis: the branch's balls must fit in the junction's ball scaled by ratio
                c = (np.asarray(tree.positions[u], float) - np.asarray(origin, float)) / vs
                xs = coords[sel]
                if squared is None:
                    reach = max(float(np.linalg.norm(x - c)) + radius_at(x) for x in xs)
                else:          # the same, for all the branch's voxels at once
                    rad = np.sqrt(sq[tuple((xs - off).T)].astype(float))
                    reach = float((np.sqrt(((xs - c) ** 2).sum(axis=1)) + rad).max())
                bump = reach < ratio * r
            if bump and (u not in best or length < best[u][0]):
                best[u] = (length, v, eindex[frozenset((u, v))], radius[u])
        if not best:
            break
        for u, (length, v, j, r) in best.items():
            gone = idx[(vert == v) | (edge == j)]
            skel.reshape(-1)[gone] = False
            pruned.append({"length": float(length), "radius": float(r),
                           "position": [float(a) for a in tree.positions[v]]})
        tree = data_tree(skel, origin=origin, voxel_size=voxel_size, border=border, **tree_options)
    tree.diagnostics["pruned_bumps"] = pruned
    return skel, tree, pruned
