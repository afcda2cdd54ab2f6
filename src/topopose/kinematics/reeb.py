"""Per-frame shape structure: surface mesh, integral geodesic function, Reeb graph, pERG.

Mukasa et al. §2 steps 2–3 and §2.1:

1. the surface of the visual hull by marching cubes (:func:`surface_mesh`, scikit-image);
2. the integral geodesic function μ(v) = Σ_p g(v, p) (eq. 1) on the mesh
   (:func:`integral_geodesic`). Exact all-pairs geodesics are too slow for meshes of
   10–30 k vertices, so — as Hilaga et al. (ref. [10]) do — μ is summed over a sample of
   *base points* drawn uniformly over the surface area (default 128), each a Dijkstra run
   over the mesh edge graph (``scipy.sparse.csgraph.dijkstra``). μ is normalized to [0, 1]
   with ``(μ - min μ) / (max μ - min μ)``;
3. the Reeb graph of μ quantized in K levels: a node per connected piece of surface
   within one level, an edge between pieces of consecutive levels that touch; the surface
   is cut into triangle pieces at the level boundaries (Hilaga et al.'s T-sets,
   :func:`tset_atoms`) so that thin bands stay connected at fine levels. The levels
   K = 2^r for r = r0 … R form the multiresolution Reeb graph of Hilaga et al. (each node
   of level r is the union of nodes of level r + 1);
4. the pseudo-endoskeleton Reeb graph, pERG (:func:`perg`): start from the coarse level and
   replace every node whose centroid — or every edge whose segment — lies outside the
   volume by its children of the next finer level, recursively, so that all nodes and edges
   end up inside the volume (§2.1, Fig. 1).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.ndimage as ndi
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from topopose.errors import InputError


# --------------------------------------------------------------------------- mesh
@dataclass
class Mesh:
    """A triangle mesh in world coordinates with its edge graph."""

    verts: np.ndarray          # (n, 3) float
    faces: np.ndarray          # (m, 3) int
    edges: np.ndarray          # (e, 2) int, unique, i < j
    lengths: np.ndarray        # (e,) float
    area: np.ndarray           # (n,) vertex area (one third of the adjacent faces' areas)

    @property
    def n(self) -> int:
        return len(self.verts)

    def graph(self):
        """Symmetric sparse matrix of edge lengths (the mesh edge graph, both directions)."""
        n = self.n
        e, w = self.edges, self.lengths
        return coo_matrix((np.r_[w, w], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                          shape=(n, n)).tocsr()


def surface_mesh(data: np.ndarray, origin=(0, 0, 0), voxel_size: float = 1.0,
                 step_size: int = 1, largest: bool = True) -> Mesh:
    """Surface of a boolean volume by marching cubes (Mukasa §2 step 2).

    Parameters
    ----------
    data : bool array (nx, ny, nz)
    origin, voxel_size : placement of voxel (0, 0, 0)'s centre in the world.
    step_size : int
        Marching-cubes step (2 quarters the number of vertices).
    largest : bool
        Keep only the largest connected piece of surface.
    """
    from skimage.measure import marching_cubes

    data = np.asarray(data, bool)
    if data.ndim != 3 or not data.any():
        raise InputError("volume: empty or not 3D; no surface to mesh")
    f = np.pad(data, 1).astype(np.float32)
    verts, faces, _, _ = marching_cubes(f, level=0.5, step_size=int(step_size),
                                        allow_degenerate=False)
    verts = np.asarray(origin, float) + (verts.astype(float) - 1.0) * float(voxel_size)
    faces = faces.astype(np.int64)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    e = np.unique(e, axis=0)
    if largest:
        n = len(verts)
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
        nc, lab = connected_components(g, directed=False)
        if nc > 1:
            keep = lab == np.bincount(lab).argmax()
            remap = -np.ones(n, np.int64)
            remap[keep] = np.arange(keep.sum())
            verts = verts[keep]
            faces = remap[faces]
            faces = faces[(faces >= 0).all(1)]
            e = remap[e]
            e = e[(e >= 0).all(1)]
    lengths = np.linalg.norm(verts[e[:, 0]] - verts[e[:, 1]], axis=1)
    tri = verts[faces]
    fa = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    area = np.bincount(faces.ravel(), weights=np.repeat(fa / 3.0, 3), minlength=len(verts))
    return Mesh(verts, faces, e, np.maximum(lengths, 1e-12), area)


def integral_geodesic(mesh: Mesh, n_base: int = 128, seed: int = 0) -> np.ndarray:
    """Normalized integral geodesic function μ (Mukasa eq. 1) by base-point sampling.

    μ(v) = Σ_b A_b g(v, b) over ``n_base`` base points b scattered evenly over the surface
    (geodesic farthest-point sampling from a seeded start) and weighted by the area A_b of
    their geodesic Voronoi cells — the approximation of Hilaga et al. (ref. [10]) of the
    integral over the surface. One Dijkstra run per base point over the mesh edge graph.
    ``n_base >= mesh.n`` gives the exact eq. 1 (every vertex, unit weights). Returned
    normalized to [0, 1]: ``(μ - min) / (max - min)``.
    """
    n = mesh.n
    G = mesh.graph()
    if n_base >= n:
        d = dijkstra(G, directed=True)
        d[~np.isfinite(d)] = 0.0
        mu = d.sum(0)
    else:
        rng = np.random.default_rng(seed)
        start = int(rng.integers(n))
        rows = np.empty((n_base, n))
        nearest = np.full(n, np.inf)
        b = start
        for k in range(n_base):
            rows[k] = dijkstra(G, directed=True, indices=b)   # G is symmetric
            np.minimum(nearest, rows[k], out=nearest)
            b = int(np.argmax(np.where(np.isfinite(nearest), nearest, -1)))
        rows[~np.isfinite(rows)] = 0.0
        cell = rows.argmin(0)                  # geodesic Voronoi cell of each vertex
        A = np.bincount(cell, weights=mesh.area, minlength=n_base)
        mu = A @ rows
    lo, hi = mu.min(), mu.max()
    return (mu - lo) / (hi - lo) if hi > lo else np.zeros(n)


# --------------------------------------------------------------------------- Reeb graph
@dataclass
class ReebLevel:
    """The Reeb graph of μ quantized in ``bins`` levels.

    ``label[v]`` is the node of mesh vertex v; ``edges`` are node pairs (i < j).
    """

    bins: int
    label: np.ndarray
    n_nodes: int
    edges: np.ndarray
    node_bin: np.ndarray


def reeb_levels(mesh: Mesh, mu: np.ndarray, bins: int) -> ReebLevel:
    """Reeb graph of μ in ``bins`` equal levels (Mukasa §2.1; Hilaga et al. R-nodes)."""
    b = np.minimum((mu * bins).astype(np.int64), bins - 1)
    e = mesh.edges
    same = b[e[:, 0]] == b[e[:, 1]]
    n = mesh.n
    g = coo_matrix((np.ones(int(same.sum())), (e[same, 0], e[same, 1])), shape=(n, n))
    nc, lab = connected_components(g, directed=False)
    node_bin = np.zeros(nc, np.int64)
    node_bin[lab] = b
    return ReebLevel(bins, lab, nc, _node_edges(lab, e), node_bin)


def _node_edges(label, e):
    a, c = label[e[:, 0]], label[e[:, 1]]
    m = a != c
    pairs = np.sort(np.stack([a[m], c[m]], 1), axis=1)
    return np.unique(pairs, axis=0) if len(pairs) else np.zeros((0, 2), np.int64)


@dataclass
class Atoms:
    """The smallest surface pieces a multiresolution Reeb graph is built from.

    Vertices (``"vertices"``) or, with Hilaga's T-sets, the pieces of every triangle cut
    by the finest μ levels (``"tsets"``). ``labels[r]`` gives each atom's node at level r
    and ``levels[r]`` the :class:`ReebLevel` (node μ bins).
    """

    weight: np.ndarray     # (a,) area
    points: np.ndarray     # (a, 3) representative point
    mu: np.ndarray         # (a,)
    pairs: np.ndarray      # (p, 2) adjacent atoms
    labels: dict
    levels: dict


def vertex_atoms(mesh: Mesh, mu: np.ndarray, r0: int, R: int) -> Atoms:
    """Atoms = mesh vertices; a level's pieces are connected sets of same-level vertices."""
    levels = {r: reeb_levels(mesh, mu, 2 ** r) for r in range(r0, R + 1)}
    return Atoms(mesh.area, mesh.verts, mu, mesh.edges, {r: levels[r].label for r in levels}, levels)


