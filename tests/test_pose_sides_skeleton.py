"""Left and right from one frame's geometry, and the kinematic fit with constant bone lengths,
on hand-made skeleton curves whose truth is known."""
import numpy as np
import pytest

from topopose.sequence.options import SequenceOptions
from topopose.errors import InputError
from topopose.sequence.chirality import assign_sides, frame_scores, numbered
from topopose.frame.curves import resample
from topopose.sequence.kinematic_fit import fit_sequence, kinematic_tree
from topopose.pose.model import load_model, model_from_dict
from topopose.sequence.motion import process_sequence
from topopose.pose.pose import Pose

UP = np.array([0.0, 0.0, 1.0])
HUMAN = load_model("human")


def _rotz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _body(yaw, rng, knee=0.08, toe=0.2, arms_crossed=False):
    """A standing human facing ``R @ x`` (body frame x forward, y left, z up): true joints
    along each arc at the human model's ``at`` fractions, so that the curve through them puts
    every joint at its declared relative arc length. Returns (parts, curves, joints) with
    side-named truth, in world coordinates."""
    R = _rotz(yaw)
    o = rng.normal(scale=0.5, size=3) * [1, 1, 0]
    W = lambda v: R @ np.asarray(v, float) + o                          # noqa: E731
    J, parts, curves = {}, {}, {}
    torso, crotch, head = W([0, 0, 1.35]), W([0, 0, 0.95]), W([0, 0, 1.75])
    parts.update(torso=torso, crotch=crotch, head=head)
    curves["head"] = resample([torso, head])
    curves["crotch"] = resample([torso, crotch])
    for side, sg in (("left", 1.0), ("right", -1.0)):
        hand = W([0.15, sg * (0.05 if arms_crossed else 0.3), 0.9])
        if arms_crossed:
            hand = W([0.3, -sg * 0.15, 1.2])
        sh = W([0, sg * 0.2, 1.4])
        arm = resample([torso, sh, hand], 64)
        hip = W([0, sg * 0.1, 0.9])
        knee_p = W([knee, sg * 0.1, 0.5])
        ankle = W([0, sg * 0.1, 0.1])
        foot = W([toe, sg * 0.1, 0.05])
        leg = resample([crotch, hip, knee_p, ankle, foot], 64)
        parts[f"{side}_hand"], parts[f"{side}_foot"] = hand, foot
        curves[f"{side}_hand"], curves[f"{side}_foot"] = resample(arm), resample(leg)
    return parts, curves


def _numbered_frame(frame, parts, curves, swap_hands, swap_feet):
    """What the per-frame matcher gives: numbered names in an arbitrary order."""
    mh = {"left_hand": "hand_2", "right_hand": "hand_1"} if swap_hands else \
        {"left_hand": "hand_1", "right_hand": "hand_2"}
    mf = {"left_foot": "foot_2", "right_foot": "foot_1"} if swap_feet else \
        {"left_foot": "foot_1", "right_foot": "foot_2"}
    m = {**mh, **mf}
    return Pose(frame, "matched", 0.1, {m.get(k, k): v for k, v in parts.items()},
                diagnostics={"curves": {m.get(k, k): v for k, v in curves.items()}}), m


def _hand_2_unseen(yaw, seed):
    """Two frames of one body (``_body(yaw)``): the first whole, the second (frame
    ``HOLD_FRAMES + 1``: too far to hold the first's arm) with hand_2 not found (no part, no
    curve). Returns (whole, cut, the second frame's true parts, the second frame's numbering
    map)."""
    HOLD_FRAMES = SequenceOptions().gaps.hold_frames

    rng = np.random.default_rng(seed)
    parts, curves = _body(yaw, rng)
    full, _ = _numbered_frame("000000", parts, curves, False, False)
    parts2, curves2 = _body(yaw, rng)
    cut, m = _numbered_frame(f"{HOLD_FRAMES + 1:06d}", parts2, curves2, False, False)
    cut.parts["hand_2"] = None
    del cut.diagnostics["curves"]["hand_2"]
    return full, cut, parts2, m


@pytest.mark.parametrize("seed", range(6))
def test_single_frame_left_right_any_facing(seed):
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(0, 2 * np.pi)
    parts, curves = _body(yaw, rng)
    pose, m = _numbered_frame("000000", parts, curves, rng.random() < 0.5, rng.random() < 0.5)
    out = assign_sides([pose], HUMAN, UP)[0]
    for side in ("left", "right"):
        for stem in ("hand", "foot"):
            assert np.allclose(out.parts[f"{side}_{stem}"], parts[f"{side}_{stem}"])
    fwd = np.array(out.diagnostics["facing"])
    assert np.dot(fwd, _rotz(yaw) @ [1, 0, 0]) > 0.95
    ch = out.diagnostics["chirality"]
    assert all(d["confidence"] > 0.5 for d in ch.values())
    # evaluation turns the side names back into gt's numbering (hand_1 = left)
    back = numbered(out, HUMAN)
    assert np.allclose(back.parts["hand_1"], parts["left_hand"])
    assert np.allclose(back.parts["foot_2"], parts["right_foot"])


def test_crossed_arms_still_sided_by_the_shoulders():
    rng = np.random.default_rng(9)
    parts, curves = _body(0.7, rng, arms_crossed=True)
    pose, _ = _numbered_frame("000000", parts, curves, True, False)
    out = assign_sides([pose], HUMAN, UP)[0]
    assert np.allclose(out.parts["left_hand"], parts["left_hand"])   # its hand is on the right


def test_unsure_frame_keeps_numbered_names_and_time_decides():
    rng = np.random.default_rng(4)
    parts, curves = _body(1.0, rng, knee=0.0, toe=0.0)            # feet end-on, knees straight
    weak, _ = _numbered_frame("000001", parts, curves, True, True)
    assert all(abs(s) < 0.3 for s in frame_scores(weak, HUMAN, UP).values())
    out = assign_sides([weak], HUMAN, UP)[0]
    assert "hand_1" in out.parts and "left_hand" not in out.parts
    assert out.diagnostics["chirality"]["hand_1"]["name"] == "hand_1"
    # with a confident frame of the same tracking segment, the weak frame is decided too
    parts2, curves2 = _body(1.0, rng)
    strong, _ = _numbered_frame("000000", parts2, curves2, True, True)
    for p in (strong, weak):
        p.diagnostics["track"] = {"hand": 0, "foot": 0}
    out2 = assign_sides([strong, weak], HUMAN, UP)
    assert np.allclose(out2[1].parts["left_hand"], parts["left_hand"])
    # without time, it stays unsure
    out3 = assign_sides([strong, weak], HUMAN, UP, use_time=False)
    assert "hand_1" in out3[1].parts


@pytest.mark.parametrize("seed", range(4))
def test_one_hand_found_is_named_by_its_side_of_the_trunk(seed):
    rng = np.random.default_rng(20 + seed)
    parts, curves = _body(rng.uniform(0, 2 * np.pi), rng)
    lost = ("left_hand", "right_hand")[seed % 2]             # merged with the body: not found
    parts[lost] = None
    del curves[lost]
    pose, m = _numbered_frame("000000", parts, curves, seed >= 2, False)
    out = assign_sides([pose], HUMAN, UP)[0]
    kept = "right_hand" if lost == "left_hand" else "left_hand"
    assert np.allclose(out.parts[kept], parts[kept])
    assert out.parts[lost] is None
    assert out.diagnostics["chirality"][m[kept]]["confidence"] > 0.5


def test_a_segment_whose_frames_disagree_does_not_decide_a_weak_frame():
    rng = np.random.default_rng(5)
    frames = []
    for i, swap in enumerate((True, True, True, False, False)):  # unrelated poses the tracker
        pr, cv = _body(1.0, rng)                                 # joined: sides disagree
        frames.append(_numbered_frame(f"{i:06d}", pr, cv, swap, swap)[0])
    pr, cv = _body(1.0, rng, knee=0.0, toe=0.0)
    frames.append(_numbered_frame("000005", pr, cv, True, True)[0])
    for p in frames:
        p.diagnostics["track"] = {"hand": 0, "foot": 0}
    out = assign_sides(frames, HUMAN, UP)
    assert "hand_1" in out[5].parts        # their sum is strong, yet: unsure, numbered names kept
    assert all("left_hand" in q.parts for q in out[:5])          # the strong ones decide alone


def test_dog_sides_from_its_axis():
    dog = load_model("dog")
    R = _rotz(2.0)
    W = lambda v: R @ np.asarray(v, float)                             # noqa: E731
    parts = {"head": W([0.5, 0, 0.6]), "shoulders": W([0.3, 0, 0.5]), "hips": W([-0.3, 0, 0.5]),
             "tail": W([-0.6, 0, 0.6]), "paw_1": W([0.3, -0.1, 0]), "paw_2": W([0.3, 0.1, 0]),
             "paw_3": W([-0.3, 0.1, 0]), "paw_4": W([-0.3, -0.1, 0])}
    out = assign_sides([Pose("0", "matched", 0.1, parts)], dog, UP)[0]
    assert np.allclose(out.parts["left_front_paw"], parts["paw_2"])
    assert np.allclose(out.parts["left_hind_paw"], parts["paw_3"])


def _true_joints(pose, tree):
    """Joints of the hand-made rigid body where the model declares them: at their fractions of
    the noise-free curves (exact: the curves are polylines), shoulders and hips moved by their
    offsets. The body is rigid, so these bone lengths are constant over the frames."""
    from topopose.sequence.kinematic_fit import initial_placement
    P = initial_placement(pose, tree)
    return {n: P[j] for j, n in enumerate(tree.names)}


