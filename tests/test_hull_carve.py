"""Visual hull (thesis §2.3.2.2): hierarchical carving against independent oracles.

Oracles: (1) brute force — every voxel centre projected with ``Camera.project`` and looked up in
every mask; (2) the analytic visual hull of a sphere / capsule (intersection of the exact
silhouette cones, per voxel centre); (3) the true shape itself.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from _capture_testutils import analytic_hull, capsule_masks, in_capsule, ring
from topopose.capture import Capture
from topopose.errors import InputError
from topopose.hull import HullCarver, Volume, fit_box, visual_hull
from topopose.hull.hull import VOLUME_FIT


def brute_force(cams, masks, origin, vs, shape):
    """Direct definition: per voxel, the number of cameras whose silhouette holds the pixel
    nearest its centre's projection; and whether a projection lies on a pixel boundary."""
    ijk = np.indices(shape).reshape(3, -1).T
    pts = origin + ijk * vs
    seen = np.zeros(len(pts), int)
    near_edge = np.zeros(len(pts), bool)
    for cam, m in zip(cams, masks):
        uv = cam.project(pts)
        ok = np.all(np.isfinite(uv), axis=1)
        px = np.floor(np.where(ok[:, None], uv, -1) + 0.5)
        w, h = cam.size
        ok &= (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        hit = np.zeros(len(pts), bool)
        hit[ok] = m[px[ok, 1].astype(int), px[ok, 0].astype(int)]
        seen += hit
        frac = np.abs((uv + 0.5) - np.round(uv + 0.5))
        near_edge |= np.any(frac < 1e-7, axis=1) & ok
    return seen.reshape(shape), near_edge.reshape(shape)


def _capture(cams, masks):
    return Capture(cams, ["000000"], masks={"000000": masks})


@pytest.mark.parametrize("dist,fisheye", [((0, 0, 0, 0), False),
                                          ((-0.25, 0.08, 0.001, -0.002, -0.01), False),
                                          ((0.05, -0.02, 0.01, 0.0), True)])
def test_carver_equals_brute_force(dist, fisheye):
    cams = ring(n=6, f=500, dist=dist, fisheye=fisheye, size=(320, 240))
    masks = capsule_masks(cams, (-0.3, 0.1, 0.5), (0.35, -0.1, 1.4), 0.18)
    # corrupt one mask so the tolerance matters
    masks[2] = masks[2].copy()
    masks[2][:, :150] = False
    origin, vs, shape = np.array([-0.9, -0.8, 0.05]), 0.037, (47, 45, 52)
    carver = HullCarver(cams, origin, vs, shape)
    seen, edge = brute_force(cams, masks, origin, vs, shape)
    for tolerance in (0, 1):
        got = carver.carve(masks, tolerance=tolerance)
        want = seen >= len(cams) - tolerance
        bad = got != want
        assert want.sum() > 1000
        assert not np.any(bad & ~edge), f"{int((bad & ~edge).sum())} voxels differ from brute force"
        # hierarchical work is much smaller than the brute force one
        assert carver.stats[1] < 0.5 * np.prod(shape)


def test_projection_kernel_matches_camera_project():
    rng = np.random.default_rng(3)
    cams = ring(n=3, dist=(-0.2, 0.05, 0.002, -0.001, 0.01)) + ring(n=2, fisheye=True,
                                                                     dist=(0.1, -0.05, 0.01, 0.0))
    origin, vs = np.array([-1.0, -1.0, 0.0]), 0.01
    carver = HullCarver(cams, origin, vs, (200, 200, 200))
    ijk = rng.uniform(0, 200, size=(5000, 3))
    got = carver.project_voxels(ijk)
    for q, cam in enumerate(cams):
        uv = cam.project(origin + ijk * vs)
        px = np.floor(uv + 0.5)
        w, h = cam.size
        ok = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        want = np.where(ok, px[:, 1] * w + px[:, 0], -1)
        edge = np.any(np.abs(uv + 0.5 - np.round(uv + 0.5)) < 1e-7, axis=1)
        assert ok.sum() > 1000
        assert np.all((got[:, q] == want) | edge)


def test_points_behind_or_beyond_lens_field_are_not_seen():
    # strong barrel distortion: r·radial(r) folds back at r² = 1/(3·0.3) ≈ 1.11
    cams = ring(n=1, dist=(-0.3, 0, 0, 0))
    cam = cams[0]
    carver = HullCarver(cams, np.zeros(3), 1.0, (2, 2, 2))
    # a point far off axis: x/z = 1.9 would fold back into the image with the polynomial model
    xc = np.array([[1.9, 0.0, 1.0], [0.0, 0.0, -1.0], [0.01, 0.0, 1.0]])
    world = (xc - cam.translation) @ cam.R           # camera → world
    uv = cam.project(world)
    assert np.isfinite(uv[0]).all() and 0 <= uv[0, 0] < cam.size[0]   # the fold-back
    ijk = (world - carver.origin) / carver.voxel_size
    got = carver.project_voxels(ijk)[:, 0]
    assert got[0] == -1 and got[1] == -1 and got[2] >= 0


@pytest.fixture(scope="module")
def sphere_case():
    cams = ring(n=8)
    c, r = np.array([0.05, -0.03, 0.95]), 0.3
    return cams, c, r, capsule_masks(cams, c, c, r)


@pytest.mark.parametrize("shape", ["sphere", "capsule"])
def test_hull_matches_analytic_visual_hull_128(shape, sphere_case):
    cams, c, r, masks = sphere_case
    if shape == "sphere":
        A = B = c
    else:
        A, B, r = np.array([-0.35, -0.2, 0.6]), np.array([0.3, 0.25, 1.3]), 0.14
        masks = capsule_masks(cams, A, B, r)
    vol = visual_hull(_capture(cams, masks), 0, resolution=128)
    # 128 voxels along the fitted volume's longest side, the grid a margin beyond it
    assert max(vol.data.shape) == 128 + 2 * math.ceil(VOLUME_FIT.margin * 126 - 1e-9)
    ijk = np.indices(vol.data.shape).reshape(3, -1).T
    pts = vol.world(ijk)
    ana = analytic_hull(cams, pts, A, B, r).reshape(vol.data.shape)
    inter = np.logical_and(ana, vol.data).sum()
    union = np.logical_or(ana, vol.data).sum()
    assert inter / union >= 0.97, inter / union
    # the true shape lies inside the hull, up to the silhouettes' pixel discretization:
    # every voxel centre deeper than one pixel footprint inside the shape is in the hull
    far = max(np.linalg.norm(cam.center - (A + B) / 2) for cam in cams) + r
    eps = far / 800 * 1.0
    deep = in_capsule(pts, A, B, r - eps).reshape(vol.data.shape)
    assert deep.sum() > 10000
    assert not np.any(deep & ~vol.data)
    # one empty voxel all round (fitted volume)
    assert not vol.diagnostics["touches_border"]
    assert vol.diagnostics["components_dropped"] == []


def test_true_shape_strictly_inside_with_conservative_masks(sphere_case):
    cams, c, r, _ = sphere_case
    A, B, r = np.array([-0.2, 0.1, 0.5]), np.array([0.25, -0.15, 1.4]), 0.08
    masks = capsule_masks(cams, A, B, r, margin_px=0.75)   # every pixel the shape touches
    vol = visual_hull(_capture(cams, masks), 0, resolution=96)
    pts = vol.world(np.indices(vol.data.shape).reshape(3, -1).T)
    inside = in_capsule(pts, A, B, r).reshape(vol.data.shape)
    assert inside.sum() > 500
    assert not np.any(inside & ~vol.data)


def test_tolerance_recovers_a_bad_mask(sphere_case):
    cams, c, r, masks = sphere_case
    bad = [m.copy() for m in masks]
    h, w = bad[3].shape
    bad[3][:, : w // 2 + 20] = False                 # half of the subject missing in one camera
    vol = (-0.5, -0.5, 0.4), (0.6, 0.5, 1.5)
    good = visual_hull(_capture(cams, masks), 0, resolution=64, volume=vol).data
    cut = visual_hull(_capture(cams, bad), 0, resolution=64, volume=vol).data
    tol = visual_hull(_capture(cams, bad), 0, resolution=64, volume=vol, tolerance=1).data
    assert cut.sum() < 0.8 * good.sum()
    assert np.all(tol >= good)                        # tolerance only adds voxels
    assert tol.sum() < 1.6 * good.sum()


def test_largest_component_and_diagnostics(sphere_case):
    cams, c, r, masks = sphere_case
    small = capsule_masks(cams, (0.6, 0.6, 1.6), (0.6, 0.6, 1.6), 0.06)
    both = [a | b for a, b in zip(masks, small)]
    box = (-0.8, -0.8, 0.2), (0.9, 0.9, 1.9)
    cap = _capture(cams, both)
    kept = visual_hull(cap, 0, resolution=64, volume=box)
    allc = visual_hull(cap, 0, resolution=64, volume=box, keep_largest=False)
    assert len(kept.diagnostics["components_dropped"]) >= 1
    assert kept.data.sum() + sum(kept.diagnostics["components_dropped"]) == allc.data.sum()
    assert kept.data.sum() > 5 * kept.diagnostics["components_dropped"][0]
    assert np.all(allc.data >= kept.data)
    t = kept.diagnostics["timings_ms"]
    assert {"carve", "setup", "components", "fit"} <= set(t)


def test_capture_volume_grid_and_border(sphere_case):
    cams, c, r, masks = sphere_case
    # a volume cutting the sphere: the hull touches the border there
    box = (-0.5, -0.5, 0.4), (0.5, 0.5, 1.0)
    vol = visual_hull(_capture(cams, masks), 0, resolution=50, volume=box)
    assert vol.data.shape == (50, 50, 30)
    assert np.allclose(vol.origin, np.array(box[0]) + vol.voxel_size / 2)
    assert vol.diagnostics["touches_border"]
    assert vol.data[:, :, -1].any() and not vol.data[:, :, 0].any()


def test_fit_box_contains_hull_and_is_tight(sphere_case):
    cams, c, r, masks = sphere_case
    lo, hi = fit_box(cams, masks)
    # contains the hull of these masks (brute force on a wide grid) ...
    box = (c - 2 * r, c + 2 * r)
    seen, _ = brute_force(cams, masks, box[0], 4 * r / 60, (61, 61, 61))
    want = seen == len(cams)
    pts = box[0] + np.argwhere(want) * (4 * r / 60)
    assert len(pts) > 1000
    assert np.all(pts >= lo) and np.all(pts <= hi)
    # ... hence the sphere up to one pixel footprint (the masks sample pixel centres) ...
    eps = 3.5 / 800
    assert np.all(lo <= c - r + eps) and np.all(hi >= c + r - eps)
    # ... and it is tight
    assert np.all(hi - lo < 2 * r * 1.35)
    # a box around nothing
    assert fit_box(cams, [np.zeros_like(m) for m in masks]) is None


def test_refocus_keeps_voxel_size_and_follows_subject(sphere_case):
    cams, c, r, _ = sphere_case
    centres = [np.array([-0.6, 0.0, 0.9]), np.array([0.1, 0.4, 1.0]), np.array([0.5, -0.4, 0.8])]
    frames = {f"{i:06d}": capsule_masks(cams, p, p, 0.2) for i, p in enumerate(centres)}
    cap = Capture(cams, list(frames), masks=frames)
    vols = [visual_hull(cap, f, resolution=40, refocus=True) for f in frames]
    assert len({v.voxel_size for v in vols}) == 1
    vs = vols[0].voxel_size
    for v, p in zip(vols, centres):
        assert max(v.data.shape) <= 44
        centroid = v.world(np.argwhere(v.data)).mean(axis=0)
        assert np.linalg.norm(centroid - p) < 2 * vs
        assert not v.diagnostics["touches_border"]
        # origins on one world lattice
        assert np.allclose(v.origin / vs, np.round(v.origin / vs))
    fixed = visual_hull(cap, 0, resolution=40)
    assert fixed.voxel_size > 1.8 * vs               # the fixed grid spans all frames


def test_empty_frame_and_bad_arguments(sphere_case):
    cams, c, r, masks = sphere_case
    cap = Capture(cams, ["a", "b"], masks={"a": masks, "b": [np.zeros_like(m) for m in masks]})
    v = visual_hull(cap, "b", resolution=32)
    assert isinstance(v, Volume) and v.data.sum() == 0 and v.diagnostics["empty"]
    for kw in ({"resolution": 2}, {"resolution": 10.5}, {"tolerance": 8}, {"tolerance": -1},
               {"volume": ((0, 0, 0), (1, -1, 1))}):
        with pytest.raises(InputError):
            visual_hull(cap, "a", **kw)
    with pytest.raises(InputError):
        visual_hull(cap, "zz")


def test_carver_cached_per_grid(sphere_case):
    cams, c, r, masks = sphere_case
    cap = _capture(cams, masks)
    v1 = visual_hull(cap, 0, resolution=48)
    v2 = visual_hull(cap, 0, resolution=48)
    assert np.array_equal(v1.data, v2.data)
    assert len(cap.cache["carvers"]) == 1
    visual_hull(cap, 0, resolution=40)
    assert len(cap.cache["carvers"]) == 2


def test_components_without_cc3d_fallback(monkeypatch):
    import sys

    from topopose.hull import keep_largest_component

    rng = np.random.default_rng(5)
    occ = rng.random((20, 21, 22)) < 0.2
    occ[2:15, 3:12, 4:10] = True
    want = occ.copy()
    got_dropped = keep_largest_component(want)
    monkeypatch.setitem(sys.modules, "cc3d", None)            # import cc3d → ImportError
    fb = occ.copy()
    fb_dropped = keep_largest_component(fb)
    assert np.array_equal(fb, want) and fb_dropped == got_dropped
    # oracle: scipy labelling with the full 3×3×3 structure
    from scipy import ndimage

    lab, n = ndimage.label(occ, structure=np.ones((3, 3, 3), bool))
    sizes = np.bincount(lab.ravel())[1:]
    assert want.sum() == sizes.max() and sorted(sizes)[:-1][::-1] == got_dropped


@pytest.mark.parametrize("dist,fisheye", [((0, 0, 0, 0), False),
                                          ((-0.25, 0.08, 0.001, -0.002, -0.01), False)])
def test_carving_from_small_masks_equals_their_upsampling(dist, fisheye):
    """A silhouette given as an UpsampledMask (the small mask of the person method's maps) is
    carved from the small mask: the same hull, voxel for voxel and with the same work counters,
    as the upsampled full-size mask — and as brute force on it. cv2's nearest-neighbour
    upsampling by an integer factor is pixel (u, v) → (u // f, v // f)."""
    import cv2

    from topopose.capture.background import UpsampledMask

    cams = ring(n=5, f=500, dist=dist, fisheye=fisheye, size=(320, 240))
    rng = np.random.default_rng(4)
    full = capsule_masks(cams, (-0.3, 0.1, 0.5), (0.35, -0.1, 1.4), 0.18)
    ups, plain = [], []
    for k, (cam, m) in enumerate(zip(cams, full)):
        fx, fy = [(4, 4), (2, 2), (4, 2), (1, 1), (8, 8)][k]
        small = cv2.resize(m.astype(np.uint8), (320 // fx, 240 // fy), interpolation=cv2.INTER_AREA)
        small[rng.random(small.shape) < 0.02] ^= 1          # specks: edges everywhere
        big = cv2.resize(small, (320, 240), interpolation=cv2.INTER_NEAREST).astype(bool)
        assert np.array_equal(big, np.repeat(np.repeat(small, fy, 0), fx, 1).astype(bool))
        u = big.view(UpsampledMask)
        u.small = small
        ups.append(u)
        plain.append(big.copy())
    assert getattr(ups[0][1:], "small", None) is None        # derived arrays do not carry it
    origin, vs, shape = np.array([-0.9, -0.8, 0.05]), 0.037, (47, 45, 52)
    a = HullCarver(cams, origin, vs, shape)
    b = HullCarver(cams, origin, vs, shape)
    seen, edge = brute_force(cams, plain, origin, vs, shape)
    for tolerance in (0, 1, 2):
        got = a.carve(ups, tolerance=tolerance)
        assert a.fac.tolist() == [[4, 4], [2, 2], [4, 2], [1, 1], [8, 8]]
        want = b.carve(plain, tolerance=tolerance)
        assert want.sum() > 500
        assert np.array_equal(got, want)
        assert np.array_equal(a.stats, b.stats)
        assert not np.any((got != (seen >= len(cams) - tolerance)) & ~edge)
    assert np.array_equal(a.carve(plain), b.carve(plain)) and a.fac.max() == 1


@pytest.mark.parametrize("dist", [(0, 0, 0, 0), (-0.25, 0.08, 0.001, -0.002, -0.01)])
def test_fit_box_from_small_masks_equals_their_upsampling(dist):
    """:func:`fit_box` reads an UpsampledMask's small mask (its pixel box and summed-area
    tables, a speed-up): the same box, bit for bit, as from the plain upsampled masks — with
    and without the linear programs (``within``), with tolerance, and with lens distortion
    (whose contour is still traced on the full mask)."""
    import cv2

    from topopose.capture.background import UpsampledMask

    cams = ring(n=4, f=500, dist=dist, size=(320, 240))
    rng = np.random.default_rng(7)
    full = capsule_masks(cams, (-0.3, 0.1, 0.5), (0.35, -0.1, 1.4), 0.18)
    ups, plain = [], []
    for k, (cam, m) in enumerate(zip(cams, full)):
        fx, fy = [(4, 4), (2, 2), (4, 2), (8, 8)][k]
        small = cv2.resize(m.astype(np.uint8), (320 // fx, 240 // fy), interpolation=cv2.INTER_AREA)
        small[rng.random(small.shape) < 0.01] ^= 1          # specks: the box's edges move
        big = cv2.resize(small, (320, 240), interpolation=cv2.INTER_NEAREST).astype(bool)
        u = big.view(UpsampledMask)
        u.small = small
        ups.append(u)
        plain.append(big.copy())
    for tol in (0, 1):
        a, b = fit_box(cams, ups, tol), fit_box(cams, plain, tol)
        assert a is not None and np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        within = (np.array([-1.5, -1.5, -0.2]), np.array([1.5, 1.5, 2.2]))
        a, b = fit_box(cams, ups, tol, within), fit_box(cams, plain, tol, within)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert np.all(b[1] - b[0] < within[1] - within[0])   # the coarse passes did shrink it


def test_pixel_box_equals_the_set_pixels_extremes():
    """``_pixel_box`` (cv2.boundingRect) against ``np.nonzero`` on random sparse masks,
    C-ordered or not, and None for an empty one."""
    from topopose.hull.hull import _pixel_box

    rng = np.random.default_rng(11)
    for _ in range(200):
        m = np.zeros(rng.integers(1, 40, 2), bool)
        m[rng.integers(0, m.shape[0], 3), rng.integers(0, m.shape[1], 3)] = rng.random() < 0.8
        for a in (m, m.T, m.astype(np.uint8)):
            ys, xs = np.nonzero(a)
            want = None if xs.size == 0 else (xs.min(), xs.max(), ys.min(), ys.max())
            got = _pixel_box(a)
            assert (got is None) == (want is None)
            assert got is None or tuple(int(v) for v in got) == tuple(int(v) for v in want)


def test_keep_largest_component_kernel_equals_bincount_path():
    """``keep_largest_component`` keeps the largest label by a kernel (a speed-up): the same
    occupancy and dropped sizes as the plain ``bincount`` / ``argmax`` path (the oracle, also
    scipy's labelling), on random volumes, bounding-box views and equal-size ties."""
    import cc3d
    from scipy import ndimage

    from topopose.hull import keep_largest_component

    def plain(occ, bbox=None):
        sub = occ[bbox] if bbox is not None else occ
        lab, n = ndimage.label(sub, structure=np.ones((3, 3, 3), bool))
        if n <= 1:
            return []
        sizes = np.bincount(lab.ravel())
        sizes[0] = 0
        best = int(np.argmax(sizes))
        sub &= lab == best
        return sorted((int(s) for s in np.delete(sizes, [0, best]) if s > 0), reverse=True)

    rng = np.random.default_rng(3)
    cases = []
    for _ in range(40):
        shape = tuple(int(x) for x in rng.integers(3, 14, 3))
        cases.append((rng.random(shape) < rng.uniform(0.05, 0.4), None))
    tie = np.zeros((9, 9, 9), bool)
    tie[1:3, 1:3, 1:3] = tie[5:7, 5:7, 5:7] = True                 # two of 8 voxels
    cases.append((tie, None))
    big = rng.random((20, 18, 16)) < 0.25
    cases.append((big, (slice(2, 17), slice(1, 18), slice(3, 15))))
    many = 0
    for occ, bbox in cases:
        a, b = occ.copy(), occ.copy()
        got, want = keep_largest_component(a, bbox), plain(b, bbox)
        assert got == want and np.array_equal(a, b)
        many += len(want) > 0
    assert many > 20 and cc3d is not None
    assert tie.sum() == 16 and keep_largest_component(tie.copy()) == [8]


def test_cropped_buffers_equal_brute_force_on_odd_masks():
    """The carver keeps only each silhouette's bounding box: a mask touching the image's sides,
    one set everywhere, one empty (tolerance 1), a single pixel, and scattered pixels give the
    brute-force hull."""
    cams = ring(n=5, f=500, size=(160, 120))
    masks = capsule_masks(cams, (-0.3, 0.1, 0.5), (0.35, -0.1, 1.4), 0.5)
    rng = np.random.default_rng(4)
    masks[0] = masks[0] | (rng.random(masks[0].shape) < 0.02)
    masks[1] = np.ones_like(masks[1])
    masks[2] = np.zeros_like(masks[2])
    masks[3] = masks[3].copy()
    masks[3][:, :2] = True                       # the image's left side
    masks[4] = masks[4].copy()
    masks[4][119, 159] = True                    # the last pixel
    origin, vs, shape = np.array([-0.9, -0.8, 0.05]), 0.05, (36, 32, 40)
    carver = HullCarver(cams, origin, vs, shape)
    seen, edge = brute_force(cams, masks, origin, vs, shape)
    for tolerance in (1, 2):
        got = carver.carve(masks, tolerance=tolerance)
        want = seen >= len(cams) - tolerance
        assert want.sum() > 100 and not np.any((got != want) & ~edge)
