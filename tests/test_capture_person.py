"""Silhouette method "person" (capture/segment.py) with a stand-in for MediaPipe's pose network.

The stand-in "network" returns the true capsule silhouette (the bright pixels of the synthetic
frames) as its segmentation mask, so the hull of the method must equal the hull of the true
silhouettes; no background model is learned; a camera where no one is found does not vote."""
from __future__ import annotations

import sys
import types

import cv2
import numpy as np
import pytest

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import load_capture
from topopose.capture.background import foreground_maps
from topopose.hull import visual_hull

TOML = ('[capture.volume]\nmin = [-0.5, -0.5, 0.2]\nmax = [0.5, 0.5, 1.7]\n\n'
        '[silhouettes]\nmethod = "person"\nscale = 1.0\nmedian = 0\n')


class _Result:
    def __init__(self, mask):
        self.segmentation_mask = mask


class _FakePose:
    """Stand-in for ``mediapipe.solutions.pose.Pose``: person = bright pixels; nobody in an
    image whose top-left pixel is pure red (a camera where the network finds no one)."""
    made = 0

    def __init__(self, **kwargs):
        assert kwargs["enable_segmentation"] and kwargs["static_image_mode"]
        type(self).made += 1

    def process(self, rgb):
        if tuple(rgb[0, 0]) == (255, 0, 0):
            return _Result(None)
        return _Result((rgb.min(axis=2) > 150).astype(np.float32))


@pytest.fixture()
def fake_mediapipe(monkeypatch):
    from topopose.capture import segment

    mod = types.ModuleType("mediapipe.python.solutions.pose")
    mod.Pose = _FakePose
    for name in ("mediapipe", "mediapipe.python", "mediapipe.python.solutions"):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    monkeypatch.setitem(sys.modules, "mediapipe.python.solutions.pose", mod)
    monkeypatch.setattr(segment, "_MODEL", {})
    _FakePose.made = 0


def _scene(tmp_path, blind_camera=None):
    cams = ring(n=4, size=(160, 120), f=200)
    masks = capsule_masks(cams, (0.0, 0.0, 0.6), (0.1, 0.1, 1.3), 0.16)
    rng = np.random.default_rng(3)
    images = []
    for k, (m, c) in enumerate(zip(masks, cams)):
        bg = rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8)
        im = np.where(m[:, :, None], np.uint8([200, 220, 240]), bg)
        if k == blind_camera:
            im[0, 0] = (0, 0, 255)             # BGR pure red: the stand-in finds no one
        images.append(im)
    root = write_capture(tmp_path / "cap", cams, {}, images={"000000": images})
    (root / "capture.toml").write_text(TOML)
    truth = write_capture(tmp_path / "truth", cams, {"000000": masks})
    (truth / "capture.toml").write_text(TOML.split("\n\n")[0] + "\n")
    return load_capture(root), load_capture(truth), masks


def test_person_hull_equals_the_true_silhouettes_hull(tmp_path, fake_mediapipe):
    cap, truth, masks = _scene(tmp_path)
    maps = foreground_maps(cap, "000000")
    for q, m in zip(maps, masks):
        assert np.array_equal(q > 127, m)
    assert ("sequence_backgrounds",) not in cap.cache       # no background model learned
    h, t = visual_hull(cap, "000000", resolution=40), visual_hull(truth, "000000", resolution=40)
    assert h.diagnostics["fusion"] == "hard"                 # fusion "auto" for "person"
    assert np.array_equal(h.data, t.data) and t.data.sum() > 200
    assert _FakePose.made == 4                              # one network per camera


def test_a_camera_where_no_one_is_found_does_not_vote(tmp_path, fake_mediapipe):
    cap, _, _ = _scene(tmp_path, blind_camera=2)
    maps = foreground_maps(cap, "000000")
    assert (maps[2] == 128).all()
    assert not (maps[1] == 128).all()


# --- "person+sequence": background learned with the network's masks excluding the subject ---

SEQ_TOML = ('[silhouettes]\nmethod = "person+sequence"\nscale = 1.0\nmedian = 0\n'
            'person_samples = 6\nperson_dilate = {d}\nperson_every = {k}\n')
VOLUME = '[capture.volume]\nmin = [-0.6, -0.6, 0.1]\nmax = [0.6, 0.6, 1.8]\n\n'


