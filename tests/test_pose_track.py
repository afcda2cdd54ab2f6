"""Identities over time: hand-made crossing trajectories with arbitrary per-frame numbering."""
import numpy as np

from topopose.pose.model import load_model
from topopose.pose.pose import Pose
from topopose.sequence.track import assign_identities, track


def _crossing(n=40, seed=0, gap=(), rejected=()):
    """Two hands crossing (same point at the middle frame give or take 1 cm), feet walking;
    the per-frame numbering is a random permutation (what a per-frame matcher may output)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    a = np.stack([-0.5 + t / (n - 1), 0.3 + 0.005 * t, 1.2 + 0 * t], axis=1)     # left → right
    b = np.stack([0.5 - t / (n - 1), 0.3 - 0.005 * t + 0.01, 1.2 + 0 * t], axis=1)
    f1 = np.stack([0.3 * np.sin(t / 5), 0.1 + 0 * t, 0 * t], axis=1)
    f2 = np.stack([-0.3 * np.sin(t / 5), -0.1 + 0 * t, 0 * t], axis=1)
    poses, truth = [], []
    for i in range(n):
        sh, sf = rng.permutation(2), rng.permutation(2)
        hands, feet = [a[i], b[i]], [f1[i], f2[i]]
        parts = {"head": np.array([0, 0, 1.7]), "torso": np.array([0, 0, 1.4]),
                 "crotch": np.array([0, 0, 0.9]),
                 "hand_1": hands[sh[0]], "hand_2": hands[sh[1]],
                 "foot_1": feet[sf[0]], "foot_2": feet[sf[1]]}
        status = "rejected" if i in rejected else "matched"
        if i in gap:
            status = "failed"
        error = "confidence 0.40 below 0.7" if i in rejected else None
        poses.append(Pose(f"{i:06d}", status, 0.1, parts, error))
        truth.append((hands, feet))
    return poses, truth, (a, b, f1, f2)


def _identity_of(poses, traj, names):
    """For each matched frame, which output name holds trajectory ``traj``."""
    out = []
    for i, p in enumerate(poses):
        if p.matched:
            out.append(min(names, key=lambda nm: np.linalg.norm(p.parts[nm] - traj[i])))
    return out


def test_crossing_hands_keep_their_identity_through_a_gap():
    human = load_model("human")
    poses, _, (a, b, f1, f2) = _crossing(gap=(19, 20, 21), rejected=(15,))
    raw = _identity_of(poses, a, ["hand_1", "hand_2"])
    assert len(set(raw)) == 2                                   # the raw input does swap
    out = track(poses, human)
    assert [p.frame for p in out] == [p.frame for p in poses]
    for traj in (a, b):
        ids = _identity_of(out, traj, ["hand_1", "hand_2"])
        assert len(set(ids)) == 1, ids                          # one name all along
    for traj in (f1, f2):
        assert len(set(_identity_of(out, traj, ["foot_1", "foot_2"]))) == 1
    segs = {p.diagnostics["track"]["hand"] for p in out if p.matched}
    assert segs == {0}                                          # never lost
    assert "track" not in out[20].diagnostics                   # failed frame untouched
    assert out[20].parts["hand_1"] is poses[20].parts["hand_1"]
    assert "track" in out[15].diagnostics                 # rejected by the confidence gate only
    poses[15].error = "AHA distance 0.9 above threshold T_d = 0.4"
    assert "track" not in track(poses, human)[15].diagnostics   # rejected by the alignment
    only = track(poses, human, use_rejected=False)
    assert "track" not in only[15].diagnostics
    for traj in (a, b):
        assert len(set(_identity_of(only, traj, ["hand_1", "hand_2"]))) == 1


def test_long_gap_and_jump_reinitialize():
    t = np.arange(12, dtype=float)
    obs = [np.array([[x, 0, 0], [x, 1, 0]], float) for x in 0.01 * t]
    obs[3] = obs[3][::-1]                                       # a swap to undo
    for i in (5, 6, 7, 8, 9, 10):
        obs[i] = None                                           # a gap longer than max_gap
    obs[11] = obs[11][::-1]                                     # after the gap: per-frame order
    perm, seg = assign_identities(t, obs, gate=0.5, max_gap=5)
    assert [list(p) for p in perm[:5]] == [[0, 1], [0, 1], [0, 1], [1, 0], [0, 1]]
    assert perm[5] is None and list(perm[11]) == [0, 1] and seg[11] == 1 and seg[4] == 0
    # a misplaced part far from every prediction: an outlier, which moves no track
    obs2 = [np.array([[0, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 0], [5, 5, 5]], float),
            np.array([[0, 1, 0], [0, 0, 0]], float)]
    perm2, seg2 = assign_identities(np.arange(3.0), obs2, gate=0.5)
    assert list(seg2) == [0, 0, 0] and list(perm2[1]) == [1, 0] and list(perm2[2]) == [1, 0]
    # outliers only, for longer than max_gap: lost, re-initialized by the per-frame order
    obs3 = [np.array([[0, 0, 0], [0, 1, 0]], float)] + \
        [np.array([[5, 5, 5], [9, 9, 9]], float)] * 4
    perm3, seg3 = assign_identities(np.arange(5.0), obs3, gate=0.5, max_gap=2)
    assert list(seg3) == [0, 0, 0, 1, 1] and list(perm3[3]) == [0, 1]


def test_missing_part_keeps_the_others_identity():
    t = np.arange(6, dtype=float)
    obs = [np.array([[0.1 * i, 0, 0], [0.1 * i, 1, 0]]) for i in range(6)]
    obs[2] = np.array([[np.nan] * 3, [0.2, 0, 0]])             # hand 0 seen as "1", other lost
    obs[3] = obs[3][::-1]
    perm, seg = assign_identities(t, obs, gate=0.5)
    assert perm[2][1] == 0 and list(perm[3]) == [1, 0] and list(perm[5]) == [0, 1]
    assert set(seg) == {0}


def _walking(n=30, seed=1, misplace=()):
    """Hands swinging beside the body, feet stepping; in the frames ``misplace`` the per-frame
    result puts hand_1's position on foot_2 and foot_2's on hand_1 (what a per-frame matcher
    misplacing parts does). Per-frame numbering random, returns the true trajectories."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    h1 = np.stack([0.2 * np.sin(t / 4), 0.25 + 0 * t, 0.9 + 0 * t], axis=1)
    h2 = np.stack([-0.2 * np.sin(t / 4), -0.25 + 0 * t, 0.9 + 0 * t], axis=1)
    f1 = np.stack([-0.25 * np.sin(t / 4), 0.1 + 0 * t, 0.05 + 0 * t], axis=1)
    f2 = np.stack([0.25 * np.sin(t / 4), -0.1 + 0 * t, 0.05 + 0 * t], axis=1)
    poses = []
    for i in range(n):
        hands, feet = [h1[i], h2[i]], [f1[i], f2[i]]
        if i in misplace:
            hands, feet = [f2[i], h2[i]], [f1[i], h1[i]]
        sh, sf = rng.permutation(2), rng.permutation(2)
        parts = {"head": np.array([0, 0, 1.7]), "torso": np.array([0, 0, 1.4]),
                 "crotch": np.array([0, 0, 0.9]),
                 "hand_1": hands[sh[0]], "hand_2": hands[sh[1]],
                 "foot_1": feet[sf[0]], "foot_2": feet[sf[1]]}
        curves = {k: np.repeat(v[None], 4, axis=0) for k, v in parts.items()}
        poses.append(Pose(f"{i:06d}", "matched", 0.1, parts, None, {}, {"curves": curves}))
    return poses, (h1, h2, f1, f2)


