"""The skeleton over time: a lost joint held only while recent (``HOLD_AGE``), and the
default smoothing over runs of continuing motion (``SMOOTH`` at the capture's frame rate,
:func:`motion_runs`), on hand-made bodies and chains whose truth is known."""
import copy

import numpy as np
import pytest

from topopose.sequence.options import SequenceOptions
from topopose.sequence import kinematic_fit as kf
from topopose.sequence.kinematic_fit import fit_sequence, kinematic_tree

from test_pose_sides_skeleton import HUMAN, _body, _numbered_frame, _true_joints, _walking_arm


def _still_body(frame, yaw, shift, seed=5):
    """The same rigid body (``_body`` with a fixed translation draw) turned by ``yaw`` and
    moved by ``shift``, as the per-frame matcher gives it; returns (pose, true parts)."""
    parts, curves = _body(yaw, np.random.default_rng(seed))
    parts = {k: v + shift for k, v in parts.items()}
    curves = {k: v + shift for k, v in curves.items()}
    pose, _ = _numbered_frame(f"{frame:06d}", parts, curves, False, False)
    return pose, parts


def test_motion_runs_split_at_jumps_unfitted_frames_and_missing_frame_numbers():
    """A chain moving a little per frame (``_walking_arm``: 2 cm forward, the arm turning) makes
    one run; a frame whose joints jump 0.5 m from the root (an unrelated pose), an unfitted
    frame and a missing frame number each end a run, and runs shorter than ``win`` are
    dropped. Without the move check the jump does not split."""
    tree, _, P, _ = _walking_arm(n=30, step=0.02, turn=0.01)
    t = np.arange(30.0)
    assert kf.motion_runs(P, t, tree, 5, 0.15) == [(0, 30)]
    Q = P.copy()
    other = [j for j in range(len(tree.names)) if j != tree.root]
    Q[12:, other] += [0.0, 0.0, 0.5]                 # from frame 12 on: another pose (held)
    Q[20] = np.nan                                   # frame 20 not fitted
    t2 = t.copy()
    t2[26:] += 1                                     # a frame number missing before index 26
    assert kf.motion_runs(Q, t2, tree, 5, 0.15) == [(0, 12), (12, 20), (21, 26)]
    assert kf.motion_runs(Q, t2, tree, 6, 0.15) == [(0, 12), (12, 20)]
    assert kf.motion_runs(Q, t2, tree, 9, 0.15) == [(0, 12)]
    assert kf.motion_runs(Q, t2, tree, 5, None) == [(0, 20), (21, 26)]
    assert kf.motion_runs(Q, t, tree, 5, 0.15) == [(0, 12), (12, 20), (21, 30)]
    # frames 8–15 interpolated (not seen by the fit): the jump is checked between the seen
    # frames 7 and 16, the run ends at frame 7, the interpolated frames belong to none
    seen = np.ones(30, dtype=bool)
    seen[8:16] = False
    assert kf.motion_runs(Q, t, tree, 4, 0.15, seen=seen) == [(0, 8), (16, 20), (21, 30)]
    assert kf.motion_runs(Q, t, tree, 5, 0.15, seen=seen) == [(0, 8), (21, 30)]
    assert kf.motion_runs(P, t, tree, 5, 0.15, seen=seen) == [(0, 30)]


def test_motion_runs_ride_over_jitter_and_leave_out_a_single_wrong_frame():
    """The walking chain with 7 cm of noise on every joint each frame (a 4-camera fit's
    jitter: most frames move ≥ 0.15 m from the one before, which split the runs when each
    frame was compared with the previous one) and one wrong frame (15: joints 0.5 m off):
    one run each side of the wrong frame, which belongs to none."""
    tree, _, P, _ = _walking_arm(n=40, step=0.02, turn=0.01)
    other = [j for j in range(len(tree.names)) if j != tree.root]
    Q = P.copy()
    Q[:, other] += np.random.default_rng(3).normal(scale=0.07, size=Q[:, other].shape)
    Q[15, other] += [0.0, 0.0, 0.5]
    rel = Q - Q[:, tree.root:tree.root + 1]
    steps = np.linalg.norm(np.diff(rel, axis=0), axis=2).mean(axis=1)
    assert np.mean(steps >= 0.15) > 0.4                    # the jitter a frame-to-frame rule breaks at
    assert kf.motion_runs(Q, np.arange(40.0), tree, 9, 0.15) == [(0, 15), (16, 40)]


