"""Per-frame shape structure (Mukasa §2.1): mesh, integral geodesic μ, Reeb graph, pERG."""
import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from topopose.kinematics.reeb import (PERG, integral_geodesic, perg, prune_branches, reeb_levels,
                                      surface_mesh)
from topopose.synth.walker import voxelize_capsules


def capsules_volume(caps, lo=(-1, -1, -1), hi=(1, 1, 1), n=48):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    vs = float((hi - lo).max()) / (n - 1)
    shape = np.ceil((hi - lo) / vs).astype(int) + 1
    return voxelize_capsules(caps, shape, lo, vs), lo, vs


def test_mesh_is_closed_and_placed_in_world():
    data, lo, vs = capsules_volume([((-0.5, 0, 0), (0.5, 0, 0), 0.2)])
    m = surface_mesh(data, lo, vs)
    # closed surface: every edge is shared by exactly two faces
    e = np.sort(np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert np.all(counts == 2)
    # world placement: the surface hugs the capsule (distance to axis ≈ radius)
    v = m.verts
    u = np.clip(v[:, 0], -0.5, 0.5)
    d = np.linalg.norm(v - np.stack([u, 0 * u, 0 * u], 1), axis=1)
    assert abs(np.median(d) - 0.2) < vs
    # the area is close to the capsule's
    assert m.area.sum() == pytest.approx(2 * np.pi * 0.2 * 1.0 + 4 * np.pi * 0.2 ** 2, rel=0.12)


def test_integral_geodesic_exact_and_sampled():
    data, lo, vs = capsules_volume([((-0.6, 0, 0), (0.6, 0, 0), 0.15)], n=40)
    m = surface_mesh(data, lo, vs)
    exact = integral_geodesic(m, n_base=10 ** 9)
    # independent oracle: all-pairs Dijkstra summed directly (eq. 1)
    d = dijkstra(m.graph(), directed=False)
    mu = d.sum(1)
    np.testing.assert_allclose(exact, (mu - mu.min()) / (mu.max() - mu.min()), atol=1e-9)
    # the minimum is mid-capsule, the maxima at the tips
    assert abs(m.verts[exact.argmin(), 0]) < 0.15
    assert abs(m.verts[exact.argmax(), 0]) > 0.6
    # Hilaga sampling approximates it closely
    sampled = integral_geodesic(m, n_base=64, seed=1)
    assert np.corrcoef(exact, sampled)[0, 1] > 0.99


def _signature(caps, **kw):
    data, lo, vs = capsules_volume(caps, n=kw.pop("n", 56))
    return perg(data, lo, vs, **kw)


def test_reeb_graph_topology_of_simple_shapes():
    # a rod: a chain with two end points
    g = _signature([((-0.7, 0, 0), (0.7, 0, 0), 0.12)])
    assert g.signature() == (2, (), 0)
    # a tripod (Y): three end points, one branch point of degree 3
    arms = [((0, 0, 0), (0.7 * np.cos(a), 0.7 * np.sin(a), 0), 0.12) for a in (0, 2.1, 4.2)]
    assert _signature(arms).signature() == (3, (3,), 0)
    # a cross: four end points; one degree-4 point or two degree-3 points (§2.2 asymmetry)
    cross = [((-0.75, 0, 0), (0.75, 0, 0), 0.1), ((0, -0.75, 0), (0, 0.75, 0), 0.1)]
    e, b, loops = _signature(cross).signature()
    assert e == 4 and loops == 0 and b in ((4,), (3, 3))
    # a lollipop (square ring on a stick; a symmetric ring has a constant μ): one loop
    c = [(-0.7, -0.2, 0), (-0.1, -0.2, 0), (-0.1, 0.4, 0), (-0.7, 0.4, 0)]
    ring = [(c[i], c[(i + 1) % 4], 0.08) for i in range(4)] + [((-0.1, 0.1, 0), (0.8, 0.1, 0), 0.08)]
    g = _signature(ring, n=64)
    assert g.n_loops() == 1


def test_reeb_levels_nest():
    data, lo, vs = capsules_volume([((-0.7, 0, 0), (0.7, 0, 0), 0.12), ((0, 0, 0), (0, 0.7, 0), 0.12)])
    m = surface_mesh(data, lo, vs)
    mu = integral_geodesic(m, 64)
    a, b = reeb_levels(m, mu, 8), reeb_levels(m, mu, 16)
    # every node of the finer level lies inside one node of the coarser level
    pairs = {(int(x), int(y)) for x, y in zip(b.label, a.label)}
    parent = {}
    for child, par in pairs:
        assert parent.setdefault(child, par) == par
    assert b.n_nodes >= a.n_nodes


def test_perg_nodes_and_edges_inside_a_bent_tube():
    # a "U": at the coarse level the bottom band of μ is an arc whose centroid lies outside
    U = [((-0.5, 0.6, 0), (-0.5, -0.5, 0), 0.12), ((-0.5, -0.5, 0), (0.5, -0.5, 0), 0.12),
         ((0.5, -0.5, 0), (0.5, 0.6, 0), 0.12)]
    data, lo, vs = capsules_volume(U, n=72)
    g = perg(data, lo, vs, coarse=2, fine=32, max_level_fraction=1.0)
    assert g.level.max() > 2                       # the hierarchy was used
    assert g.signature()[2] == 0
    from scipy.ndimage import binary_dilation

    inside = binary_dilation(data)
    idx = np.rint((g.positions - lo) / vs).astype(int)
    assert inside[tuple(idx.T)].all()
    for a, b in g.edges:
        t = np.linspace(0, 1, 25)[:, None]
        p = np.rint((g.positions[a] + t * (g.positions[b] - g.positions[a]) - lo) / vs).astype(int)
        assert inside[tuple(p.T)].all()
    # without refinement the coarse graph has a node outside
    g0 = perg(data, lo, vs, coarse=2, fine=2, prune=0, persistence=0)
    idx0 = np.rint((g0.positions - lo) / vs).astype(int)
    assert not inside[tuple(idx0.T)].all()


def test_prune_removes_short_end_branches_only():
    # a path 0-1-2-3-4 with a one-edge spur 5 at node 2
    P = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0], [2, 0.2, 0]], float)
    E = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [2, 5]])
    mu = np.array([1, .5, 0, .5, 1, 0.05])
    g = prune_branches(PERG(P, E, mu, np.full(6, 16)), min_length=0.5)
    assert g.n == 5 and g.signature() == (2, (), 0)
    g = prune_branches(PERG(P, E, mu, np.full(6, 16)), min_length=0.1, min_persistence=0.1)
    assert g.n == 5
    g = prune_branches(PERG(P, E, mu, np.full(6, 16)), min_length=0.1, min_persistence=0.01)
    assert g.n == 6


def test_tsets_keep_thin_bands_connected_at_fine_levels():
    # a thin rod whose mesh edges change μ by about one level at 32 levels: vertex-based
    # bands crumble (spurious loops), triangle pieces (Hilaga's T-sets) do not
    data, lo, vs = capsules_volume([((-0.7, 0, 0), (0.7, 0, 0), 0.09)], n=56)
    kw = dict(coarse=32, fine=32, prune=0, persistence=0)
    assert perg(data, lo, vs, tsets=True, **kw).signature() == (2, (), 0)
    assert perg(data, lo, vs, tsets=False, max_level_fraction=1e9, **kw).n_loops() > 0
    # every T-set node of a level lies in one node of the coarser level
    from topopose.kinematics.reeb import tset_atoms

    m = surface_mesh(data, lo, vs)
    atoms = tset_atoms(m, integral_geodesic(m, 32), 3, 5)
    for r in (3, 4):
        parent = {}
        for c, p in zip(atoms.labels[r + 1], atoms.labels[r]):
            assert parent.setdefault(int(c), int(p)) == int(p)
    assert atoms.weight.sum() == pytest.approx(m.area.sum())
