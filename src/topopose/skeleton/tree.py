"""Curve skeleton → data tree (thesis §7.3, Alg. 13; ALGORITHMS.md §6).

The skeleton voxels are classified by their number of 26-neighbours in the
skeleton (§7.3.3): E-points (0 or 1, ends), B-points (exactly 2, branches) and
I-points (more than 2, intersections).  Every 26-component of E-points and of
I-points becomes a vertex placed at the component's centroid, and every
26-component of B-points becomes an edge between the vertices it touches.

The thesis assumes the result is a tree.  Real skeletons break that assumption
in a few ways, each handled here on purpose and counted in ``tree.diagnostics``:

* **E touching I directly** (no B-point between): an edge whose length is the
  step between the two touching voxels (1, √2 or √3 voxels; its voxel count,
  the thesis' weight, is 0).  E touching E or I touching I cannot happen: two
  touching points of one class are in the same component.
* **A branch touching one vertex at both ends** (a loop, e.g. a hand touching
  its own shoulder junction) and **cycles** (limbs touching each other): the
  graph is reduced to its minimum spanning tree over the branch lengths
  (Kruskal), so each cycle is broken at its *longest* branch.  That branch is
  not thrown away: it is *detached* from one end vertex and ends at a new leaf
  placed at the voxel where it touched that vertex.  Rationale: a cycle is
  typically one limb whose tip touches another body part; the closing limb is
  the long branch and the contact is where its tip is, which is where the new
  leaf goes.  The contact end is taken to be the end of lower degree (a tip
  landing on a branch makes a degree-3 junction that falls back to the degree
  2 it had without the contact, while the limb's root is a real junction), ties
  going to the end farther, along the spanning tree, from the tree's centre.
  Total branch length is preserved; ``diagnostics["cuts"]`` lists each cut.  A
  loop has both ends on one vertex; it is detached at its second end.  A loop
  of a single B voxel whose two contacts touch (a digital triangle, e.g. the
  corner of an axis-aligned bend) encloses no hole: it is absorbed into its
  vertex (``diagnostics["triangles"]``).
* **Skeleton bubbles**: a cycle whose perimeter is below ``small_cycle``
  (default 3 %) of the total branch length is not limbs touching but a small
  tunnel of the hull (visual hulls have them near junctions and between close
  limbs; on synthetic humans with separated limbs most frames at 100³–150³
  hold one, 5–15 voxels round, 1.5–9 % of the total length).  Its longest
  branch is dropped, not detached, so it does not add a spurious leaf
  (``diagnostics["small_cycles"]``, ``diagnostics["dropped_branches"]``).  The
  default is low on purpose: limbs that nearly touch make cycles of a few
  percent too, at coarse grids, and dropping those loses an extremity while a
  spurious short leaf costs the alignment little.  Measured on 80 synthetic
  frames with touching limbs: 3 % keeps the extremity recall of detaching
  every cycle (64³: 0.97, 100³: 0.99, 150³: 0.99 of extremities as leaves)
  with fewer vertices (150³: 13.7 instead of 15.1 on average); 10 % loses
  extremities at 64³ (0.93).
* **A branch touching more than two vertices** cannot happen: a B component is
  a simple path (each voxel has exactly two skeleton neighbours), so it has
  exactly two contacts with non-B voxels, or none when it is a closed curve.
* **An isolated closed loop** (no E- or I-point): it is opened into the arc
  from its first voxel P (lowest C-order index) to the voxel Q half-way round,
  one edge P–Q with the arc's length.
* **Several 26-components**: the largest (in voxels) is kept, the others are
  listed in ``diagnostics["dropped_components"]``.
* **A single point** (or an isolated E pair, or an I blob alone): a tree with one
  vertex and no edge.  An empty skeleton raises :class:`InputError`.
* **Incomplete models** (§7.3.3.1): with ``border``, E components holding a
  border voxel make their edges infinite; the tree is rooted at that vertex
  (the thesis roots incomplete data trees there, §11.4.2).

Weights: ``weight="length"`` (default) is the geometric length of the branch
polyline in world units, from the vertex voxel it touches at one end, through
its voxels, to the vertex voxel at the other end.  ``weight="count"`` is the
thesis' weight, the number of B-points of the branch.  The pipeline uses the
length: model edge lengths are Euclidean, while a voxel count depends on the
branch's direction in the grid (an axis-aligned run of length L has L voxels,
a diagonal one only L/√2 or L/√3), so counts make limb ratios change with the
pose.  Measured on synthetic humans (``benchmarks/tree.py``, 50³–200³): the
leaf-to-junction path weight over the limb's true bone-chain length is 1.04 on
average (CV 0.25) with ``length`` against 0.72 (CV 0.28) with ``count``, and
the CV of ``length`` is the lower one at every resolution.

Speed: the grid is scanned once (eight voxels per comparison) and everything
else runs on the skeleton's voxel list: about 0.2 ms for a 100³ human skeleton
on one core (``benchmarks/tree.py``).
"""
from __future__ import annotations

