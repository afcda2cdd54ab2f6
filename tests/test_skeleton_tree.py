"""Data tree from hand-drawn skeletons (thesis §7.3.3, Alg. 13; ALGORITHMS.md §6).

Every expected vertex, edge and weight below was worked out by hand from the
drawing (26-adjacency classes E/B/I, components, centroids, branch lengths), so
these tests are an independent oracle of :func:`topopose.data_tree`.
"""
import json
import math

import numpy as np
import pytest

import topopose as tp
from topopose import InputError
from topopose.match import Tree
from topopose.skeleton import classify, data_tree

R2, R3 = math.sqrt(2), math.sqrt(3)


def draw(shape, *paths, z=None):
    """Rasterize polylines of integer points; each segment axis-aligned or diagonal."""
    s = np.zeros(shape, bool)
    for path in paths:
        path = [tuple(p) + ((z,) if z is not None and len(p) == 2 else ()) for p in path]
        for a, b in zip(path[:-1], path[1:]):
            a, b = np.array(a), np.array(b)
            d = b - a
            m = np.abs(d).max()
            assert np.all((np.abs(d) == m) | (d == 0)), "segments must be axis-aligned or diagonal"
            for t in range(m + 1):
                s[tuple(a + np.sign(d) * t)] = True
    return s


def canon(tree, origin=(0, 0, 0), vs=1.0):
    """Vertices as voxel-coordinate tuples (rounded) and edges as {frozenset(pu, pv): [weights]}."""
    pos = {v: tuple(np.round((np.asarray(tree.positions[v]) - origin) / vs, 6) + 0.0)
           for v in tree.vertices}
    edges = {}
    for u, v, w in tree.edges:
        edges.setdefault(frozenset((pos[u], pos[v])), []).append(w)
    return sorted(pos.values()), {k: sorted(v) for k, v in edges.items()}


def check(tree, vertices, edges, origin=(0, 0, 0), vs=1.0):
    got_v, got_e = canon(tree, origin, vs)
    key = lambda p: tuple(np.round(np.asarray(p, float), 6) + 0.0)  # noqa: E731
    want_v = sorted(key(p) for p in vertices)
    np.testing.assert_allclose(np.array(got_v), np.array(want_v), atol=1e-9)
    want_e = {}
    for a, b, w in edges:
        want_e.setdefault(frozenset((key(a), key(b))), []).append(w)
    assert set(got_e) == set(want_e), (got_e, want_e)
    for k in want_e:
        np.testing.assert_allclose(got_e[k], sorted(want_e[k]), rtol=1e-12)
    assert len(tree.edges) == tree.n_vertices - 1  # a tree


# ----------------------------------------------------------------------------- shapes
def y_shape():
    # stem (4,0)-(4,4), arms (4,4)-(1,7) and (4,4)-(7,7); junction is a single I voxel
    return draw((9, 9, 3), [(4, 0), (4, 4), (1, 7)], [(4, 4), (7, 7)], z=1)


def test_y_length_and_count_world_coordinates():
    s = y_shape()
    origin, vs = np.array([1.0, 2.0, 3.0]), 0.5
    t = data_tree(s, origin=origin, voxel_size=vs)
    V = [(4, 0, 1), (1, 7, 1), (7, 7, 1), (4, 4, 1)]
    check(t, V, [((4, 0, 1), (4, 4, 1), 4 * vs), ((1, 7, 1), (4, 4, 1), 3 * R2 * vs),
                 ((7, 7, 1), (4, 4, 1), 3 * R2 * vs)], origin, vs)
    c = data_tree(s, origin=origin, voxel_size=vs, weight="count")
    check(c, V, [((4, 0, 1), (4, 4, 1), 3), ((1, 7, 1), (4, 4, 1), 2), ((7, 7, 1), (4, 4, 1), 2)],
          origin, vs)
    d = t.diagnostics
    assert d["voxel_classes"] == {"E": 3, "B": 7, "I": 1}
    assert d["max_degree"] == 3 and d["cycles_broken"] == 0 and d["loops"] == 0
    assert sorted(d["vertex_class"].values()) == ["E", "E", "E", "I"]
    # vertex ids: E components first (Alg. 13 lines 6-7), then I components
    assert [d["vertex_class"][v] for v in t.vertices] == ["E", "E", "E", "I"]


