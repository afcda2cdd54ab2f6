"""The hull's own silhouette IoU of ``benchmarks/_tracker.py`` (:func:`hull_silhouette_iou`,
child_rope's reference for the body's IoU). Oracle: a box of voxels seen straight down by a
pinhole camera, whose silhouette is a rectangle computed by hand."""
import numpy as np

import _tracker
from topopose.geometry.camera import Camera
from topopose.hull.volume import Volume
from topopose.sequence.kept import CroppedViews

F, SIZE, HEIGHT = 400.0, (200, 160), 2.0       # focal (px), image (w, h), camera height (m)


def _scene():
    """A 0.4 × 0.2 × 0.1 m box of 1 cm voxels on the floor under a camera looking down."""
    data = np.ones((40, 20, 10), bool)
    vol = Volume(data, origin=np.array([-0.195, -0.095, 0.005]), voxel_size=0.01)
    K = np.array([[F, 0, SIZE[0] / 2], [0, F, SIZE[1] / 2], [0, 0, 1.0]])
    # camera axes: x → world x, y → world −y, z (viewing) → world −z; centre at HEIGHT
    cam = Camera("down", SIZE, K, np.zeros(4), np.array([np.pi, 0.0, 0.0]),
                 np.array([0.0, 0.0, HEIGHT]))
    return vol, cam


def _rectangle(cam, half_x, half_y, z):
    """The silhouette of the box's top face (its widest outline from above) by hand."""
    m = np.zeros((SIZE[1], SIZE[0]), bool)
    s = F / (HEIGHT - z)
    u0, u1 = SIZE[0] / 2 - half_x * s, SIZE[0] / 2 + half_x * s
    v0, v1 = SIZE[1] / 2 - half_y * s, SIZE[1] / 2 + half_y * s
    rows = slice(int(np.ceil(v0 - 0.5)), int(np.floor(v1 + 0.5)))
    cols = slice(int(np.ceil(u0 - 0.5)), int(np.floor(u1 + 0.5)))
    m[rows, cols] = True
    return m


def test_the_hull_of_a_box_covers_its_own_silhouette():
    vol, cam = _scene()
    assert np.allclose(cam.project(np.array([[0.0, 0.0, 0.0]])), [[SIZE[0] / 2, SIZE[1] / 2]])
    mask = _rectangle(cam, 0.2, 0.1, 0.1)
    iou = _tracker.hull_silhouette_iou(vol, CroppedViews.scaled([cam], [mask]))
    assert iou[0] > 0.95
    # half the mask: the hull covers twice what it explains
    half = mask.copy()
    half[:, SIZE[0] // 2:] = False
    iou = _tracker.hull_silhouette_iou(vol, CroppedViews.scaled([cam], [half]))
    assert abs(iou[0] - 0.5) < 0.03