import math
from time import perf_counter

import numpy as np

from topopose.errors import InputError
from topopose.match.tree import Tree
from topopose.skeleton.tree_kernels import (B_CLASS, E_CLASS, I_CLASS, branch_contacts, find_voxels,
                           label_voxels, thick_blocks, voxel_graph)

_CLASS_NAME = {E_CLASS: "E", B_CLASS: "B", I_CLASS: "I"}


# --------------------------------------------------------------------------- input checks
def _check_skeleton(skeleton, name="skeleton"):
    arr = skeleton
    if not isinstance(arr, np.ndarray):
        raise InputError(f"{name}: expected a 3D boolean NumPy array (True = skeleton voxel), "
                         f"got {type(skeleton).__name__}")
    if arr.ndim != 3:
        raise InputError(f"{name}: expected a 3D boolean array (axes x, y, z), got shape {arr.shape}")
    if arr.dtype != bool:
        raise InputError(f"{name}: expected a boolean array (True = skeleton voxel), got dtype "
                         f"{arr.dtype}; convert a 0/1 array with `arr.astype(bool)`")
    if arr.size == 0:
        raise InputError(f"{name}: the array is empty (shape {arr.shape}); a data tree needs at "
                         "least one skeleton voxel")
    return np.ascontiguousarray(arr)