def test_kinematic_tree_of_the_models():
    t = kinematic_tree(HUMAN)
    assert t.names[t.root] == "chest" and len(t.names) == 20
    assert t.names[t.parents[t.names.index("elbow_1")]] == "shoulder_1"
    assert t.names[t.parents[t.names.index("hip_2")]] == "pelvis"
    for name in ("dog", "spider"):
        kinematic_tree(load_model(name))                   # one tree each
    bad = HUMAN.to_dict()
    bad["joint"] = [{"name": "elbow", "arc": ["torso", "hand"], "at": 0.5}]
    with pytest.raises(InputError, match="trees"):
        kinematic_tree(model_from_dict(bad))
    bad["joint"] = [{"name": "elbow", "arc": ["head", "hand"], "at": 0.5}]
    with pytest.raises(InputError, match="not a model edge"):
        model_from_dict(bad)


def test_fit_constant_bone_lengths_recovers_joints_and_fills_gaps(monkeypatch):
    # the hand-made body's neck lies 0.45 × the shoulder width above them, not where the
    # girdle puts it (the rig's 0.1): each joint on its own target here
    opts = SequenceOptions().with_(girdle=False)
    # these curves run exactly through the tips' truth: no thinned branch end to correct
    opts = opts.with_(tip_turn={}, tip_stretch={})
    rng = np.random.default_rng(1)
    tree = kinematic_tree(HUMAN)
    poses, truth = [], []
    # one body, different facings and positions: bone lengths are constant
    for i in range(8):
        parts, curves = _body(0.3 * i, rng)
        pose, m = _numbered_frame(f"{i:06d}", parts, curves, False, False)
        noisy = {k: v + rng.normal(scale=0.003, size=v.shape) for k, v in
                 pose.diagnostics["curves"].items()}
        truth.append(_true_joints(pose, tree))
        pose.diagnostics["curves"] = noisy
        poses.append(pose)
    poses[3].status = "rejected"                            # a gap to fill
    out, tree, L = fit_sequence(poses, HUMAN, opts, max_gap=2)
    for i, p in enumerate(out):
        assert set(p.joints) == set(tree.names)
        for j, par in enumerate(tree.parents):
            if par >= 0:
                d = np.linalg.norm(p.joints[tree.names[j]] - p.joints[tree.names[par]])
                assert abs(d - L[j]) < 1e-9                  # exactly constant lengths
        err = max(np.linalg.norm(p.joints[k] - truth[i][k]) for k in tree.names)
        if i == 3:
            assert p.diagnostics.get("interpolated") is True
        else:
            assert "interpolated" not in p.diagnostics
            assert err < 0.02, (i, err)
    assert np.isnan(L[tree.root])
    # smoothing keeps the lengths
    out2, _, _ = fit_sequence(poses, HUMAN, opts, max_gap=2, smooth=5)
    assert all(p.diagnostics.get("smoothed") for p in out2)
    p = out2[5]
    j = tree.names.index("elbow_1")
    assert abs(np.linalg.norm(p.joints["elbow_1"] - p.joints["shoulder_1"]) - L[j]) < 1e-9


def test_process_sequence_names_joints_by_side():
    rng = np.random.default_rng(3)
    poses = []
    for i in range(5):
        parts, curves = _body(0.1 * i, rng)
        pose, _ = _numbered_frame(f"{i:06d}", parts, curves, i % 2 == 1, i % 3 == 1)
        poses.append(pose)
    mo = process_sequence(poses, HUMAN, UP)
    assert mo.stages == ["track", "skeleton", "sides"]
    for p in mo.poses:
        assert {"left_elbow", "right_knee", "left_hand", "right_foot"} <= set(p.joints) | set(p.parts)
        # the left elbow is on the left of the facing direction
        f = np.array(p.diagnostics["facing"])
        left = np.cross(UP, f)
        assert np.dot(p.joints["left_elbow"] - p.joints["right_elbow"], left) > 0.2


def test_tip_joint_lies_beyond_the_branch_end_along_its_last_direction():
    from topopose.sequence.kinematic_fit import TIP_DIRECTION, _along, kinematic_tree
    from topopose.pose.model import load_model as _load

    # an L-shaped curve: 1 m along x, then 0.2 m along z (the last 10 % points up)
    c = np.array([[0, 0, 0], [1.0, 0, 0], [1.0, 0, 0.2]])
    assert TIP_DIRECTION <= 0.2 / 1.2                   # the chord lies on the last leg
    assert np.allclose(_along(c, 1.0), [1.0, 0, 0.2])
    assert np.allclose(_along(c, 1.0, 0.1), [1.0, 0, 0.2 + 0.1 * 1.2])
    assert np.allclose(_along(c, 0.5), [0.6, 0, 0])
    tree = kinematic_tree(_load("human"))
    by = dict(zip(tree.names, tree.beyond))
    assert by["fingertip_1"] > 0 and by["toe_2"] > 0 and by["wrist_1"] == 0 and by["neck"] == 0


def test_frame_without_head_keeps_a_skeleton_with_held_joints(monkeypatch):
    """A frame whose head (part and curve) is missing: the root (chest, at the torso part) is
    still placed, the head's chain keeps the previous frame's directions (flagged), and every
    other joint is fitted as in the complete frame."""
    # the hand-made body's neck lies 0.45 × the shoulder width above them, not where the
    # girdle puts it (the rig's 0.1): each joint on its own target here
    opts = SequenceOptions().with_(girdle=False)
    rng = np.random.default_rng(5)
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.4, rng)
    full, _ = _numbered_frame("000000", parts, curves, False, False)
    cut, _ = _numbered_frame("000001", parts, curves, False, False)
    cut.parts["head"] = None
    del cut.diagnostics["curves"]["head"]
    out, tree, L = fit_sequence([full, cut], HUMAN, opts, max_gap=0)
    a, b = out
    assert set(b.joints) == set(tree.names) and "interpolated" not in b.diagnostics
    assert sorted(b.diagnostics["held_joints"]) == ["neck", "skull"]
    assert "held_joints" not in a.diagnostics
    assert np.linalg.norm(b.joints["chest"] - parts["torso"]) < 0.01   # root refined a little
    for k in tree.names:                       # the same body: the held joints too (the
        assert np.linalg.norm(b.joints[k] - a.joints[k]) < 1e-3, k   # root refined on fewer)
    # the lone frame has no earlier fit to hold from: no skeleton, not a wrong one
    alone, _, _ = fit_sequence([cut], HUMAN, opts)
    assert alone[0].joints == {}


@pytest.mark.parametrize("dt", [1, 3, 5, 6, 9])
def test_an_unseen_arm_is_held_from_the_last_fitted_frame_up_to_hold_frames_back(dt):
    """The same body (translated) ``dt`` frames after a whole frame, the frames between not
    matched, hand_2 not found: up to ``HOLD_FRAMES`` back (5: random motion) the
    unseen arm is the whole frame's arm, moved with the root (the truth: the same body, so
    every joint where the whole frame's fit put it, plus the translation); further back it
    takes the rest pose, its upper arm hanging along the trunk."""
    HOLD_FRAMES = SequenceOptions().gaps.hold_frames

    assert HOLD_FRAMES == 5
    rng = np.random.default_rng(3)
    parts, curves = _body(0.7, rng)
    shift = np.array([0.3, -0.2, 0.0])
    full, _ = _numbered_frame("000000", parts, curves, False, False)
    cut, _ = _numbered_frame(f"{dt:06d}", {k: v + shift for k, v in parts.items()},
                             {k: v + shift for k, v in curves.items()}, False, False)
    cut.parts["hand_2"] = None
    del cut.diagnostics["curves"]["hand_2"]
    out, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0)
    a, b = out
    assert "wrist_2" in b.diagnostics["held_joints"]
    arm = ("shoulder_2", "elbow_2", "wrist_2", "fingertip_2")
    off = [np.linalg.norm(b.joints[k] - (a.joints[k] + shift)) for k in arm]
    down = parts["crotch"] - parts["torso"]
    down /= np.linalg.norm(down)
    u = b.joints["elbow_2"] - b.joints["shoulder_2"]
    hangs = np.dot(u, down) / np.linalg.norm(u) > 0.999
    if dt <= 5:
        assert max(off) < 0.005, off          # (the root refined a little on fewer joints)
        assert not hangs
    else:
        assert max(off) > 0.05, off
        assert hangs


