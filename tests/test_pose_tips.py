"""Extremity tips (pose/tips.py): a leaf part placed where its branch, prolonged, leaves the hull.

Oracle: analytic shapes whose surface point on the branch's axis is known."""
import numpy as np

from topopose.match.tree import Tree
from topopose.frame.tips import (end_direction, exit_point, extremity_tips, head_along_axis,
                                 head_from_hull, inscribed_radius, thick_top)
from topopose.topology import thin


class _Vol:
    def __init__(self, data, origin=(0.0, 0.0, 0.0), voxel_size=1.0):
        self.data, self.origin, self.voxel_size = data, origin, voxel_size


def _head_on_neck(n=48, r=8, c=(24, 24, 34)):
    """A ball of radius r (the head) on a vertical cylinder of radius 3 (the neck)."""
    z, y, x = np.indices((n, n, n))
    ball = (x - c[2]) ** 2 + (y - c[1]) ** 2 + (z - c[0]) ** 2 <= r * r
    neck = ((x - c[2]) ** 2 + (y - c[1]) ** 2 <= 9) & (z >= 4) & (z <= c[0])
    return ball | neck, np.array(c, float), r


def test_exit_point_and_radius_on_a_box():
    v = np.zeros((20, 20, 20), bool)
    v[5:15, 5:15, 5:15] = True
    p = exit_point(v, (0, 0, 0), 1.0, (10, 10, 10), (0, 0, 1), 30.0)
    assert np.allclose(p, (10, 10, 14.5), atol=0.5)          # last inside voxel: 14
    assert inscribed_radius(v, (10, 10, 10), 8) == 5.0      # voxel 15 is the first outside
    assert inscribed_radius(v, (6, 10, 10), 8) == 2.0


def test_end_direction_points_out_of_the_branch():
    line = np.array([[0, 0, z] for z in range(10)], float)
    assert np.allclose(end_direction(line, line[-1], 4.0), (0, 0, 1))
    assert end_direction(line[:1], line[0], 4.0) is None


def test_head_tip_is_the_crown():
    vol, c, r = _head_on_neck()
    skel = thin(vol)
    pts = np.argwhere(skel)
    end = pts[pts[:, 0].argmax()].astype(float)          # the branch's upper end, in the ball
    low = pts[pts[:, 0].argmin()].astype(float)
    assert np.linalg.norm(end - c) < r                    # thinning stops inside the head
    data = Tree([("h", "n", 1.0)], positions={"h": tuple(end), "n": tuple(low)})
    tips = extremity_tips(_Vol(vol), skel, data, {"head": "h", "base": "n"}, ["head"])
    crown = c + (r, 0, 0)
    assert np.linalg.norm(tips["head"] - crown) <= 1.5
    # a part matched to a vertex that is not a leaf is left alone
    data2 = Tree([("h", "n", 1.0), ("n", "m", 1.0)], positions={"h": tuple(end), "n": tuple(low),
                                                                "m": (0.0, 0.0, 0.0)})
    assert extremity_tips(_Vol(vol), skel, data2, {"head": "n"}, ["head"]) == {}


def _trunk_head_and_raised_arm(n=64):
    """A box trunk (half-width 10), a ball head (radius 6, centre z = 42) on it, and a thin rod
    (an arm, radius 2) rising beside the head higher than the crown (z up to 58)."""
    z, y, x = np.indices((n, n, n))
    trunk = (abs(x - 32) <= 10) & (abs(y - 32) <= 10) & (z >= 6) & (z <= 34)
    head = (x - 32) ** 2 + (y - 32) ** 2 + (z - 42) ** 2 <= 36
    arm = ((x - 46) ** 2 + (y - 32) ** 2 <= 4) & (z >= 20) & (z <= 58)
    return trunk | head | arm