def _check_params(origin, voxel_size, border, weight, shape):
    try:
        origin = np.asarray(origin, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InputError("origin: expected 3 numbers (world position of voxel (0,0,0)), "
                         f"got {origin!r}") from None
    if not np.all(np.isfinite(origin)):
        raise InputError(f"origin: expected 3 finite numbers, got {origin.tolist()}")
    try:
        vs = float(voxel_size)
    except (TypeError, ValueError):
        raise InputError(f"voxel_size: expected a positive number, got {voxel_size!r}") from None
    if not (math.isfinite(vs) and vs > 0):
        raise InputError(f"voxel_size: expected a positive number, got {voxel_size!r}")
    if weight not in ("length", "count"):
        raise InputError(f"weight: expected \"length\" or \"count\", got {weight!r}")
    if border is None or (isinstance(border, str) and border == "grid"):
        return origin, vs, border
    if isinstance(border, np.ndarray):
        if border.dtype != bool or border.shape != shape:
            raise InputError(f"border: expected None, \"grid\" or a boolean mask of shape {shape}, "
                             f"got dtype {border.dtype}, shape {border.shape}")
        return origin, vs, border
    raise InputError(f"border: expected None, \"grid\" or a boolean mask of shape {shape}, got {border!r}")


# --------------------------------------------------------------------------- labelling
def _canonical(labels):
    """Relabel 0..C-1 in order of first occurrence."""
    uniq, first, inv = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(uniq.size, np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(uniq.size)
    return rank[inv.reshape(-1)], int(uniq.size)


def label_ndimage(skeleton, idx):
    """Classes and components with :mod:`scipy.ndimage` on the full grid.

    The established-library path of the labelling done by
    :func:`~topopose.skeleton.tree_kernels.label_voxels` (union-find on the
    voxel list, much faster for sparse skeletons); both give identical labels
    (components numbered in the order of their first voxel in C order).
    """
    from scipy import ndimage

    kernel = np.ones((3, 3, 3), np.uint8)
    kernel[1, 1, 1] = 0
    deg = ndimage.convolve(skeleton.astype(np.uint8), kernel, mode="constant", cval=0).reshape(-1)[idx]
    cls = np.where(deg <= 1, E_CLASS, np.where(deg == 2, B_CLASS, I_CLASS)).astype(np.int8)
    struct = np.ones((3, 3, 3), bool)
    comp = np.zeros(idx.size, np.int64)
    offset = 0
    for c in (E_CLASS, B_CLASS, I_CLASS):
        sel = cls == c
        if not sel.any():
            continue
        mask = np.zeros(skeleton.size, bool)
        mask[idx[sel]] = True
        lab, nl = ndimage.label(mask.reshape(skeleton.shape), structure=struct)
        comp[sel] = lab.reshape(-1)[idx[sel]] + offset
        offset += nl
    comp, ncomp = _canonical(comp)
    slab, _ = ndimage.label(skeleton, structure=struct)
    scomp, nscomp = _canonical(slab.reshape(-1)[idx])
    return cls, comp, ncomp, scomp, nscomp


def skeleton_voxels(skeleton):
    """Voxel list, 26-adjacency and degrees of a boolean skeleton.

    Returns ``(idx, coords, nbr, deg)``: sorted C-order linear indices, (n, 3)
    voxel indices, (n, 26) neighbour table (first ``deg[a]`` entries valid).
    """
    skel = _check_skeleton(skeleton)
    flat = skel.reshape(-1).view(np.uint8)
    nw = flat.size // 8
    words = flat[: nw * 8].view(np.uint64)
    idx = find_voxels(flat, words)
    coords, nbr, deg = voxel_graph(flat, idx, *skel.shape)
    return idx, coords, nbr, deg


def classify(skeleton):
    """E/B/I class of every skeleton voxel as an int8 grid (0 background, 1 E, 2 B, 3 I).

    Thesis §7.3.3 (Fig. 7.10).  For pictures and checks.
    """
    idx, _, _, deg = skeleton_voxels(skeleton)
    out = np.zeros(skeleton.size, np.int8)
    out[idx] = np.where(deg <= 1, 1, np.where(deg == 2, 2, 3))
    return out.reshape(skeleton.shape)


# --------------------------------------------------------------------------- tree helpers
def _tree_distances(nv, adj, start):
    dist = np.full(nv, np.inf)
    dist[start] = 0.0
    stack = [start]
    while stack:
        x = stack.pop()
        for y, w in adj[x]:
            if dist[y] == np.inf:
                dist[y] = dist[x] + w
                stack.append(y)
    return dist


def _distances_from_centre(nv, adj):
    """Distances (over a tree's adjacency lists) from its centre (min eccentricity vertex)."""
    d0 = _tree_distances(nv, adj, 0)
    a = int(np.argmax(np.where(np.isfinite(d0), d0, -1)))
    da = _tree_distances(nv, adj, a)
    b = int(np.argmax(np.where(np.isfinite(da), da, -1)))
    db = _tree_distances(nv, adj, b)
    centre = int(np.argmin(np.maximum(da, db)))  # in a tree, the farthest vertex is a or b
    return _tree_distances(nv, adj, centre), centre


def _open_closed_loop(coords, nbr, comp_voxels):
    """Walk a closed B curve from its first voxel; return (P, Q, arc length P→Q, voxels between)."""
    start = int(comp_voxels[0])
    order, arcs = [start], [0.0]
    prev, cur = -1, start
    while True:
        nxt = int(nbr[cur, 0]) if int(nbr[cur, 0]) != prev else int(nbr[cur, 1])
        step = float(np.linalg.norm(coords[nxt] - coords[cur]))
        if nxt == start:
            total = arcs[-1] + step
            break
        order.append(nxt)
        arcs.append(arcs[-1] + step)
        prev, cur = cur, nxt
    arcs = np.asarray(arcs)
    q = int(np.argmin(np.abs(arcs - total / 2)))
    return start, order[q], float(arcs[q]), q - 1, total


# --------------------------------------------------------------------------- main entry
def _check_options(small_cycle, small_loop, labelling):
    """The options of :func:`data_tree` checked (InputError naming the bad one)."""
    if not (isinstance(small_cycle, (int, float)) and 0 <= small_cycle <= 1):
        raise InputError(f"small_cycle: expected a fraction in [0, 1], got {small_cycle!r}")
    if not (isinstance(small_loop, (int, float)) and not isinstance(small_loop, bool)
            and 0 <= small_loop < math.inf):
        raise InputError(f"small_loop: expected a number of voxels ≥ 0, got {small_loop!r}")
    if labelling not in ("voxels", "ndimage"):
        raise InputError(f"labelling: expected \"voxels\" or \"ndimage\", got {labelling!r}")


def _raw_edges(coords, nbr, deg, cls, comp, ncomp, kept_comp, vid, csize):
    """The data tree's edges before the cycles are broken: B components (Alg. 13, lines
    10-11) and direct E–I contacts, digital triangles absorbed; ``(raw, dsteps, triangles)``."""
    bb, contacts, csteps, direct, dsteps = branch_contacts(coords, nbr, deg, cls, comp, ncomp)
    order = np.argsort(contacts[:, 0], kind="stable")
    contacts, csteps = contacts[order], csteps[order]
    if contacts.shape[0] % 2 or np.any(contacts[0::2, 0] != contacts[1::2, 0]):
        raise AssertionError("a B component with other than two contacts (impossible for "
                             "voxels of degree 2)")
    c1, c2 = contacts[0::2], contacts[1::2]
    bcomp = c1[:, 0]
    sel = kept_comp[bcomp]
    c1, c2, bcomp = c1[sel], c2[sel], bcomp[sel]
    s1, s2 = csteps[0::2][sel], csteps[1::2][sel]
    # each edge: u, v, length (voxel units), count, contact voxel at u, contact voxel at v
    # (and its B component, -1 for none: kept beside the tree for Tree.voxels)
    raw = list(zip(vid[c1[:, 1]].tolist(), vid[c2[:, 1]].tolist(),
                   (bb[bcomp] + s1 + s2).tolist(), csize[bcomp].tolist(),
                   c1[:, 3].tolist(), c2[:, 3].tolist(), bcomp.tolist()))
    dsel = kept_comp[direct[:, 0]]
    direct, dsteps = direct[dsel], dsteps[dsel]
    raw += list(zip(vid[direct[:, 0]].tolist(), vid[direct[:, 1]].tolist(), dsteps.tolist(),
                    [0] * len(dsteps), direct[:, 2].tolist(), direct[:, 3].tolist(),
                    [-1] * len(dsteps)))

    # a loop of one B voxel whose two contacts touch each other is a digital triangle
    # (three mutually adjacent voxels, e.g. the corner of an axis-aligned bend): it encloses
    # no hole, so it is absorbed into its vertex instead of being read as a limb.
    triangles = 0
    kept_raw = []
    for e in raw:
        if e[0] == e[1] and e[3] == 1 and np.abs(coords[e[4]] - coords[e[5]]).max() <= 1:
            triangles += 1
        else:
            kept_raw.append(e)
    raw = kept_raw

    return raw, dsteps, triangles


def _break_cycles(raw, nv, positions, vclass, world, coords, vs, small_cycle, small_loop, diag):
    """Kruskal over the lengths: each rejected edge is the longest of its cycle, dropped (a
    skeleton bubble) or detached at its contact end as a new leaf (``positions``, ``vclass``
    and ``diag`` updated); returns ``(edges, n_vertices)``."""
    parent = list(range(nv))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    tree_e, rejected = [], []
    for e in sorted(raw, key=lambda e: e[2]):  # stable: ties keep construction order
        ru, rv = find(e[0]), find(e[1])
        if ru == rv:
            rejected.append(e)
        else:
            parent[ru] = rv
            tree_e.append(e)
    adj = [[] for _ in range(nv)]
    for u, v, length, *_ in tree_e:
        adj[u].append((v, length))
        adj[v].append((u, length))
    dist, centre = _distances_from_centre(nv, adj)
    total = sum(e[2] for e in raw)
    mdeg = [0] * nv
    for u, v, *_ in raw:
        mdeg[u] += 1
        mdeg[v] += 1
    edges = tree_e
    for u, v, length, count, eu, ev, bc in rejected:
        diag["loops" if u == v else "cycles_broken"] += 1
        # the cycle this branch closes: the branch plus the spanning-tree path between its ends
        # (for a loop, the gap between its two contact voxels inside the vertex component)
        if u == v:
            perimeter = length + float(np.linalg.norm(coords[eu] - coords[ev]))
        else:
            perimeter = length + _tree_distances(nv, adj, u)[v]
        if perimeter < small_cycle * total or perimeter <= small_loop:
            # a skeleton bubble (a small tunnel of the hull): two parallel paths for one
            # stretch of limb; the longer one is dropped, nothing is detached
            diag["small_cycles"] += 1
            diag["dropped_branches"].append(length * vs)
            mdeg[u] -= 1
            mdeg[v] -= 1
            continue
        if u == v:
            keep_end, cut_end, cut_vox = u, v, ev
        else:
            # detach at the contact end: the lower-degree end (a tip landing on a branch
            # makes a degree-3 junction, degree 2 once detached); tie: farther from centre
            if (mdeg[u], -dist[u]) < (mdeg[v], -dist[v]):
                keep_end, cut_end, cut_vox = v, u, eu
            else:
                keep_end, cut_end, cut_vox = u, v, ev
        mdeg[cut_end] -= 1
        w = len(positions)
        positions.append(world[cut_vox])
        vclass.append("cut")
        edges.append((keep_end, w, length, count, cut_vox, cut_vox, bc))
        diag["cuts"].append({"edge": [keep_end, w], "detached_from": cut_end,
                             "length": length * vs, "loop": u == v,
                             "perimeter": perimeter * vs})
    diag["centre"] = centre
    nv = len(positions)
    return edges, nv


def _border_vertices(border, coords, shape, idx, comp, ncomp, vcomps, ccls, vid, diag) -> set:
    """Incomplete models (§7.3.3.1): the E components on the border, whose edges become
    infinite (``diag["border_vertices"]``, ``diag["border_vertex"]``)."""
    if isinstance(border, str):
        on = ((coords == 0) | (coords == np.asarray(shape) - 1)).any(1)
    else:
        on = border.reshape(-1)[idx]
    hits = np.bincount(comp[on], minlength=ncomp)
    bverts = [(int(-hits[c]), int(vid[c])) for c in vcomps if ccls[c] == E_CLASS and hits[c] > 0]
    bverts.sort()
    inf_vertices = {v for _, v in bverts}
    diag["border_vertices"] = [v for _, v in bverts]
    diag["border_vertex"] = bverts[0][1] if bverts else None
    return inf_vertices


def _components(n, cls, comp, ncomp, scomp, nscomp, coords, origin, vs):
    """Per-component facts and the data tree's vertices (E components, then I components:
    Alg. 13, lines 6-9): ``(ccls, csize, dropped, kept_comp, vcomps, vid, world, positions,
    vclass)``."""
    # ---- per-component facts (components are numbered in the order of their first voxel)
    first = np.empty(ncomp, np.int64)
    first[comp[::-1]] = np.arange(n - 1, -1, -1)
    ccls = cls[first]
    csize = np.bincount(comp, minlength=ncomp)
    cscomp = scomp[first]
    if nscomp > 1:
        ssize = np.bincount(scomp, minlength=nscomp)
        keep = int(np.argmax(ssize))
        dropped = sorted((int(s) for i, s in enumerate(ssize) if i != keep), reverse=True)
    else:
        keep, dropped = 0, []
    kept_comp = cscomp == keep

    # ---- vertices: E components then I components (Alg. 13, lines 6-9)
    is_vertex = kept_comp & (ccls != B_CLASS)
    vcomps = np.concatenate([np.flatnonzero(is_vertex & (ccls == E_CLASS)),
                             np.flatnonzero(is_vertex & (ccls == I_CLASS))])
    vid = np.full(ncomp, -1, np.int64)
    vid[vcomps] = np.arange(vcomps.size)
    world = origin + coords * vs
    cent = np.stack([np.bincount(comp, weights=world[:, d], minlength=ncomp) for d in range(3)], 1)
    cent /= csize[:, None]
    positions = [cent[c] for c in vcomps]
    vclass = [_CLASS_NAME[int(ccls[c])] for c in vcomps]
    return ccls, csize, dropped, kept_comp, vcomps, vid, world, positions, vclass


def _weighted(edges, inf_vertices, vs, weight, vclass, nv, idx, vid, comp, ncomp, diag):
    """The weighted edges (infinite at the border vertices) and which voxel makes which
    vertex or edge (segmentation, thesis §13.3.1.1): ``(out, voxels)``."""
    out = []
    for u, v, length, count, *_ in edges:
        if u in inf_vertices or v in inf_vertices:
            w = math.inf
        else:
            w = length * vs if weight == "length" else float(count)
        out.append((u, v, w))
    diag["vertex_class"] = {i: c for i, c in enumerate(vclass)}
    degs = np.zeros(nv, np.int64)
    for u, v, _ in out:
        degs[u] += 1
        degs[v] += 1
    diag["max_degree"] = int(degs.max()) if nv else 0
    # which voxel makes which vertex or edge (segmentation, thesis §13.3.1.1)
    ecomp = np.full(ncomp, -1, np.int64)
    for j, e in enumerate(edges):
        if e[6] >= 0:
            ecomp[e[6]] = j
    voxels = {"index": idx, "vertex": vid[comp], "edge": ecomp[comp]}
    return out, voxels


def data_tree(skeleton, origin=(0.0, 0.0, 0.0), voxel_size=1.0, border=None, weight="length",
              *, small_cycle=0.03, small_loop=8.0, labelling="voxels") -> Tree:
    """Build the data tree of a curve skeleton (thesis §7.3.3, Alg. 13).

    Parameters
    ----------
    skeleton : ndarray of bool, shape (nx, ny, nz), or :class:`~topopose.hull.Volume`
        A curve skeleton (e.g. ``tp.thin(volume, method="d6i1d")``), axes x, y, z.
        A ``Volume`` brings its own origin and voxel size (used when ``origin``
        and ``voxel_size`` are left at their defaults).
    origin : (3,) float
        World position of the centre of voxel (0, 0, 0).
    voxel_size : float
        Voxel edge length in world units.
    border : None, "grid" or ndarray of bool (same shape)
        Incomplete models (§7.3.3.1): E components holding a border voxel — a
        voxel on the array's faces for ``"grid"``, a True voxel of the mask
        otherwise — make their edges infinite; ``diagnostics["border_vertex"]``
        names that vertex and the tree is rooted there.
    weight : "length" or "count"
        Edge weight: geometric branch length in world units (default) or the
        thesis' B-point count.  See the module docstring for why length.
    small_cycle : float
        A cycle (or loop) whose perimeter is below this fraction of the total
        branch length is a skeleton *bubble* (a small tunnel of the hull, e.g.
        at a junction), not limbs touching: its longest branch is dropped
        instead of detached (``diagnostics["small_cycles"]``).  0 detaches all.
        Default 0.03 (see the module docstring for the measurement).
    small_loop : float
        A cycle whose perimeter is at most this many voxels is a bubble too,
        whatever the skeleton's total length (0: off).  Eight voxels enclose a
        tunnel under three voxels wide: two limbs touching enclose at least the
        limbs' own length, while noisy visual hulls at 100³ hold tunnels of 6–7
        voxels round that, detached, became two spurious leaves 3–4 voxels long
        matched as a head or a hand (``benchmarks/quality.py``, human, noise 1).
    labelling : "voxels" or "ndimage"
        Component labelling by union-find on the voxel list (fast, default)
        or by :func:`scipy.ndimage.label` on the full grid; the results agree.

    Returns
    -------
    Tree
        Integer vertex ids (E components first, then I components, then the
        leaves made when breaking cycles), world ``positions`` (component
        centroids), ``root`` = the border vertex or None, and ``diagnostics``:
        ``n_voxels``, ``voxel_classes``, ``components``, ``dropped_components``
        (voxel counts of the components not kept), ``direct_edges`` (E–I
        contacts with no branch between), ``loops``, ``cycles_broken``,
        ``cuts`` (per detached branch: ``edge`` [kept end, new leaf],
        ``detached_from``, ``length``, ``perimeter`` of its cycle, ``loop``),
        ``closed_loop``, ``border_vertex``, ``border_vertices``,
        ``vertex_class``, ``weight``, ``max_degree``, ``thick_squares``,
        ``thick_cubes``, ``time_ms``.

    Raises
    ------
    InputError
        Not a 3D boolean array, no skeleton voxel, or not a curve skeleton:
        more than half of the voxels are intersection points and there are at
        least half as many full 2×2 squares as voxels (a surface or a solid,
        e.g. a volume passed instead of its skeleton).

    Examples
    --------
    >>> import numpy as np
    >>> s = np.zeros((9, 9, 3), bool)
    >>> for j in range(0, 5): s[4, j, 1] = True                   # stem along y
    >>> for d in range(1, 4): s[4 - d, 4 + d, 1] = s[4 + d, 4 + d, 1] = True  # two diagonal arms
    >>> t = data_tree(s)
    >>> t.n_vertices, [round(w, 3) for _, _, w in t.edges]
    (4, [4.243, 4.0, 4.243])
    """
    t0 = perf_counter()
    if hasattr(skeleton, "data") and hasattr(skeleton, "origin") and hasattr(skeleton, "voxel_size"):
        if np.allclose(np.asarray(origin, dtype=float), 0.0) and voxel_size == 1.0:
            origin, voxel_size = skeleton.origin, skeleton.voxel_size
        skeleton = skeleton.data
    skel = _check_skeleton(skeleton)
    origin, vs, border = _check_params(origin, voxel_size, border, weight, skel.shape)
    _check_options(small_cycle, small_loop, labelling)
    shape = skel.shape
    flat = skel.reshape(-1).view(np.uint8)
    nw = flat.size // 8
    idx = find_voxels(flat, flat[: nw * 8].view(np.uint64))
    n = int(idx.size)
    if n == 0:
        raise InputError(f"skeleton: no voxel is set (shape {shape}); an empty skeleton has no data "
                         "tree (was the visual hull empty?)")
    coords, nbr, deg = voxel_graph(flat, idx, *shape)
    if labelling == "voxels":
        cls, comp, ncomp, scomp, nscomp = label_voxels(nbr, deg)
    else:
        cls, comp, ncomp, scomp, nscomp = label_ndimage(skel, idx)
    ncls = np.bincount(cls, minlength=3)
    squares, cubes = thick_blocks(flat, coords, *shape)
    # a solid or a surface: mostly I-points and made of full 2x2 squares.  Real skeletons of
    # visual hulls with many tunnels can be mostly I-points (dense nets of short curves, a few
    # squares inside junctions), so both conditions are required.
    if ncls[I_CLASS] * 2 > n and squares * 2 >= n:
        raise InputError(
            f"skeleton: not a curve skeleton: {ncls[I_CLASS]} of its {n} voxels have more than two "
            f"neighbours and it holds {squares} full 2x2 squares and {cubes} full 2x2x2 blocks "
            "(a surface or a solid). Thin the volume first (tp.thin / `topopose skeleton`).")

    ccls, csize, dropped, kept_comp, vcomps, vid, world, positions, vclass = _components(
        n, cls, comp, ncomp, scomp, nscomp, coords, origin, vs)

    raw, dsteps, triangles = _raw_edges(coords, nbr, deg, cls, comp, ncomp, kept_comp, vid,
                                        csize)

    diag = {"n_voxels": n,
            "voxel_classes": {"E": int(ncls[E_CLASS]), "B": int(ncls[B_CLASS]), "I": int(ncls[I_CLASS])},
            "components": int(nscomp), "dropped_components": dropped,
            "direct_edges": int(len(dsteps)), "triangles": triangles, "loops": 0, "cycles_broken": 0,
            "small_cycles": 0, "dropped_branches": [], "cuts": [],
            "closed_loop": False, "border_vertex": None, "border_vertices": [],
            "weight": weight, "thick_squares": int(squares), "thick_cubes": int(cubes)}

    # ---- an isolated closed curve: no vertex at all
    closed = np.flatnonzero(kept_comp & (ccls == B_CLASS))
    if vcomps.size == 0 and closed.size:
        vox = np.flatnonzero(comp == closed[0])
        p, q, arc, between, total = _open_closed_loop(coords, nbr, vox)
        positions = [world[p], world[q]]
        vclass = ["loop", "loop"]
        raw = [(0, 1, arc, between, p, q, int(closed[0]))]
        diag["closed_loop"] = True
        diag["closed_loop_length"] = total * vs

    nv = len(positions)
    # ---- cycles: Kruskal over the lengths; rejected edges are the longest of their cycle
    edges = raw
    if len(raw) > nv - 1:
        edges, nv = _break_cycles(raw, nv, positions, vclass, world, coords, vs, small_cycle,
                                  small_loop, diag)

    # ---- incomplete models: E components on the border (§7.3.3.1)
    inf_vertices = set()
    if border is not None and not diag["closed_loop"]:
        inf_vertices = _border_vertices(border, coords, shape, idx, comp, ncomp, vcomps, ccls,
                                        vid, diag)

    out, voxels = _weighted(edges, inf_vertices, vs, weight, vclass, nv, idx, vid, comp, ncomp,
                            diag)
    diag["time_ms"] = (perf_counter() - t0) * 1e3
    return Tree(out, vertices=list(range(nv)), positions=dict(enumerate(positions)),
                root=diag["border_vertex"], diagnostics=diag, voxels=voxels)
