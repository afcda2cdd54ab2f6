"""The capture volume fitted across the sequence, and masks read at the resolution the grid
needs: a subject that jumps between the sampled frames is carved on a grid of its own (same
voxels, same lattice) and does not fail; the hull of reduced masks lies between the hulls of
the full masks eroded and dilated by the reduction (exact inclusions)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from topopose.capture import Capture
from topopose.capture.io import reduce_mask, reduce_masks
from topopose.frame import FrameEstimator
from topopose.hull import HullCarver, capture_box, visual_hull
from topopose.hull.hull import MaskResolution, _sample_frames, grid_for_box, mask_factors
from topopose.synth import synthetic_capture
from topopose.synth.geometry import ray_table, render

LIFT = 0.25      # metres


@pytest.fixture(scope="module")
def jumping():
    """100 frames of one standing body; one frame, missed by an even sampling of 8 or 32
    frames, lifted by LIFT."""
    base = synthetic_capture("human", frames=1, seed=4, cameras=6, size=(320, 240),
                             separated=True)
    body = base.options["bodies"][0]
    names = [str(i) for i in range(100)]
    jump = next(f for f in names[10:] if all(f not in _sample_frames(names, n) for n in (8, 32)))
    up = body.transformed(np.eye(3), [0.0, 0.0, LIFT])
    masks0 = base.masks[base.frames[0]]
    masks1 = [render(c, ray_table(c), up.prims) for c in base.cameras]
    for m in masks1:           # still inside every image: in the cameras' common view
        assert m.any() and not (m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any())
    cap = Capture(base.cameras, names, None, "+z", "m", 25.0, None, {},
                  {f: (masks1 if f == jump else masks0) for f in names})
    return cap, jump, body, up


def test_jump_above_the_fitted_volume_does_not_fail(jumping):
    cap, jump, body, up = jumping
    lo, hi = capture_box(cap, 0)
    assert up.parts["head"][2] > hi[2]        # the head is above the fitted volume
    fixed = visual_hull(cap, names_other(cap, jump), 64)
    vol = visual_hull(cap, jump, 64)
    d = vol.diagnostics
    assert d["grid"] == "beyond" and not d["touches_border"] and d["voxels"] > 0
    assert vol.voxel_size == fixed.voxel_size                 # the same voxels …
    step = (vol.origin - fixed.origin) / vol.voxel_size
    assert np.allclose(step, np.round(step), atol=1e-6)       # … on the same lattice
    top = vol.world(np.argwhere(vol.data))[:, 2].max()
    assert top > up.parts["head"][2]
    pose = FrameEstimator(cap, "human", 64).estimate(jump)
    assert pose.status != "failed", pose.error
    assert np.linalg.norm(pose.parts["head"] - up.parts["head"]) < 0.12


def names_other(cap, jump):
    return next(f for f in cap.frames if f != jump)


@pytest.mark.parametrize("factor", [2, 4])
@pytest.mark.parametrize("tolerance", [0, 1])
def test_reduced_masks_hull_between_eroded_and_dilated(factor, tolerance):
    cap = synthetic_capture("human", frames=1, seed=2, cameras=5, size=(320, 240), noise=2)
    masks = cap.masks[cap.frames[0]]
    origin, vs, shape = grid_for_box(*cap.volume, 72, margin=False)
    carver = HullCarver(cap.cameras, origin, vs, shape)
    k = np.ones((2 * factor - 1,) * 2, np.uint8)
    eroded = [cv2.erode(m.view(np.uint8), k).view(bool) for m in masks]
    dilated = [cv2.dilate(m.view(np.uint8), k).view(bool) for m in masks]
    reduced = reduce_masks(masks, [factor] * len(masks))
    assert all(r.small.shape == (240 // factor, 320 // factor) for r in reduced)
    h_r = carver.carve(reduced, tolerance).copy()
    h_e = carver.carve(eroded, tolerance).copy()
    h_d = carver.carve(dilated, tolerance).copy()
    h_f = carver.carve(masks, tolerance).copy()
    assert not (h_e & ~h_r).any() and not (h_r & ~h_d).any()
    assert not (h_e & ~h_f).any() and not (h_f & ~h_d).any()  # the full hull between them too
    # the reduced carve reads the small masks: the same hull as their full-size upsampling
    assert np.array_equal(h_r, carver.carve([np.asarray(r).view(bool).copy() for r in reduced],
                                            tolerance))
    assert reduce_mask(reduced[0], factor) is reduced[0]       # reducing again: a no-op


def test_mask_factors_keep_the_voxel_wide_enough():
    cap = synthetic_capture("human", frames=1, seed=2, cameras=4, size=(640, 480))
    for res in (MaskResolution(1.0), MaskResolution(2.0), MaskResolution(1.0, max_factor=2)):
        origin, vs, shape = grid_for_box(*cap.volume, 50, margin=False)
        centre = origin + (np.array(shape) - 1) / 2 * vs
        for cam, f in zip(cap.cameras, mask_factors(cap.cameras, origin, vs, shape, res)):
            assert 1 <= f <= res.max_factor and cam.size[0] % f == 0 and cam.size[1] % f == 0
            z = (cam.R @ centre + cam.translation)[2]
            span = min(cam.matrix[0, 0], cam.matrix[1, 1]) * vs / z
            assert f == 1 or span / f >= res.pixels_per_voxel
            assert f == res.max_factor or span / (f + 1) < res.pixels_per_voxel or \
                cam.size[0] % (f + 1) or cam.size[1] % (f + 1)
