"""Silhouettes without an empty scene, the soft hull (Franco & Boyer) and what the hull lost."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from topopose.capture import Camera
from topopose.capture.background import (foreground_probability, learn_backgrounds,
                                         scaled_camera)
from topopose.capture.calibration import read_calibration
from topopose.capture.options import SILHOUETTE_DEFAULTS
from topopose.hull.soft import posterior, soft_carve, voxel_pixels

DATA = Path(__file__).parent / "data" / "pose2sim_small"


def _recording():
    import shutil
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        text = (DATA / "Calib.toml").read_text().replace("cam_0", "cam0")
        (Path(tmp) / "calibration.toml").write_text(text)
        cams = read_calibration(Path(tmp) / "calibration.toml")
    kp = json.loads((DATA / "keypoints.json").read_text())
    n = len(kp["index"])
    stacks = [np.stack([cv2.imread(str(DATA / f"{c.name}_{k:02d}.jpg")) for k in range(n)])
              for c in cams]
    return cams, stacks, kp


def test_sequence_background_finds_the_subject():
    """No empty scene: the background learned from 12 frames gives masks (p > ½) that hold the
    subject's OpenPose keypoints (a reference made independently, used only to check) while
    covering a small part of the image."""
    cams, stacks, kp = _recording()
    scale = stacks[0].shape[2] / cams[0].size[0]
    small = [scaled_camera(c, scale) for c in cams]
    p = dict(SILHOUETTE_DEFAULTS, method="sequence")
    models, region = learn_backgrounds(stacks, small, p, 1.0)
    assert region is not None
    inside, total, areas = 0, 0, []
    for c, (cam, bg) in enumerate(zip(cams, models)):
        for k in range(stacks[c].shape[0]):
            q = foreground_probability(stacks[c][k], bg, p)
            m = cv2.dilate((q > 127).astype(np.uint8), np.ones((5, 5), np.uint8))
            areas.append(m.mean())
            for x, y, s in kp["keypoints"][cam.name][k]:
                if s < 0.5:
                    continue
                u, v = int(round(x * scale)), int(round(y * scale))
                if 0 <= u < m.shape[1] and 0 <= v < m.shape[0]:
                    total += 1
                    inside += int(m[v, u])
    assert total > 300
    assert inside / total >= 0.75, (inside, total)
    assert float(np.median(areas)) < 0.2


def _cams(k=1):
    out = []
    for q, (cx, cy) in enumerate([(3, 0), (0, 3), (-3, 0.5)]):
        c = np.array([cx, cy, 1.0])
        z = -c / np.linalg.norm(c)
        x = np.cross(z, [0, 0, 1.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        R = np.stack([x, y, z])
        out.append(Camera(f"c{q}", (24 * k, 20 * k), [[30 * k, 0, 12 * k], [0, 30 * k, 10 * k],
                                                       [0, 0, 1]], [0, 0, 0, 0],
                          cv2.Rodrigues(R)[0].ravel(), -R @ c))
    return out


def test_voxel_pixels_match_camera_project():
    """The soft hull's projection table (one kernel pass) against ``Camera.project`` of every
    voxel centre (NumPy), for pinhole, radial-tangential and fisheye cameras: equal except at
    exact half-pixel edges (rounding); voxels behind a camera are -1."""
    from _capture_testutils import ring

    cams = (ring(n=2, size=(64, 48), f=60) + ring(n=2, size=(64, 48), f=60,
                                                  dist=(-0.2, 0.05, 0.002, -0.001, 0.01))
            + ring(n=2, size=(64, 48), f=60, fisheye=True, dist=(0.1, -0.05, 0.01, 0.0)))
    origin, vs, shape = np.array([-3.5, -3.2, -0.5]), 0.1, (70, 64, 30)   # cameras inside
    pix = voxel_pixels(cams, origin, vs, shape)
    ijk = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1).reshape(-1, 3)
    X = origin + vs * ijk
    for c, cam in enumerate(cams):
        uv = cam.project(X)
        front = cam.to_camera(X)[:, 2] > 0
        px = np.floor(uv + 0.5)
        w, h = cam.size
        ok = front & (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        want = np.where(ok, px[:, 1] * w + px[:, 0], -1)
        edge = np.any(np.abs(uv + 0.5 - np.round(uv + 0.5)) < 1e-7, axis=1)
        assert ok.sum() > 1000 and (~front).sum() > 1000
        assert np.all((pix[:, c] == want) | edge)
        assert np.all(pix[~front, c] == -1)


def test_soft_fusion_matches_the_posterior_oracle():
    """Every voxel of a tiny grid against the formula evaluated by hand (brute force)."""
    rng = np.random.default_rng(3)
    cams = _cams()
    maps = [rng.integers(0, 256, size=(c.size[1], c.size[0]), dtype=np.uint8) for c in cams]
    origin, vs, shape = np.array([-0.5, -0.5, -0.5]), 0.2, (6, 6, 6)
    pix = voxel_pixels(cams, origin, vs, shape)
    for pd_, pf, occ_t in ((0.9, 0.4, 0.5), (0.8, 0.1, 0.7)):
        occ, n = soft_carve(pix, maps, shape, pd_, pf, occ_t)
        want = np.zeros(shape, bool)
        for i, j, k in np.ndindex(*shape):
            X = origin + vs * np.array([i, j, k])
            qs = []
            for c, m in zip(cams, maps):
                u, v = c.project([X])[0]
                u, v = int(np.floor(u + 0.5)), int(np.floor(v + 0.5))
                inside = 0 <= u < c.size[0] and 0 <= v < c.size[1]
                qs.append(m[v, u] / 255.0 if inside else 0.0)
            want[i, j, k] = posterior(qs, pd_, pf) > occ_t
        assert n == want.sum() and np.array_equal(occ.astype(bool), want)
    # hand-computed: two sure cameras and one sure it is background
    # P(occ) = .9·.9·.1 / (.9·.9·.1 + .4·.4·.6) = .081 / .177
    assert posterior([1, 1, 0], 0.9, 0.4) == pytest.approx(0.081 / 0.177)
    # an uncertain camera (q = ½) does not vote
    assert posterior([1, 1, 0.5], 0.9, 0.4) == pytest.approx(posterior([1, 1], 0.9, 0.4))


def test_two_piece_hull_is_flagged():
    """A hull in two comparable pieces: the diagnostics give the dropped piece's size and
    share, and a frame whose largest piece holds < 80 % is rejected, with the reason."""
    import topopose as tp
    from topopose.capture.capture import Capture
    from topopose.frame.estimate import FrameEstimator

    cams = _cams(4)
    big = [np.zeros((c.size[1], c.size[0]), bool) for c in cams]
    # two balls: project two world spheres into every camera
    for c, m in zip(cams, big):
        for ctr, r in (((0.0, -0.3, 0.0), 0.15), ((0.0, 0.3, 0.0), 0.13)):
            uv = c.project([ctr])[0]
            d = np.linalg.norm(c.to_camera([ctr])[0])
            cv2.circle(m.view(np.uint8), (int(round(uv[0])), int(round(uv[1]))),
                       int(round(120 * r / d)), 1, -1)
    cap = Capture(cameras=cams, frames=["0"], masks={"0": big},
                  volume=((-0.6, -0.6, -0.6), (0.6, 0.6, 0.6)))
    vol = tp.visual_hull(cap, "0", resolution=40)
    d = vol.diagnostics
    assert len(d["components_dropped"]) >= 1
    total = d["voxels"] + sum(d["components_dropped"])
    assert d["largest_share"] == pytest.approx(d["voxels"] / total, abs=1e-4)
    assert d["components_share"][0] == pytest.approx(d["components_dropped"][0] / total, abs=1e-4)
    assert d["largest_share"] < 0.8
    est = FrameEstimator(cap, "human", 40, threshold=100.0, max_missing=10, gate=False)
    pose = est.estimate("0")
    assert pose.status == "rejected" and "hull split" in pose.error, (pose.status, pose.error)
    assert pose.diagnostics["largest_share"] < 0.8


def test_colour_probability_kernel_matches_the_formula():
    """The kernel against the brightness / chromaticity distortion written out in numpy."""
    from topopose.capture.background import SequenceBackground

    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (9, 7, 3), dtype=np.uint8)
    bgi = rng.integers(0, 256, (9, 7, 3), dtype=np.uint8)
    bgi[0] = img[0]                                   # identical: background
    img[1] = (bgi[1] * 0.8).astype(np.uint8)                 # shadow
    known = rng.random((9, 7)) > 0.3
    p = dict(SILHOUETTE_DEFAULTS, method="sequence", median=0)
    q = foreground_probability(img, SequenceBackground(bgi, known, None, None), p)
    I, B = img.astype(float), bgi.astype(float) + 1
    a = (I * B).sum(2) / (B * B).sum(2)
    cd = np.linalg.norm(I - a[..., None] * B, axis=2)
    nb = np.linalg.norm(B, axis=2)
    bd = np.where(a > 1, (a - 1) * nb, np.where(a >= p["shadow"], 0, (p["shadow"] - a) * nb))
    d = np.hypot(cd, bd)
    pr = 1 / (1 + np.exp(-np.clip((d - p["threshold"]) / (p["threshold"] / 4), -30, 30)))
    pr = np.where(known, pr, 0.5 + (pr - 0.5) * p["uncertain"])
    assert np.abs(q.astype(int) - np.floor(pr * 255 + 0.5)).max() <= 1
    assert q[0][known[0]].max() < 30 and q[1][known[1]].max() < 60


def test_confidence_factors_and_time_only_on_coherent_sequences():
    """Hand-computed factors; the time factor applies to a coherent sequence and not to
    independent poses, and gates 'matched'."""
    from topopose.frame.confidence import frame_confidence, temporal_confidence
    from topopose.pose.pose import Pose

    c = frame_confidence(0.4, 0.4, 0.9, 1, 0.8, fatness=0.05)
    assert c["alignment"] == pytest.approx(0.5) and c["placement"] == 0.5
    assert c["hull"] == pytest.approx(2 / 3, abs=1e-4) and c["fat"] == pytest.approx(0.5)
    assert c["confidence"] == pytest.approx(0.5 * (2 / 3) * 0.5 * 0.5, abs=1e-4)
    assert frame_confidence(None, 0.4, 1.0, 0)["confidence"] == 0.0

    def poses(step, jump_at=None):
        out = []
        for i in range(10):
            x = i * step + (1.0 if i == jump_at else 0.0)
            parts = {"head": np.array([x, 0, 1.7]), "hand_1": np.array([x, -0.5, 1.0]),
                     "hand_2": np.array([x, 0.5, 1.0])}
            out.append(Pose(f"{i:02d}", "matched", 0.1, parts, None, {},
                            {"confidence": 0.9, "confidence_factors": {}, "height": 1.7,
                             "hull_voxels": 1000}))
        return out

    ps = poses(0.01, jump_at=5)                     # coherent, one frame jumps 1 m
    temporal_confidence(ps, {p.frame: i for i, p in enumerate(ps)}, min_confidence=0.7)
    assert ps[5].status == "rejected" and "confidence" in ps[5].error
    assert ps[6].status == "rejected"               # its predecessor was far
    assert all(ps[i].status == "matched" for i in (1, 2, 3, 4, 7, 8, 9))
    assert ps[3].diagnostics["confidence_factors"]["time"] == pytest.approx(
        2 ** -((0.01 / 0.17) ** 2), abs=1e-4)
    ps = poses(0.5)                                 # independent poses: no time factor
    temporal_confidence(ps, {p.frame: i for i, p in enumerate(ps)}, min_confidence=0.7)
    assert all(p.status == "matched" for p in ps)
    assert ps[3].diagnostics["confidence_factors"]["time"] is None
