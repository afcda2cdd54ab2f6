"""The consensus hull in one carve (thesis §2.3.2.2; ``visual_hull(..., consensus=r)``).

Oracles: (1) the two-call reference — the tolerant hull's largest component, a second strict
carve, scipy's binary dilation in the component's box, cc3d's largest component — frozen here
as it stood in ``pose/estimate.py`` before the one-pass path; (2) the carver's own tolerance
0 / 1 hulls for the labels; (3) scipy labelling and dilation on random label grids.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from _capture_testutils import capsule_masks, ring
from topopose.capture import Capture
from topopose.hull import HullCarver, visual_hull
from topopose.hull.components import consensus_hull_labels


def reference_consensus(cap, frame, resolution, repair=1, max_removed=0.2, masks=None):
    """The two-call consensus hull (frozen copy of the former ``pose.estimate.consensus_hull``)."""
    import cc3d

    vol = visual_hull(cap, frame, resolution=resolution, tolerance=1, masks=masks)
    strict = visual_hull(cap, frame, resolution=resolution, tolerance=0, keep_largest=False,
                         masks=masks)
    assert strict.data.shape == vol.data.shape and np.allclose(strict.origin, vol.origin)
    if not vol.data.any():
        return vol
    nz = np.argwhere(vol.data)
    box = tuple(slice(int(a), int(b) + 1) for a, b in zip(nz.min(0), nz.max(0)))
    near = strict.data[box]
    if repair > 0:
        near = ndimage.binary_dilation(np.pad(near, repair),
                                       ndimage.generate_binary_structure(3, 3),
                                       iterations=repair)[(slice(repair, -repair),) * 3]
    sub = vol.data[box] & near
    if sub.any():
        sub = cc3d.largest_k(sub, k=1, connectivity=26) > 0
    n_tol = int(np.count_nonzero(vol.data))
    removed = n_tol - int(np.count_nonzero(sub))
    if removed > max_removed * n_tol:
        vol.diagnostics["consensus_skipped"] = removed
        return vol
    a = np.zeros_like(vol.data)
    a[box] = sub
    vol.data = a
    vol.diagnostics["voxels"] = int(np.count_nonzero(a))
    vol.diagnostics["touches_border"] = bool(a[0].any() or a[-1].any() or a[:, 0].any()
                                             or a[:, -1].any() or a[:, :, 0].any()
                                             or a[:, :, -1].any())
    vol.diagnostics["consensus_removed"] = removed
    return vol


def _same(got, want):
    assert np.array_equal(got.data, want.data), int((got.data != want.data).sum())
    g, w = got.diagnostics, want.diagnostics
    for key in ("voxels", "touches_border", "components_dropped", "consensus_removed",
                "consensus_skipped"):
        assert g.get(key) == w.get(key), (key, g.get(key), w.get(key))


@pytest.fixture(scope="module")
def human():
    from topopose.synth import synthetic_capture

    return synthetic_capture(subject="human", frames=4, seed=3, noise=1, separated=True, cameras=8)


@pytest.mark.parametrize("resolution", [60, 100])
def test_one_pass_equals_two_call_reference(human, resolution):
    removed = 0
    for f in human.frames:
        got = visual_hull(human, f, resolution=resolution, tolerance=1, consensus=1)
        want = reference_consensus(human, f, resolution)
        _same(got, want)
        assert got.diagnostics["consensus"]["path"] == "one-pass"
        removed += got.diagnostics.get("consensus_removed", 0)
    assert removed > 0                        # the noise left phantom volume to remove


def test_repair_zero_equals_reference(human):
    f = human.frames[1]
    _same(visual_hull(human, f, resolution=70, tolerance=1, consensus=0),
          reference_consensus(human, f, 70, repair=0))


def test_empty_silhouette_skips_the_consensus(human):
    f = human.frames[0]
    masks = [np.asarray(m, bool).copy() for m in human.silhouettes(f)]
    masks[3][:] = False                       # one camera lost the subject: strict hull empty
    got = visual_hull(human, f, resolution=80, tolerance=1, consensus=1, masks=masks)
    want = reference_consensus(human, f, 80, masks=masks)
    _same(got, want)
    assert got.diagnostics["consensus_skipped"] == got.diagnostics["voxels"] > 1000
    assert got.diagnostics["consensus"]["strict_voxels"] == 0
    assert got.diagnostics["consensus"]["path"] == "labelled"


def test_three_comparable_bodies_take_the_labelled_path():
    """Three separate blobs of similar size: the largest consensus piece is not more than half
    the tolerant voxels, so the tolerant hull is labelled explicitly; same result as the
    reference."""
    cams = ring(n=8)
    m1 = capsule_masks(cams, (-0.45, 0.0, 0.9), (-0.45, 0.0, 1.3), 0.16)
    m2 = capsule_masks(cams, (0.45, 0.05, 0.7), (0.45, 0.05, 1.1), 0.16)
    m3 = capsule_masks(cams, (0.0, 0.4, 0.6), (0.0, 0.4, 0.9), 0.17)
    masks = [a | b | c for a, b, c in zip(m1, m2, m3)]
    masks[5] = ndimage.binary_erosion(masks[5], iterations=2)     # an eroded silhouette
    cap = Capture(cams, ["000000"], masks={"000000": masks}, volume=((-1, -0.6, 0.3), (1, 0.6, 1.6)))
    got = visual_hull(cap, 0, resolution=64, tolerance=1, consensus=1)
    want = reference_consensus(cap, 0, 64)
    _same(got, want)
    assert got.diagnostics["consensus"]["path"] == "labelled"
    assert len(got.diagnostics["components_dropped"]) >= 2


def test_levels_are_the_strict_and_tolerant_hulls(human):
    f = human.frames[2]
    vol = visual_hull(human, f, resolution=64)
    carver = HullCarver(human.cameras, vol.origin, vol.voxel_size, vol.data.shape)
    masks = human.silhouettes(f)
    t1 = carver.carve(masks, tolerance=1)
    n1 = int(carver.stats[5])
    t0 = carver.carve(masks, tolerance=0)
    lab = carver.carve(masks, tolerance=1, levels=True)
    assert lab.dtype == np.uint8 and set(np.unique(lab)) <= {0, 1, 2}
    assert np.array_equal(lab >= 1, t1) and np.array_equal(lab == 2, t0)
    assert n1 == int(carver.stats[5]) == int(t1.sum())
    assert (lab == 1).sum() > 0


def _oracle(lab, repair, max_removed):
    """Direct definition on a label grid, with scipy only."""
    s26 = np.ones((3, 3, 3), bool)
    tl, n = ndimage.label(lab >= 1, structure=s26)
    sizes = np.bincount(tl.ravel())[1:]
    T = tl == (np.argmax(sizes) + 1)
    dropped = sorted((int(x) for i, x in enumerate(sizes) if i != np.argmax(sizes)), reverse=True)
    near = lab == 2
    if repair:
        near = ndimage.binary_dilation(near, s26, iterations=repair)
    keep = T & near
    if keep.any():
        kl, _ = ndimage.label(keep, structure=s26)
        ks = np.bincount(kl.ravel())
        ks[0] = 0
        keep = kl == np.argmax(ks)
    removed = int(T.sum() - keep.sum())
    if removed > max_removed * T.sum():
        return T, dropped, True
    return keep, dropped, False


@pytest.mark.parametrize("seed", range(12))
def test_labels_against_scipy_oracle(seed):
    rng = np.random.default_rng(seed)
    shape = (18, 20, 16)
    # smooth blobs: a tolerant region, a strict core with holes, scattered extra bits
    f = ndimage.gaussian_filter(rng.random(shape), 1.5)
    tol = f > np.quantile(f, 0.55 + 0.03 * (seed % 4))
    strict = tol & (ndimage.gaussian_filter(rng.random(shape), 1.0) > 0.47 + 0.01 * (seed % 5))
    if seed == 3:
        strict[:] = False
    lab = tol.astype(np.uint8) + strict.astype(np.uint8)
    nz = np.argwhere(lab)
    repair = seed % 3
    max_removed = (0.6, 0.2, 0.02)[(seed // 3) % 3]
    want, wdrop, wskip = _oracle(lab, repair, max_removed)
    got = lab.copy()
    dropped, nvox, lo, hi, diag = consensus_hull_labels(got, nz.min(0), nz.max(0), repair,
                                                        max_removed)
    assert set(np.unique(got)) <= {0, 1}
    assert np.array_equal(got.view(bool), want), (diag, int((got.view(bool) != want).sum()))
    assert dropped == wdrop and nvox == int(want.sum())
    assert ("consensus_skipped" in diag) == wskip
    wz = np.argwhere(want)
    assert np.array_equal(lo, wz.min(0)) and np.array_equal(hi, wz.max(0))


def test_refocused_grid_and_arguments(human):
    """On a refocused grid both hulls still come from the same carve (the two-call reference
    could not compare grids fitted with different tolerances); bad arguments are named."""
    from topopose.errors import InputError

    f = human.frames[0]
    cons = visual_hull(human, f, resolution=80, tolerance=1, consensus=1, refocus=True)
    tol = visual_hull(human, f, resolution=80, tolerance=1, refocus=True)
    assert cons.data.shape == tol.data.shape and not (cons.data & ~tol.data).any()
    d = cons.diagnostics
    assert d["voxels"] == int(cons.data.sum()) == int(tol.data.sum()) - d["consensus_removed"]
    assert d["consensus"]["strict_voxels"] < d["consensus"]["tolerant_voxels"]
    assert "consensus" not in visual_hull(human, f, resolution=40, consensus=1).diagnostics
    for bad in (-1, True, 1.5):
        with pytest.raises(InputError, match="consensus"):
            visual_hull(human, f, resolution=40, tolerance=1, consensus=bad)
    with pytest.raises(InputError, match="max_removed"):
        visual_hull(human, f, resolution=40, tolerance=1, consensus=1, max_removed=2)
