"""Exact silhouettes of the synthetic subjects: ray tests, renderer, clearances.

Oracles: brute-force minimisation over densely sampled axis points (ray tests), dense surface
sampling projected with ``Camera.project`` (silhouettes, lens distortion included), brute-force
nearest surface points (clearances).
"""
import numpy as np
import pytest
from scipy.spatial import cKDTree

from topopose.capture import Camera
from topopose.synth.capture import camera_ring
from topopose.synth.geometry import (Prim, clearance, ray_hits_cone, ray_hits_ellipsoid,
                                             ray_table, render, render_numpy)
from topopose.synth.subjects import rz, rx


def _random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_ray_cone_closed_form_matches_brute_force():
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(16):
        a, b = rng.uniform(-0.3, 0.3, (2, 3))
        ra, rb = rng.uniform(0.01, 0.12, 2)
        o = rng.normal(size=3)
        o = o / np.linalg.norm(o) * 3.0
        d = rng.normal(size=(300, 3)) * 0.15 - o / 3.0
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        hit = ray_hits_cone(o, d, a, b, ra, rb)
        s = np.linspace(0, 1, 2001)
        q = a + s[:, None] * (b - a)                           # (S, 3)
        w = q - o                                              # (S, 3)
        t = (w @ d.T).T                                        # (N, S) foot of the perpendicular
        perp = np.linalg.norm(w[None] - t[:, :, None] * d[:, None, :], axis=2)
        val = np.min(perp - (ra + s * (rb - ra))[None], axis=1)
        clear = np.abs(val) > 2e-4
        assert np.array_equal(hit[clear], val[clear] <= 0)
        checked += clear.sum()
    assert checked > 2000


def test_ray_ellipsoid_matches_brute_force():
    rng = np.random.default_rng(2)
    for _ in range(10):
        c = rng.uniform(-0.2, 0.2, 3)
        axes = _random_rotation(rng)
        semi = rng.uniform(0.03, 0.2, 3)
        o = np.array([2.5, -1.0, 0.7])
        d = (c - o) + rng.normal(size=(300, 3)) * 0.15
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        hit = ray_hits_ellipsoid(o, d, c, axes, semi)
        t = np.linspace(1.0, 5.0, 4001)
        pts = o + t[None, :, None] * d[:, None, :]
        y = (pts - c) @ axes / semi
        val = np.min(np.linalg.norm(y, axis=2), axis=1) - 1.0  # ≤ 0: a sample point inside
        clear = np.abs(val) > 4e-3
        assert np.array_equal(hit[clear], val[clear] <= 0)


def _dense_samples(p, step):
    """Points on spheres densely filling the surface of a primitive (round cone) or its surface."""
    if p.kind == "ellipsoid":
        n = int(4 * np.pi * np.max(p.semi) ** 2 / step ** 2)
        k = np.arange(n) + 0.5
        phi = np.arccos(1 - 2 * k / n)
        th = np.pi * (1 + 5 ** 0.5) * k
        sph = np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], 1)
        return p.c + (sph * p.semi) @ p.axes.T
    L = np.linalg.norm(p.b - p.a)
    out = []
    for si in np.linspace(0, 1, int(L / step) + 2):
        r = p.ra + si * (p.rb - p.ra)
        n = int(4 * np.pi * r * r / step ** 2) + 8
        k = np.arange(n) + 0.5
        phi = np.arccos(1 - 2 * k / n)
        th = np.pi * (1 + 5 ** 0.5) * k
        sph = np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], 1)
        out.append(p.a + si * (p.b - p.a) + r * sph)
    return np.concatenate(out)