def test_misplaced_part_is_held_at_its_prediction_and_flagged():
    human = load_model("human")
    poses, (h1, h2, f1, f2) = _walking(misplace=(12, 20, 21))
    out = track(poses, human)
    for traj, names in ((h1, ["hand_1", "hand_2"]), (h2, ["hand_1", "hand_2"]),
                        (f1, ["foot_1", "foot_2"]), (f2, ["foot_1", "foot_2"])):
        ids = _identity_of(out, traj, names)
        assert len(set(ids)) == 1, ids                         # no switch
    name_h1 = _identity_of(out, h1, ["hand_1", "hand_2"])[0]
    name_f2 = _identity_of(out, f2, ["foot_1", "foot_2"])[0]
    for i, p in enumerate(out):
        if i in (12, 20, 21):
            assert sorted(p.diagnostics["predicted"]) == sorted([name_h1, name_f2])
            # the part is at its prediction (a few cm from the truth), the per-frame position kept
            assert np.linalg.norm(p.parts[name_h1] - h1[i]) < 0.1
            assert np.linalg.norm(p.parts[name_f2] - f2[i]) < 0.1
            assert np.allclose(p.diagnostics["misplaced"][name_h1], f2[i], atol=1e-4)
            assert name_h1 not in p.diagnostics["curves"] and "head" in p.diagnostics["curves"]
            assert set(p.diagnostics["track"].values()) == {0}
        else:
            assert "predicted" not in p.diagnostics                   # never flagged otherwise
            assert np.allclose(p.parts[name_h1], h1[i])
    # the raw numbering does follow the misplaced part: the oracle can see the difference
    assert len(set(_identity_of(poses, h1, ["hand_1", "hand_2"]))) == 2