def tset_atoms(mesh: Mesh, mu: np.ndarray, r0: int, R: int) -> Atoms:
    """Atoms = triangle pieces between consecutive finest μ levels (Hilaga et al.'s T-sets).

    A triangle whose vertices span levels lo … hi holds one piece per level; at a level k two
    triangles sharing an edge are connected when the edge's μ range meets level k, so a band
    stays connected however many levels one edge crosses (no crumbs at fine levels, no
    level-skipping edges). Pieces of consecutive levels of one triangle are adjacent.
    """
    F = mesh.faces
    m = len(F)
    # triangles sharing each edge, as consecutive runs of the sorted edge keys
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    fid = np.tile(np.arange(m), 3)
    e.sort(axis=1)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, fid = e[order], fid[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    fa, fb, eu, ev = fid[:-1][same], fid[1:][same], e[:-1][same, 0], e[:-1][same, 1]
    tri = mesh.verts[F]
    farea = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    labels, levels, offR, loR, spanR = {}, {}, None, None, None
    for r in range(R, r0 - 1, -1):
        K = 2 ** r
        b = np.minimum((mu * K).astype(np.int64), K - 1)
        bf = b[F]
        lo, hi = bf.min(1), bf.max(1)
        span = hi - lo + 1
        off = np.concatenate([[0], np.cumsum(span)])
        n_p = int(off[-1])
        # same-level links across shared edges
        klo = np.minimum(b[eu], b[ev])
        cnt = np.abs(b[eu] - b[ev]) + 1
        rep = np.repeat(np.arange(len(fa)), cnt)
        k = klo[rep] + (np.arange(len(rep)) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        pa = off[fa[rep]] + k - lo[fa[rep]]
        pb = off[fb[rep]] + k - lo[fb[rep]]
        g = coo_matrix((np.ones(len(pa)), (pa, pb)), shape=(n_p, n_p))
        nc, lab = connected_components(g, directed=False)
        piece_bin = np.repeat(lo, span) + (np.arange(n_p) - np.repeat(off[:-1], span))
        node_bin = np.zeros(nc, np.int64)
        node_bin[lab] = piece_bin
        if r == R:
            offR, loR, spanR, binR, KR = off, lo, span, piece_bin, K
            labels[r] = lab
            # node edges: consecutive levels within a triangle
            fpiece = np.repeat(np.arange(m), span)
            nxt = np.arange(n_p - 1)
            ok = (fpiece[:-1] == fpiece[1:])
            cross = np.stack([nxt[ok], nxt[ok] + 1], 1)
            levels[r] = ReebLevel(K, lab, nc, _node_edges(lab, cross), node_bin)
        else:
            # atom (f, kR) -> piece (f, kR >> (R - r)) of this level
            fpiece = np.repeat(np.arange(m), spanR)
            kr = binR >> (R - r)
            labels[r] = lab[off[fpiece] + kr - lo[fpiece]]
            levels[r] = ReebLevel(K, labels[r], nc, np.zeros((0, 2), np.int64), node_bin)
    # atoms = finest pieces: weight, representative point, μ
    fpiece = np.repeat(np.arange(m), spanR)
    mid = (binR + 0.5) / KR
    pts = np.zeros((len(binR), 3))
    for a_, b_ in ((0, 1), (1, 2), (2, 0)):
        ma, mb = mu[F[fpiece, a_]], mu[F[fpiece, b_]]
        den = mb - ma
        t = np.where(np.abs(den) > 1e-15, (mid - ma) / np.where(np.abs(den) > 1e-15, den, 1.0), 0.5)
        t = np.clip(t, 0.0, 1.0)[:, None]
        pts += mesh.verts[F[fpiece, a_]] + t * (mesh.verts[F[fpiece, b_]] - mesh.verts[F[fpiece, a_]])
    pts /= 3.0
    fmu = mu[F]
    amu = np.clip(mid, fmu.min(1)[fpiece], fmu.max(1)[fpiece])
    w = farea[fpiece] / spanR[fpiece]
    # atom adjacency: same-level links at R plus consecutive levels within a triangle
    K = KR
    b = np.minimum((mu * K).astype(np.int64), K - 1)
    klo = np.minimum(b[eu], b[ev])
    cnt = np.abs(b[eu] - b[ev]) + 1
    rep = np.repeat(np.arange(len(fa)), cnt)
    k = klo[rep] + (np.arange(len(rep)) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    same_pairs = np.stack([offR[fa[rep]] + k - loR[fa[rep]], offR[fb[rep]] + k - loR[fb[rep]]], 1)
    n_p = len(binR)
    nxt = np.arange(n_p - 1)
    ok = fpiece[:-1] == fpiece[1:]
    pairs = np.concatenate([same_pairs, np.stack([nxt[ok], nxt[ok] + 1], 1)])
    return Atoms(w, pts, amu, pairs, labels, levels)


@dataclass
class PERG:
    """A pseudo-endoskeleton Reeb graph of one frame (Mukasa §2.1).

    Attributes
    ----------
    positions : (k, 3) node positions (area-weighted centroids of their surface pieces).
    edges : (e, 2) node pairs.
    mu : (k,) mean normalized μ of each node.
    level : (k,) resolution level (number of bins) each node comes from.
    diagnostics : dict (mesh size, outside nodes left, loops, timings ...).
    """

    positions: np.ndarray
    edges: np.ndarray
    mu: np.ndarray
    level: np.ndarray
    diagnostics: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.positions)

    def adjacency(self) -> list:
        adj = [[] for _ in range(self.n)]
        for a, b in self.edges:
            adj[a].append(int(b))
            adj[b].append(int(a))
        return adj

    def degrees(self) -> np.ndarray:
        return np.bincount(self.edges.ravel(), minlength=self.n) if len(self.edges) else np.zeros(self.n, int)

    def n_loops(self) -> int:
        """Independent cycles (first Betti number) of the graph."""
        if self.n == 0:
            return 0
        g = coo_matrix((np.ones(len(self.edges)), (self.edges[:, 0], self.edges[:, 1])),
                       shape=(self.n, self.n))
        nc, _ = connected_components(g, directed=False)
        return int(len(self.edges) - self.n + nc)

    def signature(self) -> tuple:
        """``(end points, sorted branch degrees descending, loops)`` (§2.2 'topology')."""
        d = self.degrees()
        return (int((d == 1).sum()), tuple(sorted((int(x) for x in d[d >= 3]), reverse=True)),
                self.n_loops())


def _inside(points, inside_mask, origin, voxel_size):
    idx = np.rint((np.asarray(points, float) - origin) / voxel_size).astype(np.int64)
    shape = np.array(inside_mask.shape)
    ok = np.all((idx >= 0) & (idx < shape), axis=-1)
    res = np.zeros(len(idx), bool)
    res[ok] = inside_mask[tuple(idx[ok].T)]
    return res


def perg(data: np.ndarray, origin=(0, 0, 0), voxel_size: float = 1.0, *, coarse: int = 16,
         fine: int = 64, n_base: int = 64, step_size: int = 1, tolerance: int = 1,
         prune: float = 0.04, persistence: float = 0.1, seed: int = 0,
         max_level_fraction: float = 0.5, tsets: bool = True,
         mesh: Mesh | None = None) -> PERG:
    """The pERG of one frame (Mukasa §2.1, Fig. 1).

    Parameters
    ----------
    data, origin, voxel_size : the frame's volume.
    coarse, fine : int
        Number of μ levels of the coarsest and finest Reeb graphs of the multiresolution
        hierarchy (powers of two; each level doubles the previous one).
    tsets : bool
        Build the levels from triangle pieces (Hilaga et al.'s T-sets, :func:`tset_atoms`;
        default). False: from vertices (:func:`vertex_atoms`), which breaks bands into
        crumbs at levels finer than μ's change along one mesh edge, so both level counts
        are then clamped so that 95 % of the mesh edges change μ by at most
        ``max_level_fraction`` level (at 100³ a human allows about 16 levels).
    n_base : int
        Base points for μ (Hilaga sampling; see :func:`integral_geodesic`).
    step_size : int
        Marching-cubes step.
    tolerance : int
        A node or edge is "inside" when it lies in the volume dilated by this many voxels
        (the centroid of a thin limb's surface ring may fall half a voxel off its axis).
    prune, persistence : float
        End branches shorter than ``prune`` × the subject's extent, or whose μ rises by
        less than ``persistence`` from their branch point to their end point (a low
        persistence pair of critical points: a bump of the surface, not a limb), are
        removed (0 and 0 keep everything).
    """
    import time

    t0 = time.perf_counter()
    data = np.asarray(data, bool)
    origin = np.asarray(origin, float)
    if mesh is None:
        mesh = surface_mesh(data, origin, voxel_size, step_size=step_size)
    t1 = time.perf_counter()
    mu = integral_geodesic(mesh, n_base=n_base, seed=seed)
    t2 = time.perf_counter()
    r0 = int(round(np.log2(coarse)))
    R = int(round(np.log2(fine)))
    if 2 ** r0 != coarse or 2 ** R != fine or r0 > R:
        raise InputError(f"perg: coarse={coarse} and fine={fine} must be powers of two, coarse <= fine")
    # Without T-sets, levels finer than μ's change along one mesh edge break every band into
    # crumbs: clamp the levels.
    dmu = np.abs(mu[mesh.edges[:, 0]] - mu[mesh.edges[:, 1]])
    if tsets:
        r_max = R
    else:
        r_max = int(np.floor(np.log2(max_level_fraction / max(np.percentile(dmu, 95), 1e-12))))
        r0 = max(min(r0, r_max), 1)
    R = max(min(R, r_max), r0)
    atoms = tset_atoms(mesh, mu, r0, R) if tsets else vertex_atoms(mesh, mu, r0, R)
    levels = atoms.levels
    inside = ndi.binary_dilation(data, iterations=tolerance) if tolerance > 0 else data
    w = atoms.weight
    na = len(w)

    # active node = (level r, node id at that level); atom -> active node by label maps
    active = {(r0, i) for i in range(levels[r0].n_nodes)}
    children = {}
    for r in range(r0, R):
        # child node of level r+1 -> parent node at level r, via any atom
        par = np.zeros(levels[r + 1].n_nodes, np.int64)
        par[atoms.labels[r + 1]] = atoms.labels[r]
        ch = {}
        for c, p in enumerate(par):
            ch.setdefault(int(p), []).append(c)
        children[r] = ch
    for _ in range(R - r0 + 1):
        act = sorted(active)
        ids = {a: i for i, a in enumerate(act)}
        key = np.full(na, -1, np.int64)
        for r in range(r0, R + 1):
            lut = np.full(levels[r].n_nodes, -1, np.int64)
            for (rr, i) in act:
                if rr == r:
                    lut[i] = ids[(rr, i)]
            mm = lut[atoms.labels[r]]
            sel = (mm >= 0) & (key < 0)
            key[sel] = mm[sel]
        k = len(act)
        wsum = np.bincount(key, weights=w, minlength=k)
        pos = np.stack([np.bincount(key, weights=w * atoms.points[:, c], minlength=k) for c in range(3)], 1)
        pos /= np.maximum(wsum, 1e-300)[:, None]
        E = _node_edges(key, atoms.pairs)
        E = _adjacent_levels(E, act, levels, R)
        bad = set()
        out_nodes = ~_inside(pos, inside, origin, voxel_size)
        for i in np.nonzero(out_nodes)[0]:
            bad.add(act[i])
        for a, b in E:
            seg = _segment_points(pos[a], pos[b], voxel_size)
            if not _inside(seg, inside, origin, voxel_size).all():
                ra, rb = act[a][0], act[b][0]
                if ra <= rb:
                    bad.add(act[a])
                if rb <= ra:
                    bad.add(act[b])
        bad = {a for a in bad if a[0] < R}
        if not bad:
            break
        for (r, i) in bad:
            active.discard((r, i))
            active.update((r + 1, c) for c in children[r][i])
    mu_node = np.bincount(key, weights=w * atoms.mu, minlength=k) / np.maximum(wsum, 1e-300)
    lvl = np.array([2 ** a[0] for a in act])
    g = PERG(pos, E.astype(np.int64), mu_node, lvl)
    extent = float(np.ptp(mesh.verts, axis=0).max())
    if prune > 0 or persistence > 0:
        g = prune_branches(g, prune * extent, persistence)
    g.diagnostics.update({
        "mesh_vertices": int(mesh.n), "base_points": int(min(n_base, mesh.n)),
        "outside_nodes": int(out_nodes.sum()), "extent": extent, "finest_levels": int(2 ** R),
        "timings_ms": {"mesh": 1e3 * (t1 - t0), "geodesic": 1e3 * (t2 - t1),
                       "reeb_perg": 1e3 * (time.perf_counter() - t2)}})
    return g


def _adjacent_levels(E, act, levels, R):
    """Keep the Reeb-graph edges whose μ ranges touch (Hilaga's adjacency of R-nodes).

    A mesh edge longer than a fine μ level can join nodes whose ranges are not adjacent
    (it skips a level), which makes spurious triangles — most of all between nodes of
    different resolutions in a pERG. Edges between non-touching ranges are kept only when
    they join otherwise disconnected parts (smallest gap first).
    """
    if len(E) == 0:
        return E
    lo = np.empty(len(act), np.int64)
    hi = np.empty(len(act), np.int64)
    bins_f = 2 ** R
    for k, (r, i) in enumerate(act):
        step = bins_f // (2 ** r)
        b = int(levels[r].node_bin[i])
        lo[k], hi[k] = b * step, (b + 1) * step
    a, c = E[:, 0], E[:, 1]
    gap = np.maximum(lo[c] - hi[a], lo[a] - hi[c])
    keep = gap <= 0
    parent = np.arange(len(act))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for u, v in E[keep]:
        parent[find(u)] = find(v)
    for k in np.nonzero(~keep)[0][np.argsort(gap[~keep], kind="stable")]:
        u, v = E[k]
        if find(u) != find(v):
            parent[find(u)] = find(v)
            keep[k] = True
    return E[keep]


def _segment_points(a, b, voxel_size):
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / (0.5 * voxel_size))) + 1)
    t = np.linspace(0, 1, n)[:, None]
    return a + t * (b - a)


