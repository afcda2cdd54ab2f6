"""Evidence for an unseen arm from the frame's hull (topopose.pose.unseen)."""
import numpy as np
import pytest

from topopose import Volume
from topopose.pose.curves import resample
from topopose.pose.kinematic_fit import fit_sequence
from topopose.pose.unseen import _seg_dist, hull_remainder
from test_pose_sides_skeleton import HUMAN, _hand_2_unseen


def _cylinder(shape, a, b, r):
    """Bool grid: voxels within ``r`` of the segment a→b (voxel units)."""
    X = np.argwhere(np.ones(shape, bool)).astype(float)
    return (_seg_dist(X, np.asarray([a], float), np.asarray([b], float))[0] <= r).reshape(shape)


@pytest.mark.parametrize("angle", [15.0, 40.0])
def test_hull_remainder_is_the_arm_beside_the_trunk(angle):
    """A trunk (cylinder, its curve on the axis) and an arm against its side at a known angle
    from the vertical: the remainder (hull voxels the curve's inscribed balls leave
    unexplained) lies on the arm, along most of its length; without the arm it is empty."""
    shape, vs, origin = (60, 60, 70), 0.01, np.array([-0.3, -0.3, 0.0])
    trunk = _cylinder(shape, (30, 30, 8), (30, 30, 60), 10)
    t = np.radians(angle)
    a0 = np.array([30.0, 43.0, 58.0])
    a1 = a0 + 40 * np.array([0.0, np.sin(t), -np.cos(t)])
    arm = _cylinder(shape, a0, a1, 3.5)
    curve = {"crotch": origin + vs * np.array([[30, 30, 60], [30, 30, 8]], float)}
    X = hull_remainder(Volume(trunk | arm, origin, vs), curve)
    assert len(X) >= 20
    d = _seg_dist(X, origin + vs * a0[None], origin + vs * a1[None])[0]
    assert np.mean(d < 0.05) > 0.95, np.quantile(d, [0.5, 0.9])
    along = np.dot(X - (origin + vs * a0), (a1 - a0) / 40)
    assert along.max() - along.min() > 0.25            # most of the arm's 0.4 m
    assert len(hull_remainder(Volume(trunk, origin, vs), curve)) == 0


@pytest.mark.parametrize("yaw", [0.4, 2.5])
def test_unseen_arm_elbow_follows_the_evidence(yaw):
    """An unseen arm (hand unplaced, no curve) and hull evidence along a true arm from its
    shoulder to the rest pose's wrist, the elbow turned 90° about the shoulder → wrist line (away
    from the chest):
    the fitted elbow lies within 3 cm of the true one (the rest pose's is > 10 cm off), shoulder
    and wrist stay, bone lengths are kept; without evidence (absent, or ``evidence=False``)
    the arm is the rest pose's."""
    full, cut, parts2, _ = _hand_2_unseen(yaw, 3)
    rng = np.random.default_rng(4)                       # the evidence's noise
    off, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0, evidence=False)
    J0 = off[1].joints
    S, E0, W = J0["shoulder_2"], J0["elbow_2"], J0["wrist_2"]
    k = (W - S) / np.linalg.norm(W - S)                 # the elbow turned 90° about S → W
    c = S + np.dot(E0 - S, k) * k
    r = E0 - c
    E = max((c + np.cross(k, r), c - np.cross(k, r)),        # the side away from the chest
            key=lambda x: np.linalg.norm(x - J0["chest"]))
    assert np.linalg.norm(E - E0) > 0.10
    pts = np.vstack([resample([S, E], 12), resample([E, W], 12)[1:]])
    cut.diagnostics["arm_evidence"] = (pts + rng.normal(scale=0.005, size=pts.shape)).tolist()
    out, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0)
    J = out[1].joints
    assert np.linalg.norm(J["elbow_2"] - E) < 0.03, np.linalg.norm(J["elbow_2"] - E)
    assert np.linalg.norm(J["shoulder_2"] - S) < 1e-6 and np.linalg.norm(J["wrist_2"] - W) < 1e-6
    for j, n in enumerate(tree.names):                          # lengths constant
        if tree.parents[j] >= 0:
            assert abs(np.linalg.norm(J[n] - J[tree.names[tree.parents[j]]]) - L[j]) < 1e-6
    assert np.linalg.norm(J["wrist_1"] - J0["wrist_1"]) < 1e-9      # the seen arm
    same, _, _ = fit_sequence([full, cut], HUMAN, max_gap=0, evidence=False)
    assert np.linalg.norm(same[1].joints["elbow_2"] - E0) < 1e-9
    del cut.diagnostics["arm_evidence"]
    none, _, _ = fit_sequence([full, cut], HUMAN, max_gap=0)
    assert np.linalg.norm(none[1].joints["elbow_2"] - E0) < 1e-9