def test_default_smoothing_brings_a_noisy_continuing_motion_closer_to_the_truth(monkeypatch):
    """A rigid body turning 0.02 rad and moving 1 cm per frame, its curves noisy (1 cm): the
    default fit (``SMOOTH``) is nearer each frame's true joints than the unsmoothed fit, flags
    the frames ``smoothed`` and keeps every bone at its constant length."""
    assert kf.SMOOTH == 9
    opts = SequenceOptions().with_(tip_turn={})          # curves through the tips' truth
    opts = opts.with_(tip_stretch={})
    rng = np.random.default_rng(0)
    tree = kinematic_tree(HUMAN)
    poses, truth = [], []
    for i in range(21):
        pose, _ = _still_body(i, 0.02 * i, np.array([0.01 * i, 0.0, 0.0]))
        truth.append(np.array([_true_joints(pose, tree)[n] for n in tree.names]))
        pose.diagnostics["curves"] = {k: v + rng.normal(scale=0.01, size=v.shape)
                                      for k, v in pose.diagnostics["curves"].items()}
        poses.append(pose)
    err = {}
    for smooth in (None, 0):
        out, tree, L = fit_sequence(poses, HUMAN, opts, smooth=smooth)
        P = np.array([[p.joints[n] for n in tree.names] for p in out])
        err[smooth] = float(np.linalg.norm(P - np.array(truth), axis=2).mean())
        if smooth is None:
            assert all(p.diagnostics.get("smoothed") for p in out)
            for j, par in enumerate(tree.parents):
                if par >= 0:
                    assert np.allclose(np.linalg.norm(P[:, j] - P[:, par], axis=1), L[j])
        else:
            assert not any(p.diagnostics.get("smoothed") for p in out)
    assert err[None] < 0.8 * err[0], err


def test_the_default_window_keeps_its_duration_at_the_capture_frame_rate(monkeypatch):
    """``SMOOTH`` is 9 frames at 25 frames/s (0.36 s): at 60 frames/s the default window is 21
    frames, and ``process_sequence(fps=60)`` (what ``run`` passes: the capture's rate) fits
    with it. The same noisy turning body filmed at 60 frames/s (its motion per frame scaled by
    25 / 60) comes nearer its noise-free fit with the 21-frame window than with 9 frames
    (0.15 s)."""
    from topopose.sequence.motion import process_sequence

    assert (kf.smooth_window(25), kf.smooth_window(60), kf.smooth_window(None)) == (9, 21, 9)
    assert kf.smooth_window(1) == 3
    from topopose.sequence.smoothing import odd_window
    from topopose.sequence.tracker import TrackOptions

    # the tracker's window in seconds is the same one (TrackOptions.smooth)
    assert [odd_window(TrackOptions().smooth, f) for f in (25, 60, 10)] == [9, 21, 3]
    assert odd_window(0.0, 60) == 0
    opts = SequenceOptions().with_(tip_turn={}, tip_stretch={})
    rng = np.random.default_rng(1)
    tree = kinematic_tree(HUMAN)
    poses, clean = [], []
    for i in range(45):
        pose, _ = _still_body(i, 0.02 * i * 25 / 60, np.array([0.01 * i * 25 / 60, 0.0, 0.0]))
        clean.append(pose)
        pose = copy.deepcopy(pose)
        pose.diagnostics["curves"] = {k: v + rng.normal(scale=0.01, size=v.shape)
                                      for k, v in pose.diagnostics["curves"].items()}
        poses.append(pose)
    out, _, _ = fit_sequence(clean, HUMAN, opts, smooth=0)
    truth = [[p.joints[n] for n in tree.names] for p in out]
    err, fits = {}, {}
    for smooth in (9, 21):
        out, _, _ = fit_sequence(poses, HUMAN, opts, smooth=smooth)
        fits[smooth] = np.array([[p.joints[n] for n in tree.names] for p in out])
        err[smooth] = float(np.linalg.norm(fits[smooth] - np.array(truth), axis=2).mean())
    assert err[21] < 0.9 * err[9], err
    m = process_sequence(poses, HUMAN, np.array([0.0, 0.0, 1.0]), opts, track=False, sides=False,
                         fps=60, consistency=False)
    got = np.array([[p.joints[n] for n in tree.names] for p in m.poses])
    assert np.allclose(got, fits[21])
    assert not np.allclose(got, fits[9])