def prune_branches(g: PERG, min_length: float, min_persistence: float = 0.0) -> PERG:
    """Remove end branches (end point … first branch point) shorter than ``min_length``
    or along which μ rises by less than ``min_persistence``.

    Short end branches of a Reeb graph come from small bumps of the surface (voxel
    staircase, visual-hull phantoms), not from limbs. Branches are removed shortest first,
    never leaving fewer than two end points.
    """
    n = g.n
    alive = np.ones(n, bool)
    adj = [set(a) for a in g.adjacency()]
    changed = True
    while changed:
        changed = False
        leaves = [v for v in range(n) if alive[v] and len(adj[v]) == 1]
        if len(leaves) <= 2:
            break
        best = None
        for v in leaves:
            path, length, prev, cur = [v], 0.0, -1, v
            while True:
                nxt = [u for u in adj[cur] if u != prev]
                if len(adj[cur]) > 2 or not nxt or (cur != v and len(adj[cur]) != 2):
                    break
                u = nxt[0]
                length += float(np.linalg.norm(g.positions[u] - g.positions[cur]))
                prev, cur = cur, u
                if len(adj[cur]) != 2:
                    break
                path.append(cur)
            rise = float(g.mu[v] - g.mu[cur])
            short = length < min_length or rise < min_persistence
            score = min(length / max(min_length, 1e-300), rise / max(min_persistence, 1e-300))
            if len(adj[cur]) >= 3 and short and (best is None or score < best[0]):
                best = (score, path)
        if best is not None:
            for v in best[1]:
                for u in adj[v]:
                    adj[u].discard(v)
                adj[v] = set()
                alive[v] = False
            changed = True
    idx = np.nonzero(alive)[0]
    remap = -np.ones(n, np.int64)
    remap[idx] = np.arange(len(idx))
    E = np.array(sorted({(min(remap[a], remap[b]), max(remap[a], remap[b]))
                         for a in range(n) for b in adj[a] if alive[a] and alive[b]}), np.int64).reshape(-1, 2)
    return PERG(g.positions[idx], E, g.mu[idx], g.level[idx], dict(g.diagnostics))
