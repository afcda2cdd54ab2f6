"""The tracker's Numba kernels against the NumPy formulas they compute, bit for bit: the
bones' bases (two unit normals by cross products) and the joints' Jacobian (each bone's end
moved by its own parameters, summed along the path from the root)."""
import numpy as np

from topopose.sequence.body import CapsuleBody
from topopose.sequence.tracker import TrackOptions, _Fitter
from topopose.sequence.tracker_kernels import bone_bases

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