def test_consistently_different_for_several_frames_reinitializes():
    # identity 0 moves smoothly, then from frame 6 on the per-frame result sees it 1 m away,
    # consistently (a smooth trajectory of its own): followed after `reinit` frames
    t = np.arange(14, dtype=float)
    obs = [np.array([[0.02 * i, 0, 0], [0.02 * i, 2, 0]]) for i in range(14)]
    for i in range(6, 14):
        obs[i][0] = [0.02 * i, 0, 1.0]
    perm, seg, held, pred = assign_identities(t, obs, gate=0.3, reinit=3, detail=True)
    assert not held.any()                       # never judged misplaced: nothing to hold
    assert [list(p) for p in perm] == [[0, 1]] * 14
    assert list(seg[:8]) == [0] * 8 and list(seg[8:]) == [1] * 6     # re-initialized at frame 8
    assert np.allclose(pred[9, 0], [0.02 * 8 + 0.5 * 0.02, 0, 1.0])  # now following it
    # a jump for 4 frames judged misplaced (out of reach): held, never followed, no new segment
    obs = [np.array([[0.02 * i, 0, 0], [0.02 * i, 2, 0]]) for i in range(14)]
    for i in range(6, 10):
        obs[i][0] = [0.02 * i, 0, 1.0]
    bad = [np.array([6 <= i < 10, False]) for i in range(14)]
    perm, seg, held, pred = assign_identities(t, obs, gate=0.3, reinit=3, misplaced=bad,
                                              detail=True)
    assert list(np.flatnonzero(held[:, 0])) == [6, 7, 8, 9] and not held[:, 1].any()
    assert set(seg) == {0} and [list(p) for p in perm] == [[0, 1]] * 14
    assert np.allclose(pred[9, 0, 1:], [0, 0])                        # on its trajectory
    assert abs(pred[9, 0, 0] - 0.02 * 9) < 0.05
    # held for longer than max_gap: the identity goes stale and takes the per-frame result
    perm, seg, held, pred = assign_identities(t, obs, gate=0.3, reinit=3, max_gap=2,
                                              misplaced=bad, detail=True)
    assert list(np.flatnonzero(held[:, 0])) == [6, 7] and set(seg) == {0}