def _turned_frames(n, wrong):
    """A body moving 1 cm a frame, the frames in ``wrong`` with the curves of the body turned
    half about the vertical (hands and feet on the other sides: a wrong per-frame result);
    returns (poses, the true joints per frame)."""
    tree = kinematic_tree(HUMAN)
    poses, truth = [], []
    for i in range(n):
        shift = np.array([0.01 * i, 0.0, 0.0])
        pose = _still_body(i, np.pi if i in wrong else 0.0, shift)[0]
        right = _still_body(i, 0.0, shift)[0]
        truth.append(np.array([_true_joints(right, tree)[m] for m in tree.names]))
        poses.append(pose)
    return poses, np.array(truth)


def test_a_frame_off_the_motion_around_it_is_flagged_and_bridged(monkeypatch):
    """Frame 7 of a body moving 1 cm a frame is wrong (turned half about the vertical). The
    fit records each frame's distance from its neighbours' median; frame 7 alone is a
    ``temporal_outlier`` (≥ ``SMOOTH_MOVE``) and is bridged: replaced by the interpolation of
    frames 6 and 8, flagged ``interpolated``, within 2 cm of the truth where its own fit is
    0.2 m off, and smoothed with the run it no longer breaks. With ``BRIDGE`` off it keeps
    its own (unsmoothed) fit, flagged only."""
    poses, truth = _turned_frames(21, {7})
    out, tree, _ = fit_sequence(poses, HUMAN)
    raw, _, _ = fit_sequence(poses, HUMAN, smooth=0)
    J = lambda p: np.array([p.joints[n] for n in tree.names])   # noqa: E731
    flagged = [i for i, p in enumerate(out) if p.diagnostics.get("temporal_outlier")]
    assert flagged == [7]
    d = [p.diagnostics["neighbour_distance"] for p in out]
    assert d[7] >= kf.SMOOTHING.move and max(d[:7] + d[8:]) < 0.5 * kf.SMOOTHING.move
    assert [i for i, p in enumerate(out) if p.diagnostics.get("interpolated")] == [7]
    assert np.linalg.norm(J(raw[7]) - truth[7], axis=1).mean() > 0.2
    assert np.linalg.norm(J(out[7]) - truth[7], axis=1).mean() < 0.02
    # its parts too (hands and feet back on their sides), from frames 6 and 8
    right = _still_body(7, 0.0, np.array([0.07, 0.0, 0.0]))[0].parts
    assert sorted(out[7].diagnostics["interpolated_parts"]) == sorted(right)
    assert max(np.linalg.norm(out[7].parts[k] - right[k]) for k in right) < 1e-9
    assert max(np.linalg.norm(poses[7].parts[k] - right[k]) for k in right) > 0.2
    assert "interpolated_parts" not in out[6].diagnostics and out[6].parts is poses[6].parts
    assert all(p.diagnostics.get("smoothed") for p in out)
    assert not any("neighbour_distance" in p.diagnostics for p in raw)   # smoothing off
    from topopose.batch.run import RunResult, summary_text
    text = summary_text(RunResult(out, None, counts={"matched": 21}))
    assert ("1 skeleton off the motion around it (diagnostics.temporal_outlier, 1 interpolated "
            "from the frames either side)") in text
    assert "off the motion" not in summary_text(RunResult(raw, None))
    opts = SequenceOptions().with_(bridge=False)
    kept, _, _ = fit_sequence(poses, HUMAN, opts)
    assert kept[7].diagnostics.get("temporal_outlier")
    assert "smoothed" not in kept[7].diagnostics and "interpolated" not in kept[7].diagnostics
    assert np.array_equal(J(kept[7]), J(raw[7]))
    assert all(kept[i].diagnostics.get("smoothed") for i in range(8, 21))
    text = summary_text(RunResult(kept, None, counts={"matched": 21}))
    assert "1 skeleton off the motion around it (diagnostics.temporal_outlier)" in text


