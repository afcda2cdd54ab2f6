"""Evidence for an unseen arm from the frame's hull (topopose.frame.unseen)."""
import numpy as np
import pytest

from topopose import Volume
from topopose.frame.curves import resample
from topopose.sequence.kinematic_fit import fit_sequence
from topopose.frame.unseen import _seg_dist, hull_remainder
from test_pose_sides_skeleton import HUMAN, _hand_2_unseen, _raised_left_frame


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


def _upper_body(yaw, shift, across):
    """A hull (1 cm voxels) of an upper body facing ``R @ x`` (body frame x forward, y left, z
    up): an elliptic trunk (0.11 m front-back, 0.17 m to each side, z 1.0–1.45), a neck, a
    deltoid ball (0.05 m) at each shoulder (0, ±0.19, 1.40), the left arm hanging against the
    trunk's side, the right arm ``across`` the trunk's front (a hand on the body) or hanging.
    Returns (Volume, the shoulders in the world, R, the world offset)."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    vs, origin = 0.01, np.array([-0.45, -0.45, 0.85]) + shift
    shape = (91, 91, 80)
    X = origin + vs * np.argwhere(np.ones(shape, bool))
    B = (X - shift) @ R                        # body frame
    inside = ((B[:, 0] / 0.11) ** 2 + (B[:, 1] / 0.17) ** 2 <= 1) & (B[:, 2] >= 1.0) & \
        (B[:, 2] <= 1.45)
    inside |= (np.hypot(B[:, 0], B[:, 1]) <= 0.05) & (B[:, 2] > 1.4) & (B[:, 2] <= 1.62)
    shoulders = np.array([[0.0, 0.19, 1.40], [0.0, -0.19, 1.40]])
    ends = np.array([[0.0, 0.21, 1.0], [0.16, -0.02, 1.15] if across else [0.0, -0.21, 1.0]])
    for sh, end in zip(shoulders, ends):
        inside |= np.linalg.norm(B - sh, axis=1) <= 0.05
        inside |= _seg_dist(B, sh[None], end[None])[0] <= 0.045
    return Volume(inside.reshape(shape), origin, vs), shoulders @ R.T + shift, R, shift


@pytest.mark.parametrize("yaw,across", [(0.3, True), (2.2, False), (-1.0, True)])
def test_hull_shoulders_from_the_trunks_cross_section(yaw, across):
    """The shoulders of a synthetic upper body (deltoids, one arm hanging against the trunk,
    the other across its front) from its hull alone — the junction 5 cm below the shoulders,
    the trunk axis, the front, the largest inscribed radius (0.11 m): each within 3 cm of the
    true shoulder, on the side of axis × front first; the rest pose's guess for an unseen arm
    (the mate's mirror, ``HELD_SHOULDER`` up) is not the point: this is the trunk's own
    geometry."""
    from topopose.frame.unseen import hull_shoulders

    vol, S, R, shift = _upper_body(yaw, np.array([0.3, -0.2, 0.0]), across)
    H = hull_shoulders(vol, R @ [0.0, 0.0, 1.35] + shift, R @ [0, 0, 1.0], R @ [1.0, 0, 0], 0.11)
    assert H.shape == (2, 3)
    err = np.linalg.norm(H - S, axis=1)
    assert (err < 0.03).all(), err
    # a wrong front (the body turned 90°) puts them elsewhere: the test can fail
    H2 = hull_shoulders(vol, R @ [0.0, 0.0, 1.35] + shift, R @ [0, 0, 1.0], R @ [0, 1.0, 0], 0.11)
    assert np.linalg.norm(H2 - S, axis=1).min() > 0.05


def test_hull_shoulders_place_hanging_and_unseen_arms_only(monkeypatch):
    """``diagnostics["hull_shoulders"]`` in the kinematic fit: a hanging seen arm's shoulder is
    placed there (initial placement, within ``HULL_GATE``); a raised arm's keeps its
    place on its curve; an unseen arm moves whole by ``SHOULDER_BLEND`` of the way to the nearer
    one (within ``HULL_GATE``), bone lengths kept; ``shoulders=False``: as without."""
    from topopose.sequence import kinematic_fit as kf
    tree = kf.kinematic_tree(HUMAN)
    pose, m, _ = _raised_left_frame()
    P0 = kf.initial_placement(pose, tree)
    up, down = ("shoulder_" + m[x][-1] for x in ("left_hand", "right_hand"))
    iu, idn = tree.names.index(up), tree.names.index(down)
    H = np.array([P0[iu] + [0.0, 0.0, 0.05], P0[idn] + [0.03, -0.04, 0.02]])
    pose.diagnostics["hull_shoulders"] = H.tolist()
    P = kf.initial_placement(pose, tree)
    assert np.allclose(P[idn], H[1]) and np.allclose(P[iu], P0[iu])
    others = [j for j in range(len(tree.names)) if j != idn]
    assert np.allclose(P[others], P0[others], equal_nan=True)
    assert np.allclose(kf.initial_placement(pose, tree, hull=False), P0, equal_nan=True)
    far = H.copy()
    far[1] = P0[idn] + [0.0, 0.0, kf.HULL_GATE + 0.02]                  # beyond the gate
    pose.diagnostics["hull_shoulders"] = far.tolist()
    assert np.allclose(kf.initial_placement(pose, tree)[idn], P0[idn])
    # an unseen arm (hand_2 not found): moved whole, half-way to the hull's shoulder
    full, cut, _, _ = _hand_2_unseen(0.4, 3)
    off, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0, shoulders=False)
    J0 = off[1].joints
    arm = [f"{j}_2" for j in ("shoulder", "elbow", "wrist", "fingertip")]
    h = J0["shoulder_2"] + np.array([0.0, 0.0, 0.06])
    far1 = J0["shoulder_1"] + (kf.HULL_GATE + 0.1) * (J0["chest"] - J0["pelvis"]) / \
        np.linalg.norm(J0["chest"] - J0["pelvis"])          # the seen arm's: beyond the gate
    cut.diagnostics["hull_shoulders"] = [h.tolist(), far1.tolist()]
    on, _, _ = fit_sequence([full, cut], HUMAN, max_gap=0, evidence=False, hints=False)
    J = on[1].joints
    start = kf.shoulder_fill(np.array([J0[n] for n in tree.names]), cut, tree,
                             np.array([n in arm for n in tree.names]))
    moved = start[tree.names.index("shoulder_2")] - J0["shoulder_2"]
    assert np.allclose(moved, kf.SHOULDER_BLEND * (h - J0["shoulder_2"]))
    assert np.linalg.norm(J["shoulder_2"] - h) < np.linalg.norm(J0["shoulder_2"] - h) - 0.01
    for a, b in zip(arm, arm[1:]):
        assert np.isclose(np.linalg.norm(J[b] - J[a]), np.linalg.norm(J0[b] - J0[a]))
    assert np.allclose(J["wrist_1"], J0["wrist_1"], atol=1e-6)
