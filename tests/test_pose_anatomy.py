"""The spine behind the medial axis (pose/anatomy.py).

Oracles: synthetic skeletons whose feet point in a known direction, a ball whose inscribed
radius is known, and the ground truth of a ``body`` frame (its front and its spine)."""
import numpy as np

from topopose.match.tree import Tree
from topopose.frame.anatomy import (crotch_drop, front_direction, hand_on_trunk, hull_radius,
                                   room_below, spine_shift, torso_on_trunk)


class _Vol:
    def __init__(self, data, origin=(0.0, 0.0, 0.0), voxel_size=1.0):
        self.data, self.origin, self.voxel_size, self.diagnostics = data, origin, voxel_size, {}


def _legs(toe=(0, 1, 0), n=40):
    """Two vertical legs (x = 10 and 30) from z = 36 down to z = 12, each ending in a foot of
    8 voxels along ``toe``; returns the skeleton, the data tree and its mapping."""
    skel = np.zeros((n, n, n), bool)
    ends = []
    for x in (10, 30):
        for z in range(12, 37):
            skel[x, 10, z] = True
        p = np.array([x, 10, 12])
        for _ in range(8):
            p = p + np.asarray(toe)
            skel[tuple(p)] = True
        ends.append(tuple(float(c) for c in p))
    data = Tree([("c", "f1", 30.0), ("c", "f2", 30.0)],
                positions={"c": (20.0, 10.0, 36.0), "f1": ends[0], "f2": ends[1]})
    return skel, data, {"foot_1": "f1", "foot_2": "f2", "crotch": "c"}


def test_front_is_where_the_toes_point():
    for toe, want in (((0, 1, 0), (0, 1, 0)), ((1, 0, -1), (1, 0, 0)), ((-1, -1, 0), (-1, -1, 0))):
        skel, data, m = _legs(toe)
        f = front_direction(_Vol(skel), skel, data, m, ["foot_1", "foot_2"], (0, 0, 1))
        want = np.asarray(want, float) / np.linalg.norm(want)
        assert f is not None and np.allclose(f, want, atol=1e-9), (toe, f)
    # one foot unmatched: the other one alone decides
    skel, data, m = _legs((0, 1, 0))
    f = front_direction(_Vol(skel), skel, data, {**m, "foot_2": None}, ["foot_1", "foot_2"], (0, 0, 1))
    assert np.allclose(f, (0, 1, 0))


def test_no_front_without_toes_or_with_feet_apart():
    skel, data, m = _legs((0, 0, -1))            # feet pointing straight down: no front
    assert front_direction(_Vol(skel), skel, data, m, ["foot_1", "foot_2"], (0, 0, 1)) is None
    # feet pointing apart (180°): their mean says nothing
    skel = np.zeros((40, 40, 40), bool)
    ends = []
    for x, s in ((10, -1), (30, 1)):
        skel[x, 20, 5:31] = True
        skel[x:x + 9 * s:s, 20, 5] = True
        ends.append((float(x + 8 * s), 20.0, 5.0))
    data = Tree([("c", "f1", 30.0), ("c", "f2", 30.0)],
                positions={"c": (20.0, 20.0, 30.0), "f1": ends[0], "f2": ends[1]})
    m = {"foot_1": "f1", "foot_2": "f2"}
    assert front_direction(_Vol(skel), skel, data, m, ["foot_1", "foot_2"], (0, 0, 1)) is None
    # a foot matched to a junction, not a leaf, is not used
    skel, data, m = _legs((0, 1, 0))
    assert front_direction(_Vol(skel), skel, data, {"foot_1": "c"}, ["foot_1"], (0, 0, 1)) is None


def test_hull_radius_of_a_ball():
    z, y, x = np.indices((40, 40, 40))
    ball = (x - 20) ** 2 + (y - 20) ** 2 + (z - 20) ** 2 <= 12 ** 2
    r = hull_radius(_Vol(ball, voxel_size=0.01))
    assert abs(r - 0.12) <= 0.01 + 1e-9
    assert hull_radius(_Vol(np.zeros((5, 5, 5), bool))) == 0.0


