"""Thinning: topology preserved, thin results, invariances, options, bad input.

Oracles: scipy.ndimage.label (26-components of X, 6-components of the padded
complement) and skimage.measure.euler_number (26/6) — independent of topopose; the
simple-point test of the thinness checks uses the 2^26 table, which
tests/test_topology_tables.py cross-checks against a BFS on all configurations.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

import topopose as tp
from topopose import InputError
from topopose.topology import METHODS, border_constraint, thin, thinning
from topopose.topology import neighbourhood as nb
from topopose.topology.tables import load_tables

from topology_shapes import (
    S26,
    has_2x2x2_block,
    neighbour_counts,
    pack,
    random_volumes,
    topology,
)

DATA = Path(__file__).resolve().parent / "data"   # body volumes shipped with the tests (README there)
CURVE = ("pkd6", "d6i1d", "ack3")
N_RANDOM = 2000


def configs(vol: np.ndarray, points: np.ndarray) -> np.ndarray:
    """26-bit configuration index of each point (rows of ``points``) in ``vol``."""
    p = np.pad(vol, 1)
    q = points + 1
    out = np.zeros(len(points), dtype=np.int64)
    for i, (dx, dy, dz) in enumerate(nb.OFFSETS):
        out |= p[q[:, 0] + dx, q[:, 1] + dy, q[:, 2] + dz].astype(np.int64) << i
    return out


def simple_mask(vol: np.ndarray, points: np.ndarray) -> np.ndarray:
    tab = load_tables()
    c = configs(vol, points)
    return ((tab[12][c >> 3] >> (c & 7)) & 1).astype(bool)


def check_thin(method, skel, K, where=""):
    """Thinness of curve and ultimate skeletons (no 2×2×2 block; no simple voxel left
    unless it is in K or, for curve methods, a curve end point)."""
    if method == "d6i2d":
        return
    assert not has_2x2x2_block(skel), f"{method}: 2x2x2 block {where}"
    pts = np.argwhere(skel & ~K)
    if len(pts) == 0:
        return
    s = simple_mask(skel, pts)
    if method != "d6u":
        ends = neighbour_counts(skel)[tuple(pts.T)] == 1
        s &= ~ends
    assert not s.any(), f"{method}: simple voxels left at {pts[s][:3].tolist()} {where}"


@pytest.fixture(scope="module")
def random_pack():
    vols = random_volumes(N_RANDOM, seed=7)
    big, slices = pack(vols)
    before = [topology(v) for v in vols]
    return vols, big, slices, before


@pytest.mark.parametrize("method", METHODS)
def test_random_volumes_keep_topology_and_are_thin(method, random_pack):
    vols, big, slices, before = random_pack
    r = thinning(big, method)
    assert not np.any(r.skeleton & ~big)
    bad = []
    for i, sl in enumerate(slices):
        s = r.skeleton[sl]
        if topology(s) != before[i]:
            bad.append((i, before[i], topology(s)))
    assert not bad, f"{method}: topology changed on {len(bad)} volumes, e.g. {bad[:3]}"
    check_thin(method, r.skeleton, r.constraints)
    # the constraint set holds only 1D (or 2D) isthmuses found on the way, inside the skeleton
    assert not np.any(r.constraints & ~r.skeleton)
    if method in ("pkd6", "d6u"):
        assert not r.constraints.any()


def _bodies():
    return sorted(DATA.glob("body_tpose_*.npz"), key=lambda p: int(p.stem.split("_")[-1]))


@pytest.mark.parametrize("method", METHODS)
def test_body_volumes(method):
    paths = [p for p in _bodies() if int(p.stem.split("_")[-1]) <= 200]
    assert paths, "tests/data/body_tpose_*.npz not found"
    for p in paths:
        v = np.load(p)["volume"]
        r = thinning(v, method)
        assert topology(r.skeleton) == topology(v), p.name
        check_thin(method, r.skeleton, r.constraints, p.name)
        if method != "d6u":
            assert r.skeleton.sum() > 20


def test_largest_body_d6i1d():
    p = [p for p in _bodies() if p.stem.endswith("_400")]
    v = np.load(p[0])["volume"]
    r = thinning(v, "d6i1d")
    assert topology(r.skeleton) == topology(v)
    check_thin("d6i1d", r.skeleton, r.constraints)


def ball(r, n=None):
    n = n or 2 * r + 3
    g = np.indices((n, n, n)) - (n - 1) / 2
    return (g ** 2).sum(0) <= r * r


@pytest.mark.parametrize("r", [1, 2, 3, 5, 8])
def test_ball_to_one_voxel_under_d6u(r):
    assert thin(ball(r), "d6u").sum() == 1


@pytest.mark.parametrize("method", CURVE)
@pytest.mark.parametrize("size", [(20, 6, 6), (30, 9, 5), (16, 11, 7), (25, 25, 4)])
def test_box_to_curve(method, size):
    box = np.zeros(tuple(s + 4 for s in size), bool)
    box[2:-2, 2:-2, 2:-2] = True
    r = thinning(box, method)
    s = r.skeleton
    assert topology(s) == (1, 1, 1)
    check_thin(method, s, r.constraints)
    # a curve: no voxel is interior (T6bar = 0) or on a surface (T6bar >= 2)
    pts = np.argwhere(s)
    from topopose.topology import t6bar

    assert all(t6bar(c) == 1 for c in configs(s, pts).tolist())
    assert s.sum() < box.sum() / 3


@pytest.mark.parametrize("method", METHODS)
def test_two_voxel_objects_never_vanish(method):
    for off in nb.OFFSETS[:13]:
        for base in ((0, 0, 0), (2, 2, 2)):
            v = np.zeros((5, 5, 5), bool)
            a = np.array(base) + np.where(off < 0, 1, 0)
            v[tuple(a)] = True
            v[tuple(a + off)] = True
            s = thin(v, method)
            assert s.sum() >= 1 and ndimage.label(s, structure=S26)[1] == 1, (method, off, base)


@pytest.mark.parametrize("method", METHODS)
def test_translation_and_array_border(method):
    rng = np.random.default_rng(3)
    for v in random_volumes(25, seed=11):
        ref = thin(v, method)  # touches the array border on every side it reaches
        big = np.zeros(tuple(s + 9 for s in v.shape), bool)
        o = rng.integers(0, 10, 3)
        sl = tuple(slice(a, a + s) for a, s in zip(o, v.shape))
        big[sl] = v
        out = thin(big, method)
        assert np.array_equal(out[sl], ref) and out.sum() == ref.sum()


@pytest.mark.parametrize("method", METHODS)
def test_48_cube_symmetries_keep_topology_and_thinness(method):
    """Directional thinning is not symmetric voxel by voxel; what must hold under
    each of the 48 symmetries is topology preservation and thinness."""
    vols = random_volumes(10, seed=5)[:10]
    transformed = []
    for v in vols:
        for m in nb.cube_symmetries():
            perm = [int(np.flatnonzero(row)[0]) for row in m]
            w = np.transpose(v, perm)
            for ax in range(3):
                if m[ax].sum() < 0:
                    w = np.flip(w, ax)
            transformed.append(np.ascontiguousarray(w))
    big, slices = pack(transformed)
    r = thinning(big, method)
    for i, sl in enumerate(slices):
        assert topology(r.skeleton[sl]) == topology(transformed[i])
    check_thin(method, r.skeleton, r.constraints)


@pytest.mark.parametrize("method", METHODS)
def test_optimizations_do_not_change_the_result(method):
    vols = random_volumes(150, seed=9)
    big, _ = pack(vols)
    body = np.load(DATA / "body_tpose_100.npz")["volume"]
    for v in (big, body):
        ref = thin(v, method)
        for bl in (True, False):
            for lut in (True, False):
                for ccsu in (True, False, "full"):
                    out = thin(v, method, border_list=bl, lut=lut, ccsu=ccsu)
                    if method == "ack3" and not bl:
                        # another visiting order: other asymmetric choices, same topology
                        assert topology(out) == topology(v)
                    else:
                        assert np.array_equal(out, ref), (bl, lut, ccsu)


@pytest.mark.parametrize("method", METHODS)
def test_keep_voxels_survive(method):
    rng = np.random.default_rng(2)
    vols = random_volumes(200, seed=13)
    big, _ = pack(vols)
    keep = big & (rng.random(big.shape) < 0.01)
    r = thinning(big, method, keep=keep)
    assert np.all(r.skeleton[keep]) and np.all(r.constraints[keep])
    assert topology(r.skeleton) == topology(big)


def test_border_constraint():
    v = np.zeros((10, 12, 8), bool)
    assert not border_constraint(v).any()
    v[3:7, 3:9, 2:6] = True  # not touching the border
    assert not border_constraint(v).any()
    v[4:6, 0:3, 3:5] = True  # an arm leaving through the y = 0 face
    k = border_constraint(v)
    assert k.sum() == 1
    # centroid of the boundary voxels is (4.5, 0, 3.5); nearest object voxel has y = 0
    p = np.argwhere(k)[0]
    assert p[1] == 0 and p[0] in (4, 5) and p[2] in (3, 4)
    for method in METHODS:
        assert thin(v, method, keep=k)[tuple(p)]


def test_d6i1d_has_fewer_end_points_than_pkd6_on_noisy_shapes():
    """Isthmus constraints give fewer spurious branches than end-point constraints (§6.3)."""
    rng = np.random.default_rng(4)
    v = np.zeros((60, 24, 24), bool)
    g = np.indices(v.shape)
    v[((g[1] - 11.5) ** 2 + (g[2] - 11.5) ** 2) <= 81] = True
    v[:2] = v[-2:] = False
    noisy = v.copy()
    surf = v & ~ndimage.binary_erosion(v)
    bumps = ndimage.binary_dilation(surf & (rng.random(v.shape) < 0.05))
    noisy |= bumps
    noisy ^= surf & (rng.random(v.shape) < 0.1)
    ends = {}
    for m in ("pkd6", "d6i1d"):
        s = thin(noisy, m)
        ends[m] = int((neighbour_counts(s)[s] == 1).sum())
    assert ends["d6i1d"] <= ends["pkd6"]


def test_empty_volume_and_public_name():
    v = np.zeros((4, 5, 6), bool)
    for m in METHODS:
        out = thin(v, m)
        assert out.shape == v.shape and not out.any()
    assert tp.thin is thin


@pytest.mark.parametrize("bad", [
    np.zeros((4, 4), bool), np.zeros((2, 2, 2, 2), bool), np.zeros((0, 3, 3), bool),
    np.zeros((3, 3, 3), np.uint8), np.zeros((3, 3, 3), float), [[[True]]],
])
def test_bad_volumes(bad):
    with pytest.raises(InputError):
        thin(bad)


def test_bad_method_and_keep():
    v = np.ones((3, 3, 3), bool)
    with pytest.raises(InputError, match="method"):
        thin(v, "zhang")
    with pytest.raises(InputError, match="keep"):
        thin(v, keep=np.ones((3, 3, 4), bool))
    with pytest.raises(InputError, match="keep"):
        thin(v, keep=np.ones((3, 3, 3), np.uint8))


def test_cli_skeleton(tmp_path):
    from topopose.cli import main
    from topopose.hull import Volume

    v = np.load(DATA / "body_tpose_64.npz")["volume"]
    Volume(v, (1.0, 2.0, 3.0), 0.5).save(tmp_path / "v.npz")
    for m in ("pkd6", "d6i1d"):
        assert main(["skeleton", str(tmp_path / "v.npz"), "--method", m, "--out", str(tmp_path / "s.npz")]) == 0
        s = Volume.load(tmp_path / "s.npz")
        assert np.array_equal(s.data, thin(v, m))
        assert s.voxel_size == 0.5 and np.allclose(s.origin, (1, 2, 3))


def test_bounding_box_kernels_agree_with_numpy():
    """The word-scanning bounding box (C-contiguous inputs) and the row-scanning one
    (any layout) equal numpy's bounds and row occupancy, empty arrays included."""
    from topopose.topology.thinning_kernels import bounding_box, bounding_box_flat

    rng = np.random.default_rng(5)
    for _ in range(200):
        shape = tuple(int(s) for s in rng.integers(1, 14, 3))
        a = rng.random(shape) < rng.choice([0.0, 0.002, 0.05, 0.5])
        u = a.view(np.uint8)
        rows = a.any(axis=2)
        for lo, hi, r in (bounding_box_flat(u.reshape(-1), *shape), bounding_box(u),
                          bounding_box(np.asfortranarray(u))):
            assert np.array_equal(r.astype(bool), rows)
            if a.any():
                idx = np.argwhere(a)
                assert np.array_equal(lo, idx.min(axis=0)) and np.array_equal(hi, idx.max(axis=0))
            else:
                assert (lo > hi).all()
