"""The per-frame estimator's compiled kernels against plain NumPy oracles, and the in-memory
capture keeping a decoded silhouette's bounding box."""
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
