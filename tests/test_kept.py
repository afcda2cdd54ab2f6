"""What the run's frame loop keeps of each frame for the tracking stage (topopose.sequence.kept).

Oracles: OpenCV's resize of the whole mask (the resize around the silhouette's box gives the
same pixels), the grid itself (packing loses no voxel), the tracking stage on the hulls carved
again (the same poses), and the number of times the capture's masks are read.
"""
from collections import Counter

import cv2
import numpy as np
import pytest

from topopose.capture import Capture
from topopose.geometry.camera import Camera
from topopose.geometry.masks import boxed
from topopose.hull.volume import Volume
from topopose.sequence.kept import CroppedViews, KeptFrame, PackedVolume
from topopose.sequence.silhouette import scaled_views


def _camera(w, h):
    K = [[0.9 * w, 0, w / 2], [0, 0.9 * w, h / 2], [0, 0, 1]]
    return Camera("c", (w, h), K, [0.0, 0.0, 0.0, 0.0], [0.1, -0.2, 0.05], [0.0, 0.0, 3.0])


def _blob(rng, w, h):
    """A random silhouette: a few filled ellipses (some crossing the image's border) and
    stray pixels."""
    m = np.zeros((h, w), np.uint8)
    for _ in range(rng.integers(1, 4)):
        c = (int(rng.integers(-w // 8, w + w // 8)), int(rng.integers(-h // 8, h + h // 8)))
        ax = (int(rng.integers(1, w // 3)), int(rng.integers(1, h // 3)))
        cv2.ellipse(m, c, ax, float(rng.uniform(0, 180)), 0, 360, 1, -1)
    m[rng.integers(0, h, 5), rng.integers(0, w, 5)] = 1
    return m.astype(bool)


@pytest.mark.parametrize("size", [(1624, 1224), (1920, 1080), (641, 479), (333, 250),
                                  (300, 200)])
def test_cropped_views_are_the_scaled_views(size):
    """Every pixel and camera as :func:`scaled_views` gives them (OpenCV resizing the whole
    mask): non-integer reductions, an integer one (1920 → 320), none (300 wide)."""
    rng = np.random.default_rng(size[0])
    w, h = size
    masks = [_blob(rng, w, h) for _ in range(12)] + [np.zeros((h, w), bool),
                                                     np.ones((h, w), bool)]
    cams = [_camera(w, h)] * len(masks)
    for given in (masks, [boxed(m) for m in masks]):
        want_c, want_m = scaled_views(cams, given)
        kept = CroppedViews.scaled(cams, given)
        got_c, got_m = kept.views()
        for a, b in zip(want_m, got_m):
            assert a.shape == b.shape and np.array_equal(a, b)
        for a, b in zip(want_c, got_c):
            assert a.size == b.size and np.array_equal(a.matrix, b.matrix)
        assert kept.nbytes <= sum(m.size for m in want_m)


def test_packed_volume_gives_the_grid_back():
    rng = np.random.default_rng(0)
    for k in range(6):
        data = np.zeros((20, 17, 31), bool)
        if k:
            lo = rng.integers(0, 10, 3)
            hi = lo + rng.integers(1, 8, 3)
            data[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = rng.random(hi - lo) < 0.6
        vol = Volume(data, (0.1, -0.2, 0.3), 0.02, {"voxels": int(data.sum())})
        back = PackedVolume.pack(vol).volume()
        assert np.array_equal(back.data, vol.data) and back.data.shape == vol.data.shape
        assert np.array_equal(back.origin, vol.origin) and back.voxel_size == vol.voxel_size
        assert back.diagnostics == vol.diagnostics
        assert PackedVolume.pack(vol).nbytes <= max(1, data.sum() // 8 + 8 * 8 * 8)


class CountingMasks(dict):
    """A capture's masks by frame, counting each frame's reads."""

    def __init__(self, *args):
        super().__init__(*args)
        self.reads = Counter()

    def __getitem__(self, frame):
        self.reads[frame] += 1
        return super().__getitem__(frame)


@pytest.fixture(scope="module")
def walk():
    from topopose.synth.capture import synthetic_capture

    return synthetic_capture("body", frames=10, seed=2, cameras=5, size=(320, 240),
                             motion="walk")


def _counting(cap):
    return Capture(cap.cameras, cap.frames, None, cap.up, cap.units, cap.fps, cap.volume, {},
                   CountingMasks(cap.masks))


def _fields(poses):
    out = []
    for p in poses:
        d = p.to_dict()
        d.pop("timings_ms", None)
        out.append(d)
    return out


def test_the_tracker_reads_no_mask_again(walk):
    """A run reads each frame's masks as often with the tracker as without it: the tracker
    reads the hulls and silhouettes the frame loop kept."""
    from topopose.batch.run import run
    from topopose.sequence.follow import FollowOptions

    counts = []
    for follow in (FollowOptions(enabled=False), None):
        cap = _counting(walk)
        res = run(cap, resolution=48, progress=False, follow=follow)
        counts.append(dict(cap.masks.reads))
    assert any(p.status == "tracked" for p in res.poses)         # the tracker ran
    assert counts[1] == counts[0]
    assert set(counts[1]) == set(walk.frames)


@pytest.mark.parametrize("support", [True, False])
def test_kept_frames_track_as_the_carved_again(walk, support):
    """The tracking stage on the kept frames gives the poses it gives on hulls carved again
    from the masks (with the estimator's silhouettes, and with the capture's when the
    estimator keeps none)."""
    from topopose.batch.run import KeepingEstimator
    from topopose.frame.options import EstimatorOptions
    from topopose.pose.model import load_model
    from topopose.sequence.follow import follow_run
    from topopose.sequence.motion import process_sequence
    from topopose.sequence.options import SequenceOptions

    model = load_model("human")
    eo = EstimatorOptions().with_(support=support, centre=support)
    cap = _counting(walk)
    est = KeepingEstimator(cap, model, 48, None, eo)
    poses = [est.estimate(f) for f in cap.frames]
    assert set(est.kept) == set(cap.frames)
    assert all(isinstance(k, KeptFrame) for k in est.kept.values())
    motion = process_sequence(poses, model, cap.up_vector, SequenceOptions(), fps=cap.fps)
    before = dict(cap.masks.reads)
    kept = follow_run(motion.poses, motion, model, cap, 48, None, eo, kept=est.kept)
    assert dict(cap.masks.reads) == before
    again = follow_run(motion.poses, motion, model, cap, 48, None, eo)
    assert sum(cap.masks.reads.values()) > sum(before.values())     # carved again
    assert any(p.status == "tracked" for p in kept)
    assert _fields(kept) == _fields(again)


def test_frame_data_of_the_kept_frame_is_the_volumes():
    """The fit's data from the packed hull and the cropped silhouettes: every surface point,
    sampled point and ray as from the whole grid and images (the same random draws), also
    for hulls touching the grid's sides and an empty one; the silhouette IoU counted on the
    crops is the whole images'."""
    from topopose.sequence.silhouette import silhouette_iou
    from topopose.sequence.tracker import frame_data

    from test_tracker import NAMES, hull_of, make_body, pose, rest_directions

    rng = np.random.default_rng(4)
    w, h = 641, 479
    cams = [_camera(w, h)] * 3
    body = make_body()
    P = pose(rest_directions())
    grids = [hull_of(body, P), hull_of(body, P, lo=(-0.3, -0.5, 0.3), hi=(0.4, 0.5, 1.6))]
    grids.append(Volume(np.zeros((10, 10, 10), bool), np.zeros(3), 0.02))
    for vol in grids:
        masks = [_blob(rng, w, h) for _ in cams]
        views = scaled_views(cams, masks)
        kept = KeptFrame.keep(vol, (cams, masks))
        a = frame_data(vol, 300, np.random.default_rng(1), views, 40)
        b = frame_data(kept.hull, 300, np.random.default_rng(1),
                       (kept.views.cameras, kept.views.crops), 40)
        for x, y in ((a.points, b.points), (a.surface, b.surface), (a.occupancy, b.occupancy),
                     (a.lo, b.lo), (a.rays[0], b.rays[0]), (a.rays[1], b.rays[1])):
            assert x.shape == y.shape and np.array_equal(x, y)
        assert (a.kd is None) == (b.kd is None) == (not vol.data.any())
        got = silhouette_iou(body, P, kept.views.cameras, kept.views.crops, kept.views.shapes)
        want = silhouette_iou(body, P, *views)
        assert np.array_equal(got, want, equal_nan=True) and np.isfinite(want).any()
    assert len(NAMES) == len(P)


def test_surface_voxels_are_the_erosions():
    """The surface by slicing against :func:`scipy.ndimage.binary_erosion` (the array's sides
    outside the object), on random grids and thin ones."""
    from scipy import ndimage

    from topopose.sequence.tracker import _eroded

    rng = np.random.default_rng(2)
    for shape in ((1, 1, 1), (1, 6, 3), (2, 2, 2), (7, 9, 4), (16, 11, 13), (0, 3, 3)):
        for p in (0.5, 0.9, 1.0):
            occ = rng.random(shape) < p
            assert np.array_equal(_eroded(occ), ndimage.binary_erosion(occ))
