"""Thickness of the parts: the arc-cost hook of the Matcher against a brute-force
assignment on star trees, the inscribed-ball radii of the data vertices, and one small end-to-end
accuracy check on the anatomically real ``body`` subject."""
import itertools
import math

import numpy as np
import pytest

from topopose.match import Matcher, Tree


def _brute_star(pw, dw, extra):
    """AHA distance of a rooted pattern star against a data star rooted at its centre (no
    degree-2 vertex, so no merging): the best partial injection of pattern arcs into data arcs,
    matched pairs cost |w − w′| + extra, unmatched arcs their weight."""
    best = math.inf
    n, m = len(pw), len(dw)
    for k in range(min(n, m) + 1):
        for ps in itertools.combinations(range(n), k):
            for ds in itertools.permutations(range(m), k):
                c = sum(abs(pw[i] - dw[j]) + extra[i, j] for i, j in zip(ps, ds))
                c += sum(pw[i] for i in range(n) if i not in ps)
                c += sum(dw[j] for j in range(m) if j not in ds)
                best = min(best, c)
    return best


@pytest.mark.parametrize("seed", range(12))
def test_arc_cost_equals_brute_force_on_stars(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(2, 4)), int(rng.integers(2, 5))
    pw, dw = rng.uniform(0.1, 1, n), rng.uniform(0.1, 1, m)
    extra = np.where(rng.random((n, m)) < 0.2, np.inf, rng.uniform(0, 0.6, (n, m)))
    P = Tree([("r", f"p{i}", float(w)) for i, w in enumerate(pw)], root="r")
    D = Tree([(0, j + 1, float(w)) for j, w in enumerate(dw)])

    def cost(p_up, p_low, d_up, d_low):
        C = np.zeros((len(p_up), len(d_up)))
        for a, (pu, pl) in enumerate(zip(p_up, p_low)):
            for b, (du, dl) in enumerate(zip(d_up, d_low)):
                # a star item is one arc: centre → leaf (other items, if any, get +inf)
                ok = pu == "r" and du == 0 and dl != 0
                C[a, b] = extra[int(pl[1:]), dl - 1] if ok else math.inf
        return C

    mt = Matcher(P, "aha")
    al = mt.align(D, data_root=0, arc_cost=cost)
    assert al.distance == pytest.approx(_brute_star(pw, dw, extra), abs=1e-9)
    # zero extra cost: the plain alignment
    zero = mt.align(D, data_root=0, arc_cost=lambda pu, pl, du, dl: np.zeros((len(pu), len(du))))
    assert zero.distance == pytest.approx(mt.align(D, data_root=0).distance, abs=1e-12)
    assert zero.distance == pytest.approx(_brute_star(pw, dw, np.zeros((n, m))), abs=1e-9)


def test_thickness_moves_the_head_to_the_thick_branch():
    """Two torso branches of equal length: lengths cannot tell head from hand, radii can."""
    from topopose.frame.thickness import thickness_arc_cost

    P = Tree([("torso", "head", 0.2), ("torso", "hand", 0.2)], root="torso")
    D = Tree([(0, 1, 0.2), (0, 2, 0.2)])
    radii = {0: 1.0, 1: 0.15, 2: 0.6}               # vertex 2 is thick: the head
    prof = {"head": (0.3, 9.0), "hand": (0.0, 0.34), "torso": (0.26, 9.0)}
    mt = Matcher(P, "aha")
    al = mt.align(D, data_root=0, arc_cost=thickness_arc_cost(radii, prof, 0.3))
    assert al.mapping["head"] == 2 and al.mapping["hand"] == 1
    assert al.distance == pytest.approx(0.0)
    radii = {0: 1.0, 1: 0.6, 2: 0.15}
    al = mt.align(D, data_root=0, arc_cost=thickness_arc_cost(radii, prof, 0.3))
    assert al.mapping["head"] == 1 and al.mapping["hand"] == 2


def test_vertex_radii_of_a_ball_and_a_rod():
    """A ball of radius 10 voxels with a rod of radius 2 voxels: the ball's centre has the
    largest radius (1), the rod's axis 2/10 of it (± the EDT's voxel rounding)."""
    from topopose.hull import Volume
    from topopose.frame.thickness import vertex_radii

    g = np.indices((40, 30, 30)).astype(float)
    ball = ((g[0] - 12) ** 2 + (g[1] - 15) ** 2 + (g[2] - 15) ** 2) <= 10 ** 2
    rod = (g[0] >= 12) & (g[0] <= 36) & ((g[1] - 15) ** 2 + (g[2] - 15) ** 2 <= 2 ** 2)
    vol = Volume(ball | rod, origin=(1.0, 2.0, 3.0), voxel_size=0.5)
    pos = {0: np.array([1 + 12 * 0.5, 2 + 15 * 0.5, 3 + 15 * 0.5]),
           1: np.array([1 + 32 * 0.5, 2 + 15 * 0.5, 3 + 15 * 0.5])}
    data = Tree([(0, 1, 1.0)], positions=pos)
    r = vertex_radii(vol, data)
    assert r[0] == pytest.approx(1.0)
    assert 0.2 <= r[1] <= 0.31


