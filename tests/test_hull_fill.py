"""Cavity filling (``topopose.hull.fill_cavities``) against scipy's ``binary_fill_holes``
(background 6-connectivity, its default structure) as the oracle."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from topopose.errors import InputError
from topopose.hull import fill_cavities


def _random_volume(seed, shape=(22, 19, 25)):
    rng = np.random.default_rng(seed)
    f = ndimage.gaussian_filter(rng.random(shape), 1.0 + 0.3 * (seed % 3))
    occ = f > np.quantile(f, 0.35 + 0.05 * (seed % 5))
    # a few closed shells with something inside, one touching a side of the grid
    occ[3:10, 4:11, 5:12] = True
    occ[5:8, 6:9, 7:10] = False
    occ[6, 7, 8] = seed % 2 == 0
    occ[0:5, 10:16, 14:20] = True
    occ[1:4, 11:15, 15:19] = False        # open on no side: face i = 0 is object
    return np.ascontiguousarray(occ)


@pytest.mark.parametrize("seed", range(16))
@pytest.mark.parametrize("given_box", [False, True])
def test_equals_binary_fill_holes(seed, given_box):
    occ = _random_volume(seed)
    want = ndimage.binary_fill_holes(occ)
    got = occ.copy()
    box = None
    if given_box:
        nz = np.argwhere(occ)
        box = (nz.min(0).tolist(), nz.max(0).tolist())
    n, filled = fill_cavities(got, box)
    assert got.dtype == bool and set(np.unique(got.view(np.uint8))) <= {0, 1}
    assert np.array_equal(got, want), int((got != want).sum())
    assert filled == int(want.sum() - occ.sum())
    lab, m = ndimage.label(want & ~occ)       # cavities are 6-components of the filled voxels
    assert n == m


def test_hull_cavities_and_loose_box():
    occ = np.zeros((30, 30, 30), bool)
    occ[5:25, 5:25, 5:25] = True
    occ[10:15, 10:15, 10:15] = False          # one cavity
    occ[18:20, 18:20, 18:20] = False          # another
    occ[12, 20:25, 12] = False                # a tunnel to the outside: not a cavity
    occ[12, 19, 12] = False
    want = ndimage.binary_fill_holes(occ)
    got = occ.copy()
    assert fill_cavities(got, ([2, 2, 2], [27, 27, 27])) == (2, 125 + 8)
    assert np.array_equal(got, want)
    empty = np.zeros((4, 4, 4), bool)
    assert fill_cavities(empty) == (0, 0)
    with pytest.raises(InputError, match="occ"):
        fill_cavities(np.zeros((4, 4), bool))


def test_noisy_hulls_with_their_bbox():
    """Visual hulls of noisy synthetic frames, filled on the hull's own bounding box
    (``diagnostics["bbox"]``, as the pose pipeline does)."""
    from topopose.synth import synthetic_capture
    from topopose.hull import visual_hull
    from topopose.frame.placement import fill_cavities as fill_volume

    cap = synthetic_capture(subject="human", frames=3, seed=5, noise=2, separated=True, cameras=8)
    filled = 0
    for f in cap.frames:
        for kw in ({"tolerance": 0}, {"tolerance": 1, "consensus": 1}):
            vol = visual_hull(cap, f, resolution=90, **kw)
            nz = np.argwhere(vol.data)
            assert vol.diagnostics["bbox"] == (nz.min(0).tolist(), nz.max(0).tolist())
            want = ndimage.binary_fill_holes(vol.data)
            fill_volume(vol)
            assert np.array_equal(vol.data, want)
            filled += vol.diagnostics.get("cavities_filled", 0)
    assert filled > 0, "noise 2 should leave some cavity to fill"
