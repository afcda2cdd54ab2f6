"""Placing the parts of one frame from its alignment (thesis §12.1, §12.2.2.3): betweenness
by path lengths, junction centroids, the rules that leave a leaf unplaced, and the volume
helpers the estimator applies before thinning."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

def path_length(adj, u, v):
    """Length of the path from ``u`` to ``v`` in a tree given as ``{vertex: [(neighbour,
    weight), ...]}`` (``Tree.adjacency()``), or None when they are not connected."""
    seen, stack = {u: 0.0}, [u]
    while stack:
        x = stack.pop()
        if x == v:
            return seen[x]
        for y, w in adj[x]:
            if y not in seen:
                seen[y] = seen[x] + w
                stack.append(y)
    return None


def betweenness_by_lengths(al, pattern, data, constraint):
    """Apply a betweenness constraint (thesis §12.2.2), choosing by limb lengths among the
    co-optimal alignments that satisfy it.

    :func:`topopose.match.apply_betweenness` returns the first co-optimal alignment that
    satisfies the constraint. A betweenness sequence (thumb, index, middle, ring, little) is
    satisfied by an order and by its reverse alike (R(P1, P2, P3) is symmetric in P1, P2), and
    the alignment often cannot tell them apart either: when every data finger is shorter
    (or longer) than every model finger, Σ|w − w′| is the same for every permutation of the
    fingers (on synthetic hands all 120 were co-optimal), so "first" was the little finger
    named thumb in most frames. Among the satisfying co-optimal alignments this keeps the one
    whose limb lengths, relative to their mean, are closest to the model's (Σ of absolute
    differences; the limb of a part is its tree path from the image of the part's model
    neighbour): the thumb is the short one. The mirror image of the chosen assignment is
    compared too (it may not be co-optimal); when it wins only ``mapping`` is swapped
    (``diagnostics["betweenness"] = "mirrored"``; distance and arcs stay the alignment's).
    Same return convention as ``apply_betweenness``.
    """
    from topopose.match import apply_betweenness
    from topopose.match.betweenness import cooptimal_alignments, satisfies

    parts = tuple(constraint.parts)
    ctx = getattr(al, "_ctx", None)
    if ctx is None:
        return apply_betweenness(al, pattern, data, constraint)
    rel = constraint.relation or "b"
    adj = pattern.adjacency()
    plen, base = {}, {}
    for p in parts:
        nb = [(n, w) for n, w in adj[p] if math.isfinite(w)]
        if len(nb) != 1:                  # not a limb end: plain betweenness
            return apply_betweenness(al, pattern, data, constraint)
        base[p], plen[p] = nb[0]
    pm = float(np.mean(list(plen.values())))
    dadj = data.adjacency()

    def tree_dist(u, v):
        return None if u is None or v is None else path_length(dadj, u, v)

    def score(cand, use):
        d = {p: tree_dist(cand.mapping.get(base[p]), cand.mapping.get(p)) for p in use}
        ok = [p for p in use if d[p] is not None and math.isfinite(d[p])]
        dm = float(np.mean([d[p] for p in ok])) if ok else 0.0
        pmu = float(np.mean([plen[p] for p in ok])) if ok else pm
        return sum(abs(d[p] / dm - plen[p] / pmu) for p in ok) if dm > 0 else math.inf

    cands = [ctx.make(ctx.top, np.array(ev, np.int64).reshape(-1, 3))
             for ev in cooptimal_alignments(al, parts)]
    best = None
    for cand in cands:
        if satisfies(cand.mapping, data.positions, parts, rel):
            s = score(cand, parts)
            if best is None or s < best[0]:
                best = (s, cand)
    if best is None:
        al.diagnostics["betweenness"] = "unsatisfied"
        return al
    cand = best[1]
    cand.diagnostics["betweenness"] = "applied"
    # the mirror image of the sequence satisfies the constraint as well (same triples); the
    # alignment may have kept only one orientation, so compare both by their lengths
    n = len(parts)
    mirror = SimpleNamespace(mapping={**cand.mapping, **{parts[i]: cand.mapping.get(parts[n - 1 - i])
                                                         for i in range(n)}})
    if score(mirror, parts) < best[0]:
        cand.mapping = mirror.mapping
        cand.diagnostics["betweenness"] = "mirrored"
    return cand


def arm_keep(vol) -> np.ndarray:
    """Keep mask of an incomplete model's thinning (thesis §12.1): one voxel where the
    infinite limb (the forearm) leaves the grid.

    The thesis keeps the object voxel nearest the centroid of the object voxels on the grid
    boundary (:func:`topopose.topology.border_constraint`). Two refinements make it the limb's
    exit point in every frame: the boundary voxels are split into 26-connected pieces and
    only the largest one (the limb's cut section; a fingertip grazing the grid side makes a
    small second piece) is used, and the kept voxel is taken among that piece's own voxels,
    so it always lies on the boundary — a limb leaving across an edge or a corner of the grid
    gives an L-shaped section whose centroid is inside the object, and the object voxel
    nearest it is then not on the boundary (no skeleton end touches the border, the frame
    fails). Empty mask when the object does not touch the boundary.
    """
    import cc3d

    a = vol.data
    onb = np.zeros(a.shape, dtype=bool)
    for ax in range(3):
        for end in (0, -1):
            idx = [slice(None)] * 3
            idx[ax] = end
            onb[tuple(idx)] = a[tuple(idx)]
    out = np.zeros(a.shape, dtype=bool)
    if not onb.any():
        return out
    lab, n = cc3d.connected_components(onb, connectivity=26, return_N=True)
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    pts = np.argwhere(lab == int(np.argmax(sizes)))
    c = pts.mean(axis=0)
    out[tuple(pts[int(np.argmin(((pts - c) ** 2).sum(axis=1)))])] = True
    return out


def off_axis_leaf(data, mapping, leaf, junction, axis_end, min_cos) -> bool:
    """Whether ``leaf``'s data vertex leaves the data vertex of ``junction`` at more than
    acos(``min_cos``) from the axis ``axis_end`` → ``junction`` (a head beside the neck: a
    shoulder spur or an arm's bend). False when one of the three is unmatched or two coincide."""
    pts = [data.positions.get(mapping.get(p)) if mapping.get(p) is not None else None
           for p in (leaf, junction, axis_end)]
    if any(x is None for x in pts):
        return False
    leaf_p, junc, end = (np.asarray(x, dtype=float) for x in pts)
    a, b = junc - end, leaf_p - junc
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na == 0 or nb == 0:
        return False
    return float(a @ b) / (na * nb) < min_cos


def short_limb(data, mapping, limbs, base, leg_base, legs, min_ratio):
    """The part of ``limbs`` (the hands) whose data path from ``base``'s vertex (the torso) is
    the shortest, when it is shorter than ``min_ratio`` × the longest data path from
    ``leg_base`` (the crotch) to one of ``legs`` (the feet); else None (also when ``base``,
    ``leg_base`` or every leg is unmatched). A real arm's branch, shoulder centre → hand, is
    about 0.7 of a leg's (``body``, median); one that ends at the elbow (a forearm folded onto the body, fused with
    it in the hull) is shorter than the upper arm, and the hand placed at its end is wrong."""
    adj = data.adjacency()

    def length(a, b):
        u, v = mapping.get(a), mapping.get(b)
        return None if u is None or v is None else path_length(adj, u, v)

    leg = max((x for x in (length(leg_base, f) for f in legs) if x is not None), default=None)
    if not leg:
        return None
    arms = [(x, p) for p, x in ((p, length(base, p)) for p in limbs) if x is not None]
    if not arms:
        return None
    x, p = min(arms)
    return p if x < min_ratio * leg else None


def junction_position(al, data, part, v, leaves: bool = True):
    """Position of the junction part ``part`` mapped to data vertex ``v``.

    Thinning seldom leaves one intersection voxel where several limbs meet (§7.3): the data tree
    holds a cluster of junction vertices joined by edges of a voxel or two, and the alignment
    can map the model junction to any of them at the same cost (its co-optimal
    ``alternatives``, §12.2.2). The chosen one is a tie-break; the cluster — the alternatives
    connected to ``v`` through alternatives in the data tree — is the junction, and its centroid
    the estimate (measured by ``benchmarks/quality.py``; its figures: ``docs/decisions.md``).
    ``leaves`` False: the cluster's leaves of the data tree left out
    (unless it has nothing else) — the far end of a branch contracted into the junction
    (:data:`JUNCTION_CORE`).
    """
    alts = set((al.alternatives or {}).get(part) or ())
    if len(alts) <= 1 or v not in alts:
        return data.positions.get(v)
    adj = data.adjacency()
    seen, stack = {v}, [v]
    while stack:
        x = stack.pop()
        for y, _w in adj.get(x, ()):
            if y in alts and y not in seen:
                seen.add(y)
                stack.append(y)
    if not leaves:
        seen = [u for u in seen if len(adj.get(u, ())) > 1] or seen
    pts = [data.positions[u] for u in seen if data.positions.get(u) is not None]
    return np.mean(np.asarray(pts, dtype=float), axis=0) if pts else data.positions.get(v)


def fill_cavities(vol):
    """Fill the volume's cavities, in place: background components (6-adjacency, the dual of
    the object's 26-adjacency) that do not reach the outside become object. Returns ``vol``.

    :func:`topopose.hull.fill_cavities` (same result as ``scipy.ndimage.binary_fill_holes``)
    on the hull's bounding box ``vol.diagnostics["bbox"]`` when :func:`topopose.visual_hull`
    left one (it must still hold every voxel), else on the box it computes."""
    from topopose.hull import fill_cavities as fill

    if not vol.data.flags.c_contiguous:
        vol.data = np.ascontiguousarray(vol.data)
    n, _ = fill(vol.data, (vol.diagnostics or {}).get("bbox"))     # in place: the frame's own hull
    if n:
        vol.diagnostics["cavities_filled"] = n
    return vol


def _touches_border(a: np.ndarray) -> bool:
    return bool(a[0].any() or a[-1].any() or a[:, 0].any() or a[:, -1].any()
                or a[:, :, 0].any() or a[:, :, -1].any())