def test_thick_top_skips_a_thin_arm_above_the_head():
    vol = _trunk_head_and_raised_arm()
    top, r = thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4)   # axis 0 is up here
    # largest inscribed radius ≈ 11 (the trunk) → thick means ≥ 4.4: the arm (2) is not, the
    # head's core (radius 6) is: its highest point lies 6 − 4.4 ≈ 1.6 above the centre
    assert abs(top[1] - 32) <= 1 and abs(top[2] - 32) <= 1
    assert 42 <= top[0] <= 44 and r >= 4.4
    # with the threshold below the arm's radius the arm wins (the oracle is not vacuous)
    top2, _ = thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.1, min_voxels=1.0)
    assert top2[0] >= 55 and abs(top2[2] - 46) <= 2
    # a grid too coarse to tell a head from an arm by thickness: no answer
    assert thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.1) is None           # 0.1 × 11 < 1.5 voxels
    assert thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4, min_voxels=5.0) is None


def test_head_from_hull_is_the_crown_not_the_arm():
    vol = _trunk_head_and_raised_arm()
    torso = np.array([30.0, 32.0, 32.0])
    head = head_from_hull(_Vol(vol), (1, 0, 0), torso, 0.4)
    assert np.linalg.norm(head - (48, 32, 32)) <= 1.0          # crown of the ball: z = 42 + 6
    # a leaning subject: the head's crown along torso → head, not straight up
    z, y, x = np.indices(vol.shape)
    lean = vol & ~((x - 32) ** 2 + (y - 32) ** 2 + (z - 42) ** 2 <= 36)
    lean |= (x - 38) ** 2 + (y - 32) ** 2 + (z - 40) ** 2 <= 36     # head moved sideways
    head = head_from_hull(_Vol(lean), (1, 0, 0), torso, 0.4)
    d = np.array([40, 32, 38]) - torso
    crown = np.array([40, 32, 38]) + 6 * d / np.linalg.norm(d)
    assert np.linalg.norm(head - crown) <= 1.5
    assert head_from_hull(_Vol(np.zeros((5, 5, 5), bool)), (1, 0, 0), torso) is None


def test_head_tip_from_the_torso_past_a_bent_branch_end():
    """A head branch whose last voxels come in at 45° (a spur towards a cheek): along its own
    end direction the tip lands on the side of the head; from the torso vertex through the
    branch end (``anchors``, TIP_ANCHOR) it lands on the crown."""
    vol, c, r = _head_on_neck()
    end = c + (4, 0, 0)                                   # on the axis, 4 voxels below the crown
    skel = np.zeros_like(vol)
    for k in range(1, 4):                                 # the spur: from below and the side
        skel[tuple((end - (k, 0, k)).astype(int))] = True
    skel[tuple(end.astype(int))] = True
    torso = c - (14, 0, 0)
    skel[tuple(torso.astype(int))] = True
    data = Tree([("h", "t", 1.0)], positions={"h": tuple(end), "t": tuple(torso)})
    crown = c + (r, 0, 0)
    args = (_Vol(vol), skel, data, {"head": "h", "torso": "t"}, ["head"])
    own = extremity_tips(*args)["head"]
    anchored = extremity_tips(*args, anchors={"head": ("torso", 3.0)})["head"]
    assert np.linalg.norm(own - crown) > 2.5              # sent sideways by the spur
    assert np.linalg.norm(anchored - crown) <= 1.0
    # an unmatched anchor falls back to the branch's own end direction
    none = extremity_tips(_Vol(vol), skel, data, {"head": "h"}, ["head"],
                          anchors={"head": ("torso", 3.0)})["head"]
    assert np.allclose(none, own)


def test_thick_top_ball_sets_a_raised_fist_aside():
    """A fist (ball of radius 5) on a thin raised arm above the head: thick enough for
    ``min_fraction`` 0.4 of the trunk's radius (≈ 11) but holding no ball of 0.55 × it; the
    head (radius 6) does. Oracle: the centres of the analytic balls."""
    vol = _trunk_head_and_raised_arm()
    z, y, x = np.indices(vol.shape)
    vol |= (x - 46) ** 2 + (y - 32) ** 2 + (z - 56) ** 2 <= 25         # the fist, centre z 56
    top, _ = thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4)
    assert top[0] >= 56 and abs(top[2] - 46) <= 1                      # without: the fist
    top, r = thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4, ball=0.5, reach=1.5)
    assert 42 <= top[0] <= 44 and abs(top[2] - 32) <= 1 and r >= 4.4   # with it: the head
    # one try only: the fist is set aside and nothing is left to try
    assert thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4, ball=0.5, reach=1.5, tries=1) is None


