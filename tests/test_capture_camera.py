"""Camera projection: hand-computed pixels (pinhole, rotation, distortion) and OpenCV as oracle."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from topopose.capture import Camera
from topopose.hull import HullCarver

K = [[500.0, 0.0, 320.0], [0.0, 400.0, 240.0], [0.0, 0.0, 1.0]]


def test_pinhole_by_hand():
    cam = Camera("c", (640, 480), K, [0, 0, 0, 0], [0, 0, 0], [0, 0, 5])
    # camera coords (1, 0.5, 5): x/z = 0.2, y/z = 0.1 → (320 + 500·0.2, 240 + 400·0.1)
    assert np.allclose(cam.project([[1.0, 0.5, 0.0]]), [[420.0, 280.0]])
    # a quarter turn about z: R (1, 0.5, 0) = (-0.5, 1, 0)
    cam = Camera("c", (640, 480), K, [0, 0, 0, 0], [0, 0, np.pi / 2], [0, 0, 5])
    assert np.allclose(cam.project([[1.0, 0.5, 0.0]]), [[270.0, 320.0]])
    assert np.allclose(cam.center, [0, 0, -5])
    # behind the camera
    assert np.isnan(cam.project([[0.0, 0.0, -6.0]])).all()


def test_distortion_by_hand():
    cam = Camera("c", (640, 480), K, [0.1, 0.01, 0.001, 0.002], [0, 0, 0], [0, 0, 5])
    # a = 0.2, b = 0.1, r² = 0.05, radial = 1 + 0.1·0.05 + 0.01·0.0025 = 1.005025
    # a' = 0.2·radial + 2·p1·a·b + p2·(r² + 2a²) = 0.201005 + 0.00004 + 0.00026 = 0.201305
    # b' = 0.1·radial + p1·(r² + 2b²) + 2·p2·a·b = 0.1005025 + 0.00007 + 0.00008 = 0.1006525
    want = [[320 + 500 * 0.201305, 240 + 400 * 0.1006525]]
    assert np.allclose(cam.project([[1.0, 0.5, 0.0]]), want, atol=1e-9)
    # the carver's kernel: nearest pixel (421, 280) → flat index 280·640 + 421
    carver = HullCarver([cam], origin=[1.0, 0.5, 0.0], voxel_size=1.0, shape=(1, 1, 1))
    assert carver.project_voxels([[0, 0, 0]]).tolist() == [[280 * 640 + 421]]
    # out of the image → -1
    assert carver.project_voxels([[10, 0, 0]]).tolist() == [[-1]]


@pytest.mark.parametrize("fisheye", [False, True])
def test_against_opencv(fisheye):
    rng = np.random.default_rng(0)
    d = [0.05, -0.02, 0.01, -0.004] if fisheye else [-0.21, 0.07, 0.0012, -0.0007, -0.01]
    rvec, tvec = np.array([0.3, -1.1, 0.2]), np.array([0.2, -0.1, 4.0])
    cam = Camera("c", (640, 480), K, d, rvec, tvec, fisheye=fisheye)
    pts = rng.uniform(-1, 1, (500, 3))
    if fisheye:
        want = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), rvec, tvec, np.array(K),
                                         np.array(d))[0].reshape(-1, 2)
    else:
        want = cv2.projectPoints(pts, rvec, tvec, np.array(K), np.array(d))[0].reshape(-1, 2)
    assert np.allclose(cam.project(pts), want, atol=1e-6)
    carver = HullCarver([cam], origin=np.zeros(3), voxel_size=1.0, shape=(1, 1, 1))
    px = np.floor(want + 0.5).astype(int)
    inside = (px[:, 0] >= 0) & (px[:, 0] < 640) & (px[:, 1] >= 0) & (px[:, 1] < 480)
    edge = np.any(np.abs(want + 0.5 - np.round(want + 0.5)) < 1e-6, axis=1)
    got = carver.project_voxels(pts)[:, 0]
    expect = np.where(inside, px[:, 1] * 640 + px[:, 0], -1)
    assert inside.sum() > 100
    assert np.all((got == expect) | edge)
