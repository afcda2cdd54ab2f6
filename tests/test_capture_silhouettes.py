"""Silhouettes from colour images + backgrounds (background subtraction + morphological clean-up)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import clean_mask, extract_silhouette, load_capture
from topopose.hull import visual_hull


def iou(a, b):
    return np.logical_and(a, b).sum() / np.logical_or(a, b).sum()


def scene(mask, rng, noise=10.0):
    """A textured background and the same view with a shaded subject, Gaussian noise on both."""
    h, w = mask.shape
    yy, xx = np.mgrid[0:h, 0:w]
    base = np.stack([60 + 40 * xx / w, 70 + 30 * yy / h, 90 + 20 * np.sin(xx / 17.0)], axis=-1)
    texture = cv2.GaussianBlur(rng.normal(0, 12, (h, w, 3)), (0, 0), 3)
    bg = base + texture
    shade = 25 * np.sin(xx / 23.0 + yy / 31.0)[..., None]
    subject = np.array([150.0, 165.0, 205.0]) + shade
    img = np.where(mask[..., None], subject, bg)
    def noisy(x):
        return np.clip(x + rng.normal(0, noise, x.shape), 0, 255).astype(np.uint8)

    return noisy(img), noisy(bg)


@pytest.fixture(scope="module")
def setup():
    cams = ring(n=4, size=(320, 240), f=380)
    masks = capsule_masks(cams, (-0.2, 0.0, 0.5), (0.25, 0.1, 1.4), 0.12)
    arm = capsule_masks(cams, (0.1, 0.05, 1.2), (0.6, -0.2, 1.3), 0.04)
    return cams, [a | b for a, b in zip(masks, arm)]


@pytest.mark.parametrize("method", ["diff", "mog2", "knn"])
def test_extract_matches_true_masks_with_noise(setup, method):
    cams, masks = setup
    rng = np.random.default_rng(1)
    for m in masks:
        img, bg = scene(m, rng)
        raw = np.abs(img.astype(int) - bg.astype(int)).max(axis=2) > 30
        sil = extract_silhouette(img, bg, {"method": method, "threshold": 30})
        assert iou(sil, m) >= 0.95, (method, iou(sil, m))
        assert iou(sil, m) > iou(raw, m)      # the clean-up helps


def test_clean_mask_removes_specks_and_fills_holes():
    m = np.zeros((100, 100), bool)
    m[20:80, 30:70] = True
    m[45:50, 45:50] = False                  # a hole of 25 px
    m[5, 5] = m[90:93, 90:93] = True         # specks
    out = clean_mask(m, {"open": 0, "close": 0, "min_area": 20, "fill_holes": 30})
    want = np.zeros_like(m)
    want[20:80, 30:70] = True
    assert np.array_equal(out, want)
    out = clean_mask(m, {"open": 0, "close": 0, "min_area": 20, "fill_holes": 0})
    assert not out[47, 47]


def test_images_capture_gives_the_same_hull(tmp_path, setup):
    cams, masks = setup
    rng = np.random.default_rng(2)
    pairs = [scene(m, rng) for m in masks]
    root = write_capture(tmp_path / "img", cams, {}, images={"000000": [p[0] for p in pairs]},
                         backgrounds=[p[1] for p in pairs])
    cap = load_capture(root)
    assert cap.options["source"] == "images"
    sils = cap.silhouettes("000000")
    assert all(iou(s, m) >= 0.95 for s, m in zip(sils, masks))
    box = (-0.6, -0.5, 0.3), (0.8, 0.5, 1.6)
    v_img = visual_hull(cap, 0, resolution=48, volume=box).data
    v_true = visual_hull(cap, 0, resolution=48, volume=box, masks=masks).data
    assert iou(v_img, v_true) >= 0.9