def test_an_arm_unseen_after_an_unrelated_frame_hangs_with_its_forearm_folded_forward(monkeypatch):
    """Not the frame before (a capture of unrelated poses): no earlier arm to hold; the unseen
    arm's shoulder is opposite its mate across the trunk, raised ``HELD_SHOULDER`` from the
    plane across it (:func:`test_an_unseen_shoulder_is_not_raised_with_its_raised_mate`), the
    upper arm hangs along the trunk, the forearm and hand fold up by
    ``FOLD`` from hanging, towards the front turned ``ACROSS`` the body (the toes' direction
    across the trunk; the toes of _body point 0.2 m forward, the ankle is 5 cm above them, so
    within 20°; across: towards the other shoulder); the frame right after a frame of the
    same body holds that frame's arm instead."""
    from topopose.sequence import kinematic_fit as kf
    # the hand-made body's neck lies 0.45 × the shoulder width above them, not where the
    # girdle puts it (the rig's 0.1): each joint on its own target here
    opts = SequenceOptions().with_(girdle=False)
    from topopose.sequence.kinematic_fit import ACROSS, FOLD
    HELD_SHOULDER = kf.GAPS.held_shoulder

    full, cut, parts2, m = _hand_2_unseen(0.9, 8)          # the right hand: not found
    out, tree, L = fit_sequence([full, cut], HUMAN, opts, max_gap=0)
    b = out[1]
    assert sorted(b.diagnostics["held_joints"]) == ["elbow_2", "fingertip_2", "shoulder_2",
                                                    "wrist_2"]
    down = parts2["crotch"] - parts2["torso"]
    down /= np.linalg.norm(down)
    # the shoulder: opposite its mate across the trunk, raised HELD_SHOULDER from the plane
    # across it, at its bone length from the chest
    s1, s2 = (b.joints[k] - b.joints["chest"] for k in ("shoulder_1", "shoulder_2"))
    k2 = tree.names.index("shoulder_2")
    assert abs(np.linalg.norm(s2) - L[k2]) < 1e-9
    assert abs(np.dot(s2, -down) / L[k2] - np.sin(HELD_SHOULDER)) < 1e-3
    h1, h2 = (v - np.dot(v, down) * down for v in (s1, s2))
    assert np.dot(h1, h2) / np.linalg.norm(h1) / np.linalg.norm(h2) < -0.9999
    forward = _rotz(0.9) @ [1.0, 0.0, 0.0]               # the body's facing (its toes)
    d = b.joints["elbow_2"] - b.joints["shoulder_2"]     # the upper arm hangs
    assert np.dot(d, down) / np.linalg.norm(d) > 0.999
    inward = b.joints["shoulder_1"] - b.joints["shoulder_2"]
    inward -= np.dot(inward, down) * down
    inward /= np.linalg.norm(inward)
    front = np.cos(ACROSS) * forward - np.sin(ACROSS) * np.cross(down, forward) * np.sign(
        np.dot(np.cross(down, forward), -inward))      # forward turned across, towards inward
    for a, c in (("elbow_2", "wrist_2"), ("wrist_2", "fingertip_2")):   # folded up and across
        d = b.joints[c] - b.joints[a]
        d /= np.linalg.norm(d)
        assert abs(np.dot(d, -down) + np.cos(FOLD)) < 1e-6, d          # exactly FOLD from down
        h = d - np.dot(d, down) * down                                  # across the trunk:
        h /= np.linalg.norm(h)
        assert np.dot(h, front) > np.cos(np.radians(20)), (h, front)    # the turned front
        assert np.dot(h, inward) > np.sin(ACROSS) - 0.35, (h, inward)   # towards the other side
    # the frame right after the same body: the arm of that frame, not the rest pose
    cut.frame = "000001"
    out, tree, L = fit_sequence([full, cut], HUMAN, opts, max_gap=0)
    rel = [q.joints["wrist_2"] - q.joints["chest"] for q in out]
    assert np.linalg.norm(rel[1] - rel[0]) < 0.02


def _crossed_legs_sequence(n, rng):
    """n frames of one tracked body (same segment); in the middle frame the legs cross (each
    leg's curve on the other side: its own score is strong and wrong)."""
    poses, truth = [], []
    for i in range(n):
        parts, curves = _body(0.2, rng)
        if i == n // 2:
            curves["left_foot"], curves["right_foot"] = curves["right_foot"], curves["left_foot"]
        pose, _ = _numbered_frame(f"{i:06d}", parts, curves, False, False)
        pose.diagnostics["track"] = {"hand": 0, "foot": 0}
        poses.append(pose)
        truth.append(parts)
    return poses, truth


def test_a_long_tracked_segment_overrules_one_frame_with_crossed_legs():
    from topopose.sequence.chirality import SIDES
    COHERENT, OVERRULE_MIN = SIDES.coherent, SIDES.overrule_min
    rng = np.random.default_rng(2)
    n = max(OVERRULE_MIN + 1, int(np.ceil(2 / (1 - COHERENT))) + 1)   # coherent despite one
    poses, truth = _crossed_legs_sequence(n, rng)
    k = len(poses) // 2
    assert frame_scores(poses[k], HUMAN, UP)[1] <= -0.5          # strong, wrong
    out = assign_sides(poses, HUMAN, UP)
    for p, parts in zip(out, truth):
        assert np.allclose(p.parts["left_foot"], parts["left_foot"])
    # a short segment (captures of unrelated poses) does not overrule a strong frame
    short, t2 = _crossed_legs_sequence(OVERRULE_MIN, rng)
    out = assign_sides(short, HUMAN, UP)
    assert np.allclose(out[len(short) // 2].parts["left_foot"], t2[len(short) // 2]["right_foot"])
    # without time, the single frame decides alone
    out = assign_sides(poses, HUMAN, UP, use_time=False)
    assert np.allclose(out[k].parts["left_foot"], truth[k]["right_foot"])


def test_chain_fit_finds_the_elbow_at_the_corner_of_a_bent_arm_curve(monkeypatch):
    """Oracle: an arm curve bent 90° at a known elbow, true bone lengths, no placement target
    for the elbow and wrist: the chain's elbow lands on the curve's corner (the relative arc
    length alone, the initial placement without ``BEND``, misses it by several cm)."""
    from topopose.sequence.kinematic_fit import bone_lengths, fit_frame, initial_placement

    opts = SequenceOptions().with_(bend=None)
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.0, np.random.default_rng(3))
    torso = parts["torso"]
    S = torso + [0.0, 0.2, 0.05]
    E = S + [0.0, 0.03, -0.27]                      # upper arm down, forearm forward
    W = E + [0.26, 0.0, 0.0]
    H = W + [0.08, 0.0, 0.0]
    parts["left_hand"], curves["left_hand"] = H, resample([torso, S, E, W, H], 64)
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    P0 = initial_placement(pose, tree, fit=opts.skeleton_fit)
    L = bone_lengths(P0[None], tree, fit=opts.skeleton_fit)
    el, wr = tree.names.index("elbow_1"), tree.names.index("wrist_1")
    sh, tip = tree.names.index("shoulder_1"), tree.names.index("fingertip_1")
    L[el], L[wr] = np.linalg.norm(E - P0[sh]), np.linalg.norm(W - E)
    L[tip] = np.linalg.norm(P0[tip] - W)
    target = P0.copy()
    target[[el, wr]] = np.nan
    P, rms = fit_frame(target, pose.diagnostics["curves"], L, tree, root_steps=0)
    assert np.linalg.norm(P0[el] - E) > 0.04         # the placement misses the corner
    assert np.linalg.norm(P[el] - E) < 0.02, np.linalg.norm(P[el] - E)
    assert np.linalg.norm(P[wr] - W) < 0.03, np.linalg.norm(P[wr] - W)
    # the wrong bone lengths (the upper arm 20 % short, as the placements give) miss it
    L[el] *= 0.8
    Pb, _ = fit_frame(target, pose.diagnostics["curves"], L, tree, root_steps=0)
    assert np.linalg.norm(Pb[el] - E) > np.linalg.norm(P[el] - E) + 0.02


def test_bone_lengths_quantile_recovers_a_chain_shortened_in_some_frames():
    """A chain of known lengths whose placement shortens some frames' bones (a curve cut short
    at a junction): the 70th percentile gives the true lengths, the median does not."""
    from topopose.sequence.kinematic_fit import bone_lengths

    rng = np.random.default_rng(3)
    tree = kinematic_tree(HUMAN)
    order = tree.order()
    true_L = rng.uniform(0.1, 0.4, len(tree.names))
    n = 40
    init = np.zeros((n, len(tree.names), 3))
    short = np.zeros(n, dtype=bool)
    short[rng.permutation(n)[:int(0.55 * n)]] = True       # 55 % of the frames cut short
    for f in range(n):
        init[f, tree.root] = rng.normal(size=3)
        for j in order[1:]:
            d = rng.normal(size=3)
            k = rng.uniform(0.6, 0.9) if short[f] else 1.0
            init[f, j] = init[f, tree.parents[j]] + k * true_L[j] * d / np.linalg.norm(d)
    L = bone_lengths(init, tree)                           # 70th percentile (the default)
    med = bone_lengths(init, tree, quantile=50)
    # mirror bones pool their samples: the true length is shared by construction only when
    # the mates' lengths agree, so compare the unpaired bones and each pair's mean
    for j, p in enumerate(tree.parents):
        if p < 0:
            continue
        mates = [k for k in range(len(tree.names)) if tree.base[k] == tree.base[j]
                 and tree.base[tree.parents[k]] == tree.base[p]]
        if len(mates) == 1 and tree.slide[j]:       # the neck: at its median (SLIDE_QUANTILE)
            assert abs(L[j] - med[j]) < 1e-12 and med[j] < 0.95 * true_L[j]
        elif len(mates) == 1:
            assert abs(L[j] - true_L[j]) < 1e-9
            assert med[j] < 0.95 * true_L[j]


def test_hips_from_the_junction_by_hull_radius_and_spine_shift():
    """Hips with a ``width``: at the legs' junction moved along the trunk and outward by width ×
    the hull radius (the spine shift's length), then back with the trunk; the trunk's curves
    move back by SPINE_BACK × the spine shift, the limbs' curves do not. A hanging leg (this
    standing body's) takes HANGING_WIDTH, a raised one the model's ``width``."""
    from topopose.sequence import kinematic_fit as kf
    HANGING_WIDTH, SPINE_BACK = kf.FIT.hanging_width, kf.FIT.spine
    from topopose.sequence.kinematic_fit import (frame_curves,
                                             initial_placement)

    rng = np.random.default_rng(4)
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.7, rng)
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    R = _rotz(0.7)
    back = -R[:, 0]                                        # the body faces R @ x
    r = 0.14
    pose.diagnostics["spine_shift"] = list(r * back)
    c = frame_curves(pose, tree)
    assert np.allclose(c["head"], np.asarray(curves["head"]) + SPINE_BACK * r * back)
    assert np.allclose(c["hand_1"], curves["left_hand"])
    P = initial_placement(pose, tree)
    w_al, w_out = HANGING_WIDTH
    assert w_out > 0 and HANGING_WIDTH != next(j.width for j in HUMAN.joints if j.name == "hip")
    ax = parts["torso"] - parts["crotch"]
    ax /= np.linalg.norm(ax)
    for k, sg in (("1", 1.0), ("2", -1.0)):               # foot_1 is the left one here
        left = R @ np.array([0.0, 1.0, 0.0])
        want = (parts["crotch"] + w_al * r * ax + sg * w_out * r * left
                + SPINE_BACK * r * back)
        assert np.allclose(P[tree.names.index("hip_" + k)], want, atol=1e-9)
    # twice the radius: twice as far beside the junction (girth, not trunk length)
    P2 = initial_placement(pose, tree, radius=2 * r)
    h = tree.names.index("hip_1")
    assert np.allclose(P2[h] - P[h], w_al * r * ax + w_out * r * (R @ [0.0, 1.0, 0.0]))
    # no spine shift, no radius: the offset along the leg's curve, no move back
    pose.diagnostics["spine_shift"] = None
    P0 = initial_placement(pose, tree)
    assert np.allclose(frame_curves(pose, tree)["head"], curves["head"])
    assert not np.allclose(P0[h], P[h] - SPINE_BACK * r * back)