def _sequence(tmp_path, dilate=0, volume=False, n=6, every=1):
    """A subject (capsule) that sways by ±8 cm but never leaves its place over ``n`` frames,
    in front of a textured background: the rendered empty scene is the oracle."""
    cams = ring(n=4, size=(160, 120), f=200)
    rng = np.random.default_rng(5)
    empty = [rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8) for c in cams]
    frames, truth = {}, {}
    for i in range(n):
        dx = 0.08 * np.sin(2 * np.pi * i / n)
        masks = capsule_masks(cams, (dx, 0.0, 0.5), (dx + 0.05, 0.05, 1.4), 0.15)
        frames[f"{i:06d}"] = [np.where(m[:, :, None], np.uint8([200, 220, 240]), bg)
                              for m, bg in zip(masks, empty)]
        truth[f"{i:06d}"] = masks
    root = write_capture(tmp_path / "cap", cams, {}, images=frames)
    (root / "capture.toml").write_text((VOLUME if volume else "") + SEQ_TOML.format(d=dilate, k=every))
    t = write_capture(tmp_path / "truth", cams, truth)
    (t / "capture.toml").write_text(VOLUME)
    return load_capture(root), load_capture(t), empty, truth


def test_clean_background_equals_the_empty_scene(tmp_path, fake_mediapipe):
    """Without dilation the pixels ever free are exactly those not covered in every frame, and
    there the learned background equals the rendered empty scene; the never-free pixels (the
    subject's core) vote for the subject, the others see it by colour."""
    from topopose.capture.background import NEVER_FREE, capture_backgrounds, subject_box

    cap, _, empty, truth = _sequence(tmp_path)
    models = capture_backgrounds(cap)
    for c, (m, bg) in enumerate(zip(models, empty)):
        always = np.all([truth[f][c] for f in truth], axis=0)
        assert always.sum() > 300 and (~always).sum() > 10000
        assert np.array_equal(m.known, ~always)                  # never free: handled apart
        assert np.array_equal(m.image[m.known], bg[m.known])
    maps = foreground_maps(cap, "000002")
    for c, (q, m) in enumerate(zip(maps, models)):
        assert (q[~m.known] >= NEVER_FREE).all()             # or the keyframe: the frame
        assert np.array_equal(q > 127, truth["000002"][c])
    lo, hi = subject_box(cap)                                      # the capture volume
    assert np.all(lo <= [-0.1, -0.15, 0.35]) and np.all(hi >= [0.2, 0.2, 1.55])
    assert np.all(hi - lo < 2.0)


def test_clean_background_with_dilated_masks(tmp_path, fake_mediapipe):
    """Dilated masks (the samples far from the subject are preferred): the same pixels are
    known, and every known one is still the empty scene."""
    cap, _, empty, truth = _sequence(tmp_path, dilate=3)
    from topopose.capture.background import capture_backgrounds

    for c, (m, bg) in enumerate(zip(capture_backgrounds(cap), empty)):
        always = np.all([truth[f][c] for f in truth], axis=0)
        assert np.array_equal(m.known, ~always)
        assert np.array_equal(m.image[m.known], bg[m.known])


def test_person_sequence_hull_equals_the_true_hull(tmp_path, fake_mediapipe):
    """The hull from "person+sequence" silhouettes (fusion "auto": hard) against the hull of
    the true silhouettes on the same grid: equal within 3 % of the voxels; the network runs
    at set-up only (6 samples × 4 cameras), not per frame."""
    cap, truth, _, _ = _sequence(tmp_path, dilate=2, volume=True)
    made = None
    for f in ("000001", "000004"):
        h, t = visual_hull(cap, f, resolution=40), visual_hull(truth, f, resolution=40)
        made = made or _FakePose.made
        assert h.diagnostics["fusion"] == "hard"
        diff = np.logical_xor(h.data, t.data).sum()
        assert t.data.sum() > 1000 and diff <= 0.03 * t.data.sum(), (diff, t.data.sum())
    assert made == 4 and _FakePose.made == 4                    # one graph per camera, reused


def test_keyframe_mask_is_added_eroded(tmp_path, fake_mediapipe):
    """Every 3rd frame is a keyframe: frame 4's map is its colour foreground raised to the
    network's mask of frame 3, eroded by KEYFRAME_ERODE (a square)."""
    from topopose.capture.background import KEYFRAME_ERODE

    cap, _, _, truth = _sequence(tmp_path, every=3)
    k = np.ones((KEYFRAME_ERODE,) * 2, np.uint8)
    for c, q in enumerate(foreground_maps(cap, "000004")):
        key = cv2.erode(truth["000003"][c].astype(np.uint8), k).astype(bool)
        assert key.sum() > 100
        assert np.array_equal(q > 127, truth["000004"][c] | key)
