"""The skeleton over time: one frame's wrong limb is not smoothed into its
neighbours (:func:`~topopose.sequence.kinematic_fit.despike`), and a hanging arm's elbow and wrist
keep their bones' lengths from the shoulder when its curve ends short
(:func:`~topopose.sequence.kinematic_fit.from_start`) — on hand-made bodies whose truth is known."""
import numpy as np

from topopose.sequence.options import SequenceOptions
from topopose.sequence import kinematic_fit as kf
from topopose.frame.curves import resample
from topopose.sequence.kinematic_fit import fit_sequence, kinematic_tree

from test_pose_sides_skeleton import HUMAN, _rotz, _true_joints, _walking_arm
from test_pose_smooth_hold import _still_body


def test_despike_replaces_one_frames_swung_bone_and_leaves_a_turning_limb():
    """A limb turning 0.01 rad per frame over 21 frames has no spike; the same limb with
    frame 10's arm bones swung 60° has exactly those bones replaced, by their window's median
    direction (within the turn's few degrees of the truth)."""
    tree, _, P, arm = _walking_arm(n=21, step=0.02, turn=0.01)
    D = np.stack([kf._directions(p, tree) for p in P])
    out, bad = kf.despike(D, 10, 3.0, 15.0)
    assert not bad.any() and np.array_equal(out, D)
    W = D.copy()
    W[10, arm] = W[10, arm] @ _rotz(np.radians(60.0)).T
    out, bad = kf.despike(W, 10, 3.0, 15.0)
    assert set(np.flatnonzero(bad[10])) == set(arm) and bad.sum() == len(arm)
    cos = np.einsum("jk,jk->j", out[10, arm], D[10, arm])
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 5.0
    assert np.array_equal(out[np.arange(21) != 10], W[np.arange(21) != 10])


def _arm_swung(pose, k="hand_1"):
    """``pose`` with arm ``k``'s curve and hand on another branch: swung 90° up and out (as a
    hand matched to a wrong branch for one frame)."""
    c = np.asarray(pose.diagnostics["curves"][k], float)
    top = c[0]
    R = _rotz(np.pi / 2)
    swung = top + (c - top) @ R.T + [0.0, 0.0, 0.5]
    pose.diagnostics["curves"][k] = swung
    pose.parts[k] = swung[-1]
    return pose


def test_one_frames_wrong_arm_is_not_smoothed_into_its_neighbours(monkeypatch):
    """A body turning slowly over 21 frames, frame 10's arm on a wrong branch (the rest of the
    skeleton right, so the frame is no temporal outlier): with :data:`DESPIKE` the neighbours'
    arms stay on their truth and frame 10's arm comes back near it, listed in
    ``diagnostics["despiked_joints"]``; without, the wrong arm is averaged into the frames
    around it."""
    opts = SequenceOptions().with_(tip_turn={}, tip_stretch={})
    tree = kinematic_tree(HUMAN)
    poses, truth = [], []
    for i in range(21):
        pose, _ = _still_body(i, 0.01 * i, np.array([0.01 * i, 0.0, 0.0]))
        truth.append(np.array([_true_joints(pose, tree)[n] for n in tree.names]))
        poses.append(pose)
    arm = [j for j, n in enumerate(tree.names) if n.endswith("_1") and tree.arc[j][1] == "hand_1"]
    near = [6, 7, 8, 9, 11, 12, 13, 14]

    def arm_errors(frames):
        out, tree, _ = fit_sequence(frames, HUMAN, opts, smooth=9)
        assert not any(p.diagnostics.get("temporal_outlier") for p in out)
        P = np.array([[p.joints[n] for n in tree.names] for p in out])
        e = np.linalg.norm(P - np.array(truth), axis=2)[:, arm]
        return out, e[near].max(), e[10].max()
    _, clean, _ = arm_errors(poses)                 # the fit's own error, no wrong arm
    poses[10] = _arm_swung(poses[10])
    out, near_on, at_on = arm_errors(poses)
    assert [i for i, p in enumerate(out) if p.diagnostics.get("despiked_joints")] == [10]
    assert set(out[10].diagnostics["despiked_joints"]) <= {tree.names[j] for j in arm}
    assert near_on < clean + 0.005 and at_on < clean + 0.01, (clean, near_on, at_on)
    from topopose.batch.run import RunResult, summary_text
    text = summary_text(RunResult(out, None, counts={"matched": 21}))
    assert "1 frame with a bone far off the frames around, replaced by theirs " \
        "(diagnostics.despiked_joints)" in text
    opts = opts.with_(despike=None)
    out, near_off, at_off = arm_errors(poses)
    assert not any(p.diagnostics.get("despiked_joints") for p in out)
    assert "despiked" not in summary_text(RunResult(out, None))
    assert near_off > clean + 0.05 and at_off > clean + 0.05, (clean, near_off, at_off)