def test_a_raised_leg_hip_takes_the_model_width_a_hanging_one_the_hanging_width():
    """One leg raised forward to the horizontal (its curve 90° from straight down), the other
    hanging: the raised leg's hip sits by the model's ``width``, the hanging one's by
    HANGING_WIDTH; with HANGING_WIDTH off (None) both take the model's."""
    from topopose.sequence import kinematic_fit as kf
    rng = np.random.default_rng(5)
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.0, rng)
    cr = parts["crotch"]
    for side, sg in (("left", 1.0),):                    # the left leg raised forward
        pts = [cr, cr + [0.05, sg * 0.1, -0.05], cr + [0.45, sg * 0.1, -0.05],
               cr + [0.85, sg * 0.1, -0.05]]
        curves[f"{side}_foot"] = resample(pts, 64)
        parts[f"{side}_foot"] = pts[-1]
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    r = 0.14
    pose.diagnostics["spine_shift"] = [-r, 0.0, 0.0]    # the body faces +x: back is -x
    ax = np.array([0.0, 0.0, 1.0])
    model_w = next(j.width for j in HUMAN.joints if j.name == "hip")
    legs = SequenceOptions.of(hip_feet=False).skeleton_fit    # outward: the curve points alone
    P = kf.initial_placement(pose, tree, spine=0.0, fit=legs)
    on = {k: kf._along(np.asarray(curves[s + "_foot"], float), 0.11)    # the hips' at on
          for k, s in (("1", "left"), ("2", "right"))}                  # their curves
    for k, m in (("1", "2"), ("2", "1")):
        x = P[tree.names.index("hip_" + k)]
        w_al, w_out = model_w if k == "1" else kf.FIT.hanging_width
        lat = (on[k] - on[m]) * [1.0, 1.0, 0.0]                        # outward: across the trunk
        want = cr + w_al * r * ax + w_out * r * lat / np.linalg.norm(lat)
        assert np.allclose(x, want, atol=1e-9), (k, x - want)
    P1 = kf.initial_placement(pose, tree, spine=0.0,
                              fit=SequenceOptions.of(hanging_width=None,
                                                     hip_feet=False).skeleton_fit)
    lat = (on["2"] - on["1"]) * [1.0, 1.0, 0.0]
    assert np.allclose(P1[tree.names.index("hip_2")],
                       cr + model_w[0] * r * ax + model_w[1] * r * lat / np.linalg.norm(lat))


def test_hip_line_turns_half_way_to_the_side_the_feet_tell():
    """A leg lifted forward turns the line between the legs' curve points (the hips' outward
    direction from the mate's curve point) away from the pelvis's left–right line (this
    body's: +y, facing +x); the front the feet tell (the spine shift) does not turn with it.
    With ``SkeletonFitOptions.hip_feet`` (the default) the hips' line lies half as far from
    the true left–right line about the vertical, each hip on its own side; both legs hanging,
    the two directions agree and the hips do not move."""
    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    h1, h2 = tree.names.index("hip_1"), tree.names.index("hip_2")
    legs = SequenceOptions.of(hip_feet=False).skeleton_fit

    def yaw(P):                                 # degrees between the hip line and +y, about z
        d = P[h1] - P[h2]
        return float(np.degrees(np.arctan2(abs(d[0]), d[1])))

    parts, curves = _body(0.0, np.random.default_rng(5))
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    pose.diagnostics["spine_shift"] = [-0.14, 0.0, 0.0]   # the body faces +x: back is -x
    P0, P1 = (kf.initial_placement(pose, tree, spine=0.0, fit=f) for f in (legs, kf.FIT))
    assert yaw(P0) < 1.0 and np.allclose(P1[[h1, h2]], P0[[h1, h2]], atol=1e-9)
    cr = parts["crotch"]                        # the left leg lifted forward
    pts = [cr, cr + [0.05, 0.1, -0.05], cr + [0.45, 0.1, -0.05], cr + [0.85, 0.1, -0.05]]
    curves["left_foot"], parts["left_foot"] = resample(pts, 64), pts[-1]
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    pose.diagnostics["spine_shift"] = [-0.14, 0.0, 0.0]
    P0, P1 = (kf.initial_placement(pose, tree, spine=0.0, fit=f) for f in (legs, kf.FIT))
    assert yaw(P0) > 10.0                        # the curve points' line turned with the leg
    assert abs(yaw(P1) - 0.5 * yaw(P0)) < 0.5
    assert P1[h1][1] > cr[1] > P1[h2][1]        # hip_1 (the left foot's) on the left


def test_joint_width_field_round_trips_and_is_checked():
    d = HUMAN.to_dict()
    m = model_from_dict(d)
    assert next(j.width for j in m.joints if j.name == "hip") == \
        next(j.width for j in HUMAN.joints if j.name == "hip")
    d["joint"] = [dict(j) for j in d["joint"]]
    next(j for j in d["joint"] if j["name"] == "hip")["width"] = [0.1]
    with pytest.raises(InputError, match="width"):
        model_from_dict(d)


def test_joint_extends_field_round_trips_and_is_checked():
    """The human body goes on past its skull and ankles (the tracked body's capsules there)."""
    tree = kinematic_tree(model_from_dict(HUMAN.to_dict()))
    assert sorted(n for n, e in zip(tree.names, tree.extends) if e) == \
        ["ankle_1", "ankle_2", "skull"]
    d = HUMAN.to_dict()
    d["joint"] = [dict(j) for j in d["joint"]]
    next(j for j in d["joint"] if j["name"] == "knee")["extends"] = 1
    with pytest.raises(InputError, match="extends"):
        model_from_dict(d)


def test_raised_arm_joints_at_their_raised_fraction():
    """A hand above the chest junction (along the trunk): the elbow and wrist at their
    ``at_raised`` of the arm's curve; a hand below it: at their ``at``."""
    from topopose.sequence.kinematic_fit import _along, initial_placement

    rng = np.random.default_rng(5)
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.2, rng)
    R = _rotz(0.2)
    sh = parts["torso"] + R @ [0.0, 0.2, 0.05]
    up_hand = parts["torso"] + R @ [0.1, 0.35, 0.6]        # the left hand raised
    parts["left_hand"] = up_hand
    curves["left_hand"] = resample([parts["torso"], sh, up_hand], 64)
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    P = initial_placement(pose, tree)
    spec = {j.name: j for j in HUMAN.joints}
    for name in ("elbow", "wrist"):
        assert spec[name].at_raised is not None and spec[name].at_raised != spec[name].at
        up = P[tree.names.index(name + "_1")]
        down = P[tree.names.index(name + "_2")]
        assert np.allclose(up, _along(curves["left_hand"], spec[name].at_raised))
        assert np.allclose(down, _along(curves["right_hand"], spec[name].at))
    d = HUMAN.to_dict()
    d["joint"] = [dict(j) for j in d["joint"]]
    next(j for j in d["joint"] if j["name"] == "elbow")["at_raised"] = 1.5
    with pytest.raises(InputError, match="at_raised"):
        model_from_dict(d)


