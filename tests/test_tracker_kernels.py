"""The tracker's Numba kernels against the NumPy formulas they compute: bit for bit, the
bones' bases (two unit normals by cross products), the joints' Jacobian (each bone's end
moved by its own parameters, summed along the path from the root), the joints' positions and
the count of points near the capsules' surfaces, the nearest surface voxels (against
``scipy.spatial.cKDTree``); the capsule terms' normal equations against the residuals and
Jacobian rows of :meth:`_Fitter.terms`, whichever capsule is tried first."""
import numpy as np
import pytest

from topopose.sequence.body import CapsuleBody, joint_positions
from topopose.sequence.tracker import FrameData, SurfaceGrid, TrackOptions, _Fitter
from topopose.sequence.tracker_kernels import (bone_bases, capsule_normal_equations,
                                               chain_positions, inside_rows, near_surface,
                                               normal_equations)

NAMES = ("chest", "pelvis", "shoulder_1", "elbow_1", "shoulder_2", "elbow_2", "hip_1", "knee_1")
PARENTS = np.array([-1, 0, 0, 2, 0, 4, 1, 6])


def _body():
    rng = np.random.default_rng(3)
    lengths = np.r_[np.nan, rng.uniform(0.1, 0.5, len(NAMES) - 1)]
    radii = np.r_[np.nan, rng.uniform(0.03, 0.1, len(NAMES) - 1)]
    groups = ((2, 4), (1, 6))                      # two rigid groups, the other bones free
    D = rng.normal(size=(len(NAMES), 3))
    D /= np.linalg.norm(D, axis=1)[:, None]
    return CapsuleBody(NAMES, PARENTS, lengths, radii, (0, 1, 2, 4, 6, 3, 5, 7), groups,
                       tuple(D[list(g)] for g in groups))


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def reference_bases(D):
    a = np.where((np.abs(D[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = np.cross(D, a)
    e1 /= np.maximum(np.linalg.norm(e1, axis=1), 1e-12)[:, None]
    e2 = np.cross(D, e1)
    return np.stack([e1, e2], axis=2)


def reference_jacobian(f, D):
    E = reference_bases(D)
    M = {}
    for j in f.bones:
        c, w = f.col[int(j)]
        M[int(j)] = f.body.lengths[j] * (E[j] if w == 2 else -_skew(D[j]))
    G = np.zeros((len(f.body.names), 3, f.n))
    G[:, :, :3] = np.eye(3)
    for j in f.bones:
        c, w = f.col[int(j)]
        G[f.anc[:, j], :, c:c + w] += M[int(j)]
    return G, M


def _directions(rng, n):
    D = rng.normal(size=(n, 3))
    D[rng.random(n) < 0.3, 0] = rng.choice([-0.95, 0.95, 0.9, -0.9])   # both branches
    D /= np.linalg.norm(D, axis=1)[:, None]
    D[rng.random(n) < 0.1] = (1.0, 0.0, 0.0)
    return D


def test_bases_and_jacobian_are_numpys_bit_for_bit():
    f = _Fitter(_body(), TrackOptions())
    assert {w for _c, w in f.col.values()} == {2, 3}
    rng = np.random.default_rng(0)
    for _ in range(300):
        D = _directions(rng, len(NAMES))
        assert np.array_equal(bone_bases(D), reference_bases(D))
        G, M = f.jacobian(D)
        G0, M0 = reference_jacobian(f, D)
        assert np.array_equal(G, G0)
        assert M.keys() == M0.keys()
        for j in M:
            assert np.array_equal(M[j], M0[j])
            assert np.array_equal(np.signbit(M[j]), np.signbit(M0[j]))


def test_bases_are_orthonormal_to_the_directions():
    D = _directions(np.random.default_rng(1), 500)
    E = bone_bases(D)
    for k in range(2):
        assert np.allclose(np.einsum("jc,jc->j", D, E[:, :, k]), 0.0, atol=1e-12)
        assert np.allclose(np.linalg.norm(E[:, :, k], axis=1), 1.0)
    assert np.allclose(np.einsum("jc,jc->j", E[:, :, 0], E[:, :, 1]), 0.0, atol=1e-12)


def test_normal_equations_are_numpys_einsums():
    """JᵀJ and Jᵀr of sparse rows (zeros of both signs), and of the terms' own rows."""
    rng = np.random.default_rng(8)
    for _ in range(50):
        J = rng.normal(size=(120, 20))
        J[rng.random(J.shape) < 0.6] = 0.0
        J[rng.random(J.shape) < 0.1] = -0.0
        r = rng.normal(size=len(J))
        H, g = normal_equations(J, r)
        H0, g0 = np.einsum("mi,mj->ij", J, J), np.einsum("mi,m->i", J, r)
        assert np.allclose(H, H0, rtol=1e-13, atol=0) and np.allclose(g, g0, rtol=1e-13, atol=0)
        assert np.array_equal(np.signbit(H), np.signbit(H0))


def test_positions_are_numpys_bit_for_bit():
    body = _body()
    f = _Fitter(body, TrackOptions())
    parents, order, r0, lengths = f._chain
    rng = np.random.default_rng(5)
    for _ in range(50):
        D = _directions(rng, len(NAMES))
        root = rng.normal(size=3)
        assert np.array_equal(chain_positions(root, D, lengths, parents, order, r0),
                              joint_positions(body, root, D))


def _capsules(rng, f):
    """A random pose's capsules and the points around them."""
    D = _directions(rng, len(NAMES))
    root = rng.normal(size=3) * 0.1
    P, G, _M, Pe, Ge = f.at(root, D)
    A, B = Pe[f.cpar], Pe[f.cbone]
    Q = (A + rng.random((len(A), 1)) * (B - A))[rng.integers(0, len(A), 300)]
    Q = Q + rng.normal(size=Q.shape) * 0.08
    return root, D, Pe, Ge, A, B, Q


def test_near_surface_counts_as_numpy():
    """The agreement's explained points: the NumPy formula over every point and capsule."""
    f = _Fitter(_body(), TrackOptions())
    rng = np.random.default_rng(6)
    for _ in range(20):
        _root, _D, _Pe, _Ge, A, B, Q = _capsules(rng, f)
        seg = B - A
        ll = np.maximum(np.einsum("kc,kc->k", seg, seg), 1e-12)
        t = np.clip(np.einsum("mkc,kc->mk", Q[:, None] - A[None], seg) / ll, 0.0, 1.0)
        d = np.linalg.norm(Q[:, None] - (A[None] + t[..., None] * seg[None]), axis=2)
        d = np.min(np.abs(d - f.r[None]), axis=1)
        for tol in (0.0, 0.01, 0.04, 1.0):
            assert near_surface(Q, A, B, f.r, tol) == np.count_nonzero(d <= tol)


@pytest.mark.parametrize("rays", [False, True])
def test_capsule_normal_equations_are_the_terms(rays):
    """The data term (points, two-sided) and the silhouette term (rays, one-sided): the
    kernel's normal equations are those of :meth:`_Fitter.terms`' rows; the capsule tried
    first (none, random, out of range, the last call's) changes no bit of them, and the
    kernel leaves each point's nearest capsule (two-sided) or one holding it (one-sided)."""
    opts = TrackOptions(rays=0.0 if not rays else 10.0)
    f = _Fitter(_body(), opts)
    rng = np.random.default_rng(7 + rays)
    none = np.zeros((0, 3))
    for _ in range(10):
        root, D, Pe, Ge, A, B, Q = _capsules(rng, f)
        if rays:
            C = Q + rng.normal(size=Q.shape) * 0.5
            U = Q - C + rng.normal(size=Q.shape) * 0.05
            U /= np.linalg.norm(U, axis=1)[:, None]
            data = FrameData(np.zeros((0, 3)), none, np.zeros((1, 1, 1), bool), np.zeros(3),
                             0.02, None, (C, U))
            args = (C, U)
        else:
            data = FrameData(Q, none, np.zeros((1, 1, 1), bool), np.zeros(3), 0.02)
            args = (Q, none)
        J, r = f.terms(root, D, data, None, None)
        h = opts.huber * 0.02
        weight = opts.rays / len(Q) if rays else 1.0 / len(Q)
        firsts = [np.zeros(len(Q), np.int64), rng.integers(-3, len(A) + 3, len(Q))]
        got = []
        for first in firsts + [None]:
            first = firsts[0] if first is None else first      # the last call's capsules
            H, g = np.zeros((f.n, f.n)), np.zeros(f.n)
            cost = capsule_normal_equations(*args, A, B, f.r, f.cpar, f.cbone, Ge, f.cols, h,
                                            weight, rays, H, g, first)
            got.append((H, g, cost))
            assert ((first >= 0) & (first < len(A))).all()
        if not rays:                                # each point's nearest capsule
            seg = B - A
            t = np.clip(np.einsum("mkc,kc->mk", Q[:, None] - A[None], seg)
                        / np.einsum("kc,kc->k", seg, seg), 0.0, 1.0)
            dq = np.linalg.norm(Q[:, None] - (A[None] + t[..., None] * seg[None]), axis=2)
            assert np.array_equal(firsts[0], np.argmin(dq - f.r[None], axis=1))
        for H, g, cost in got[1:]:
            assert np.array_equal(H, got[0][0]) and np.array_equal(g, got[0][1])
            assert cost == got[0][2]
        H, g, cost = got[0]
        assert np.allclose(H, J.T @ J, rtol=1e-9, atol=1e-12)
        assert np.allclose(g, J.T @ r, rtol=1e-9, atol=1e-12)
        assert np.isclose(cost, r @ r, rtol=1e-9)
        assert np.abs(g).max() > 0


@pytest.mark.parametrize("bucket", [1, 3, 4])
def test_surface_grid_finds_the_trees_nearest(bucket):
    """Every point's nearest voxel and distance, bit for bit, as ``cKDTree.query``: points
    near a random voxel set, deep inside it, far outside the grid; of two voxels at the same
    distance the first."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(9 + bucket)
    for _ in range(5):
        ijk = np.argwhere(rng.random(rng.integers(3, 25, 3)) < rng.uniform(0.02, 0.3))
        if not len(ijk):
            continue
        corner, size = rng.normal(size=3), 0.02
        X = corner + ijk * size
        grid = SurfaceGrid(X, ijk, corner, size, bucket)
        x = np.r_[X[rng.integers(0, len(X), 200)] + rng.normal(size=(200, 3)) * 0.05,
                  X.mean(axis=0) + rng.normal(size=(30, 3)) * 2.0, X[:5]]
        d, i = grid.query(x)
        d0, i0 = cKDTree(X).query(x)
        assert np.array_equal(d, d0) and np.array_equal(i, i0)
    X = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0]])
    d, i = SurfaceGrid(X, np.array([[0, 0, 0], [1, 0, 0]]), np.zeros(3), 0.02).query(
        np.array([[0.01, 0.3, 0.0]]))
    assert i[0] == 0 and d[0] == np.sqrt(0.01 ** 2 + 0.3 ** 2)


def reference_inside(S, dist, near, surface, origin, voxel, lo, occ, need, sk, start, end, G,
                     h, deep, w):
    """The inside term's rows and residuals as NumPy expressions."""
    idx = np.rint((S - origin) / voxel).astype(np.int64) - lo
    ok = ((idx >= 0) & (idx < np.array(occ.shape))).all(axis=1)
    held = np.zeros(len(S), bool)
    held[ok] = occ[tuple(idx[ok].T)]
    s = np.where(held, 1.0, -1.0)
    g = (S - surface[near]) / np.maximum(dist, 1e-9)[:, None] * s[:, None]
    ri = need - s * dist
    act = np.where(ri > 0, 1.0, deep * np.minimum(1.0, h / np.maximum(-ri, 1e-12)))
    Ji = -(np.einsum("mc,mcn->mn", g * (1 - sk)[:, None], G[start])
           + np.einsum("mc,mcn->mn", g * sk[:, None], G[end]))
    act = np.sqrt(act)
    return Ji * (w * act)[:, None], ri * w * act


@pytest.mark.parametrize("deep", [0.0, 0.5])
def test_inside_rows_are_numpys_bit_for_bit(deep):
    """Points inside and outside a ball and beyond its grid; both sides of the one-sided
    residual."""
    from scipy.ndimage import binary_erosion
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(11)
    for _ in range(5):
        ijk = np.indices((14, 12, 16)).transpose(1, 2, 3, 0)
        occ = np.linalg.norm(ijk - (7, 6, 8), axis=-1) < rng.uniform(4, 6)
        surf = np.argwhere(occ & ~binary_erosion(occ))
        lo, voxel = rng.integers(0, 5, 3), 0.02
        origin = rng.normal(size=3)
        surface = origin + (surf + lo) * voxel
        S = np.r_[origin + (lo + rng.uniform(-3, 18, (60, 3))) * voxel,
                  origin + (lo + (7, 6, 8) + rng.normal(size=(30, 3))) * voxel,
                  surface[:5] + 1e-4]
        dist, near = cKDTree(surface).query(S)
        M, n = len(S), 17
        need = rng.uniform(0.0, 0.06, M)
        sk = rng.random(M)
        start, end = rng.integers(0, 6, M), rng.integers(0, 6, M)
        G = rng.normal(size=(6, 3, n))
        G[rng.random(G.shape) < 0.3] = 0.0
        args = (S, dist, near, surface, origin, voxel, lo, occ, need, sk, start, end, G,
                0.03, deep, 0.37)
        rows, res = inside_rows(*args)
        rows0, res0 = reference_inside(*args)
        assert np.array_equal(rows, rows0) and np.array_equal(res, res0)
        assert (res > 0).any() and (res0 <= 0).any()


def test_step_turns_each_block_as_its_own_loop():
    """The step's bones turned all at once against each block turned on its own (a rigid
    group by its rotation, another bone in the plane normal to it), steps longer than
    ``max_step`` shortened."""
    from topopose.sequence.tracker import _rotation

    f = _Fitter(_body(), TrackOptions())
    rng = np.random.default_rng(10)
    for _ in range(100):
        D = _directions(rng, len(NAMES))
        root = rng.normal(size=3)
        x = rng.normal(size=f.n) * rng.choice([0.01, 0.3, 1.0])
        E = reference_bases(D)
        want = D.copy()
        for members, c, w in f.blocks:
            a = x[c:c + w]
            na = np.linalg.norm(a)
            if na > f.opts.max_step:
                a = a * (f.opts.max_step / na)
            if w == 3:
                want[members] = D[members] @ _rotation(a).T
            else:
                d = D[members[0]] + E[members[0]] @ a
                want[members[0]] = d / np.linalg.norm(d)
        r1, D1 = f.step(root, D, x)
        assert np.array_equal(r1, root + x[:3])
        assert np.allclose(D1, want, rtol=0, atol=1e-15)