@pytest.mark.parametrize("prim", [
    Prim("cone", "x", np.array([-0.15, 0.05, 0.9]), np.array([0.2, -0.1, 1.25]), 0.05, 0.05),
    Prim("cone", "x", np.array([0.1, 0.1, 0.7]), np.array([-0.2, 0.0, 1.2]), 0.09, 0.03),
    Prim("ellipsoid", "x", c=np.array([0.05, -0.05, 1.0]), axes=rz(30) @ rx(40),
         semi=np.array([0.2, 0.08, 0.05])),
])
def test_silhouette_equals_projected_surface(prim):
    """Exact silhouette vs dense surface sampling projected by Camera.project (distorted cams)."""
    cams = camera_ring((np.array([-0.5, -0.5, 0.5]), np.array([0.5, 0.5, 1.5])), 3, (320, 240),
                       np.random.default_rng(5))
    cams[0] = Camera("barrel", (320, 240), cams[0].matrix, [-0.12, 0.03, 1e-3, -1e-3],
                     cams[0].rotation, cams[0].translation)
    for cam in cams:
        mask = render(cam, ray_table(cam), [prim])
        assert mask.sum() > 100
        px = cam.project(_dense_samples(prim, 0.005))          # ≈ 0.3 px apart in the images
        on = np.argwhere(mask)[:, ::-1].astype(float)
        # no false positive: every silhouette pixel centre is the image of a surface point
        # (within the sampling spacing)
        dist, _ = cKDTree(px).query(on)
        assert dist.max() <= 0.5, (cam.name, dist.max())
        # no false negative: every projected surface point is within ~1 px of a silhouette pixel
        # centre, and on average as close as a uniform point of a pixel to its centre (0.38 px);
        # a mask eroded by a single pixel gives max > 2 px and mean > 0.5 px
        dist2, _ = cKDTree(on).query(px)
        assert dist2.max() <= 1.25, (cam.name, dist2.max())
        assert dist2.mean() <= 0.46, (cam.name, dist2.mean())


def test_numba_renderer_matches_numpy_reference():
    rng = np.random.default_rng(3)
    cams = camera_ring((np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 2.0])), 3, (200, 150), rng)
    prims = []
    for _ in range(12):
        a, b = rng.uniform([-0.6, -0.6, 0.2], [0.6, 0.6, 1.8], (2, 3))
        prims.append(Prim("cone", "x", a, b, *rng.uniform(0.02, 0.1, 2)))
        prims.append(Prim("ellipsoid", "x", c=a, axes=_random_rotation(rng), semi=rng.uniform(0.03, 0.2, 3)))
    for cam in cams:
        tab = ray_table(cam)
        m1 = render(cam, tab, prims)
        m2 = render_numpy(cam, tab, prims)
        assert m1.sum() > 1000
        assert np.array_equal(m1, m2)


def _brute_gap(p, q, step=0.006):
    pp = _dense_samples(p, step)
    qq = _dense_samples(q, step)
    # keep the outer surface points only: drop points strictly inside their own primitive
    from topopose.synth.geometry import sdf
    pp = pp[sdf(p, pp) > -step]
    qq = qq[sdf(q, qq) > -step]
    d, _ = cKDTree(qq).query(pp)
    return d.min()


def test_clearance_matches_brute_force():
    rng = np.random.default_rng(4)
    seen = set()
    for _ in range(4):
        a, b = rng.uniform(-0.2, 0.2, (2, 3))
        c1 = Prim("cone", "a", a, b, 0.04, 0.04)
        off = rng.normal(size=3)
        off = off / np.linalg.norm(off) * rng.uniform(0.1, 0.2)
        c2 = Prim("cone", "b", a + off, b + off + rng.normal(size=3) * 0.05, 0.03, 0.03)
        e = Prim("ellipsoid", "c", c=(a + b) / 2 - off, axes=_random_rotation(rng),
                 semi=np.array([0.08, 0.05, 0.04]))
        for p, q in ((c1, c2), (c1, e)):
            g = clearance(p, q)
            bg = _brute_gap(p, q)
            if g > 0.003:        # both apart: the gaps agree to within the sampling steps
                assert abs(g - bg) < 0.009, (g, bg)
                seen.add("apart")
            elif g < -0.003:     # overlapping primitives: brute-force surfaces meet
                assert bg < 0.004
                seen.add("overlap")
    assert seen == {"apart", "overlap"}