def test_neck_slides_with_the_chest_junction(monkeypatch):
    """The chest (the curves' junction, the tree's root) slides along the spine from frame to
    frame while the neck and head stay: with the neck's bone ``slide`` (its frame's length) the
    fitted neck is its placement on the curve; with every bone constant (``slide=False``) the
    neck keeps a fixed distance from the moving junction and leaves it (the truth: the neck's
    placement on the frame's curve, which runs through the true neck)."""
    # the hand-made body's neck lies 0.45 × the shoulder width above them, not where the
    # girdle puts it (the rig's 0.1): each joint on its own target here
    opts = SequenceOptions().with_(girdle=False)
    from topopose.sequence.kinematic_fit import frame_lengths, initial_placement

    rng = np.random.default_rng(5)
    tree = kinematic_tree(HUMAN)
    assert [tree.names[j] for j in range(len(tree.names)) if tree.slide[j]] == ["neck"]
    poses = []
    for i, dz in enumerate([0.0, 0.08, -0.06, 0.12, 0.02, -0.04]):
        parts, curves = _body(0.0, np.random.default_rng(7))     # one body, one place
        neck_true = parts["torso"] + 0.58 * (parts["head"] - parts["torso"])
        parts["torso"] = parts["torso"] + [0, 0, dz]              # the junction slides
        # the head's curve: junction → true neck → head (the neck half-way up the curve)
        head = resample([parts["torso"], neck_true, parts["head"]])
        curves = {k: (head if k == "head" else resample(np.vstack([parts["torso"], c[1:]])))
                  for k, c in curves.items()}
        pose, _ = _numbered_frame(f"{i:06d}", parts, curves, False, False)
        pose.diagnostics["curves"] = {k: v + rng.normal(scale=0.002, size=v.shape)
                                      for k, v in pose.diagnostics["curves"].items()}
        poses.append(pose)
    k = tree.names.index("neck")
    out, _, L = fit_sequence(poses, HUMAN, opts, max_gap=0, slide=True)
    median, _, _ = fit_sequence(poses, HUMAN, opts, max_gap=0)     # constant, at its median length
    opts = opts.with_(slide_quantile=None)              # at the limbs' 70th percentile
    fixed, _, L = fit_sequence(poses, HUMAN, opts, max_gap=0)
    err_median = [np.linalg.norm(q.joints["neck"] - initial_placement(q, tree, fit=opts.skeleton_fit)[k])
                  for q in median]
    err_slide, err_fixed = [], []
    for p, q in zip(out, fixed):
        P0 = initial_placement(p, tree, fit=opts.skeleton_fit)
        Lf = frame_lengths(P0, L, tree, slide=True, fit=opts.skeleton_fit)
        assert abs(Lf[k] - np.linalg.norm(P0[k] - P0[tree.root])) < 1e-12
        assert abs(np.linalg.norm(p.joints["neck"] - p.joints["chest"]) - Lf[k]) < 1e-9
        err_slide.append(np.linalg.norm(p.joints["neck"] - P0[k]))
        err_fixed.append(np.linalg.norm(q.joints["neck"] - P0[k]))
        assert abs(np.linalg.norm(q.joints["neck"] - q.joints["chest"]) - L[k]) < 1e-9
    # the slide fit's remaining error: the root refined by the other joints (ROOT_STEPS)
    assert max(err_slide) < 0.025, err_slide
    assert max(err_fixed) > 0.05 and np.mean(err_fixed) > 2 * np.mean(err_slide), err_fixed
    assert np.mean(err_median) < np.mean(err_fixed) - 0.005, (err_median, err_fixed)


def test_joint_slide_field_round_trips_and_is_checked():
    d = HUMAN.to_dict()
    assert [j["name"] for j in d["joint"] if j.get("slide")] == ["neck"]
    assert [j.name for j in model_from_dict(d).joints if j.slide] == ["neck"]
    d["joint"] = [dict(j) for j in d["joint"]]
    next(j for j in d["joint"] if j["name"] == "neck")["slide"] = "yes"
    with pytest.raises(InputError, match="slide"):
        model_from_dict(d)


@pytest.mark.parametrize("yaw", [0.4, 2.5])
def test_an_unseen_arm_with_a_hand_hint_reaches_the_hint_end_with_its_wrist(yaw):
    """A hand the per-frame stage left unplaced, its branch kept as a hint
    (``diagnostics["hand_hints"]``, the per-frame stage's hint ends near the wrist:
    measured on the body subject): the fit bends the unseen arm to reach the hint's end — wrist at
    the end (here 0.8 × the arm's length from the shoulder, towards the true hand), the elbow a
    bone length from both, bent the way the rest pose bends (down, its upper arm hangs), bone
    lengths kept; an end beyond reach: the arm straight towards it. Without the hint
    (``hints=False``) the rest pose folds the arm far away."""
    full, cut, parts2, _ = _hand_2_unseen(yaw, 3)
    off, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0, hints=False)
    S = off[1].joints["shoulder_2"]                   # the hint does not move the shoulder
    a, b = L[tree.names.index("elbow_2")], L[tree.names.index("wrist_2")]
    u = parts2["hand_2" if "hand_2" in parts2 else "right_hand"] - S
    u /= np.linalg.norm(u)
    down = parts2["crotch"] - parts2["torso"]
    down /= np.linalg.norm(down)
    for k, straight in ((0.8, False), (1.3, True)):
        end = S + k * (a + b) * u
        cut.diagnostics["hand_hints"] = {"hand_2": resample([parts2["torso"], end], 32)}
        out, tree, L = fit_sequence([full, cut], HUMAN, max_gap=0)
        J = out[1].joints
        assert "wrist_2" in out[1].diagnostics["held_joints"]
        for j, n in enumerate(tree.names):                      # lengths constant
            if tree.parents[j] >= 0:
                assert abs(np.linalg.norm(J[n] - J[tree.names[tree.parents[j]]]) - L[j]) < 1e-6
        assert np.linalg.norm(J["shoulder_2"] - S) < 1e-9
        if straight:
            assert np.linalg.norm(J["wrist_2"] - (S + (a + b) * u)) < 0.01
        else:      # (bone directions as hint_fill set them; the fit's root steps move 2 mm)
            assert np.linalg.norm(J["wrist_2"] - end) < 0.01
            mid = S + np.dot(J["elbow_2"] - S, u) * u
            n = down - np.dot(down, u) * u                # bent as the hanging upper arm:
            e = J["elbow_2"] - mid                        # towards down, across the arm
            assert np.dot(e, n) / np.linalg.norm(e) / np.linalg.norm(n) > 0.99
        assert np.linalg.norm(off[1].joints["wrist_2"] - end) > 0.15
        assert np.linalg.norm(J["wrist_1"] - off[1].joints["wrist_1"]) < 1e-9   # seen arm


def test_neck_bone_at_its_median_follows_a_junction_sliding_both_ways(monkeypatch):
    """The chest junction slides up and down the spine around the true chest (raised arms pull
    it up, the trunk's curves cut it down) while the neck stays: the chest → neck distance
    scatters symmetrically about the true length, and no curve cuts it short. The neck's bone
    at its median length (``SLIDE_QUANTILE``) is the true length and the fitted neck stays
    nearer the true neck than with the limbs' 70th percentile, which is too long."""
    # the hand-made body's neck lies 0.45 × the shoulder width above them, not where the
    # girdle puts it (the rig's 0.1): each joint on its own target here
    opts = SequenceOptions().with_(girdle=False)

    tree = kinematic_tree(HUMAN)
    k = tree.names.index("neck")
    rng = np.random.default_rng(11)
    poses, truth = [], []
    dzs = np.concatenate([[0.0], rng.uniform(-0.08, 0.08, 20)])
    dzs = np.concatenate([dzs, -dzs[1:]])                 # symmetric: the median is 0
    for i, dz in enumerate(dzs):
        parts, curves = _body(0.3, np.random.default_rng(7))
        neck_true = parts["torso"] + 0.58 * (parts["head"] - parts["torso"])
        parts["torso"] = parts["torso"] + [0, 0, dz]
        head = resample([parts["torso"], neck_true, parts["head"]])
        curves = {c: (head if c == "head" else resample(np.vstack([parts["torso"], v[1:]])))
                  for c, v in curves.items()}
        pose, _ = _numbered_frame(f"{i:06d}", parts, curves, False, False)
        poses.append(pose)
        truth.append(neck_true)
    true_len = np.linalg.norm(truth[0] - (_body(0.3, np.random.default_rng(7))[0]["torso"]))

    def neck_error():
        out, _, L = fit_sequence(poses, HUMAN, opts, max_gap=0)
        return L[k], np.mean([np.linalg.norm(p.joints["neck"] - t) for p, t in zip(out, truth)])

    L50, e50 = neck_error()
    opts = opts.with_(slide_quantile=None)
    L70, e70 = neck_error()
    assert abs(L50 - true_len) < 0.005, (L50, true_len)
    assert L70 > true_len + 0.01
    assert e50 < e70 - 0.003, (e50, e70)


def test_an_unseen_shoulder_is_not_raised_with_its_raised_mate(monkeypatch):
    """One arm raised above the head (its shoulder's placement on the curve pulled up), the
    other not found: the unseen shoulder is placed opposite its mate, ``HELD_SHOULDER`` above
    the plane across the trunk — near the body's hanging shoulder (the same body with both arms
    hanging, fitted) — where the mate's half turn (``HELD_SHOULDER = None``) copies the raised
    shoulder's height."""
    def frames(raise_left):
        parts, curves = _body(1.2, np.random.default_rng(4))
        torso = parts["torso"]
        if raise_left:                  # the left arm straight up: its curve up from the chest
            up = parts["head"] - torso
            up /= np.linalg.norm(up)
            side = parts["left_hand"] - parts["right_hand"]
            side -= np.dot(side, up) * up
            side /= np.linalg.norm(side)
            hand = torso + 0.15 * side + 0.75 * up
            parts["left_hand"] = hand
            curves["left_hand"] = resample([torso, torso + 0.12 * side + 0.12 * up, hand], 64)
        return parts, curves

    parts, curves = frames(False)
    ref, _ = _numbered_frame("000000", parts, curves, False, False)
    parts2, curves2 = frames(True)
    cut, m = _numbered_frame("000009", parts2, curves2, False, False)
    cut.parts[m["right_hand"]] = None
    del cut.diagnostics["curves"][m["right_hand"]]
    k = "shoulder_" + m["right_hand"][-1]
    out, tree, _ = fit_sequence([ref, cut], HUMAN, max_gap=0)
    truth = out[0].joints[k]                 # the same body, both arms hanging, seen
    new = np.linalg.norm(out[1].joints[k] - truth)
    opts = SequenceOptions().with_(held_shoulder=None)
    out0, _, _ = fit_sequence([ref, cut], HUMAN, opts, max_gap=0)
    old = np.linalg.norm(out0[1].joints[k] - truth)
    assert new < 0.03 and old > new + 0.03, (new, old)


