"""The per-frame estimator's faster paths against the plain NumPy they replace (oracles written
out here), and the in-memory capture keeping a decoded silhouette's bounding box."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from topopose.frame.centre import STEP, scan_widths


def scan_widths_numpy(mask, uv, normal, half):
    """The scan written with whole arrays: every sample of every point, then the first
    outside one."""
    m = np.asarray(mask, bool)
    H, W = m.shape
    K = int(np.ceil(np.nanmax(np.where(np.isfinite(half), half, 0)) / STEP)) + 1
    s = np.arange(K + 1) * STEP
    out = []
    for sign in (1.0, -1.0):
        xy = uv[:, None, :] + sign * s[None, :, None] * normal[:, None, :]
        x = np.rint(xy[..., 0])
        y = np.rint(xy[..., 1])
        ok = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x < W) & (y < H)
        inside = ok & m[np.where(ok, y, 0).astype(int), np.where(ok, x, 0).astype(int)]
        first_out = np.argmax(~inside, axis=1)
        found = ~inside.all(axis=1) & inside[:, 0]
        d = (first_out - 0.5) * STEP
        out.append(np.where(found & (d <= half), d, np.nan))
    return -out[1], out[0]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 40),
       special=st.sampled_from(["none", "nan_uv", "nan_half", "inf_half"]))
def test_scan_widths_equals_the_whole_array_scan(seed, n, special):
    rng = np.random.default_rng(seed)
    H, W = rng.integers(5, 60, 2)
    mask = np.zeros((H, W), bool)
    for _ in range(rng.integers(1, 5)):                  # a few filled rectangles
        y0, x0 = rng.integers(0, H), rng.integers(0, W)
        mask[y0:y0 + rng.integers(1, H), x0:x0 + rng.integers(1, W)] = True
    uv = rng.uniform(-3, max(H, W) + 3, (n, 2))
    ties = rng.random(n) < 0.3
    uv[ties] = np.floor(uv[ties]) + 0.5                  # halfway between pixels: np.rint's ties
    a = rng.uniform(0, 2 * np.pi, n)
    normal = np.stack([np.cos(a), np.sin(a)], axis=1)
    half = np.where(rng.random(n) < 0.5, rng.integers(0, 100, n) * (STEP / 2),  # on a crossing
                    rng.uniform(0, 25, n))
    if special == "nan_uv":
        uv[rng.random(n) < 0.3] = np.nan
    elif special == "nan_half":
        half[rng.random(n) < 0.3] = np.nan
    elif special == "inf_half":
        half[rng.random(n) < 0.3] = np.inf
    got = scan_widths(mask, uv, normal, half)
    want = scan_widths_numpy(mask, uv, normal, half)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


def test_an_in_memory_capture_keeps_a_decoded_mask_box():
    from topopose.capture import Capture
    from topopose.geometry.camera import Camera
    from topopose.geometry.masks import boxed, mask_box

    cam = Camera("c", (8, 6), [[8, 0, 4], [0, 8, 3], [0, 0, 1]], [0, 0, 0, 0], [0, 0, 0],
                 [0, 0, 5])
    m = np.zeros((6, 8), bool)
    m[2:4, 3:6] = True
    plain = Capture([cam], ["f"], None, masks={"f": [m.astype(np.uint8)]})
    kept = Capture([cam], ["f"], None, masks={"f": [boxed(m)]})
    got_plain, got_kept = plain.silhouettes("f")[0], kept.silhouettes("f")[0]
    assert got_plain.dtype == bool and getattr(got_plain, "box", None) is None
    assert got_kept.box == (3, 2, 3, 2) == mask_box(m)
    np.testing.assert_array_equal(got_kept, m)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), fill=st.floats(0.0, 1.0))
def test_largest_depth_is_the_exact_transforms_largest(seed, fill):
    from topopose.frame.support import exact_edt, largest_depth

    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 70, 2)
    m = rng.random((h, w)) < fill
    if rng.random() < 0.5:                     # blobs: larger depths than noise gives
        from scipy.ndimage import binary_closing
        m = binary_closing(m, np.ones((5, 5)), border_value=1)
    assert largest_depth(m) == float(exact_edt(m).max())


def project_with_terms(cam, points):
    """:meth:`Camera.project` with every distortion term written out (zero or not)."""
    xc = cam.to_camera(points)
    z = xc[:, 2]
    a, b = xc[:, 0] / z, xc[:, 1] / z
    k = np.zeros(5)
    k[: min(5, cam.distortions.size)] = cam.distortions[:5]
    r2 = a * a + b * b
    radial = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2**3
    ad = a * radial + 2 * k[2] * a * b + k[3] * (r2 + 2 * a * a)
    bd = b * radial + k[2] * (r2 + 2 * b * b) + 2 * k[3] * a * b
    K = cam.matrix
    out = np.stack([K[0, 0] * ad + K[0, 1] * bd + K[0, 2], K[1, 1] * bd + K[1, 2]], axis=1)
    out[~(z > 0)] = np.nan
    return out


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-3, 1.0, 10.0, 1e80]),
       centred=st.booleans())
def test_projection_without_distortion_equals_the_full_formula_bit_for_bit(seed, scale,
                                                                            centred):
    from topopose.geometry.camera import Camera

    rng = np.random.default_rng(seed)
    K = [[rng.uniform(100, 2000), rng.choice([0.0, 0.5]), 0.0 if centred else 320.0],
         [0, rng.uniform(100, 2000), 0.0 if centred else 240.0], [0, 0, 1]]
    cam = Camera("c", (640, 480), K, [0, 0, 0, 0], rng.normal(size=3) * rng.integers(0, 2),
                 rng.normal(size=3) * rng.integers(0, 2) * rng.choice([1, 5]))
    P = rng.normal(size=(40, 3)) * scale
    P[rng.random(40) < 0.2] = cam.center              # z = 0
    P[rng.random(40) < 0.2, :2] = 0.0                 # on the axis: signed zeros
    if not cam.rotation.any() and not cam.translation.any():
        P[:2] = [[1e60, -1e60, 1e-100], [1e10, 0.0, 1e-300]]   # a² + b² overflows: NaN
    with np.errstate(all="ignore"):
        got, want = cam.project(P), project_with_terms(cam, P)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    fin = ~np.isnan(want)
    np.testing.assert_array_equal(got[fin], want[fin])
    np.testing.assert_array_equal(np.signbit(got[fin]), np.signbit(want[fin]))


def test_hull_remainder_densifies_each_segment_as_linspace_does():
    from topopose.frame.unseen import hull_remainder
    from topopose.hull.volume import Volume

    rng = np.random.default_rng(5)
    occ = np.zeros((30, 24, 40), bool)
    occ[5:25, 6:18, 4:36] = True
    occ[12:18, 2:22, 30:34] = True
    vol = Volume(occ, np.array([0.1, -0.2, 0.3]), 0.02)
    curves = {"a": np.array([[0.3, 0.0, 0.4], [0.35, 0.02, 0.6], [0.36, 0.05, 0.9]]),
              "b": rng.uniform([0.1, -0.2, 0.3], [0.6, 0.26, 1.1], (9, 3)),
              "c": np.array([[0.4, 0.0, 0.5]])}
    got = hull_remainder(vol, curves)
    # the oracle: each segment by np.linspace, then the same test of every sub-sampled voxel
    from topopose.frame.tips import inscribed_distances
    dt, lo = inscribed_distances(occ)
    pts = []
    for c in curves.values():
        if len(c) < 2:
            pts.append(c)
            continue
        for a, b in zip(c[:-1], c[1:]):
            k = max(int(np.ceil(np.linalg.norm(b - a) / vol.voxel_size)), 1)
            pts.append(a + np.linspace(0.0, 1.0, k, endpoint=False)[:, None] * (b - a))
        pts.append(c[-1:])
    S = np.vstack(pts)
    ijk = np.clip(np.rint((S - vol.origin) / vol.voxel_size).astype(int) - lo + 1, 0,
                  np.array(dt.shape) - 1)
    reach = 1.3 * dt[tuple(ijk.T)] * vol.voxel_size + vol.voxel_size
    X = vol.origin + np.argwhere(occ[::2, ::2, ::2]) * 2 * vol.voxel_size
    far = np.array([np.all(np.linalg.norm(S - x, axis=1) > reach) for x in X])
    np.testing.assert_array_equal(got, X[far])
    assert 0 < len(got) < len(X)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 6), tolerance=st.integers(0, 2),
       distorted=st.booleans(), reduced=st.booleans())
def test_hierarchical_carve_equals_every_voxel_tested_alone(seed, n, tolerance, distorted,
                                                            reduced):
    """The carver's labels (2: every camera, 1: all but ``tolerance`` at most) equal those of
    each voxel centre looked up in every full-size mask at the pixel the carver's own
    projection gives (``project_voxels``): bit for bit, blocks, crops and reduced masks
    included."""
    import cv2
    from _capture_testutils import capsule_masks, ring

    from topopose.capture.background import UpsampledMask
    from topopose.hull import HullCarver

    rng = np.random.default_rng(seed)
    tolerance = min(tolerance, n - 1)
    cams = ring(n=n, f=300, size=(120, 96),
                dist=(-0.2, 0.05, 0.001, -0.002, -0.01) if distorted else (0, 0, 0, 0))
    a, b = rng.uniform([-0.4, -0.3, 0.4], [0.4, 0.3, 1.4], (2, 3))
    full = capsule_masks(cams, a, b, rng.uniform(0.05, 0.3))
    masks = []
    for q, m in enumerate(full):
        m = m | (rng.random(m.shape) < 0.01)             # specks: edges everywhere
        if rng.random() < 0.3:
            m[rng.integers(0, 96):, :rng.integers(0, 120)] = False
        if reduced and q % 2:                            # a small mask, read upsampled
            f = (2, 4)[q % 4 // 2]
            small = np.ascontiguousarray(m[::f, ::f]).view(np.uint8)
            m = cv2.resize(small, (120, 96), interpolation=cv2.INTER_NEAREST).view(bool)
            m = m.view(UpsampledMask)
            m.small = small
        masks.append(m)
    origin, shape = np.array([-0.8, -0.7, 0.1]), tuple(rng.integers(8, 30, 3))
    carver = HullCarver(cams, origin, rng.uniform(0.03, 0.08), shape)
    got = carver.carve(masks, tolerance=tolerance, levels=True)
    pix = carver.project_voxels(np.indices(shape).reshape(3, -1).T)     # row · 120 + column
    seen = sum((p >= 0) & np.asarray(m, bool).ravel()[np.maximum(p, 0)]
               for p, m in zip(pix.T, masks))
    want = np.where(seen == n, 2, np.where(seen >= n - tolerance, 1, 0)).reshape(shape)
    np.testing.assert_array_equal(got, want)
