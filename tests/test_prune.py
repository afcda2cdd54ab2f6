"""Scale-axis pruning of skeleton bumps (topopose.skeleton.prune) on a hand-built tube.

Oracles: the geometry of the scene (a thick tube, a small bump on its surface, a thin limb
much longer than the tube's radius; skeleton drawn by hand on their axes) decides which
branch is a bump; scipy's exact Euclidean distance transform checks the inscribed-ball
radius."""
import numpy as np
from scipy import ndimage

from topopose.skeleton import data_tree
from topopose.skeleton.prune import ball_radius, prune_bumps

SHAPE = (90, 33, 60)
AXIS = (16, 16)                  # the tube's axis: y = z = 16
R_TUBE = 6


def scene():
    x, y, z = np.indices(SHAPE)
    tube = ((y - AXIS[0]) ** 2 + (z - AXIS[1]) ** 2 <= R_TUBE ** 2) & (x >= 4) & (x <= 84)
    bump = (x - 30) ** 2 + (y - 16) ** 2 + (z - 22) ** 2 <= 9      # radius 3, centre on the surface
    limb = ((x - 56) ** 2 + (y - 16) ** 2 <= 4) & (z >= 16) & (z <= 50)   # radius 2, 34 long
    hull = tube | bump | limb
    skel = np.zeros(SHAPE, bool)
    skel[6:83, 16, 16] = True          # the tube's axis
    skel[30, 16, 17:25] = True         # out to the bump (8 voxels)
    skel[56, 16, 17:49] = True         # the limb (32 voxels)
    return hull, skel


def leaves(tree):
    adj = tree.adjacency()
    return sorted(tuple(np.round(tree.positions[v]).astype(int)) for v in tree.vertices
                  if len(adj[v]) == 1)


def test_ball_radius_is_the_exact_distance_to_the_background():
    hull, _ = scene()
    edt = ndimage.distance_transform_edt(np.pad(hull, 1))[1:-1, 1:-1, 1:-1]
    rng = np.random.default_rng(0)
    inside = np.argwhere(hull)
    for x in inside[rng.choice(len(inside), 60, replace=False)]:
        assert abs(ball_radius(hull, x) - edt[tuple(x)]) < 1e-9
    assert ball_radius(hull, (0, 0, 0)) == 0.0


def test_the_bump_is_pruned_and_the_limb_kept():
    hull, skel = scene()
    before = data_tree(skel)
    assert len(leaves(before)) == 4                      # two tube ends, bump, limb
    assert (30, 16, 24) in leaves(before)
    for measure in ("contain", "length"):
        out, tree, pruned = prune_bumps(skel, hull, 2.0, measure=measure)
        assert leaves(tree) == [(6, 16, 16), (56, 16, 48), (82, 16, 16)], measure
        assert len(pruned) == 1 and np.allclose(pruned[0]["position"], (30, 16, 24))
        assert 6 <= pruned[0]["radius"] <= 7
        # only the bump's voxels left the skeleton, the input is untouched
        gone = np.argwhere(skel & ~out)
        # (its voxel next to the axis belongs to the junction's I-component and stays)
        assert len(gone) >= 7 and set(map(tuple, gone)) <= {(30, 16, z) for z in range(17, 25)}
        assert not (out & ~skel).any()
        # one tree: the tube's axis and the limb — one junction of degree 3, no other branch
        degs = sorted(tree.degree(v) for v in tree.vertices)
        assert degs.count(1) == 3 and degs.count(3) == 1 and set(degs) <= {1, 2, 3}
        assert abs(tree.total_weight() - (before.total_weight() - 7)) <= 1.5


def test_ratio_decides_and_zero_is_off():
    hull, skel = scene()
    for ratio in (0, 1.0):               # the bump reaches ~1.5 junction radii: kept below that
        out, tree, pruned = prune_bumps(skel, hull, ratio)
        assert pruned == [] and np.array_equal(out, skel) and len(leaves(tree)) == 4
    # the limb reaches ~5 junction radii, the tube's ends ~4: kept at 3.5
    _, tree, pruned = prune_bumps(skel, hull, 3.5)
    assert len(pruned) == 1 and len(leaves(tree)) == 3
    # a huge ratio prunes down to a path (two leaves), never further
    _, tree, pruned = prune_bumps(skel, hull, 50.0)
    assert len(leaves(tree)) == 2 and len(pruned) == 2


def test_a_border_leaf_is_never_pruned():
    hull, skel = scene()
    border = np.zeros(SHAPE, bool)
    border[30, 16, 24] = True            # the bump's tip marked as an infinite limb's exit
    _, tree, pruned = prune_bumps(skel, hull, 2.0, border=border)
    assert pruned == [] and (30, 16, 24) in leaves(tree)