def _raised_left_frame():
    """A numbered frame of :func:`_body` (seed 2) with the left hand raised above the chest
    junction; returns the pose, the side → numbered part map and (torso, crotch, trunk axis)."""
    parts, curves = _body(0.7, np.random.default_rng(2))
    torso, crotch = parts["torso"], parts["crotch"]
    ax = (torso - crotch) / np.linalg.norm(torso - crotch)
    parts["left_hand"] = torso + 0.6 * ax + np.array([0.05, 0.1, 0.0])      # raised
    curves["left_hand"] = resample([torso, torso + 0.15 * ax + [0.0, 0.12, 0.0],
                                    parts["left_hand"]], 64)
    pose, m = _numbered_frame("000000", parts, curves, False, False)
    return pose, m, (torso, crotch, ax)


def test_a_raised_arms_shoulder_moves_down_the_trunk(monkeypatch):
    """``RAISED_SHOULDER``: the shoulder of an arm whose hand lies above the chest junction
    (along the trunk crotch → torso) moves down the trunk by that many trunk lengths, exactly;
    a hanging arm's shoulder, the hips and every other joint stay where they were."""
    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    pose, m, (torso, crotch, ax) = _raised_left_frame()
    P, drop = kf.initial_placement(pose, tree), kf.FIT.raised_shoulder
    assert drop > 0
    opts = SequenceOptions().with_(raised_shoulder=None)
    P0 = kf.initial_placement(pose, tree, fit=opts.skeleton_fit)
    S = np.linalg.norm(torso - crotch)
    up = "shoulder_" + m["left_hand"][-1]
    for j, n in enumerate(tree.names):
        want = P0[j] - (drop * S * ax if n == up else 0.0)
        assert np.allclose(P[j], want, atol=1e-12), n


def _bent_arm_pose(seed=3):
    """``_body`` with its left arm's curve bent 90° at a known elbow E (upper arm down, forearm
    forward); returns (pose, E, W: the wrist)."""
    parts, curves = _body(0.0, np.random.default_rng(seed))
    torso = parts["torso"]
    S = torso + [0.0, 0.2, 0.05]
    E = S + [0.0, 0.03, -0.27]
    W = E + [0.26, 0.0, 0.0]
    H = W + [0.08, 0.0, 0.0]
    parts["left_hand"], curves["left_hand"] = H, resample([torso, S, E, W, H], 64)
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    return pose, E, W


def parts_of(pose, name):
    return np.asarray(pose.parts[name], float)


def test_a_bent_limbs_middle_joint_is_placed_at_its_curves_bend(monkeypatch):
    """Oracle: an arm curve bent 90° at a known elbow. With ``BEND`` on (``BEND_DEPTH``; off by
    default) the initial placement puts
    the elbow on the corner (within a curve sample) and the ankles on the heel's corner (the
    foot turns forward); at their relative arc lengths alone they are off. The knees, bent by
    0.08 m over a 0.8 m chord (depth 0.1 < ``BEND``), the wrists and the straight right arm
    keep their ``at``; a deeper knee bend takes the knee nearer its corner."""
    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    pose, E, _ = _bent_arm_pose()
    el = tree.names.index("elbow_1")
    assert kf.FIT.bend is None                       # off by default
    opts = SequenceOptions().with_(bend=kf.BEND_DEPTH)
    P = kf.initial_placement(pose, tree, fit=opts.skeleton_fit)
    opts = opts.with_(bend=None)
    P0 = kf.initial_placement(pose, tree, fit=opts.skeleton_fit)
    assert np.linalg.norm(P[el] - E) < 0.015, np.linalg.norm(P[el] - E)
    assert np.linalg.norm(P0[el] - E) > 0.04
    changed = {tree.names[j] for j in range(len(tree.names)) if not np.allclose(P[j], P0[j])}
    assert changed == {"elbow_1", "ankle_1", "ankle_2"}, changed
    # the ankle, between knee and toe, at the heel's corner (the foot turns forward there)
    for k, sg in (("1", 1.0), ("2", -1.0)):            # hand_1/foot_1 are the left ones
        ankle = parts_of(pose, "crotch") + np.array([0.0, sg * 0.1, -0.85])
        a = tree.names.index(f"ankle_{k}")
        c = np.asarray(pose.diagnostics["curves"][f"foot_{k}"])
        step = np.linalg.norm(np.diff(c, axis=0), axis=1).max()      # one curve sample
        assert np.linalg.norm(P[a] - ankle) < step < np.linalg.norm(P0[a] - ankle), step
    # a deeper knee bend (0.3 m over the 0.8 m chord) moves the knee nearer its corner
    parts, curves = _body(0.0, np.random.default_rng(3), knee=0.3)
    pose2, _ = _numbered_frame("000000", parts, curves, False, False)
    knee = parts["crotch"] + np.array([0.3, 0.1, -0.45])     # W([knee, 0.1, 0.5]), yaw 0
    opts = opts.with_(bend=kf.BEND_DEPTH)
    k = tree.names.index("knee_1")
    e = np.linalg.norm(kf.initial_placement(pose2, tree, fit=opts.skeleton_fit)[k] - knee)
    opts = opts.with_(bend=None)
    e0 = np.linalg.norm(kf.initial_placement(pose2, tree, fit=opts.skeleton_fit)[k] - knee)
    assert e < e0 - 0.01, (e, e0)


def test_shoulder_bone_at_its_median_as_the_junction_slides(monkeypatch):
    """The chest junction slides along the trunk around the true chest while the shoulders
    stay (a raised arm pulls it up, the curves cut it down): the junction → shoulder distance
    scatters about the true length and no corner cuts it short. At ``SHOULDER_QUANTILE`` (the
    median) the shoulder's bone is nearer the true length than at the limbs' 70th
    percentile, the other bones keep theirs."""
    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    rng = np.random.default_rng(5)
    parts, curves = _body(0.0, np.random.default_rng(7))
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    base = kf.initial_placement(pose, tree)
    sh = [j for j in range(len(tree.names)) if tree.base[j] == "shoulder"]
    true_len = np.linalg.norm(base[sh[0]] - base[tree.root])
    dz = rng.uniform(-0.08, 0.08, 30)
    init = np.repeat(base[None], 2 * len(dz), axis=0)
    init[:, tree.root, 2] += np.concatenate([dz, -dz])
    L = kf.bone_lengths(init, tree)
    opts = SequenceOptions().with_(shoulder_quantile=None)
    L70 = kf.bone_lengths(init, tree, fit=opts.skeleton_fit)
    assert abs(L[sh[0]] - true_len) < abs(L70[sh[0]] - true_len) - 0.003, (L[sh[0]], L70[sh[0]])
    assert abs(L[sh[0]] - L[sh[1]]) < 1e-12
    others = [j for j in range(len(tree.names)) if tree.parents[j] >= 0 and j not in sh]
    assert np.allclose(L[others], L70[others])


def test_leg_bones_at_the_limb_quantile_arm_bones_at_the_bone_quantile(monkeypatch):
    """Every bone cut short (×0.6–0.9) in 75 % of the frames: the leg's bones along its arc
    (knee, ankle, toe: ``LIMB_QUANTILE["foot"]`` = 80) recover their true length, the arm's
    (at ``BONE_QUANTILE`` = 70) come out short; an explicit quantile applies to every bone."""
    from topopose.sequence import kinematic_fit as kf
    opts = SequenceOptions().with_(quantile=70, limb_quantile={"foot": 80})
    rng = np.random.default_rng(8)
    tree = kinematic_tree(HUMAN)
    order = tree.order()
    keys = {(tree.base[j], tree.base[p]) for j, p in enumerate(tree.parents) if p >= 0}
    true_L = {k: rng.uniform(0.1, 0.4) for k in sorted(keys)}   # mirror bones share theirs
    n = 40
    short = np.zeros(n, dtype=bool)
    short[rng.permutation(n)[:30]] = True
    init = np.zeros((n, len(tree.names), 3))
    for f in range(n):
        init[f, tree.root] = rng.normal(size=3)
        for j in order[1:]:
            p = tree.parents[j]
            d = rng.normal(size=3)
            k = rng.uniform(0.6, 0.9) if short[f] else 1.0
            init[f, j] = init[f, p] + k * true_L[(tree.base[j], tree.base[p])] * d / np.linalg.norm(d)
    L = kf.bone_lengths(init, tree, fit=opts.skeleton_fit)
    L70 = kf.bone_lengths(init, tree, quantile=70, fit=opts.skeleton_fit)
    for base in ("knee", "ankle", "toe", "elbow", "wrist", "fingertip"):
        js = [j for j in range(len(tree.names)) if tree.base[j] == base]
        assert len(js) == 2
        for j in js:
            want = true_L[(base, tree.base[tree.parents[j]])]
            if base in ("knee", "ankle", "toe"):
                assert abs(L[j] - want) < 1e-9, (base, L[j], want)
                assert L70[j] < 0.97 * want                 # every bone at 70: short
            else:
                assert L[j] < 0.97 * want and abs(L[j] - L70[j]) < 1e-12


def _walking_arm(n=7, step=0.02, turn=0.15):
    """A skeleton moving forward by ``step`` per frame, its arm hand_1's bones turning (the
    truth: each frame's directions the normalized blend of the first and last frame's, so
    interpolation between them is exact); returns (tree, lengths, P (n, joints, 3), arm)."""
    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    parts, curves = _body(0.3, np.random.default_rng(2))
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    P0 = kf.initial_placement(pose, tree)
    L = np.linalg.norm(P0 - P0[np.maximum(tree.parents, 0)], axis=1)
    L[tree.root] = np.nan
    D0 = kf._directions(P0, tree)
    arm = [j for j in range(len(tree.names)) if tree.arc[j][1] == "hand_1"]
    D1 = D0.copy()
    D1[arm] = D0[arm] @ _rotz(turn * (n - 1)).T + [0.0, 0.0, 0.3]
    D1[arm] /= np.linalg.norm(D1[arm], axis=1)[:, None]
    P = np.zeros((n, len(tree.names), 3))
    for f in range(n):
        s = f / (n - 1)
        D = (1 - s) * D0 + s * D1
        P[f] = kf.forward(P0[tree.root] + [step * f, 0.0, 0.0], D, L, tree)
    return tree, np.tile(L, (n, 1)), P, arm


