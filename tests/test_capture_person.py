"""Silhouette method "person" (capture/segment.py) with a stand-in for MediaPipe's pose network.

The stand-in "network" returns the true capsule silhouette (the bright pixels of the synthetic
frames) as its segmentation mask, so the hull of the method must equal the hull of the true
silhouettes; no background model is learned; a camera where no one is found does not vote."""
from __future__ import annotations

import sys
import types

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