def _cut_hand(pose, by, k="hand_1"):
    """``pose`` with arm ``k``'s curve ending ``by`` metres short (the hand lost in the masks),
    its hand part at the new end."""
    c = np.asarray(pose.diagnostics["curves"][k], float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    keep = s <= s[-1] - by
    cut = resample(c[keep], len(c))
    pose.diagnostics["curves"][k] = cut
    pose.parts[k] = cut[-1]
    return pose


def test_a_hanging_arm_cut_short_keeps_its_elbow_and_wrist(monkeypatch):
    """The still body's arms hang (hands below the chest junction). Every other frame loses
    the last 12 cm of arm hand_1's curve: the fraction ``at`` puts its elbow and wrist higher
    up the arm in those frames (10–11 cm off after the fit). From the shoulder by the bones'
    lengths (:data:`FROM_START`, weight 1) their targets are the truth; the default weight
    (0.5) moves them half-way, and the fitted elbow and wrist come nearer (the wrist less: the
    fingertip's target, at the cut end, pulls it back); the uncut frames are unchanged."""
    opts = SequenceOptions().with_(tip_turn={}, tip_stretch={}, girdle=False)
    tree = kinematic_tree(HUMAN)
    poses, truth = [], []
    for i in range(12):
        pose, _ = _still_body(i, 0.0, np.zeros(3))
        truth.append(np.array([_true_joints(pose, tree)[n] for n in tree.names]))
        poses.append(_cut_hand(pose, 0.12) if i % 2 else pose)
    truth = np.array(truth)
    js = [tree.names.index(n) for n in ("elbow_1", "wrist_1")]
    init = np.stack([kf.initial_placement(p, tree, fit=opts.skeleton_fit) for p in poses])
    L = kf.bone_lengths(init, tree, fit=opts.skeleton_fit)
    arm = {("hand", "elbow"), ("hand", "wrist")}
    opts = opts.with_(from_start_weight=1.0)
    placed = kf.from_start(init, poses, tree, L, joints=arm, fit=opts.skeleton_fit)
    assert np.linalg.norm(placed[1::2, js] - truth[1::2, js], axis=2).max() < 0.01
    assert np.linalg.norm(init[1::2, js] - truth[1::2, js], axis=2).min() > 0.05
    opts = opts.with_(from_start_weight=0.5)   # the default: half-way
    half = kf.from_start(init, poses, tree, L, joints=arm, fit=opts.skeleton_fit)
    assert np.allclose(half[1::2, js[0]], 0.5 * (placed[1::2, js[0]] + init[1::2, js[0]]))
    err = {}
    for on in (True, False):
        opts = opts.with_(from_start={("hand", "elbow"), ("hand", "wrist")} if on else {})
        out, tree, _ = fit_sequence(poses, HUMAN, opts, smooth=0)
        P = np.array([[p.joints[n] for n in tree.names] for p in out])
        err[on] = np.linalg.norm(P - truth, axis=2)[:, js]
    assert err[False][1::2].min() > 0.09, err                     # 10–11 cm without
    assert err[True][1::2, 0].max() < err[False][1::2, 0].min() - 0.025, err
    assert err[True][1::2, 1].max() < err[False][1::2, 1].min() - 0.01, err
    assert np.allclose(err[True][0::2], err[False][0::2], atol=0.005)


def test_from_start_leaves_a_raised_arm_and_reaches_past_a_short_curve(monkeypatch):
    """:func:`from_start` on single frames (weight 1): a raised arm (hand above the chest
    junction) keeps its placement; a hanging arm's wrist whose curve ends before its bone's
    length is placed past the end, along the curve's last direction, at exactly that length
    from the elbow — unless that is more than :data:`REACH_PAST` past it (then a curve cut
    that short is no lost hand: the placement is kept)."""
    opts = SequenceOptions().with_(from_start_weight=1.0)
    tree = kinematic_tree(HUMAN)
    pose, _ = _still_body(0, 0.0, np.zeros(3))
    c = np.asarray(pose.diagnostics["curves"]["hand_1"], float)
    raised = _still_body(1, 0.0, np.zeros(3))[0]
    top = c[0]
    up = top + (c - top) * [1.0, 1.0, -1.0]             # the arm mirrored up
    raised.diagnostics["curves"]["hand_1"] = up
    raised.parts["hand_1"] = up[-1]
    short = _cut_hand(_still_body(2, 0.0, np.zeros(3))[0], 0.12)
    cut = _cut_hand(_still_body(3, 0.0, np.zeros(3))[0], 0.3)
    frames = [pose, raised, short, cut]
    init = np.stack([kf.initial_placement(p, tree, fit=opts.skeleton_fit) for p in frames])
    L = kf.bone_lengths(init, tree, fit=opts.skeleton_fit)
    out = kf.from_start(init, frames, tree, L, joints={("hand", "elbow"), ("hand", "wrist")}, fit=opts.skeleton_fit)
    e, w = tree.names.index("elbow_1"), tree.names.index("wrist_1")
    assert np.array_equal(out[1], init[1])                          # raised: untouched
    assert abs(np.linalg.norm(out[2, w] - out[2, e]) - L[w]) < 1e-9
    end = np.asarray(short.diagnostics["curves"]["hand_1"], float)
    d = out[2, w] - end[-1]
    assert 0.02 < np.linalg.norm(d) <= kf.REACH_PAST                # past the cut end
    last = end[-1] - end[-8]
    assert np.dot(d, last) / (np.linalg.norm(d) * np.linalg.norm(last)) > 0.99
    assert np.array_equal(out[3, w], init[3, w])                    # too far past: kept