def test_x_plus_with_five_voxel_junction():
    # a plus: arms of length 4 along ±x, ±y; the centre and its 4 face neighbours are I-points
    s = draw((9, 9, 3), [(4, 0), (4, 8)], [(0, 4), (8, 4)], z=1)
    assert (classify(s) == 3).sum() == 5
    t = data_tree(s)
    c = (4, 4, 1)
    ends = [(4, 0, 1), (4, 8, 1), (0, 4, 1), (8, 4, 1)]
    # each arm: E, two B voxels, then the contact I voxel at distance 1 from the centre -> 3
    check(t, ends + [c], [(e, c, 3.0) for e in ends])
    check(data_tree(s, weight="count"), ends + [c], [(e, c, 2) for e in ends])
    assert t.max_degree() == 4


def test_t_with_two_voxel_thick_junction():
    # bar along x at y=4, stem along y up to (4,3), plus (5,3): a 2-voxel-thick junction
    s = draw((9, 6, 3), [(0, 4), (8, 4)], [(4, 0), (4, 3)], [(5, 3), (5, 3)], z=1)
    # I voxels by hand: (4,4) (4,3) (5,3) (3,4) (5,4) (6,4) (4,2)
    ivox = [(4, 4), (4, 3), (5, 3), (3, 4), (5, 4), (6, 4), (4, 2)]
    cl = classify(s)
    assert sorted(map(tuple, np.argwhere(cl == 3)[:, :2])) == sorted(ivox)
    c = (31 / 7, 24 / 7, 1)
    t = data_tree(s)
    check(t, [(0, 4, 1), (8, 4, 1), (4, 0, 1), c],
          [((0, 4, 1), c, 3.0),   # (0,4) -> (1,4),(2,4) -> contact (3,4)
           ((8, 4, 1), c, 2.0),   # (8,4) -> (7,4) -> contact (6,4)
           ((4, 0, 1), c, 2.0)])  # (4,0) -> (4,1) -> contact (4,2)
    check(data_tree(s, weight="count"), [(0, 4, 1), (8, 4, 1), (4, 0, 1), c],
          [((0, 4, 1), c, 2), ((8, 4, 1), c, 1), ((4, 0, 1), c, 1)])


def test_h_two_junction_clumps():
    s = draw((7, 9, 3), [(0, 0), (0, 8)], [(6, 0), (6, 8)], [(1, 4), (5, 4)], z=1)
    jl, jr = (0.25, 4, 1), (5.75, 4, 1)  # I clumps {(0,3),(0,4),(0,5),(1,4)} and mirror
    ends = [(0, 0, 1), (0, 8, 1), (6, 0, 1), (6, 8, 1)]
    t = data_tree(s)
    check(t, ends + [jl, jr],
          [((0, 0, 1), jl, 3.0), ((0, 8, 1), jl, 3.0), ((6, 0, 1), jr, 3.0), ((6, 8, 1), jr, 3.0),
           (jl, jr, 4.0)])  # crossbar (2,4),(3,4),(4,4) between contacts (1,4) and (5,4)
    check(data_tree(s, weight="count"), ends + [jl, jr],
          [((0, 0, 1), jl, 2), ((0, 8, 1), jl, 2), ((6, 0, 1), jr, 2), ((6, 8, 1), jr, 2),
           (jl, jr, 3)])


def test_isolated_closed_loop():
    # a diamond of 16 voxels, all B-points, no E or I: opened from its first voxel (0,4)
    s = draw((9, 9, 3), [(0, 4), (4, 0), (8, 4), (4, 8), (0, 4)], z=1)
    assert (classify(s) == 2).sum() == 16
    t = data_tree(s)
    check(t, [(0, 4, 1), (8, 4, 1)], [((0, 4, 1), (8, 4, 1), 8 * R2)])
    check(data_tree(s, weight="count"), [(0, 4, 1), (8, 4, 1)], [((0, 4, 1), (8, 4, 1), 7)])
    assert t.diagnostics["closed_loop"] and t.diagnostics["closed_loop_length"] == pytest.approx(16 * R2)


