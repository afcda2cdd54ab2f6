"""Extremity tips (pose/tips.py): a leaf part placed where its branch, prolonged, leaves the hull.

Oracle: analytic shapes whose surface point on the branch's axis is known."""
import numpy as np

from topopose.match.tree import Tree
from topopose.pose.tips import end_direction, exit_point, extremity_tips, inscribed_radius
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