def test_lost_across_a_gap_relinks_by_position_relative_to_the_anchor():
    # the subject walks 0.05 m / frame along x; hands on either side of the torso (y = ±0.25)
    # swing ±0.2 m; 8 frames unseen (> max_gap): tracking is lost, the walk has moved 0.45 m
    # and the per-frame numbering of the first frame after the gap is swapped
    t = np.array([0, 1, 2, 3, 4, 5, 14, 15, 16], float)
    torso = np.stack([0.05 * t, 0 * t, 1.4 + 0 * t], axis=1)
    h = [torso + np.stack([s * 0.2 * np.sin(t / 3), y + 0 * t, -0.5 + 0 * t], axis=1)
         for s, y in ((1, 0.25), (-1, -0.25))]
    obs = [np.stack([h[0][i], h[1][i]]) for i in range(len(t))]
    obs[6] = obs[6][::-1]
    perm, seg = assign_identities(t, obs, gate=0.3, max_gap=5, anchors=torso)
    assert list(seg) == [0] * 6 + [1] * 3                    # lost, a new segment
    assert list(perm[6]) == [1, 0] and list(perm[8]) == [0, 1]   # but the same identities
    perm, seg = assign_identities(t, obs, gate=0.3, max_gap=5)   # without anchors:
    assert list(perm[6]) == [0, 1]                           # the per-frame numbering (swapped)
    perm, seg = assign_identities(t, obs, gate=0.3, max_gap=5, anchors=torso, relink=6)
    assert list(perm[6]) == [0, 1]                           # gap longer than relink


def test_relink_of_feet_compares_the_lateral_side_only():
    # feet 0.2 m apart (y = ±0.1), swinging ±0.3 m fore and aft while the subject walks along
    # x; after a 9-frame gap their fore-aft order has reversed: in 3D each foot is nearer the
    # other's last relative position, laterally each stays on its side
    t = np.array([0, 1, 2, 3, 4, 14, 15], float)
    crotch = np.stack([0.05 * t, 0 * t, 0.9 + 0 * t], axis=1)
    swing = np.array([0.3, 0.3, 0.3, 0.3, 0.3, -0.3, -0.3])
    fa = crotch + np.stack([swing, 0.1 + 0 * t, -0.85 + 0 * t], axis=1)
    fb = crotch + np.stack([-swing, -0.1 + 0 * t, -0.85 + 0 * t], axis=1)
    obs = [np.stack([fa[i], fb[i]]) for i in range(len(t))]
    up = np.tile([0.0, 0.0, 1.0], (len(t), 1))
    perm, seg = assign_identities(t, obs, gate=0.3, anchors=crotch, up=up)
    assert seg[5] == 1 and list(perm[5]) == [0, 1]          # lost, relinked laterally: right
    perm, seg = assign_identities(t, obs, gate=0.3, anchors=crotch)
    assert list(perm[5]) == [1, 0]                          # in 3D: the oracle sees the swap


def test_a_part_on_another_groups_previous_position_is_flagged():
    from topopose.sequence.track import on_other_parts

    def pose(i, h1, f1):
        return Pose(f"{i:06d}", "matched", 0.1, {"hand_1": np.array(h1, float),
                                                 "foot_1": np.array(f1, float),
                                                 "torso": np.array([0, 0, 1.4])})
    poses = [pose(0, [0.3, 0.2, 0.9], [0.2, 0.1, 0.05]),
             pose(1, [0.25, 0.1, 0.08], [0.6, 0.1, 0.05]),        # hand where the foot was
             pose(2, [0.3, 0.2, 0.9], [0.25, 0.1, 0.05])]
    near = on_other_parts(poses, [True] * 3, ["hand_1"], ["foot_1"], 0.1)
    assert near[0] is None and list(near[1]) == [True] and list(near[2]) == [False]
    # the torso is not another group: a hand near it is not suspicious
    assert list(on_other_parts(poses, [True] * 3, ["hand_1"], [], 0.1)[1]) == [False]


