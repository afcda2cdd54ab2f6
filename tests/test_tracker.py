"""The articulated tracker (topopose.sequence) on synthetic ground truth: a capsule body whose
true poses are known, its hull voxelized from those capsules."""
import numpy as np
import pytest

from topopose.hull.volume import Volume
from topopose.sequence.body import (CapsuleBody, bone_directions, group_shape, joint_positions,
                                    kabsch, radius_profile, snap, beyond_capsules, reach_beyond,
                                    trunk_sides)
from topopose.sequence.smoothing import smooth_track
from topopose.sequence.limbs import limb_pairs, limb_starts, mirror_groups
from topopose.sequence.tracker import (TrackOptions, agreement, fit_frame, frame_data,
                                       track_sequence)

VOXEL = 0.02
#: chest (root), pelvis below it, two arms (shoulder, elbow, wrist), two legs (hip, knee)
NAMES = ("chest", "pelvis", "shoulder_1", "elbow_1", "wrist_1", "shoulder_2", "elbow_2",
         "wrist_2", "hip_1", "knee_1", "hip_2", "knee_2")
PARENTS = np.array([-1, 0, 0, 2, 3, 0, 5, 6, 1, 8, 1, 10])
LENGTHS = np.array([np.nan, 0.45, 0.18, 0.28, 0.25, 0.18, 0.28, 0.25, 0.1, 0.42, 0.1, 0.42])
RADII = np.array([np.nan, 0.11, 0.06, 0.045, 0.04, 0.06, 0.045, 0.04, 0.07, 0.06, 0.07, 0.06])


