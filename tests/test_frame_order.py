"""Frames in natural order (``2`` before ``10``) wherever frames are ordered: the capture's
frame list, the poses file, the exports and the sequence stages."""
from __future__ import annotations

import csv

import numpy as np

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import load_capture
from topopose.frames import frame_key, sort_frames, sort_poses
from topopose.pose.export import write_csv
from topopose.pose.pose import Pose, read_poses, write_poses

RNG = np.random.default_rng(3)


def test_frame_key_orders_numbers_as_numbers():
    """Oracle: digit names by their integer value; mixed names by (prefix, number)."""
    names = [str(i) for i in range(130)]
    shuffled = list(RNG.permutation(names))
    assert sort_frames(shuffled) == names
    mixed = [f"{p}{i}" for p in ("a_", "b_") for i in (1, 2, 9, 10, 11, 100)]
    assert sort_frames(list(RNG.permutation(mixed))) == sorted(
        mixed, key=lambda s: (s[:2], int(s[2:])))
    assert frame_key("2") < frame_key("10")
    assert len({frame_key(s) for s in ("7", "07", "007")}) == 3  # distinct names, distinct keys


def _pose(frame, x):
    return Pose(frame, "matched", 0.5, {"head": np.array([x, 0.0, 1.0])}, None, {"total": 1.0}, {})


def test_poses_file_and_exports_in_natural_order(tmp_path):
    frames = [str(i) for i in range(12)]
    poses = [_pose(f, float(f)) for f in RNG.permutation(frames)]
    assert [p.frame for p in sort_poses(poses)] == frames
    out = tmp_path / "poses.jsonl"
    write_poses(out, poses, {"topopose": "test"})
    assert [p.frame for p in read_poses(out)] == frames
    rows = list(csv.reader(open(write_csv(tmp_path / "p.csv", poses, ["head"]))))
    assert [r[0] for r in rows[1:]] == frames
    assert [float(r[3]) for r in rows[1:]] == [float(f) for f in frames]   # rows kept whole


def test_capture_frames_unpadded_numbers(tmp_path):
    """``0.png`` … ``11.png`` (no zero padding, as studio captures ship them): frame 10
    follows frame 9, not frame 1."""
    cams = ring(n=3, size=(64, 48), f=60)
    masks = capsule_masks(cams, (0, 0, 0.6), (0, 0, 1.4), 0.2)
    root = write_capture(tmp_path / "cap", cams, {str(i): masks for i in range(12)})
    cap = load_capture(root)
    assert cap.frames == [str(i) for i in range(12)]
    assert cap.frame_name(10) == "10"
