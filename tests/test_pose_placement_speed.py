"""The per-frame shortcuts of FrameEstimator's placement (one skeleton voxel list, one distance
transform, bounding boxes) give exactly what the straightforward computations give.

Oracles: brute force on small random volumes (np.argwhere on the whole grid, ball_radius's
growing-cube search, the EDT on the projections' box), and the estimator's poses against the
reference path (every shortcut switched off by calling the plain functions) on synthetic
capsule and body frames."""
from dataclasses import replace

import numpy as np
import pytest

from topopose.frame.tips import (hull_box, inscribed_distances, skeleton_voxels,
                                 squared_distances)
from topopose.skeleton.prune import ball_radius, prune_bumps


class _Vol:
    def __init__(self, data, bbox=None):
        self.data, self.origin, self.voxel_size = data, (0.0, 0.0, 0.0), 1.0
        self.diagnostics = {"bbox": bbox} if bbox else {}


def _blob(seed, shape=(18, 20, 16), touch=False):
    rng = np.random.default_rng(seed)
    v = np.zeros(shape, bool)
    for _ in range(6):
        c = rng.integers(3, np.array(shape) - 3)
        r = rng.uniform(1.5, 4.0)
        z, y, x = np.indices(shape)
        v |= (z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2 <= r * r
    if touch:
        v[0, 5:9, 5:9] = True
    return v


@pytest.mark.parametrize("seed,touch", [(0, False), (1, True), (2, False), (3, True)])
def test_box_shortcuts_equal_brute_force(seed, touch):
    v = _blob(seed, touch=touch)
    nz = np.argwhere(v)
    tight = ([int(a) for a in nz.min(0)], [int(a) for a in nz.max(0)])
    loose = ([max(a - 2, 0) for a in tight[0]], [min(b + 1, n - 1) for b, n in zip(tight[1], v.shape)])
    for bbox in (None, tight, loose):
        box = hull_box(_Vol(v, bbox))
        assert np.array_equal(skeleton_voxels(v, box), np.argwhere(v))
        sq, lo = squared_distances(v, box)
        dt, lo2 = inscribed_distances(v, box)
        assert np.array_equal(lo, lo2) and np.array_equal(dt, np.sqrt(sq))
        # every voxel's radius equals ball_radius's exact search (grid outside = background)
        for x in nz[:: max(1, len(nz) // 60)]:
            assert float(np.sqrt(float(sq[tuple(x - lo + 1)]))) == ball_radius(v, x)
        ref, _ = inscribed_distances(v)                  # box from the axis projections
        assert dt.max() == ref.max()


def test_prune_with_distances_equals_search():
    from topopose.topology import thin

    z, y, x = np.indices((44, 40, 40))
    v = (z - 20) ** 2 + (y - 20) ** 2 + (x - 20) ** 2 <= 64                 # trunk
    v |= ((y - 20) ** 2 + (x - 20) ** 2 <= 6) & (z >= 20) & (z <= 41)        # neck and head
    v |= ((z - 20) ** 2 + (y - 20) ** 2 <= 6) & (x <= 20) & (x >= 2)         # arm
    v |= ((z - 14) ** 2 + (y - 20) ** 2 <= 6) & (x <= 20) & (x >= 2)         # second arm
    v |= (z - 20) ** 2 + (y - 28) ** 2 + (x - 20) ** 2 <= 6                 # bump
    skel = thin(v)
    a = prune_bumps(skel, v, 1.5)
    b = prune_bumps(skel, v, 1.5, squared=squared_distances(v))
    assert a[2], "nothing pruned: the check below would be empty"
    assert np.array_equal(a[0], b[0]) and a[2] == b[2]


def _plain(est, frame, monkeypatch):
    """The estimator's pose through the plain functions: every shared voxel list, box and
    distance transform switched off."""
    from topopose.frame import confidence
    from topopose.frame import tips
    from topopose.skeleton import prune

    with monkeypatch.context() as m:
        m.setattr(tips, "skeleton_voxels", lambda s, box=None: np.argwhere(s))
        m.setattr(tips, "hull_box", lambda vol: None)
        sqd = tips.squared_distances
        m.setattr(tips, "squared_distances", lambda volume, box=None: sqd(volume))
        pb = prune.prune_bumps
        m.setattr(prune, "prune_bumps", lambda *a, squared=None, **k: pb(*a, **k))
        jf = confidence.judge_frame
        m.setattr(confidence, "judge_frame",
                  lambda *a, aligned=None, **k: jf(*a, aligned=replace(aligned, radius_map=None),
                                                   **k))
        return est.estimate(frame)


def _same(a, b):
    if isinstance(a, dict):
        return set(a) == set(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and not (a and isinstance(a[0], (int, float))):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if a is None or b is None or isinstance(a, str):
        return a == b
    return np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=0, atol=1e-9)


@pytest.mark.parametrize("subject,seed", [("human", 0), ("body", 41)])
def test_estimator_equals_plain_path(subject, seed, monkeypatch):
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator

    cap = synthetic_capture(subject=subject, frames=2, seed=seed, noise=1, separated=True)
    est = FrameEstimator(cap, "human", 60, threshold=2.0)
    for f in cap.frames:
        p, q = est.estimate(f), _plain(est, f, monkeypatch)
        assert p.status == q.status and p.error == q.error and p.distance == q.distance
        assert _same(p.parts, q.parts)
        assert _same(p.diagnostics, q.diagnostics)
        assert "placement" in p.timings_ms and p.timings_ms["placement"] <= p.timings_ms["total"]