def test_lollipop_loop_is_detached_not_dropped():
    # stick (4,0)-(4,4), ring (4,4)-(7,7)-(4,10)-(1,7)-(4,4) of 12 voxels; (4,4) is the only I voxel
    s = draw((9, 12, 3), [(4, 0), (4, 4), (7, 7), (4, 10), (1, 7), (4, 4)], z=1)
    t = data_tree(s)
    j = (4, 4, 1)
    # the loop (11 B voxels, 12 diagonal steps) is detached at its second end: a leaf at the
    # contact voxel, which is the junction voxel itself
    check(t, [(4, 0, 1), j, j], [((4, 0, 1), j, 4.0), (j, j, 12 * R2)])
    assert t.diagnostics["loops"] == 1 and t.diagnostics["cycles_broken"] == 0
    assert t.diagnostics["vertex_class"][2] == "cut"
    check(data_tree(s, weight="count"), [(4, 0, 1), j, j], [((4, 0, 1), j, 3), (j, j, 11)])


def test_star_with_six_arms_3d():
    c = (5, 5, 5)
    ends = [(1, 5, 5), (9, 5, 5), (5, 1, 5), (5, 9, 5), (5, 5, 1), (5, 5, 9)]
    s = draw((11, 11, 11), *[[e, c] for e in ends])
    assert (classify(s) == 3).sum() == 7  # centre + its 6 face neighbours (mutually 26-adjacent)
    t = data_tree(s, voxel_size=2.0)
    check(t, ends + [c], [(e, c, 3.0 * 2.0) for e in ends], vs=2.0)
    assert t.max_degree() == 6
    check(data_tree(s, weight="count"), ends + [c], [(e, c, 2) for e in ends])


def test_3d_diagonal_branch_length_vs_count():
    # the same Euclidean length along an axis and along a space diagonal: length agrees,
    # voxel count differs by √3 (why the pipeline weighs by length)
    s = draw((14, 14, 14), [(0, 0, 0), (12, 0, 0)])
    d = draw((14, 14, 14), [(0, 0, 0), (7, 7, 7)])
    ta, td = data_tree(s), data_tree(d)
    assert ta.edges[0][2] == pytest.approx(12) and td.edges[0][2] == pytest.approx(7 * R3)
    assert abs(ta.edges[0][2] - td.edges[0][2]) / 12 < 0.02
    assert data_tree(s, weight="count").edges[0][2] == 11
    assert data_tree(d, weight="count").edges[0][2] == 6


def test_direct_e_i_contact_has_step_length():
    # a T whose junction clump touches all three ends directly: no B-point at all
    s = np.zeros((5, 5, 3), bool)
    s[2, 0:5, 1] = True
    s[0:2, 2, 1] = True
    t = data_tree(s)
    c = ((2 + 1 + 2 + 2) / 4, (2 + 2 + 1 + 3) / 4, 1)  # I = (2,2),(1,2),(2,1),(2,3)
    check(t, [(0, 2, 1), (2, 0, 1), (2, 4, 1), c],
          [((0, 2, 1), c, 1.0), ((2, 0, 1), c, 1.0), ((2, 4, 1), c, 1.0)])
    check(data_tree(s, weight="count"), [(0, 2, 1), (2, 0, 1), (2, 4, 1), c],
          [((0, 2, 1), c, 0), ((2, 0, 1), c, 0), ((2, 4, 1), c, 0)])
    assert t.diagnostics["direct_edges"] == 3
    # a Y with two one-voxel arms: diagonal direct contacts of length √2
    u = draw((9, 9, 3), [(4, 0), (4, 4), (3, 5)], [(4, 4), (5, 5)], z=1)
    check(data_tree(u), [(4, 0, 1), (3, 5, 1), (5, 5, 1), (4, 4, 1)],
          [((4, 0, 1), (4, 4, 1), 4.0), ((3, 5, 1), (4, 4, 1), R2), ((5, 5, 1), (4, 4, 1), R2)])