def test_when_nearly_every_frame_is_rejected_the_rejected_frames_are_tracked():
    """A recording whose frames all miss T_d (status rejected, as the real 4-camera recording):
    the misplaced parts are held only because the rejected frames become observations
    (FEW_USABLE); with ``few=0`` they are left as the per-frame result put them."""
    import copy
    from dataclasses import replace

    human = load_model("human")
    poses, (h1, h2, f1, f2) = _walking(misplace=(12, 20))
    poses = [replace(p, status="rejected", error="AHA distance 0.6 above threshold T_d = 0.4")
             if i != 3 else p for i, p in enumerate(poses)]
    off = track(copy.deepcopy(poses), human, few=0)
    out = track(poses, human)
    name_f2 = _identity_of(out, f2, ["foot_1", "foot_2"])[0]
    for i, p in enumerate(out):
        if i in (12, 20):
            assert name_f2 in p.diagnostics["predicted"]
            assert np.linalg.norm(p.parts[name_f2] - f2[i]) < 0.1
        else:
            assert "predicted" not in p.diagnostics
    assert all(p.status == "rejected" for i, p in enumerate(out) if i != 3)   # status untouched
    assert not any(p.diagnostics.get("predicted") for p in off)
    assert all("track" not in p.diagnostics for i, p in enumerate(off) if i != 3)


