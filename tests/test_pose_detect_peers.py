"""benchmarks/applications.py ``peer_points`` (issue 14): the points the detection benchmark
compares as peers, on hand-made poses with known answers."""
from types import SimpleNamespace

import numpy as np

from _benchmarks import load_benchmark


def test_peer_points_on_a_straight_branch():
    """A head straight above the torso moves down by HEAD_CENTRE_DROP; a hand at the end of a
    straight horizontal branch moves on along it by HAND_REACH; the crotch becomes the crotch
    curve's end; parts without a curve or unplaced stay as they are."""
    A = load_benchmark("applications")
    arm = np.c_[np.linspace(0.2, 0.8, 16), np.zeros(16), np.full(16, 1.4)]   # along +x
    crotch_curve = np.c_[np.zeros(16), np.zeros(16), np.linspace(1.3, 0.9, 16)]
    parts = {"torso": (0, 0, 1.3), "head": (0, 0, 1.7), "hand_1": (0.8, 0, 1.4),
             "hand_2": (-0.5, 0, 1.0), "crotch": (0.03, 0, 0.95), "foot_1": None}
    pose = SimpleNamespace(diagnostics={"curves": {"hand_1": arm, "crotch": crotch_curve}})
    cc, gp = A.peer_points(pose, parts)
    assert np.allclose(gp["head"], (0, 0, 1.7 - A.HEAD_CENTRE_DROP))
    assert np.allclose(gp["hand_1"], (0.8 + A.HAND_REACH, 0, 1.4))
    assert gp["hand_2"] == parts["hand_2"] and gp["crotch"] == parts["crotch"]
    assert np.allclose(cc["crotch"], (0, 0, 0.9))
    assert cc["hand_1"] == parts["hand_1"] and cc["foot_1"] is None
    # an unplaced head or crotch stays unplaced
    cc, gp = A.peer_points(pose, {**parts, "head": None, "crotch": None})
    assert gp["head"] is None and cc["crotch"] is None