def test_spine_shift_moves_back_by_the_share():
    parts = {"torso": np.array([1.0, 2.0, 3.0]), "crotch": np.array([0.0, 0.0, 1.0]),
             "head": None, "hand_1": np.array([5.0, 5.0, 5.0])}
    out = spine_shift(parts, np.array([0.0, 1.0, 0.0]), 0.2, {"torso": 0.5, "crotch": 0.25,
                                                              "head": 0.1})
    assert np.allclose(out["torso"], (1.0, 1.9, 3.0))
    assert np.allclose(out["crotch"], (0.0, -0.05, 1.0))
    assert out["head"] is None and out["hand_1"] is parts["hand_1"]
    assert spine_shift(parts, None, 0.2, {"torso": 0.5})["torso"] is parts["torso"]


def test_body_frame_the_shift_points_to_the_back():
    """On `body` frames (MakeHuman mesh, toes forward) the shift points against the body's
    true front (gt: left hip × up) and brings the torso nearer its gt segment on average."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator
    from topopose.batch.quality import point_segment_distance

    cap = synthetic_capture(subject="body", frames=4, seed=7, noise=0, separated=True, cameras=8,
                            build="average", margin=0.075)
    on = FrameEstimator(cap, "human", 100, gate=False)
    off = FrameEstimator(cap, "human", 100, gate=False, spine=False)
    assert on.spine and not off.spine
    cos, gain = [], []
    for f in cap.frames:
        p, q = on.estimate(f), off.estimate(f)
        g = cap.gt["frames"][f]
        s, j = g["segments"], g["joints"]
        up = np.asarray(s["torso"][0]) - np.mean(np.asarray(s["crotch"]), axis=0)
        up /= np.linalg.norm(up)
        left = np.asarray(j["LeftUpLeg_head"]) - np.asarray(j["RightUpLeg_head"])
        front = np.cross(left - (left @ up) * up, up)
        front /= np.linalg.norm(front)
        shift = p.diagnostics.get("spine_shift")
        if shift is None or p.parts["torso"] is None or q.parts["torso"] is None:
            continue
        cos.append(-np.asarray(shift) @ front / np.linalg.norm(shift))
        gain.append(point_segment_distance(q.parts["torso"], *s["torso"])
                    - point_segment_distance(p.parts["torso"], *s["torso"]))
    assert len(cos) >= 2
    assert min(cos) > 0.7
    assert np.mean(gain) > 0


def test_torso_on_trunk_moves_only_a_torso_slid_down():
    rule = ("torso", "crotch", "head", 0.35, 0.6)
    base = {"crotch": np.array([0.0, 0.0, 1.0]), "head": np.array([0.0, 0.2, 2.0])}
    # at the crotch (a contracted torso–crotch arc), and 0.3 of the way up but off the line:
    # both below 0.35 of crotch → head, both put at 0.6 of it
    for torso in ((0.0, 0.0, 1.0), (0.5, 0.06, 1.3)):
        out, moved = torso_on_trunk({**base, "torso": np.array(torso)}, rule)
        assert moved and np.allclose(out["torso"], [0.0, 0.12, 1.6])
        assert out["crotch"] is base["crotch"] and out["head"] is base["head"]
    # at 0.4 (above 0.35): unchanged, the same object
    t = np.array([0.3, 0.08, 1.4])
    out, moved = torso_on_trunk({**base, "torso": t}, rule)
    assert not moved and out["torso"] is t
    # a part unplaced, or crotch and head at one point: nothing moves
    for parts in ({**base, "torso": np.zeros(3), "head": None},
                  {"crotch": base["crotch"], "head": base["crotch"], "torso": np.zeros(3)}):
        out, moved = torso_on_trunk(parts, rule)
        assert not moved and out is parts


def test_crotch_drop_moves_down_and_back_by_the_shares():
    parts = {"crotch": np.array([1.0, 2.0, 3.0]), "torso": np.array([1.0, 2.0, 4.0])}
    front = np.array([0.0, 1.0, 0.0])
    out = crotch_drop(parts, (0, 0, 2), front, 0.2, ("crotch", 0.5, 0.25))
    assert np.allclose(out["crotch"], [1.0, 2.0 - 0.05, 3.0 - 0.1])
    assert out["torso"] is parts["torso"] and np.allclose(parts["crotch"], [1, 2, 3])
    for f, r in ((None, 0.2), (front, 0.0)):          # no front, no radius: unchanged
        assert np.allclose(crotch_drop(parts, (0, 0, 1), f, r, ("crotch", 0.5, 0.25))["crotch"],
                           parts["crotch"])
    assert crotch_drop({"crotch": None}, (0, 0, 1), front, 0.2, ("crotch", 0.5, 0.25)) == {
        "crotch": None}


def _hips(flexed: bool, n=40):
    """A voxel hull (z up, +y the front) of a trunk block (x 8–31, y 10–21, z 22–39) on two legs
    (x 8–17 and 22–31): upright, vertical legs down to z 0 with the gap between them (x 18–21)
    from z 21 down; flexed (sitting), the thighs forward and horizontal, a 10-voxel slab under
    the whole trunk (z 12–21) with no gap beneath its middle."""
    v = np.zeros((n, n, n), bool)
    v[8:32, 10:22, 22:40] = True
    if flexed:
        v[8:32, 10:36, 12:22] = True
    else:
        v[8:18, 10:22, 0:22] = True
        v[22:32, 10:22, 0:22] = True
    return _Vol(v)


def test_room_below_is_the_distance_to_the_hull_border():
    """Oracle: the hulls of :func:`_hips`, their lower borders counted by hand."""
    up = np.array([0.0, 0.0, 1.0])
    x = np.array([20.0, 15.0, 25.0])             # above the legs' gap (its top: z 21)
    assert room_below(_hips(False), x, up, 30.0) == 4.0     # first outside sample: z 21
    assert room_below(_hips(True), x, up, 30.0) == 14.0     # the slab's bottom is z 12
    assert room_below(_hips(True), x, up, 5.0) == 5.0       # the limit
    assert room_below(_hips(False), np.array([12.0, 15.0, 25.0]), 2 * up, 30.0) == 26.0


def test_crotch_drop_floor_fires_on_flexed_hips_not_on_an_upright_stance():
    """The rule's floor (:data:`CROTCH_DROP`'s fourth entry): with the hips flexed (a slab of
    thigh beneath the junction) the crotch drops the whole down share; upright, the gap between
    the legs right beneath it, it drops only to ``floor`` × radius above the gap."""
    from topopose.frame.anatomy import CROTCH_DROP

    up, front = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    c = np.array([20.0, 15.0, 25.0])
    part, down, back, floor = CROTCH_DROP["human"]
    r = 6.0                                        # drop 2.1, floor 3: room 4 upright, 14 flexed
    flexed = crotch_drop({part: c}, up, front, r, CROTCH_DROP["human"], _hips(True))[part]
    assert np.allclose(flexed, c - down * r * up - back * r * front)
    upright = crotch_drop({part: c}, up, front, r, CROTCH_DROP["human"], _hips(False))[part]
    assert np.isclose(upright[2], c[2] - (4.0 - floor * r))        # 1 voxel down, not 2.1
    assert np.isclose(upright[1], c[1] - back * r)
    c2 = np.array([20.0, 15.0, 23.0])              # right above the gap: no drop at all
    assert np.isclose(crotch_drop({part: c2}, up, front, r, CROTCH_DROP["human"],
                                  _hips(False))[part][2], 23.0)
    # without the hull, or a rule of three entries: the whole drop
    for rule, vol in ((CROTCH_DROP["human"], None), ((part, down, back), _hips(False))):
        assert np.allclose(crotch_drop({part: c}, up, front, r, rule, vol)[part],
                           c - down * r * up - back * r * front)


def test_body_crouch_the_crotch_reaches_the_pelvis():
    """Oracle: the gt pelvis segment of a `body` frame with flexed hips (heavy build, seed 43,
    frame 2: hips flexed 92–96°, trunk bent 34°) — the legs' junction, spine-shifted, lies
    beyond 0.08 × height above it; lowered by the crotch drop it lies within."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator
    from topopose.batch.quality import point_segment_distance

    cap = synthetic_capture(subject="body", frames=12, seed=43, noise=1, separated=True,
                            cameras=8, build="heavy", margin=0.075)
    f = cap.frames[2]
    seg = cap.gt["frames"][f]["segments"]["crotch"]
    tol = 0.08 * cap.gt["height"]
    old = FrameEstimator(cap, "human", 100, gate=False, crotch_drop=False).estimate(f)
    new = FrameEstimator(cap, "human", 100, gate=False, crotch_drop=True).estimate(f)
    assert old.status == new.status == "matched"
    assert point_segment_distance(old.parts["crotch"], *seg) > tol
    assert np.asarray(old.parts["crotch"])[2] > max(np.asarray(seg)[:, 2])    # high
    assert point_segment_distance(new.parts["crotch"], *seg) <= tol
    assert np.asarray(new.parts["crotch"])[2] < np.asarray(old.parts["crotch"])[2]
    # the junction before the drop, what the pose descriptions compare (§13.3.2.1): the
    # crotch of the estimate without the drop
    assert "detect_parts" not in old.diagnostics
    assert np.allclose(new.diagnostics["detect_parts"]["crotch"], old.parts["crotch"], atol=1e-5)