def _phantom_jump(n=16, jump=(8, 9, 10), seed=2):
    """Two hands moving smoothly (1 cm / frame); in the frames ``jump`` the per-frame result puts
    hand 0 at the end of a phantom branch 0.6 m away (beyond the gate), while the real hand's
    leaf is in the frame's free leaves (noisy by ≤ 1 cm), with a decoy leaf 0.5 m away."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    a = np.stack([0.01 * t, 0.3 + 0 * t, 1.2 + 0 * t], axis=1)
    b = np.stack([0.01 * t, -0.3 + 0 * t, 1.2 + 0 * t], axis=1)
    obs, cands = [], []
    for i in range(n):
        o = np.stack([a[i], b[i]])
        free = [a[i] + np.array([0.0, 0.0, 0.5])]                     # decoy
        if i in jump:
            o[0] = a[i] + np.array([0.0, -0.6, -0.2])                  # phantom branch end
            free.append(a[i] + rng.uniform(-0.006, 0.006, 3))          # the real hand's leaf
        obs.append(o)
        cands.append(np.array(free))
    return t, obs, cands, a, b


def test_outlier_snaps_to_the_free_leaf_nearest_its_prediction():
    t, obs, cands, a, b = _phantom_jump()
    before = [o.copy() for o in obs]
    perm, seg, held, pred, snapped = assign_identities(t, obs, gate=0.3, reinit=3, detail=True,
                                                       candidates=cands)
    assert all(np.array_equal(x, y) for x, y in zip(obs, before))    # input not modified
    moved = ~np.isnan(snapped).any(axis=2)
    assert list(np.flatnonzero(moved[:, 0])) == [8, 9, 10] and not moved[:, 1].any()
    for i in (8, 9, 10):
        assert np.linalg.norm(snapped[i, 0] - a[i]) < 0.011        # the real hand, not the decoy
    assert set(seg) == {0} and [list(p) for p in perm] == [[0, 1]] * len(t)
    assert not held.any()
    assert np.linalg.norm(pred[11, 0] - a[11]) < 0.03               # the track kept following a
    # without candidates the phantom branch is followed after `reinit` frames
    perm, seg, held, pred = assign_identities(t, obs, gate=0.3, reinit=3, detail=True)
    assert len(set(seg)) > 1 and np.linalg.norm(pred[11, 0] - a[11]) > 0.3
    # a real arm moving fast but within the gate is never moved, even next to a free leaf
    # nearer its prediction; nor is a part of a track not yet established (frames < reinit)
    t2, obs2, _, a2, _ = _phantom_jump(jump=())
    obs2[8][0] = a2[8] + [0.0, 0.0, 0.25]
    obs2[1][0] = a2[1] + [0.0, 0.0, 0.6]
    near = [np.array([a2[i] + [0.0, 0.0, 0.01]]) for i in range(len(t2))]
    *_, snapped = assign_identities(t2, obs2, gate=0.3, reinit=3, detail=True, candidates=near)
    assert np.isnan(snapped).all()
    # a snap radius below the leaf's distance to the prediction: no snap
    *_, snapped = assign_identities(t, obs, gate=0.3, reinit=3, detail=True, candidates=cands,
                                    snap=0.002)
    assert np.isnan(snapped).all()


def test_a_snap_does_not_keep_a_track_on_a_phantom_leaf():
    """From frame 8 the per-frame result follows the real foot on a trajectory of its own
    (0.5 m from the track, 3 cm / frame), while a phantom leaf stays where the track is: the
    leaf is taken for ``max_gap`` frames (8–12), then the per-frame trajectory re-initializes
    the identity (frame 13) and is followed; the other foot is never touched (the real
    recording, frames 26–48: a raised foot held on a phantom leaf for 23 frames)."""
    n = 24
    t = np.arange(n, dtype=float)
    a = np.stack([0.0 * t, 0.15 + 0 * t, 0.1 + 0 * t], axis=1)
    b = np.stack([0.0 * t, -0.15 + 0 * t, 0.1 + 0 * t], axis=1)
    real = a.copy()
    real[8:, 0] = 0.5 + 0.03 * (t[8:] - 8)
    obs = [np.stack([real[i], b[i]]) for i in range(n)]
    cands = [np.array([a[i] + [0.0, 0.0, 0.02]]) for i in range(n)]
    perm, seg, held, pred, snapped = assign_identities(t, obs, gate=0.3, reinit=3, max_gap=5,
                                                       detail=True, candidates=cands)
    moved = ~np.isnan(snapped).any(axis=2)
    assert list(np.flatnonzero(moved[:, 0])) == [8, 9, 10, 11, 12] and not moved[:, 1].any()
    assert [list(p) for p in perm] == [[0, 1]] * n and not held.any()
    assert seg[12] == seg[0] and seg[13] > seg[12]
    for i in range(15, n):
        assert np.linalg.norm(pred[i, 0] - real[i]) < 0.05        # following the real foot
        assert np.linalg.norm(pred[i, 1] - b[i]) < 0.01
    # the rule before: snaps never give way, the track stays on the phantom leaf
    *_, snapped = assign_identities(t, obs, gate=0.3, reinit=3, max_gap=5, detail=True,
                                    candidates=cands, snap_run=10 ** 9)
    assert (~np.isnan(snapped[8:, 0]).any(axis=1)).all()


def test_track_moves_a_snapped_part_to_its_leaf_and_flags_it():
    human = load_model("human")
    poses, (h1, h2, f1, f2) = _walking()
    for i, p in enumerate(poses):
        p.diagnostics["free_leaves"] = [[round(float(c), 4) for c in h1[i] + [0, 0, 0.45]]]
    wrong = h1[14] + np.array([0.0, -0.5, 0.2])
    k = min(("hand_1", "hand_2"), key=lambda nm: np.linalg.norm(poses[14].parts[nm] - h1[14]))
    poses[14].parts[k] = wrong
    poses[14].diagnostics["free_leaves"].append([float(c) for c in h1[14]])
    out = track(poses, human)
    name = _identity_of(out, h1, ["hand_1", "hand_2"])[0]
    assert len(set(_identity_of(out, h1, ["hand_1", "hand_2"]))) == 1
    q = out[14]
    assert q.diagnostics["snapped"] == [name] and "predicted" not in q.diagnostics
    assert np.allclose(q.parts[name], h1[14]) and np.allclose(q.diagnostics["misplaced"][name], wrong, atol=1e-4)
    assert name not in q.diagnostics["curves"]
    assert all("snapped" not in p.diagnostics for i, p in enumerate(out) if i != 14)
    off = track(poses, human, snap=False)[14]
    assert "snapped" not in off.diagnostics and np.allclose(off.parts[name], wrong)


def test_free_leaves_are_the_unmatched_degree_one_vertices():
    from topopose.match.tree import Tree
    from topopose.frame.tips import free_leaves

    # a star 0 – {1, 2, 3} with a tail 3 – 4: leaves 1, 2, 4
    pos = {v: np.array([v, 0.5 * v, 0.0]) for v in range(5)}
    tree = Tree([(0, 1, 1.0), (0, 2, 1.0), (0, 3, 1.0), (3, 4, 1.0)], positions=pos)
    assert free_leaves(tree, {"head": 1, "torso": 0}) == [[2.0, 1.0, 0.0], [4.0, 2.0, 0.0]]
    assert free_leaves(tree, {"a": 1, "b": 2, "c": 4, "d": None}) == []


def test_estimator_records_free_leaves_and_nothing_else_changes():
    """A synthetic capsule human: the frame's ``free_leaves`` are the data tree's degree-1
    vertices the alignment left unmatched (brute force over the edges); switched off
    (``FrameEstimator.leaves = False``) the pose is the same, without them."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator

    cap = synthetic_capture("human", frames=1, seed=5, noise=1)
    est = FrameEstimator(cap, "human", resolution=60)
    p, det = est.estimate(0, detail=True)
    ends = [v for v in det.data.vertices
            if sum(v in (a, b) for a, b, _ in det.data.edges) == 1]
    mapped = set(det.alignment.mapping.values())
    want = sorted(np.round(det.data.positions[v], 4).tolist() for v in ends if v not in mapped)
    assert sorted(p.diagnostics["free_leaves"]) == want
    assert len(ends) > len(want)                       # the matched extremities are left out
    est.leaves = False
    q = est.estimate(0)
    assert "free_leaves" not in q.diagnostics and q.status == p.status
    for k, x in p.parts.items():
        assert (x is None and q.parts[k] is None) or np.array_equal(x, q.parts[k])