def test_bridging_needs_a_short_stretch_between_two_frames_of_one_motion():
    """Two wrong frames together (8, 9) are bridged (``max_gap`` 5); a wrong stretch longer
    than ``max_gap`` or at the sequence's end is not (no frames of the motion on both sides),
    and :func:`bridge_outliers` leaves a stretch whose two ends lie apart (another motion),
    one whose pose recurs among the frames around it, and one across a missing frame
    number."""
    poses, truth = _turned_frames(30, {8, 9})
    out, tree, _ = fit_sequence(poses, HUMAN)
    J = lambda p: np.array([p.joints[n] for n in tree.names])   # noqa: E731
    assert [i for i, p in enumerate(out) if p.diagnostics.get("interpolated")] == [8, 9]
    assert max(np.linalg.norm(J(out[i]) - truth[i], axis=1).mean() for i in (8, 9)) < 0.02
    out, _, _ = fit_sequence(poses, HUMAN, max_gap=1)
    assert not any(p.diagnostics.get("interpolated") for p in out)
    poses, _ = _turned_frames(30, {27, 28, 29})
    out, _, _ = fit_sequence(poses, HUMAN)
    assert not any(p.diagnostics.get("interpolated") for p in out)
    tree, _, P, _ = _walking_arm(n=6, step=0.02, turn=0.01)
    other = [j for j in range(len(tree.names)) if j != tree.root]
    P[3:, other] += [0.0, 0.0, 0.5]                   # from frame 3: another pose
    L = np.ones((6, len(tree.names)))
    bad = np.array([0, 0, 1, 0, 0, 0.0])
    Q, done = kf.bridge_outliers(P, np.arange(6), tree, L, bad, 5, 0.15)
    assert not done.any() and np.array_equal(Q, P)
    P[3:, other] -= [0.0, 0.0, 0.5]
    assert not kf.bridge_outliers(P, np.arange(6), tree, L, bad, 5, 0.15)[1].any()  # recurs
    P[2, other] += [0.0, 0.5, 0.0]                    # frame 2 alone off the motion
    Q, done = kf.bridge_outliers(P, np.arange(6), tree, L, bad, 5, 0.15)
    assert done.tolist() == [False, False, True, False, False, False]
    assert np.allclose(Q[[0, 1, 3, 4, 5]], P[[0, 1, 3, 4, 5]])
    t = np.array([0, 1, 2, 4, 5, 6])                  # a frame number missing after frame 2
    assert not kf.bridge_outliers(P, t, tree, L, bad, 5, 0.15)[1].any()


def test_bridging_leaves_a_capture_of_mostly_outliers_alone():
    """A wrong frame (6) of a continuing motion is bridged when most frames around it are not
    outliers; when most are (a capture of unrelated poses, a few of them near their
    neighbours' median by chance) the same two agreeing ends do not bridge it."""
    tree, _, P, _ = _walking_arm(n=13, step=0.02, turn=0.01)
    other = [j for j in range(len(tree.names)) if j != tree.root]
    P[6, other] += [0.0, 0.5, 0.0]
    L = np.ones((13, len(tree.names)))
    dist = np.full(13, 0.05)
    dist[6] = 0.5
    assert np.flatnonzero(kf.bridge_outliers(P, np.arange(13), tree, L, dist, 5, 0.15, reach=4)[1]
                          ).tolist() == [6]
    dist[[1, 2, 3, 4, 8, 9, 10, 11]] = 0.2               # outliers all around (their own poses
    P[[1, 2, 3, 4, 8, 9, 10, 11]] += np.random.default_rng(0).normal(0, 0.3, (8, *P.shape[1:]))
    assert not kf.bridge_outliers(P, np.arange(13), tree, L, dist, 5, 0.15, reach=4)[1].any()