def test_body_separated_accuracy_end_to_end():
    """8 separated frames of the MakeHuman body (seeded), 80³, noise 1, scored at 0.08 × height
    (the same for every part): at least 7 true positives and no more than 1 false positive
    (measured: 8 TP, 0 FP; over 5 seeds 36 TP / 3 FP). Fails if the body accuracy regresses
    badly."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator
    from topopose.pose import load_model
    from topopose.batch.quality import evaluate

    cap = synthetic_capture(subject="body", frames=8, seed=SEED, noise=1, separated=True,
                            cameras=8, margin=0.075, build="random")
    est = FrameEstimator(cap, "human", 80, gate=False)     # the alignment's accuracy, not the gate's
    poses = [est.estimate(f) for f in cap.frames]
    ev = evaluate(cap.gt, poses, model=load_model("human"), tolerance=0.08 * cap.gt["height"],
                  junction_factor=1.0)
    s = ev.at_status()
    assert s["tp"] >= 7 and s["fp"] <= 1, ev.counts


SEED = 5


def test_matched_arc_cost_is_the_distance_part_paid():
    from topopose.frame.thickness import matched_arc_cost

    rng = np.random.default_rng(3)
    P = Tree([("r", "a", 0.3), ("r", "b", 0.5), ("b", "c", 0.2)], root="r")
    D = Tree([(0, 1, 0.35), (0, 2, 0.4), (2, 3, 0.25), (2, 4, 0.1)])
    extra = {}

    def cost(p_up, p_low, d_up, d_low):
        return np.array([[extra.setdefault((pu, pl, du, dl), float(rng.uniform(0, 0.2)))
                          for du, dl in zip(d_up, d_low)] for pu, pl in zip(p_up, p_low)])

    mt = Matcher(P, "aha")
    al = mt.align(D, data_root=0, arc_cost=cost)
    paid = matched_arc_cost(al, cost)
    assert paid > 0
    assert paid == pytest.approx(sum(extra[(p[0], p[-1], d[0], d[-1])] for p, d in al.pairs))
    # what is left is the plain length cost of the same alignment: never below the optimum
    assert al.distance - paid >= mt.align(D, data_root=0).distance - 1e-12


def test_run_thickness_switch():
    """``run(thickness=0)`` (``topopose run --thickness 0``) turns the term off; by default the
    human model pays it (``diagnostics["thickness_cost"]``) and T_d judges the length part."""
    from topopose.synth import synthetic_capture
    from topopose.batch import run
    cap = synthetic_capture(subject="body", frames=2, seed=2, noise=0, cameras=8, build="average")
    on = run(cap, "human", 48, progress=False).poses
    off = run(cap, "human", 48, progress=False, thickness=0).poses
    assert all("thickness_cost" in p.diagnostics for p in on if p.status != "failed")
    assert not any("thickness_cost" in p.diagnostics for p in off)


@pytest.mark.parametrize("seed", range(4))
def test_arc_cost_by_index_equals_the_formula(seed):
    """:func:`thickness_arc_cost` reads the radii of integer vertex ids from an array and
    computes each part's term once (a speed-up): every entry must equal the documented
    formula computed element by element (unknown radius → no cost), for integer ids (some
    without a radius, some out of the table), for other ids (the dict path) and for the root
    arc's extra term."""
    from topopose.frame.thickness import thickness_arc_cost

    rng = np.random.default_rng(seed)
    profile = {"head": (0.55, 1.2), "hand": (0.0, 0.35), "torso": (0.8, 1.0)}
    weight, cap = 0.7, 1.5

    def formula(part, r):
        stem = part.rpartition("_")[0] if part.rpartition("_")[2].isdigit() else part
        rho = profile.get(stem)
        if rho is None:
            return 0.0
        lo, hi = rho
        r = max(lo, 1e-3) if r is None else r
        r = max(r, 1e-3)
        return weight * min(max(0.0, math.log(max(lo, 1e-3) / r), math.log(r / hi)), cap)

    for ids in (list(range(40)), [f"v{i}" for i in range(40)]):
        radii = {v: float(x) for v, x in zip(ids, rng.uniform(0, 1.3, 40)) if rng.random() < 0.8}
        cost = thickness_arc_cost(radii, profile, weight, cap, root="torso", root_arc="head")
        parts_up = ["torso", "torso", "arm_1", "torso"]
        parts_low = ["head", "hand_1", "hand_2", "foot_1"]
        for _ in range(3):
            d_low = list(rng.choice(np.array(ids, dtype=object), 25))
            d_up = list(rng.choice(np.array(ids, dtype=object), 25))
            if isinstance(ids[0], int):
                d_low[0] = 1000                     # an id beyond the table: no radius
                d_low = [int(v) for v in d_low]
                d_up = [int(v) for v in d_up]
            C = cost(parts_up, parts_low, d_up, d_low)
            want = np.array([[formula(pl, radii.get(dl)) + (formula(pu, radii.get(du))
                                                             if (pu, pl) == ("torso", "head")
                                                             else 0.0)
                              for du, dl in zip(d_up, d_low)]
                             for pu, pl in zip(parts_up, parts_low)])
            assert np.allclose(C, want, rtol=0, atol=1e-12)
            assert (C > 0).any() and (C == 0).any()