def test_ungated_matches_the_frames_only_the_gate_rejected_then_every_rejected_one():
    """Level 1 lifts the frames whose every reason is the gate's: not one rejected for its AHA
    distance, nor one whose foot lies on an arm's branch (the anatomy clause, alone or after
    the gate's); level 2 lifts every rejected frame."""
    from topopose.sequence.track import ungated

    foot = ("anatomy: foot_1 0.62 of its leg's length above the subject's lowest point (at "
            "most 0.5: a foot on an arm's branch)")
    poses = [Pose(frame="0", status="matched"),
             Pose(frame="1", status="rejected", error="confidence gate: silhouette unexplained"),
             Pose(frame="2", status="rejected", error="AHA distance 0.9 above threshold"),
             Pose(frame="3", status="failed", error="hull: empty"),
             Pose(frame="4", status="rejected",
                  error="confidence gate: silhouette unexplained 0.30 (at most 0.2)",
                  diagnostics={"x": 1}),
             Pose(frame="5", status="rejected",
                  error=f"confidence gate: silhouette unexplained 0.30 (at most 0.2); {foot}"),
             Pose(frame="6", status="rejected", error=foot)]
    assert [p.status for p in ungated(poses)] == \
        ["matched", "matched", "rejected", "failed", "matched", "rejected", "rejected"]
    lifted = ungated(poses, threshold=True)
    assert [p.status for p in lifted] == ["matched", "matched", "matched", "failed", "matched",
                                          "matched", "matched"]
    assert [p.error for p in lifted] == [None, None, None, "hull: empty", None, None, None]
    lifted[4].diagnostics["x"] = 2                       # copies: the run's poses unchanged
    assert poses[4].diagnostics == {"x": 1} and poses[1].status == "rejected"