def _angle(u, v):
    return np.degrees(np.arccos(np.clip(np.dot(u, v) / np.linalg.norm(u) / np.linalg.norm(v),
                                        -1.0, 1.0)))


@pytest.mark.parametrize("yaw", [0.0, 1.1, -2.5])
def test_tip_targets_turn_the_toe_from_the_shank_and_stretch_the_fingertip(yaw):
    """A leg with its shank straight down and its foot 60° from it (the ankle's bend), an
    arm with a 12 cm hand: the toe turns 15° further from the shank in the shank–foot plane,
    its distance from the ankle kept; the fingertip moves out along wrist → fingertip by the
    factor, its direction kept; a toe along the shank (no plane) and a frame without the knee
    stay; the joints that are not tips never move."""
    from topopose.sequence.kinematic_fit import tip_targets

    tree = kinematic_tree(HUMAN)
    ix = {n: i for i, n in enumerate(tree.names)}
    R = _rotz(yaw)
    init = np.full((3, len(tree.names), 3), np.nan)
    rng = np.random.default_rng(4)
    for f in range(3):
        init[f] = rng.normal(size=(len(tree.names), 3))            # every joint placed
        o = rng.normal(size=3)
        init[f, ix["knee_1"]] = o + R @ [0.0, 0.1, 0.5]
        init[f, ix["ankle_1"]] = o + R @ [0.0, 0.1, 0.1]
        a60 = np.radians(60.0)
        init[f, ix["toe_1"]] = o + R @ ([0.0, 0.1, 0.1] + 0.2 * np.array(
            [np.sin(a60), 0.0, -np.cos(a60)]))                    # 60° from straight down
        init[f, ix["wrist_1"]] = o + R @ [0.3, -0.2, 1.0]
        init[f, ix["fingertip_1"]] = o + R @ [0.3, -0.2, 1.0] + R @ [0.12, 0.0, 0.0]
    init[1, ix["toe_1"]] = init[1, ix["ankle_1"]] + R @ [0.0, 0.0, -0.2]   # along the shank
    init[2, ix["knee_1"]] = np.nan                                         # no shank
    out = tip_targets(init, tree, turn={"toe": 15.0}, stretch={"fingertip": 1.5})
    k, a, t = (out[0, ix[n]] for n in ("knee_1", "ankle_1", "toe_1"))
    assert abs(_angle(a - k, t - a) - 75.0) < 1e-6                 # 60° + 15° from the shank
    assert abs(np.linalg.norm(t - a) - 0.2) < 1e-9
    assert abs(np.dot(np.cross(a - k, init[0, ix["toe_1"]] - a), t - a)) < 1e-9   # same plane
    assert np.dot(t - init[0, ix["toe_1"]], R @ [0.0, 0.0, 1.0]) > 0.03   # the toe rises
    assert np.allclose(out[1, ix["toe_1"]], init[1, ix["toe_1"]])
    assert np.allclose(out[2, ix["toe_1"]], init[2, ix["toe_1"]])
    for f in range(3):
        w, x = out[f, ix["wrist_1"]], out[f, ix["fingertip_1"]]
        assert np.allclose(x - w, 1.5 * (R @ [0.12, 0.0, 0.0]))
        for j in range(len(tree.names)):
            if tree.base[j] not in ("toe", "fingertip"):
                assert np.array_equal(out[f, j], init[f, j], equal_nan=True)
    # unplaced tips stay unplaced; nothing asked, nothing moves
    init[0, ix["toe_2"]] = np.nan
    assert np.isnan(tip_targets(init, tree, turn={"toe": 15.0})[0, ix["toe_2"]]).all()
    assert np.array_equal(tip_targets(init, tree, turn={}, stretch={}), init, equal_nan=True)


def test_fit_sequence_places_the_toe_on_its_turned_target(monkeypatch):
    """The fit follows the corrected tip targets: with ``TIP_TURN`` the fitted toe lies at the
    turned target (the bend at the ankle grows by the turn, as measured on the fitted joints)."""
    opts = SequenceOptions().with_(tip_stretch={})
    rng = np.random.default_rng(1)
    poses = [_numbered_frame(f"{i:06d}", *_body(0.3 * i, rng, toe=0.1), False, False)[0]
             for i in range(4)]
    bends = {}
    for turn in (0.0, 20.0):
        opts = opts.with_(tip_turn={"toe": turn})
        out, tree, _ = fit_sequence(poses, HUMAN, opts)
        bends[turn] = [_angle(p.joints["ankle_1"] - p.joints["knee_1"],
                              p.joints["toe_1"] - p.joints["ankle_1"]) for p in out]
    for b0, b1 in zip(bends[0.0], bends[20.0]):
        assert abs((b1 - b0) - 20.0) < 3.0, (b0, b1)


def test_knee_from_the_far_end_when_the_legs_junction_drops(monkeypatch):
    """Oracle: straight hand-made legs, the crotch junction 0.95 m up, the knee at 0.475 m (the
    curve's half), the foot at 0 (the far end). In 2 of 7 frames the junction drops 12 cm (the
    4-camera hull's phantom crotch): the knee, still at 0.475 m, must be found there within a
    voxel (2 cm) from the far end alone (``weight`` 1); at the fraction ``at`` of the short
    curve it is 6 cm low (0.415 m), and with the default half weight half-way between (0.445
    m). Frames with the full curve keep their knee."""
    from topopose.sequence import kinematic_fit as kf
    opts = SequenceOptions().with_(from_end={("foot", "knee"): 40})
    tree = kinematic_tree(HUMAN)
    rng = np.random.default_rng(7)
    poses, drop = [], {2, 5}
    for i in range(7):
        parts, curves = _body(0.0, rng)
        for side, y in (("left_foot", 0.1), ("right_foot", -0.1)):
            o = parts["crotch"] * [1, 1, 0] + [0, y, 0]
            top = 0.95 - (0.12 if i in drop else 0.0)
            parts[side] = o.copy()
            curves[side] = resample([o + [0, 0, top], o], 64)
        pose, _ = _numbered_frame(f"{i:06d}", parts, curves, False, False)
        poses.append(pose)
    init = np.stack([kf.initial_placement(p, tree, fit=opts.skeleton_fit) for p in poses])
    out = kf.from_end(init, poses, tree, weight=1.0, fit=opts.skeleton_fit)
    half = kf.from_end(init, poses, tree, fit=opts.skeleton_fit)
    assert kf.FIT.from_end_weight == 0.5
    for k in (tree.names.index("knee_1"), tree.names.index("knee_2")):
        assert np.all(np.abs(out[:, k, 2] - 0.475) < 0.02), out[:, k, 2]
        assert np.all(np.abs(half[sorted(drop), k, 2] - 0.445) < 0.01), half[:, k, 2]
        assert np.all(np.abs(init[sorted(drop), k, 2] - 0.475) > 0.05)   # the fraction misses
        keep = [i for i in range(7) if i not in drop]
        assert np.allclose(out[keep, k], init[keep, k], atol=1e-9)
    other = [j for j, b in enumerate(tree.base) if b != "knee"]
    assert np.allclose(out[:, other], init[:, other], equal_nan=True)
    assert np.allclose(kf.from_end(init, poses, tree, ends={}, fit=opts.skeleton_fit), init, equal_nan=True)


@pytest.mark.parametrize("seed", range(4))
def test_chain_residuals_jacobian_matches_finite_differences(seed):
    """The skeleton fit's exact Jacobian (:func:`chain_residuals`) against scipy's central
    differences at random chains, targets, weights and curves."""
    from scipy.optimize._numdiff import approx_derivative

    from topopose.sequence.kinematic_fit import chain_residuals

    rng = np.random.default_rng(seed)
    m = 1 + seed
    x = rng.normal(size=3 * m)
    p0, L = rng.normal(size=3), rng.uniform(0.1, 0.4, m)
    tgt, w = rng.normal(size=(m, 3)), rng.uniform(0.0, 1.0, (m, 1))
    for curve in (None, 0.5 * rng.normal(size=(16, 3))):
        args = (p0, L, tgt, w, curve, 1.3)
        r, J = chain_residuals(x, *args, jac=True)
        assert np.array_equal(r, chain_residuals(x, *args))
        num = approx_derivative(lambda z: chain_residuals(z, *args), x, method="3-point")
        assert J.shape == num.shape and np.abs(J - num).max() < 1e-7