def test_default_smoothing_leaves_unrelated_poses_alone():
    """A capture of unrelated poses (the body turned half about the vertical from each frame to
    the next: hands, shoulders and feet swap sides): no run of continuing motion, the default
    fit equals the unsmoothed one joint for joint; without the move check it would not."""
    poses = [_still_body(i, np.pi * (i % 2), np.zeros(3))[0] for i in range(15)]
    a, tree, _ = fit_sequence(poses, HUMAN)
    b, _, _ = fit_sequence(poses, HUMAN, smooth=0)
    for p, q in zip(a, b):
        assert "smoothed" not in p.diagnostics
        for n in tree.names:
            assert np.array_equal(p.joints[n], q.joints[n])
    # unrelated poses (turned 1.2 rad) with two rejected frames between: the frames
    # interpolated between them step a third of the jump each, yet no run links them
    rej = []
    for i in range(30):
        p, _ = _still_body(i, 1.2 * ((i // 3) % 2), np.zeros(3))
        p.status = "matched" if i % 3 == 0 else "rejected"
        rej.append(p)
    a, _, _ = fit_sequence(rej, HUMAN)
    b2, _, _ = fit_sequence(rej, HUMAN, smooth=0)
    assert sum(bool(p.diagnostics.get("interpolated")) for p in a) == 18
    assert sum(bool(p.joints) for p in a) == 28            # the last two: nothing after
    for p, q in zip(a, b2):
        assert "smoothed" not in p.diagnostics
        for n in p.joints:
            assert np.array_equal(p.joints[n], q.joints[n])
    c, _, _ = fit_sequence(poses, HUMAN, move=None)
    assert max(np.linalg.norm(p.joints["wrist_1"] - q.joints["wrist_1"])
               for p, q in zip(c, b)) > 0.1


@pytest.mark.parametrize("age", [3, 8])
def test_a_lost_arm_is_held_up_to_hold_age_frames_after_it_was_seen(monkeypatch, age):
    """One still body (moved 1 cm per frame): frame 0 sees every part, frames 1… do not see
    hand_2. Up to ``HOLD_AGE`` frames after frame 0 the unseen arm is frame 0's arm moved
    with the root (the truth: the same rigid body); later it takes the rest pose, its upper
    arm hanging along the trunk (nothing else fills it: no hull evidence, hints or hull
    shoulders in these frames). Without the limit (None) it is held throughout."""
    opts = SequenceOptions().with_(hold_age=age)
    n = age + 4
    frames, shifts = [], []
    for i in range(n):
        s = np.array([0.01 * i, 0.0, 0.0])
        pose, parts = _still_body(i, 0.7, s)
        if i:
            pose.parts["hand_2"] = None
            del pose.diagnostics["curves"]["hand_2"]
        frames.append(pose)
        shifts.append(s)
    down = parts["crotch"] - parts["torso"]
    down /= np.linalg.norm(down)
    arm = ("shoulder_2", "elbow_2", "wrist_2", "fingertip_2")

    def held_and_hanging(out):
        res = []
        for i, p in enumerate(out[1:], 1):
            assert "wrist_2" in p.diagnostics["held_joints"]
            off = max(np.linalg.norm(p.joints[k] - (out[0].joints[k] + shifts[i])) for k in arm)
            u = p.joints["elbow_2"] - p.joints["shoulder_2"]
            res.append((off < 0.005, np.dot(u, down) / np.linalg.norm(u) > 0.999))
        return res

    res = held_and_hanging(fit_sequence(frames, HUMAN, opts, max_gap=0, smooth=0)[0])
    assert res == [(True, False)] * age + [(False, True)] * (n - 1 - age)
    opts = opts.with_(hold_age=None)
    res = held_and_hanging(fit_sequence(frames, HUMAN, opts, max_gap=0, smooth=0)[0])
    assert res == [(True, False)] * (n - 1)