def test_head_along_axis_finds_the_crown_of_an_inverted_subject():
    """An upside-down subject: the head ball at the bottom (crown at z = 15), the trunk above
    it, a thin arm hanging lower than the crown. Along up the hull's thick top is the trunk's
    end; along the body's axis crotch → torso it is the head, whose crown is the oracle."""
    vol = _trunk_head_and_raised_arm()[::-1]          # axis 0 flipped: z → 63 − z
    crown = np.array([63 - 48, 32, 32], float)
    torso, crotch = np.array([33.0, 32, 32]), np.array([55.0, 32, 32])
    rule = ("head", "torso", "crotch", 0.4, 6.0)
    head = head_along_axis(_Vol(vol), {"torso": torso, "crotch": crotch, "head": None}, rule)
    assert np.linalg.norm(head - crown) <= 1.0
    # the upright rule (thick top along up) ends on the trunk: the oracle is not vacuous
    up_head = head_from_hull(_Vol(vol), (1, 0, 0), torso, 0.4)
    assert np.linalg.norm(up_head - crown) > 20
    # a head already placed near the crown is moved onto it; one farther than max_shift ×
    # the largest radius (≈ 11) from the hull's head is left alone (None: keep it)
    near = {"torso": torso, "crotch": crotch, "head": crown + (5, 3, 0)}
    assert np.linalg.norm(head_along_axis(_Vol(vol), near, rule) - crown) <= 1.0
    far = {"torso": torso, "crotch": crotch, "head": np.array([60.0, 32, 32])}
    assert head_along_axis(_Vol(vol), far, ("head", "torso", "crotch", 0.4, 2.0)) is None
    assert head_along_axis(_Vol(vol), {"torso": torso, "crotch": None}, rule) is None


def test_inverted_capsule_human_head_is_its_crown():
    """End to end, without coordinate constraints: a capsule human standing on its head (pelvis
    pitched 180°). Oracle: the crown, the end of gt.json's head segment — the lowest point of
    the body here. The head from the hull along the body's axis (HEAD_AXIS, the default) lands
    on it; the peer (head_axis=False: the head branch's tip) lands farther."""
    from topopose.synth import subjects as SS
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    old = SS.RANDOM["human"]
    SS.RANDOM["human"] = lambda rng: {**SS.HUMAN_DEFAULT, "pelvis_pitch": 180.0, "hip_abd_l": 20,
                                      "hip_abd_r": 20, "sh_abd_l": 40, "sh_abd_r": 40}
    try:
        cap = synthetic_capture("human", frames=1, seed=0, noise=0, separated=True, margin=0.075)
    finally:
        SS.RANDOM["human"] = old
    f = cap.frames[0]
    gt = cap.gt["frames"][f]
    crown = np.asarray(gt["segments"]["head"][1], float)
    assert crown[2] < min(np.asarray(x, float)[2] for k, x in gt["parts"].items() if k != "head")
    pose = FrameEstimator(cap, "human", 100, constraints=False).estimate(f)
    peer = FrameEstimator(cap, "human", 100, constraints=False, head_axis=False).estimate(f)
    assert pose.status == peer.status == "matched"
    assert "head" in pose.diagnostics["from_hull"]
    err = np.linalg.norm(np.asarray(pose.parts["head"]) - crown)
    assert err < 0.03                                  # m
    assert err < np.linalg.norm(np.asarray(peer.parts["head"]) - crown)


def test_thick_top_ball_with_a_top_of_two_clumps_does_not_fail():
    """Two equal balls side by side at the same height (two fists, two feet): the top layer's
    centroid lies between them, near no voxel of the hull; the ball check sets that layer
    aside rather than failing on an empty neighbourhood, and gives up after ``tries``."""
    z, y, x = np.indices((40, 40, 80))
    vol = ((x - 12) ** 2 + (y - 20) ** 2 + (z - 20) ** 2 <= 36) | \
          ((x - 68) ** 2 + (y - 20) ** 2 + (z - 20) ** 2 <= 36)
    assert thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4, ball=0.5, reach=1.5) is None
    # without the ball check: the centroid of the top layer, between the balls
    top, _ = thick_top(vol, (0, 0, 0), 1.0, (1, 0, 0), 0.4)
    assert abs(top[2] - 40) <= 1