def test_taxicab_kernel_equals_scipy():
    """:func:`topopose.frame.estimate_kernels.taxicab_distances` (the separable L1 distance behind
    :func:`taxicab_radii`) equals scipy's chamfer ``distance_transform_cdt(…, "taxicab")``
    exactly, on random volumes of every small shape, strided views, and volumes without any
    background voxel (-1) or without any object voxel."""
    from scipy import ndimage

    from topopose.frame.estimate_kernels import taxicab_distances

    rng = np.random.default_rng(0)
    cases = [np.ones((3, 4, 5), bool), np.zeros((2, 3, 2), bool), np.ones((1, 1, 1), bool),
             np.ones((1, 6, 1), np.uint8)]
    for _ in range(150):
        shape = tuple(int(x) for x in rng.integers(1, 9, 3))
        cases.append(rng.random(shape) < rng.uniform(0.5, 1.0))
    big = rng.random((30, 26, 40)) < 0.95
    cases += [big, big[3:25, 2:, 5:33], big.view(np.uint8)]
    for a in cases:
        want = ndimage.distance_transform_cdt(a, "taxicab")
        got = taxicab_distances(a)
        assert got.dtype == want.dtype and np.array_equal(got, want), a.shape
    assert taxicab_distances(big).max() >= 2


def _vertex_radii_plain(vol, data, reach, radii):
    """The per-vertex loop of :func:`vertex_radii` (the oracle of its kernel)."""
    dt, lo = radii
    ref = float(dt.max()) or 1.0
    org, vs = np.asarray(vol.origin, float), float(vol.voxel_size)
    out = {}
    for v in data.vertices:
        p = data.positions.get(v)
        if p is None:
            continue
        x = np.round((np.asarray(p) - org) / vs).astype(int) - lo
        x = np.clip(x, 0, np.array(dt.shape) - 1)
        r = dt[tuple(x)]
        if reach > 0:
            r = dt[tuple(slice(max(c - reach, 0), c + reach + 1) for c in x)].max()
        if r == 0:
            r = dt[tuple(slice(max(c - 1, 0), c + 2) for c in x)].max()
        out[v] = float(r) / ref
    return out


@pytest.mark.parametrize("seed", range(3))
def test_vertex_radii_equal_the_plain_loop(seed):
    """:func:`vertex_radii` (all vertices by one kernel) equals the plain per-vertex loop, bit
    for bit: vertices inside, on the background (the 3 × 3 × 3 fallback), outside the box
    (clipped), without a position; reach 0, 1, 2."""
    from types import SimpleNamespace

    from topopose.hull import Volume
    from topopose.frame.thickness import taxicab_radii, vertex_radii

    rng = np.random.default_rng(seed)
    occ = np.zeros((30, 28, 40), bool)
    occ[4:26, 5:22, 3:37] = rng.random((22, 17, 34)) < 0.9
    vol = Volume(occ, np.array([0.1, -0.2, 0.3]), 0.05, {})
    radii = taxicab_radii(vol)
    pts = vol.origin + rng.uniform(-3, 43, (60, 3)) * 0.05
    positions = {v: p for v, p in enumerate(pts)}
    positions[60] = None
    data = SimpleNamespace(vertices=list(range(61)), positions=positions)
    assert any(radii[0][tuple(np.clip(np.round((p - vol.origin) / 0.05).astype(int) - radii[1],
                                      0, np.array(radii[0].shape) - 1))] == 0 for p in pts)
    for reach in (0, 1, 2):
        got = vertex_radii(vol, data, reach, radii)
        assert got == _vertex_radii_plain(vol, data, reach, radii) and len(got) == 60