def test_girdle_places_neck_and_shoulders_as_one_symmetric_rigid_body():
    """The neck's target pushed 8 cm along the shoulder line in one frame: after
    :func:`girdle_targets` the three joints form the declared template (shoulders the
    sequence's median width apart, the neck on their mid-plane 0.1 × that width from their
    midpoint), with the targets' centroid, and no rotation of that template about it fits the
    targets better (2,000 random rotations). Frames missing a shoulder and the switch off keep
    their targets; the model field round-trips and is checked."""
    from scipy.spatial.transform import Rotation

    from topopose.sequence import kinematic_fit as kf
    tree = kinematic_tree(HUMAN)
    rng = np.random.default_rng(5)
    init = []
    for i in range(4):
        parts, curves = _body(0.4 * i, rng)
        init.append(kf.initial_placement(_numbered_frame(f"{i:06d}", parts, curves, False,
                                                         False)[0], tree))
    init = np.stack(init)
    c, a, b = (tree.names.index(x) for x in ("neck", "shoulder_1", "shoulder_2"))
    init[1, c] += 0.08 * (init[1, a] - init[1, b]) / np.linalg.norm(init[1, a] - init[1, b])
    init[3, a] += 0.03 * (init[3, a] - init[3, b]) / np.linalg.norm(init[3, a] - init[3, b])
    init[2, b] = np.nan
    out = kf.girdle_targets(init, tree)
    W = np.median(np.linalg.norm(init[[0, 1, 3], a] - init[[0, 1, 3], b], axis=1))
    for f in (0, 1, 3):
        n, s1, s2 = out[f, c], out[f, a], out[f, b]
        assert abs(np.linalg.norm(s1 - s2) - W) < 1e-9
        assert abs(np.linalg.norm(n - s1) - np.linalg.norm(n - s2)) < 1e-9
        assert abs(np.linalg.norm(n - 0.5 * (s1 + s2)) - 0.1 * W) < 1e-9
        X = init[f, [c, a, b]]
        assert np.allclose(out[f, [c, a, b]].mean(axis=0), X.mean(axis=0), atol=1e-12)
        best = np.sum((out[f, [c, a, b]] - X) ** 2)
        T = out[f, [c, a, b]] - X.mean(axis=0)
        for R in Rotation.random(2000, random_state=f):
            assert np.sum((X.mean(axis=0) + R.apply(T) - X) ** 2) >= best - 1e-12
    moved = np.linalg.norm(out[1, c] - init[1, c])
    assert moved > 0.04                                    # the pushed neck came back
    assert np.array_equal(out[2], init[2], equal_nan=True)
    others = [j for j in range(len(tree.names)) if j not in (c, a, b)]
    assert np.array_equal(out[:, others], init[:, others], equal_nan=True)
    assert np.array_equal(kf.girdle_targets(init, tree, on=False), init, equal_nan=True)
    d = HUMAN.to_dict()
    assert model_from_dict(d).joints == HUMAN.joints
    for bad in (["elbow_9", 0.1], ["shoulder"], ["shoulder", 2.0], ["neck", 0.1]):
        e = {**d, "joint": [dict(j) for j in d["joint"]]}
        next(j for j in e["joint"] if j["name"] == "neck")["girdle"] = bad
        with pytest.raises(InputError, match="joint\\[.*girdle"):
            model_from_dict(e)
    e = {**d, "joint": [dict(j) for j in d["joint"]]}
    next(j for j in e["joint"] if j["name"] == "neck")["girdle"] = ["skull", 0.1]
    with pytest.raises(InputError, match="girdle.*'skull'.*1 joints, not a mirror pair"):
        kinematic_tree(model_from_dict(e))


def _mirrored(pose):
    """The frame reflected through the vertical plane y = 0: a body whose left is the original's
    right (every part and curve mirrored, the numbering kept)."""
    M = np.diag([1.0, -1.0, 1.0])
    parts = {k: None if v is None else M @ np.asarray(v, float) for k, v in pose.parts.items()}
    curves = {k: np.asarray(c, float) @ M for k, c in pose.diagnostics["curves"].items()}
    return Pose(pose.frame, "matched", 0.1, parts, diagnostics={"curves": curves})


@pytest.mark.parametrize("seed", range(4))
def test_a_mirrored_subject_gets_the_mirrored_claim(seed):
    rng = np.random.default_rng(40 + seed)
    parts, curves = _body(rng.uniform(0, 2 * np.pi), rng)
    pose, m = _numbered_frame("000000", parts, curves, seed % 2 == 1, seed >= 2)
    ch = assign_sides([pose], HUMAN, UP)[0].diagnostics["chirality"]
    ch_m = assign_sides([_mirrored(pose)], HUMAN, UP)[0].diagnostics["chirality"]
    other = {"left_hand": "right_hand", "right_hand": "left_hand",
             "left_foot": "right_foot", "right_foot": "left_foot"}
    for side_name, part in m.items():
        assert ch[part]["name"] == side_name
        assert ch_m[part]["name"] == other[side_name]


def _kneeling(yaw, rng):
    """Both knees on the floor, the shins behind, the feet lying along the shins (pointing
    back): body frame x forward, y left, z up. Returns (parts, curves) with side-named truth."""
    R = _rotz(yaw)
    o = rng.normal(scale=0.5, size=3) * [1, 1, 0]
    W = lambda v: R @ np.asarray(v, float) + o                          # noqa: E731
    torso, crotch, head = W([0, 0, 0.95]), W([0, 0, 0.55]), W([0, 0, 1.35])
    parts = {"torso": torso, "crotch": crotch, "head": head}
    curves = {"head": resample([torso, head]), "crotch": resample([torso, crotch])}
    for side, sg in (("left", 1.0), ("right", -1.0)):
        sh, hand = W([0, sg * 0.2, 1.0]), W([0.1, sg * 0.3, 0.55])
        hip, knee = W([0, sg * 0.1, 0.5]), W([0.05, sg * 0.1, 0.05])
        ankle, toe = W([-0.35, sg * 0.1, 0.05]), W([-0.5, sg * 0.1, 0.03])
        parts[f"{side}_hand"], parts[f"{side}_foot"] = hand, toe
        curves[f"{side}_hand"] = resample(resample([torso, sh, hand], 64))
        curves[f"{side}_foot"] = resample(resample([crotch, hip, knee, ankle, toe], 64))
    return parts, curves


@pytest.mark.parametrize("seed", range(3))
def test_kneeling_feet_point_back_along_the_shins_yet_the_sides_hold(seed):
    """Oracle: the knees bend forward, the feet lie along the shins pointing back: the foot's
    direction across its shin carries no facing, so the knees decide (ankle → toe taken as
    it is would name every side the wrong way)."""
    rng = np.random.default_rng(60 + seed)
    parts, curves = _kneeling(rng.uniform(0, 2 * np.pi), rng)
    pose, m = _numbered_frame("000000", parts, curves, seed == 1, seed == 2)
    out = assign_sides([pose], HUMAN, UP)[0]
    for side_name, part in m.items():
        assert out.diagnostics["chirality"][part]["name"] == side_name


def test_a_subject_lying_on_its_side_is_sided_by_its_own_up():
    """The standing body laid on its left side (rotated 90° about its forward axis): the
    capture's up is the body's lateral axis, its own up (crotch → torso) is horizontal."""
    rng = np.random.default_rng(70)
    parts, curves = _body(0.0, rng)
    c = np.asarray(parts["crotch"], float)
    Rx = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])          # z (up) → y, y (left) → -z
    rot = lambda x: Rx @ (np.asarray(x, float) - c) + c + [0, 0, 0.3]    # noqa: E731
    parts = {k: rot(v) for k, v in parts.items()}
    curves = {k: np.array([rot(x) for x in v]) for k, v in curves.items()}
    pose, m = _numbered_frame("000000", parts, curves, True, False)
    out = assign_sides([pose], HUMAN, UP)[0]
    for side_name, part in m.items():
        assert out.diagnostics["chirality"][part]["name"] == side_name


def test_weak_evidence_keeps_the_numbered_names_and_says_why():
    from topopose.sequence.chirality import SideOptions

    rng = np.random.default_rng(80)
    parts, curves = _body(0.3, rng, knee=0.0, toe=0.0)              # feet end-on, knees straight
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    ch = assign_sides([pose], HUMAN, UP)[0].diagnostics["chirality"]
    assert ch["hand_1"]["name"] == "hand_1" and "facing weak" in ch["hand_1"]["why"]
    # hands side by side along the facing (one in front of the other): not apart
    parts, curves = _body(0.3, rng)
    lateral = _rotz(0.3) @ [0, 1.0, 0]
    for side in ("left", "right"):                  # proximal quarters moved onto the midline
        c = np.asarray(curves[f"{side}_hand"], float)
        q = c[int(round(0.25 * (len(c) - 1)))]
        curves[f"{side}_hand"] = c - np.dot(q - parts["torso"], lateral) * lateral
    pose, _ = _numbered_frame("000000", parts, curves, False, False)
    ch = assign_sides([pose], HUMAN, UP)[0].diagnostics["chirality"]
    assert ch["hand_1"]["name"] == "hand_1" and "not apart" in ch["hand_1"]["why"]
    assert ch["foot_1"]["name"] == "left_foot" and "why" not in ch["foot_1"]
    # a margin no frame reaches keeps every pair numbered
    ch = assign_sides([pose], HUMAN, UP, options=SideOptions(margin=1.01))[0].diagnostics["chirality"]
    assert all(d["name"] == p and d["why"].startswith("confidence") for p, d in ch.items())


@pytest.mark.parametrize("back, named", [(0.08, False), (0.04, True)])
def test_feet_pointing_apart_keep_the_numbered_names(back, named):
    """Knees straight, the left foot pointing 0.2 m forward and the right ``back`` m backward:
    the cues' agreement is (0.2 − back) / (0.2 + back) — 0.43 below ``min_agree`` (numbered,
    why: the cues disagree, though the score alone, 0.36, would name them), 0.67 above it
    (named, and rightly)."""
    from topopose.sequence.chirality import SIDES

    parts, curves = _body(0.7, np.random.default_rng(81), knee=0.0, toe=0.2)
    _, back_curves = _body(0.7, np.random.default_rng(81), knee=0.0, toe=-back)
    curves["right_foot"] = back_curves["right_foot"]
    assert ((0.2 - back) / (0.2 + back) >= SIDES.min_agree) == named
    pose, m = _numbered_frame("000000", parts, curves, False, True)
    ch = assign_sides([pose], HUMAN, UP)[0].diagnostics["chirality"]
    for side_name, part in m.items():
        if named:
            assert ch[part]["name"] == side_name and "why" not in ch[part]
        else:
            assert ch[part]["name"] == part and "facing cues disagree" in ch[part]["why"]