def _unit(*v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def make_body() -> CapsuleBody:
    order = (0, 1, 2, 5, 8, 10, 3, 6, 9, 11, 4, 7)
    groups = ((2, 5), (1, 8, 10))
    D = rest_directions()
    return CapsuleBody(NAMES, PARENTS, LENGTHS.copy(), RADII.copy(), order, groups,
                       tuple(D[list(g)] for g in groups), trunk=1)


def rest_directions():
    D = np.zeros((len(NAMES), 3))
    D[1] = (0, 0, -1)
    D[2], D[5] = (0, 1, 0), (0, -1, 0)
    D[8], D[10] = _unit(0, 1, -0.3), _unit(0, -1, -0.3)
    for j in (3, 4):
        D[j] = _unit(0, 1, -0.2)            # arm 1 out to the side
    for j in (6, 7):
        D[j] = (0, 0, -1)                   # arm 2 hanging
    for j in (9, 11):
        D[j] = (0, 0, -1)
    return D


def arm_down(D, s):
    """Arm 1 turned from out to the side (s = 0) down against the trunk (s = 1)."""
    D = D.copy()
    out, down = _unit(0, 1, -0.2), _unit(0, 0.05, -1)
    for j in (3, 4):
        a = np.arccos(np.clip(out @ down, -1, 1)) * s
        axis = _unit(*np.cross(out, down))
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
        D[j] = R @ out
    return D


def hull_of(body, P, lo=(-0.6, -0.75, 0.0), hi=(0.7, 0.9, 2.0)) -> Volume:
    """The union of the body's capsules voxelized (voxel centres within a capsule)."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    n = np.round((hi - lo) / VOXEL).astype(int) + 1
    occ = np.zeros(n, bool)
    for A, B, r in zip(*body.capsules(P)):
        a = np.maximum(np.floor((np.minimum(A, B) - r - lo) / VOXEL).astype(int), 0)
        b = np.minimum(np.ceil((np.maximum(A, B) + r - lo) / VOXEL).astype(int) + 1, n)
        g = np.stack(np.meshgrid(*[lo[k] + VOXEL * np.arange(a[k], b[k]) for k in range(3)],
                                 indexing="ij"), axis=-1)
        ab = B - A
        t = np.clip((g - A) @ ab / (ab @ ab), 0, 1)
        occ[a[0]:b[0], a[1]:b[1], a[2]:b[2]] |= \
            np.linalg.norm(g - (A + t[..., None] * ab), axis=-1) <= r
    return Volume(occ, lo, VOXEL)


def pose(D, root=(0.0, 0.0, 1.3)):
    return joint_positions(make_body(), np.asarray(root, float), D)


def run(truth, conf, opts=None):
    body = make_body()
    vols = [hull_of(body, P) for P in truth]
    align = np.full_like(truth, np.nan)
    align[conf] = truth[conf]
    rng = np.random.default_rng(1)
    return track_sequence(body, lambda i: frame_data(vols[i], 400, rng), align,
                          opts or TrackOptions(iterations=6))


def arm_errors(track, truth, joints=(3, 4)):
    return np.linalg.norm(track.joints[:, joints] - truth[:, joints], axis=2)


def test_rigid_helpers():
    rng = np.random.default_rng(0)
    V = rng.normal(size=(4, 3))
    a = rng.normal(size=3)
    t = np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]]) / t
    R = np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K
    assert np.allclose(kabsch(V, V @ R.T), R)
    assert np.allclose(group_shape([V, V @ R.T]), V / np.linalg.norm(V, axis=1)[:, None])
    body = make_body()
    P = pose(rest_directions())
    root, D = snap(body, P)
    assert np.allclose(joint_positions(body, root, D), P)
    assert np.allclose(bone_directions(body, P)[1:], rest_directions()[1:])


def test_mirror_groups_pair_the_numbered_joints():
    assert sorted(mirror_groups(NAMES)) == [(2, 5), (3, 6), (4, 7), (8, 10), (9, 11)]


def test_fit_recovers_a_perturbed_pose():
    body = make_body()
    truth = pose(arm_down(rest_directions(), 0.3))
    data = frame_data(hull_of(body, truth), 400)
    D = bone_directions(body, truth)
    D[3:5] = arm_down(rest_directions(), 0.6)[3:5]       # the arm 25° off
    start = joint_positions(body, truth[0] + 0.03, D)
    P = fit_frame(body, data, start, TrackOptions(iterations=10))
    assert np.linalg.norm(P - truth, axis=1).max() < 0.03
    assert agreement(body, data, P) > agreement(body, data, start)


def test_follows_an_arm_onto_the_body_and_away():
    n = 24
    s = np.r_[np.linspace(0, 1, n // 2), np.linspace(1, 0, n // 2)]
    truth = np.stack([pose(arm_down(rest_directions(), x), (0.01 * i, 0.0, 1.3))
                      for i, x in enumerate(s)])
    conf = np.zeros(n, bool)
    conf[0] = True                      # only the first frame is confident: the rest tracked
    tr = run(truth, conf)
    err = arm_errors(tr, truth)
    assert err.max() < 0.03, err.max(axis=1)
    assert all(st in ("matched", "tracked") for st in tr.status)


def test_reinitializes_after_a_jump(monkeypatch):
    """Between frames 5 and 6 the subject turns round (180°) and raises arm 1: the fit from
    the previous pose settles with the arms exchanged; the confident frame 8 re-initializes
    it, and the frames between are tracked back from there. Each run fits a frame once (no
    refit of a lost frame): the run from frame 0 goes on from 8 to the end (frames 1–11), the
    run back from 8 fits 7–1."""
    from topopose.sequence import tracker

    fitted = []
    fit = tracker._Fitter.fit

    def counted(self, root, D, data, align=None, pred=None):
        fitted.append(pred is not None)         # a run's frame, not a confident frame's start
        return fit(self, root, D, data, align, pred)

    monkeypatch.setattr(tracker._Fitter, "fit", counted)
    n = 12
    turn = np.diag([-1.0, -1.0, 1.0])
    D = rest_directions()
    D[3:5] = _unit(0, 0.3, 1)
    truth = np.stack([pose(rest_directions()) for _ in range(6)]
                     + [pose(D @ turn.T, (0.3, 0.1, 1.3)) for _ in range(6)])
    conf = np.zeros(n, bool)
    conf[[0, 8]] = True
    tr = run(truth, conf, TrackOptions(iterations=6, recover=0.0))
    assert list(tr.reinitialized) == [8]
    assert sum(fitted) == 11 + 7
    assert tr.status[8] == "matched" and tr.segment[6] == 8
    assert np.linalg.norm(tr.joints - truth, axis=2).max() < 0.03


def test_a_wrong_confident_frame_does_not_pull_the_track():
    """Frame 6's alignment is wrong (arm 1 raised where the hull has it out to the side):
    the prediction's arm is far from its arm, which does not pull the fit; the track stays on
    the hull's arm and the frame is not ``matched``."""
    n = 12
    D = rest_directions()
    truth = np.stack([pose(D, (0.01 * i, 0.0, 1.3)) for i in range(n)])
    raised = D.copy()
    raised[3:5] = _unit(0, 0.2, 1)
    align = np.full_like(truth, np.nan)
    align[0] = truth[0]
    align[6] = pose(raised, (0.06, 0.0, 1.3))
    body = make_body()
    vols = [hull_of(body, P) for P in truth]
    rng = np.random.default_rng(1)
    tr = track_sequence(body, lambda i: frame_data(vols[i], 400, rng), align,
                        TrackOptions(iterations=6))
    assert tr.status[6] != "matched" and not tr.reinitialized
    assert np.linalg.norm(tr.joints - truth, axis=2).max() < 0.03


def test_covers_the_frames_before_the_first_confident_one():
    n = 34
    s = 0.5 - 0.5 * np.cos(np.linspace(0, 2 * np.pi, n))
    truth = np.stack([pose(arm_down(rest_directions(), x), (0.0, 0.008 * i, 1.3))
                      for i, x in enumerate(s)])
    conf = np.zeros(n, bool)
    conf[30] = True
    tr = run(truth, conf)
    assert not np.isnan(tr.joints).any()
    assert np.linalg.norm(tr.joints - truth, axis=2).max() < 0.04
    assert tr.segment[0] == 30


def test_limb_starts_hang_along_the_trunk_and_mirror_the_twin():
    """The arms and the legs are the mirrored pairs; an arm's starts hang it along the
    trunk (chest → pelvis, straight down here) with its twin, or alone, or mirror its twin
    across the plane between the shoulders (arm 2 hangs: arm 1 hangs on its side too)."""
    body = make_body()
    assert limb_pairs(body) == [((2, 5), ([3, 4], [6, 7])), ((8, 10), ([9], [11]))]
    D = rest_directions()
    both, one, two, mirror_one, mirror_two = limb_starts(body, D, pose(D), limb_pairs(body)[0])
    down = np.array([0.0, 0.0, -1.0])
    assert np.allclose(both[[3, 4, 6, 7]], down) and np.allclose(both[8:], D[8:])
    assert np.allclose(one[[3, 4]], down) and np.allclose(one[[6, 7]], D[[6, 7]])
    assert np.allclose(two[[6, 7]], down) and np.allclose(two[[3, 4]], D[[3, 4]])
    assert np.allclose(mirror_one[[3, 4]], down)
    assert np.allclose(mirror_two[[6, 7]], _unit(0, -1, -0.2))      # arm 1 seen from side 2


def test_a_lost_arm_is_found_again():
    """Between frames 5 and 6 arm 1 drops from raised to hanging against the trunk, too far
    for the fit from the prediction: without a refit of a lost frame the arm stays lost
    (0.5 m off); the refit from the limbs' starts finds it and the track goes on with it."""
    raised = rest_directions()
    raised[3:5] = _unit(0, 0.3, 1)
    truth = np.stack([pose(raised)] * 6 + [pose(arm_down(rest_directions(), 1.0))] * 6)
    conf = np.zeros(len(truth), bool)
    conf[0] = True
    lost = arm_errors(run(truth, conf, TrackOptions(iterations=6, recover=0.0, smooth=0)), truth)
    found = arm_errors(run(truth, conf, TrackOptions(iterations=6, smooth=0)), truth)
    assert lost[6:].max(axis=1).min() > 0.3
    assert found.max() < 0.03, found.max(axis=1)


def test_smooth_track_smooths_each_segment_on_the_body_lengths():
    """A smooth arm motion with jittered directions, in two segments with a jump between
    them: the smoothed track is nearer the truth, keeps the body's bone lengths, and neither
    segment reads the other's frames; a NaN frame and the lone frame after it stay as they are."""
    body = make_body()
    rng = np.random.default_rng(3)
    n = 30
    s = np.linspace(0, 1, n)
    truth = np.stack([pose(arm_down(rest_directions(), x), (0.01 * i, 0.0, 1.3))
                      for i, x in enumerate(s)])
    truth[15:] += (0.5, 0.0, 0.0)                   # the second segment jumps away
    noisy = np.stack([joint_positions(body, *snap(body, P + rng.normal(0, 0.01, P.shape)))
                      for P in truth])
    noisy[28] = np.nan
    segment = np.r_[np.zeros(15, int), np.ones(15, int)]
    out = smooth_track(body, noisy, segment, 9)
    ok = np.arange(28)
    err = lambda P: np.linalg.norm(P[ok] - truth[ok], axis=2).mean()   # noqa: E731
    assert err(out) < 0.7 * err(noisy)
    assert np.isnan(out[28]).all() and np.array_equal(out[29], noisy[29])
    kids = [j for j in range(len(NAMES)) if PARENTS[j] >= 0]
    bone = np.linalg.norm(out[:28, kids] - out[:28][:, PARENTS[kids]], axis=2)
    assert np.allclose(bone, LENGTHS[kids], atol=1e-9)
    alone = smooth_track(body, noisy[:15], segment[:15], 9)
    assert np.allclose(out[:15], alone)             # the jump does not leak back
    assert np.array_equal(smooth_track(body, noisy, segment, 1), noisy, equal_nan=True)


def test_agreement_compares_poses_not_bone_lengths():
    """The confident frames' skeletons carry the kinematic fit's lengths (here the arms
    0.7 × the body's) while the tracked body has its own: the track agrees with every
    alignment (all ``matched``, no restart), since the alignment's pose is compared on the
    body's lengths (the wrists lie 0.16 m apart)."""
    n = 8
    truth = np.stack([pose(arm_down(rest_directions(), 0.1 * i), (0.01 * i, 0.0, 1.3))
                      for i in range(n)])
    short = make_body()
    short.lengths[[3, 4, 6, 7]] *= 0.7
    align = np.stack([joint_positions(short, P[0], bone_directions(short, P)) for P in truth])
    assert np.linalg.norm(align - truth, axis=2).max() > TrackOptions().agree
    body = make_body()
    vols = [hull_of(body, P) for P in truth]
    rng = np.random.default_rng(1)
    tr = track_sequence(body, lambda i: frame_data(vols[i], 400, rng), align,
                        TrackOptions(iterations=6))
    assert list(tr.status) == ["matched"] * n and not tr.reinitialized


@pytest.mark.parametrize("motion", ["hang", "hips", "fold", "jump", "crouch"])
def test_touching_motions_are_continuous(motion):
    from topopose.synth.capture import synthetic_capture

    cap = synthetic_capture("body", frames=4, seed=3, cameras=2, size=(64, 48), motion=motion)
    J = [np.array(list(cap.gt["frames"][f]["joints"].values())) for f in cap.frames]
    steps = [np.linalg.norm(b - a, axis=1).max() for a, b in zip(J, J[1:])]
    assert max(steps) < 0.2                     # 25 frames/s: no joint jumps


def test_trunk_sides_join_the_trunks_junctions():
    W = trunk_sides(NAMES, PARENTS, (0.6, 1.0))
    P = pose(rest_directions())
    assert W.shape == (2, 2, len(NAMES)) and np.allclose(W.sum(axis=2), 1.0)
    for k, (s, h) in enumerate(((2, 8), (5, 10))):       # shoulder_k, hip_k
        assert np.allclose(W[k, 0] @ P, P[0] + 0.6 * (P[s] - P[0]))
        assert np.allclose(W[k, 1] @ P, P[h])
    assert trunk_sides(("a", "b", "c"), [-1, 0, 1]) is None


def test_reach_beyond_finds_where_the_hull_ends():
    """A limb's hull goes on 0.2 m beyond the skeleton's tip joint: the reach is the rest
    of its capsule's axis (the hull's end less the radius)."""
    names, parents = ("a", "b"), np.array([-1, 0])
    lengths, radius = np.array([np.nan, 0.3]), 0.08
    full = CapsuleBody(names, parents, np.array([np.nan, 0.5]), np.array([np.nan, radius]),
                       (0, 1))
    P = np.array([[0.0, 0.0, 0.6], [0.0, 0.0, 1.1]])
    vol = hull_of(full, P)
    tip = P[0] + 0.3 * (P[1] - P[0]) / 0.5
    reach = reach_beyond(vol, np.array([P[0], tip]), parents, [0, 1])
    assert np.isnan(reach[0]) and abs(reach[1] - 0.2) < 1.5 * VOXEL
    W = beyond_capsules(parents, lengths, reach, VOXEL)
    assert np.allclose(W[0, 1] @ np.array([P[0], tip]), tip + reach[1] * np.array([0, 0, 1]))
    depth = radius_profile(vol, W[:, 0] @ np.array([P[0], tip]), W[:, 1] @ np.array([P[0], tip]))
    assert abs(np.median(depth) - radius) < 1.5 * VOXEL


def test_reach_beyond_a_heel():
    """A shank, a foot at a right angle and a heel 0.08 m on behind the ankle along the
    shank: the ankle (a joint with a child) reaches the heel's axis; the toe, not asked, none."""
    names, parents = ("knee", "ankle", "toe"), np.array([-1, 0, 1])
    P = np.array([[0.0, 0.0, 0.6], [0.0, 0.0, 0.2], [0.18, 0.0, 0.2]])
    heel = np.zeros((1, 2, 3))
    heel[0, 0, 1], heel[0, 1, 1], heel[0, 1, 0] = 1.0, 1.2, -0.2      # 0.2 × the shank: 0.08 m
    truth = CapsuleBody(names, parents, np.array([np.nan, 0.4, 0.18]),
                        np.array([np.nan, 0.05, 0.04]), (0, 1, 2), ends=heel,
                        extra_radii=np.array([0.04]))
    reach = reach_beyond(hull_of(truth, P), P, parents, [1])
    assert np.isnan(reach[[0, 2]]).all() and abs(reach[1] - 0.08) < 1.5 * VOXEL
    W = beyond_capsules(parents, truth.lengths, reach, VOXEL)
    assert np.allclose(W[0, 1] @ P, P[1] + reach[1] * np.array([0, 0, -1]))
    from topopose.sequence.body import learn_body
    from topopose.sequence.skeleton_fit import KinematicTree

    tree = KinematicTree(list(names), list(names), [-1, 0, 1], [("a", "b")] * 3, [0.0, 0.5, 1.0],
                         extends=[False, True, False])
    frames = [(hull_of(truth, P), P)]
    body = learn_body(tree, truth.lengths, frames, VOXEL, sides=None)
    A, B, r = body.capsules(P)
    assert body.n_extra == 1 and np.allclose(A[-1], P[1])
    assert abs(np.linalg.norm(B[-1] - P[1]) - 0.08) < 1.5 * VOXEL and B[-1][2] < P[1][2]
    assert abs(r[-1] - 0.04) < 1.5 * VOXEL
    assert learn_body(tree, truth.lengths, frames, VOXEL, sides=None, extends=False).n_extra == 0


def test_fit_with_extra_capsules_recovers_a_perturbed_pose():
    """The body with its trunk's sides and a capsule on beyond wrist 2: the hull of all its
    capsules; the fit from a start 25° off along arm 1 and 3 cm off at the root."""
    from dataclasses import replace

    base = make_body()
    ends = np.concatenate([trunk_sides(NAMES, PARENTS, (0.6, 1.0)),
                           beyond_capsules(PARENTS, LENGTHS, np.r_[[np.nan] * 7, 0.1,
                                                                [np.nan] * 4], VOXEL)])
    body = replace(base, ends=ends, extra_radii=np.array([0.09, 0.09, 0.04]))
    truth = joint_positions(body, np.array([0.0, 0.0, 1.3]), arm_down(rest_directions(), 0.3))
    data = frame_data(hull_of(body, truth), 400)
    D = bone_directions(body, truth)
    D[3:5] = arm_down(rest_directions(), 0.6)[3:5]
    start = joint_positions(body, truth[0] + 0.03, D)
    P = fit_frame(body, data, start, TrackOptions(iterations=10))
    assert np.linalg.norm(P - truth, axis=1).max() < 0.03
    assert agreement(body, data, P) > agreement(body, data, start)


def test_extra_capsules_move_with_their_joints():
    """The extended joints' derivatives (the extra capsules' ends) against finite differences
    of the fitter's own parameter step, and the kernel's columns cover every parameter they
    move with."""
    from dataclasses import replace

    from topopose.sequence.tracker import _Fitter

    body = replace(make_body(), ends=trunk_sides(NAMES, PARENTS, (0.6, 1.0)),
                   extra_radii=np.array([0.09, 0.09]))
    f = _Fitter(body, TrackOptions())
    root, D = np.array([0.1, -0.2, 1.3]), arm_down(rest_directions(), 0.4)
    G, _M = f.jacobian(D)
    Pe, Ge = f.extend(joint_positions(body, root, D), G)
    eps = 1e-6
    for i in range(f.n):
        x = np.zeros(f.n)
        x[i] = eps
        r1, D1 = f.step(root, D, x)
        P1, _ = f.extend(joint_positions(body, r1, D1), G)
        assert np.allclose((P1 - Pe) / eps, Ge[:, :, i], atol=1e-4)
    for v in range(len(NAMES), len(Pe)):
        moved = set(np.flatnonzero(np.abs(Ge[v]).max(axis=0) > 0))
        assert moved <= set(f.cols[v][f.cols[v] >= 0])


def test_body_masks_draw_each_capsule_as_wide_as_seen():
    """Oracle: a camera looking down the z axis (identity rotation, body 2 m in front), each
    bone's capsule drawn as the band of pixels within f·r/z of its end points' segment; a bone
    with a non-finite end or behind the camera draws nothing."""
    from topopose.geometry.camera import Camera
    from topopose.sequence.silhouette import body_masks

    body = make_body()
    P = pose(rest_directions(), root=(0.0, 0.0, 0.0))[:, [0, 2, 1]] * [1, 1, 0.1] + [0, 0, 2]
    f, w, h = 100.0, 200, 200
    cam = Camera("c", (w, h), [[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]], np.zeros(5),
                 np.zeros(3), np.zeros(3))
    m = body_masks(body, P, [cam], [(h, w)])[0]
    A, B, r = body.capsules(P)
    a, b = cam.project(A), cam.project(B)
    z = (0.5 * (A + B))[:, 2]
    v, u = np.mgrid[0:h, 0:w]
    pix = np.c_[u.ravel(), v.ravel()].astype(float)
    inside = np.zeros(len(pix), bool)
    outside = np.ones(len(pix), bool)
    for k in range(len(A)):
        d = b[k] - a[k]
        s = np.clip(((pix - a[k]) @ d) / max(d @ d, 1e-12), 0, 1)
        dist = np.linalg.norm(pix - (a[k] + s[:, None] * d), axis=1)
        half = f * r[k] / z[k]
        inside |= dist < half - 1.5
        outside &= dist > half + 1.5
    assert inside.any() and m.ravel()[inside].all() and not m.ravel()[outside].any()
    Q = P.copy()
    Q[:, 2] = -2.0                                     # behind the camera
    assert not body_masks(body, Q, [cam], [(h, w)])[0].any()
    Q = P.copy()
    Q[:] = np.nan
    assert not body_masks(body, Q, [cam], [(h, w)])[0].any()


def test_tracked_head_lies_where_the_confident_frames_put_it():
    """The human tree has no joint at the head's end: the tracker's frames place the head
    part past the skull as far as the confident frames' alignments put it (the head's top).
    Oracle: the synthetic body's crown, the skull joint at its rig joint; the skull's bone
    extended as far as its place on the arc says falls inside the head, 10+ cm short."""
    from types import SimpleNamespace

    from topopose.pose.model import load_model
    from topopose.sequence.follow import body_parts, part_reach
    from topopose.sequence.skeleton_fit import kinematic_tree
    from topopose.synth.body import BUILDS, body_random, pose_body

    tree = kinematic_tree(load_model("human"))
    neck, skull = tree.names.index("neck"), tree.names.index("skull")
    rng = np.random.default_rng(5)
    frames = []
    for _ in range(8):
        b = pose_body(body_random(rng), BUILDS["average"]).joints
        P = np.full((len(tree.names), 3), np.nan)
        P[neck], P[skull] = b["Neck_head"], b["Head_head"]
        frames.append((P, np.asarray(b["crown"])))
    conf = np.stack([P for P, _c in frames[:5]])
    poses = [SimpleNamespace(parts={"head": c}) for _P, c in frames[:5]]
    reach = part_reach(tree, poses, conf)
    assert set(reach) == {"head"}
    for P, crown in frames[5:]:
        assert np.linalg.norm(body_parts(tree, P, reach)["head"] - crown) < 0.03
        assert np.linalg.norm(body_parts(tree, P)["head"] - crown) > 0.08


def test_calibration_lengthens_an_arm_held_against_the_trunk():
    """The confident frames' bone lengths short (both arms 0.7 × their true length), one arm
    out to the side, the other pressed into the trunk (its forearm inside the trunk's hull):
    the follow stage's calibration (``FollowOptions.calibrate`` rounds) lengthens both arms
    towards the truth, the hidden one by its twin's evidence, as one length."""
    from dataclasses import replace

    from topopose.sequence.follow import FollowOptions
    from topopose.sequence.tracker import calibrate

    body = make_body()
    rng = np.random.default_rng(1)
    frames = []
    for s in (0.0, 0.25, 0.5):
        D = arm_down(rest_directions(), s)
        D[6] = D[7] = _unit(0, 0.3, -1)               # arm 2 into the trunk
        P = pose(D)
        frames.append((frame_data(hull_of(body, P), 400, rng), P))
    short = LENGTHS.copy()
    short[[3, 4, 6, 7]] *= 0.7
    rounds = FollowOptions().calibrate
    L = calibrate(replace(body, lengths=short), frames, TrackOptions(iterations=6),
                  rounds=rounds).lengths
    assert rounds > 0
    assert np.allclose(L[[3, 4]], L[[6, 7]])                  # mirrored bones: one length
    gap = LENGTHS[[6, 7]] - short[[6, 7]]
    assert (L[[6, 7]] - short[[6, 7]] > 0.15 * gap).all()      # the hidden arm lengthened
    assert (L[[6, 7]] < LENGTHS[[6, 7]] + 0.02).all()


def _twisted(degrees, axis=(0.0, 0.0, 1.0)):
    """The rest pose's directions with the pelvis group (pelvis, hips) turned about ``axis``."""
    from topopose.sequence.tracker import _rotation

    D = rest_directions()
    g = [1, 8, 10]
    D[g] = D[g] @ _rotation(np.radians(degrees) * _unit(*axis)).T
    return D


def test_twist_row_is_the_derivative_of_its_residual():
    from topopose.sequence.joint_limits import twist_term
    from topopose.sequence.tracker import _Fitter, twist_pairs

    body = make_body()
    assert twist_pairs(body) == [(2, 5, 8, 10)]            # shoulders against hips
    rng = np.random.default_rng(3)
    f = _Fitter(body, TrackOptions())
    for _ in range(5):
        D = _twisted(rng.uniform(50, 120), (*rng.normal(0, 0.1, 2), 1.0))
        D[[2, 5]] = D[[2, 5]] @ kabsch(D[[2, 5]], D[[2, 5]] + rng.normal(0, 0.05, (2, 3))).T
        root = rng.normal(size=3)
        P, G = f.at(root, D)[:2]
        quad = twist_pairs(body)[0]
        r, row, phi = twist_term(P, G, quad, np.radians(30), 0.01)
        assert r != 0 and abs(phi) > np.radians(30)
        flipped = twist_term(P, G, quad[:2] + quad[:1:-1], np.radians(30), 0.01)
        assert np.isclose(flipped[2], phi) and np.allclose(flipped[1], row)   # lines, not sides
        h, num = 1e-6, np.zeros(f.n)
        for k in range(f.n):
            x = np.zeros(f.n)
            x[k] = h
            up, down = (twist_term(joint_positions(body, *f.step(root, D, s * x)), G, quad,
                                   np.radians(30), 0.01)[0] for s in (1, -1))
            num[k] = (up - down) / (2 * h)
        assert np.allclose(row, num, atol=1e-6)


def test_twist_limit_turns_the_hips_back_under_the_shoulders():
    """Started with the hips turned 70° from the shoulders on an untwisted body's hull, the fit
    without the limit stays in that turn; with it the hips come back within the limit."""
    from topopose.sequence.joint_limits import twist_term

    body = make_body()
    truth = pose(rest_directions())
    data = frame_data(hull_of(body, truth), 400)
    start = joint_positions(body, truth[0], _twisted(70))

    def twist(P):
        return abs(np.degrees(twist_term(P, np.zeros((len(P), 3, 1)), (2, 5, 8, 10), 0, 1)[2]))

    free = fit_frame(body, data, start, TrackOptions(twist=None))
    held = fit_frame(body, data, start, TrackOptions())
    assert twist(free) > 45
    assert twist(held) < 30
    assert np.linalg.norm(held - truth, axis=1).max() < 0.04


def test_sides_carry_into_segments_no_confident_frame_named():
    """Segment 0 named its limbs (+1); segment 1 follows with the limbs crossed over, segment 2
    (only next to segment 1) as segment 1: each inherits through its neighbour, and a group
    nothing names stays undecided."""
    from topopose.sequence.follow import inherit_votes

    a, b = np.array([0.0, 0.2, 0.0]), np.array([0.0, -0.2, 0.0])
    J = np.zeros((6, 4, 3))
    J[:, 2], J[:, 3] = a + 1, b + 1            # group 1 (joints 2, 3): never named
    J[:2, 0], J[:2, 1] = a, b
    J[2:, 0], J[2:, 1] = b + 0.01, a - 0.01    # segment 1 on: the track's limbs swapped
    segment = np.array([0, 0, 1, 1, 2, 2])
    votes = inherit_votes(segment, J, {(0, 0): 3}, [[(0, 1)], [(2, 3)]])
    assert votes[(0, 0)] == 3 and votes[(1, 0)] == -1 and votes[(2, 0)] == -1
    assert not any(votes.get((s, 1)) for s in range(3))
