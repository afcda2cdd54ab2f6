"""Identities over time: hand-made crossing trajectories with arbitrary per-frame numbering."""
import numpy as np

from topopose.pose.model import load_model
from topopose.pose.pose import Pose
from topopose.pose.track import assign_identities, track


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