def test_trunk_blend_draws_the_torso_towards_the_trunk_line():
    from topopose.frame.anatomy import trunk_blend

    base = {"crotch": np.array([0.0, 0.0, 1.0]), "head": np.array([0.0, 0.2, 2.0])}
    line = np.array([0.0, 0.12, 1.6])               # 0.6 of crotch → head
    torso = np.array([0.0, 0.3, 1.7])               # forward of the line (arms on the chest)
    for w, want in ((0.0, torso), (0.5, 0.5 * (torso + line)), (1.0, line)):
        out = trunk_blend({**base, "torso": torso}, ("torso", "crotch", "head", 0.6, w))
        assert np.allclose(out["torso"], want), w
        assert out["crotch"] is base["crotch"] and out["head"] is base["head"]
    # a part unplaced: nothing moves
    parts = {**base, "torso": torso, "head": None}
    assert trunk_blend(parts, ("torso", "crotch", "head", 0.6, 0.5))["torso"] is torso


def test_hand_on_trunk_is_the_hand_next_to_the_core():
    """A box trunk (half-width 8: core radius ≈ 9 voxels) with a thin arm (radius 2) out to
    the side: a hand at the arm's far end is free, a hand on the trunk's side next to the
    core. Oracle: the brute-force distance to the voxels of radius ≥ 0.6 × the largest."""
    from topopose.frame.tips import inscribed_distances

    n = 60
    z, y, x = np.indices((n, n, n))
    trunk = (abs(x - 20) <= 8) & (abs(y - 30) <= 8) & (z >= 10) & (z <= 50)
    arm = ((y - 30) ** 2 + (z - 40) ** 2 <= 4) & (x >= 20) & (x <= 55)
    vol = _Vol(trunk | arm, origin=(1.0, 2.0, 3.0), voxel_size=0.5)
    edt = inscribed_distances(vol.data)
    dt, lo = edt
    core = np.argwhere(dt >= 0.6 * dt.max()) - 1 + lo
    world = lambda v: np.asarray(vol.origin) + 0.5 * np.asarray(v, float)
    free, near = world((40, 30, 55)), world((40, 30, 30))     # (z, y, x)
    d_free = np.sqrt(((core - (40, 30, 55)) ** 2).sum(axis=1)).min() / dt.max()
    d_near = np.sqrt(((core - (40, 30, 30)) ** 2).sum(axis=1)).min() / dt.max()
    assert d_near < 1.3 < d_free                                    # the scene is what it says
    rule = (("hand_1", "hand_2"), 0.6, 1.3)
    assert hand_on_trunk({"hand_1": free, "hand_2": near}, rule, vol, edt) == "hand_2"
    assert hand_on_trunk({"hand_1": free, "hand_2": None}, rule, vol, edt) is None
    # the reach decides: beyond the free hand's distance both qualify, the nearer is named
    wide = (("hand_1", "hand_2"), 0.6, d_free + 0.1)
    assert hand_on_trunk({"hand_1": free, "hand_2": near}, wide, vol, edt) == "hand_2"
    assert hand_on_trunk({"hand_1": free}, wide, vol, edt) == "hand_1"
    assert hand_on_trunk({"hand_1": near}, rule, vol, None) is None