def test_cycle_broken_at_longest_branch_and_detached():
    # Y junctions everywhere (single-voxel I points); cycle Ja-Jb-Jd-Jc
    Ja, Jb, Jc, Jd = (10, 10), (5, 15), (14, 14), (10, 22)
    s = draw((20, 27, 3),
             [(10, 4), Ja, Jb, (5, 17), Jd, (10, 25)],
             [Ja, Jc, (14, 18), Jd],
             [Jb, (2, 12)], [Jc, (17, 11)], z=1)
    t = data_tree(s)
    d = t.diagnostics
    assert d["cycles_broken"] == 1 and d["loops"] == 0
    P = {k: (x, y, 1) for k, (x, y) in dict(Ja=Ja, Jb=Jb, Jc=Jc, Jd=Jd, bot=(10, 4), bl=(2, 12),
                                             cr=(17, 11), head=(10, 25)).items()}
    # lengths: Jc-Jd = 4 + 4√2 is the longest of the cycle; Jc and Jd both have degree 3, Jc is
    # farther from the spanning tree's centre (Jb) -> the branch leaves Jc, a leaf at Jc's voxel
    check(t, list(P.values()) + [P["Jc"]],
          [(P["bot"], P["Ja"], 6.0), (P["Ja"], P["Jb"], 5 * R2), (P["Ja"], P["Jc"], 4 * R2),
           (P["Jb"], P["bl"], 3 * R2), (P["Jc"], P["cr"], 3 * R2), (P["Jb"], P["Jd"], 2 + 5 * R2),
           (P["Jd"], P["head"], 3.0), (P["Jd"], P["Jc"], 4 + 4 * R2)])
    cut = d["cuts"][0]
    assert cut["length"] == pytest.approx(4 + 4 * R2) and not cut["loop"]
    assert t.degree(cut["detached_from"]) == 2
    # count weights: same cut (the cycle is broken on lengths)
    check(data_tree(s, weight="count"), list(P.values()) + [P["Jc"]],
          [(P["bot"], P["Ja"], 5), (P["Ja"], P["Jb"], 4), (P["Ja"], P["Jc"], 3),
           (P["Jb"], P["bl"], 2), (P["Jc"], P["cr"], 2), (P["Jb"], P["Jd"], 6),
           (P["Jd"], P["head"], 2), (P["Jd"], P["Jc"], 7)])


def test_tip_touching_a_limb_is_cut_at_the_contact():
    # "hand on thigh": torso junction T (degree 4, four diagonal branches), crotch C; the tip of
    # arm 1 lands on leg 1 and makes a degree-3 junction J = (9,7); the cycle T-arm1-J-C-T has
    # lengths arm1 = 9√2 + 4, J-C = 3√2, spine = 8 + 2√2: the arm is cut, at J (lower degree)
    T, C, J = (10, 20), (12, 10), (9, 7)
    s = draw((20, 28, 3),
             [T, (8, 22), (8, 26)],            # head
             [T, (14, 24), (18, 24)],          # arm 2
             [T, (12, 18), C],                 # spine
             [C, (8, 6), (8, 0)],              # leg 1 (through J)
             [C, (16, 6), (16, 0)],            # leg 2
             [T, (5, 15), (5, 11), (8, 8)],    # arm 1: its last voxel (8,8) touches J
             z=1)
    t = data_tree(s)
    d = t.diagnostics
    assert d["cycles_broken"] == 1 and d["voxel_classes"]["I"] == 3
    cut = d["cuts"][0]
    assert cut["length"] == pytest.approx(9 * R2 + 4)
    keep, leaf = cut["edge"]
    np.testing.assert_allclose(t.positions[keep], [*T, 1])
    np.testing.assert_allclose(t.positions[leaf], [*J, 1])
    np.testing.assert_allclose(t.positions[cut["detached_from"]], [*J, 1])
    assert t.degree(cut["detached_from"]) == 2 and t.degree(keep) == 4 and t.degree(leaf) == 1


def test_small_loop_bubble_is_dropped_whatever_the_total_length():
    # a short line (total ~ 46 voxels) with a diamond bubble of perimeter 4·√2 ≈ 5.7 voxels:
    # above 3 % of the total (1.4), at most small_loop = 8 voxels, so a bubble all the same
    s = draw((40, 12, 3), [(0, 5), (20, 5), (21, 6), (22, 5), (39, 5)],
             [(20, 5), (21, 4), (22, 5)], z=1)
    t = data_tree(s)
    d = t.diagnostics
    assert d["small_cycles"] == 1 and d["cuts"] == [] and t.n_vertices == 4
    assert d["dropped_branches"] == [pytest.approx(2 * R2)]
    t0 = data_tree(s, small_loop=0)               # relative rule only: detached, a spurious leaf
    assert t0.diagnostics["small_cycles"] == 0 and len(t0.diagnostics["cuts"]) == 1
    assert t0.n_vertices == 5
    with pytest.raises(InputError, match="small_loop"):
        data_tree(s, small_loop=-1)


def test_small_cycle_bubble_is_dropped_not_detached():
    # a long line with a diamond bubble: J1=(30,5) and J2=(34,5) joined by two paths of 4√2
    s = draw((500, 12, 3), [(0, 5), (30, 5), (32, 7), (34, 5), (499, 5)],
             [(30, 5), (32, 3), (34, 5)], z=1)
    total = 30 + 465 + 8 * R2          # perimeter 8√2 ≈ 11.3 < 3 % of 506.3
    t = data_tree(s)
    d = t.diagnostics
    assert d["cycles_broken"] == 1 and d["small_cycles"] == 1 and d["cuts"] == []
    assert d["dropped_branches"] == [pytest.approx(4 * R2)]
    check(t, [(0, 5, 1), (499, 5, 1), (30, 5, 1), (34, 5, 1)],
          [((0, 5, 1), (30, 5, 1), 30.0), ((30, 5, 1), (34, 5, 1), 4 * R2),
           ((34, 5, 1), (499, 5, 1), 465.0)])
    assert sum(w for *_, w in t.edges) == pytest.approx(total - 4 * R2)
    # small_cycle=0: the bubble branch is detached like a limb contact instead
    t0 = data_tree(s, small_cycle=0)
    assert t0.diagnostics["small_cycles"] == 0 and len(t0.diagnostics["cuts"]) == 1
    assert t0.n_vertices == 5 and sum(w for *_, w in t0.edges) == pytest.approx(total)


def test_digital_triangle_is_absorbed():
    # an axis-aligned rectangle: each corner voxel is B with both neighbours in one 2-voxel I
    # clump (a triangle); the four clumps are joined by the sides: one cycle of 4 -> broken
    s = draw((9, 5, 3), [(0, 0), (8, 0), (8, 4), (0, 4), (0, 0)], z=1)
    t = data_tree(s)
    d = t.diagnostics
    assert d["triangles"] == 4 and d["loops"] == 0 and d["cycles_broken"] == 1
    assert t.n_vertices == 5 and len(t.edges) == 4
    # sides: long sides (1,0)..(7,0): contacts (1,0) and (7,0) are I, B = (2..6,0): length 6;
    # short sides (0,1)..(0,3): contact (0,1),(0,3), B (0,2): length 2; the cut one is long
    ws = sorted(w for _, _, w in t.edges)
    assert ws == pytest.approx([2.0, 2.0, 6.0, 6.0])


def test_border_branch_gets_infinite_weight():
    s = y_shape()  # the stem's end (4,0,1) lies on the face j = 0 of the grid
    t = data_tree(s, border="grid")
    d = t.diagnostics
    bv = d["border_vertex"]
    np.testing.assert_allclose(t.positions[bv], [4, 0, 1])
    assert t.root == bv and d["border_vertices"] == [bv]
    ws = {frozenset((u, v)): w for u, v, w in t.edges}
    assert sum(math.isinf(w) for w in ws.values()) == 1
    assert all(math.isinf(w) for k, w in ws.items() if bv in k)
    # a mask border: only the arm tip (7,7,1) is on it
    m = np.zeros(s.shape, bool)
    m[7, 7, 1] = True
    tm = data_tree(s, border=m)
    np.testing.assert_allclose(tm.positions[tm.diagnostics["border_vertex"]], [7, 7, 1])
    # no border: no infinite weight, unrooted
    t0 = data_tree(s)
    assert t0.root is None and t0.diagnostics["border_vertex"] is None
    assert not any(math.isinf(w) for _, _, w in t0.edges)
    # a Y inside the grid: border="grid" finds nothing
    inner = np.pad(s, 1)
    ti = data_tree(inner, border="grid")
    assert ti.diagnostics["border_vertex"] is None and ti.root is None


def test_several_components_keep_largest():
    s = y_shape()
    s[0, 0, 2] = True                       # a lone voxel
    s[8, 0:3, 2] = True                     # a 3-voxel segment, not touching the Y
    t = data_tree(s)
    assert t.diagnostics["components"] == 3
    assert t.diagnostics["dropped_components"] == [3, 1]
    assert t.n_vertices == 4
    tn = data_tree(s, labelling="ndimage")  # scipy.ndimage labelling: the same tree
    assert tn.edges == t.edges and tn.diagnostics["dropped_components"] == [3, 1]


def test_single_voxel_and_pair():
    s = np.zeros((3, 3, 3), bool)
    s[1, 1, 1] = True
    t = data_tree(s, origin=(1, 1, 1), voxel_size=0.1)
    assert t.n_vertices == 1 and t.edges == []
    np.testing.assert_allclose(t.positions[0], [1.1, 1.1, 1.1])
    s[1, 1, 2] = True  # two E points touching: one E component, one vertex
    t = data_tree(s)
    assert t.n_vertices == 1 and t.edges == []
    np.testing.assert_allclose(t.positions[0], [1, 1, 1.5])


def test_json_round_trip(tmp_path):
    s = y_shape()
    t = data_tree(s, origin=(0.5, -1, 2), voxel_size=0.02, border="grid")
    p = tmp_path / "tree.json"
    t.save(p)
    d = json.loads(p.read_text())
    assert sum(e[2] == "inf" for e in d["edges"]) == 1
    u = Tree.load(p)
    assert u.vertices == t.vertices and u.root == t.root
    assert [(a, b) for a, b, _ in u.edges] == [(a, b) for a, b, _ in t.edges]
    for (_, _, w1), (_, _, w2) in zip(u.edges, t.edges):
        assert w1 == w2
    for v in t.vertices:
        np.testing.assert_allclose(u.positions[v], t.positions[v])
    g = t.to_networkx()
    assert g.number_of_nodes() == 4 and g.number_of_edges() == 3
    back = Tree.from_networkx(g)
    assert sorted(w for *_, w in back.edges) == sorted(w for *_, w in t.edges)


def test_volume_input_brings_its_placement():
    s = y_shape()
    vol = tp.Volume(s, origin=(1, 2, 3), voxel_size=0.5)
    a = data_tree(vol)
    b = data_tree(s, origin=(1, 2, 3), voxel_size=0.5)
    assert canon(a) == canon(b)


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("bad, words", [
    (np.zeros((4, 4, 4), np.uint8), "boolean"),
    (np.zeros((4, 4), bool), "3D"),
    (np.zeros((0, 4, 4), bool), "empty"),
    (np.zeros((4, 4, 4), bool), "no voxel"),
    ([[[True]]], "NumPy array"),
])
def test_bad_arrays(bad, words):
    with pytest.raises(InputError, match=words):
        data_tree(bad)


def test_not_a_curve_skeleton():
    s = np.zeros((5, 5, 5), bool)
    s[1:3, 1:3, 1:3] = True  # a 2x2x2 block
    with pytest.raises(InputError, match="not a curve skeleton"):
        data_tree(s)
    p = np.zeros((8, 8, 3), bool)
    p[1:7, 1:7, 1] = True  # a plate: a surface, not curves
    with pytest.raises(InputError, match="not a curve skeleton"):
        data_tree(p)
    v = np.zeros((12, 12, 12), bool)
    v[2:10, 3:9, 2:10] = True  # a solid (a volume instead of its skeleton)
    with pytest.raises(InputError, match="not a curve skeleton"):
        data_tree(v)


def test_dense_net_of_curves_is_still_a_skeleton():
    # a lattice of lines every 4 voxels: most voxels are I-points (junction clumps), like
    # the nets real hulls with many tunnels give; with a 2x2 square in it, it is still accepted
    g = np.zeros((13, 13, 13), bool)
    m = np.arange(13) % 4 == 0
    g[:, m[:, None] & m[None, :]] = True         # lines along x
    g[m[:, None] & m[None, :], :] = True         # lines along z
    g |= m[:, None, None] & m[None, None, :]     # lines along y
    g[1:3, 1:3, 0] = True
    c = classify(g)
    assert (c == 3).sum() * 2 > (c > 0).sum()
    t = data_tree(g)
    d = t.diagnostics
    assert d["thick_squares"] >= 1 and len(t.edges) == t.n_vertices - 1
    # every branch is a single B voxel (the middle of a lattice edge): each one is an edge of the
    # tree or a branch dropped/detached when breaking the net's many cycles
    nb = int((c == 2).sum())
    assert len(t.edges) + len(d["dropped_branches"]) == nb + d["direct_edges"] - d["triangles"]
    assert d["cycles_broken"] + d["loops"] == len(d["dropped_branches"]) + len(d["cuts"]) > 50


@pytest.mark.parametrize("kw, words", [
    (dict(weight="voxels"), "weight"), (dict(voxel_size=0), "voxel_size"),
    (dict(origin=(1, 2)), "origin"), (dict(border="edges"), "border"),
    (dict(border=np.zeros((2, 2, 2), bool)), "border"), (dict(labelling="cc"), "labelling"),
    (dict(small_cycle=2), "small_cycle"),
])
def test_bad_parameters(kw, words):
    with pytest.raises(InputError, match=words):
        data_tree(y_shape(), **kw)
