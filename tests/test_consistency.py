"""topopose.sequence.consistency: matched by the run's own consistency.

Oracles: a synthetic walk of straight-line part trajectories (constant velocities: the
neighbours' midpoint predicts every part exactly), one frame's hand moved onto the trunk;
arc lengths of hand-made curves against medians computed by hand; a run of unrelated poses.
"""
import numpy as np
import pytest

from topopose.sequence import consistency as C
from topopose.pose.model import load_model
from topopose.sequence.motion import process_sequence
from topopose.pose.pose import Pose

H = 1.7
GATED = "AHA distance 0.900 above threshold T_d = 0.4; confidence 0.30 below 0.91"


@pytest.fixture(scope="module")
def model():
    return load_model("human")


def walk_parts(i):
    """Parts of frame i: the body moves 2 cm/frame along x, the hands swing at constant
    velocities (exactly predicted by the neighbours' midpoint)."""
    x = 0.02 * i
    return {"torso": np.array([x, 0.0, 1.4]), "head": np.array([x, 0.0, 1.7]),
            "crotch": np.array([x, 0.0, 0.9]),
            "hand_1": np.array([x + 0.01 * i, 0.35, 1.0]),
            "hand_2": np.array([x - 0.01 * i, -0.35, 1.0]),
            "foot_1": np.array([x + 0.1, 0.1, 0.05]), "foot_2": np.array([x - 0.1, -0.1, 0.05])}


def walk(n=12, conf=None, status="rejected", error=GATED):
    conf = conf or [0.3] * n
    return [Pose(f"{i:06d}", status, 0.9, walk_parts(i), error if status == "rejected" else None,
                 {}, {"height": H, "confidence": conf[i]}) for i in range(n)]


def test_smooth_walk_is_matched_and_a_hand_on_the_trunk_rejected(model):
    poses = walk()
    poses[6].parts["hand_1"] = poses[6].parts["torso"] + np.array([0.12, 0.0, -0.1])
    assert C.judge_sequence(poses, model, neighbours=2, min_rank=0.0)
    assert poses[6].status == "rejected" and poses[6].error == GATED     # the gate's reason kept
    d = poses[6].diagnostics["consistency"]
    assert d["part"] == "hand_1" and d["deviation"] > 0.2 and d["reasons"]
    # its best guess is kept
    assert np.allclose(poses[6].parts["hand_1"], walk_parts(6)["torso"] + [0.12, 0, -0.1])
    # every other frame agrees exactly with a pair of its neighbours: matched (frames 5 and 7
    # too, by their neighbours ±2); the run's ends have no pair: left as the gate decided
    for i, p in enumerate(poses[1:-1], 1):
        if i != 6:
            assert p.status == "matched", (i, p.diagnostics["consistency"])
            assert p.error is None
    for p in (poses[0], poses[-1]):
        assert p.status == "rejected" and p.diagnostics["consistency"]["deviation"] is None
    # a frame that was matched and is inconsistent is rejected with the reason
    poses = walk(status="matched")
    poses[5].parts["hand_2"] = poses[5].parts["crotch"].copy()
    C.judge_sequence(poses, model, neighbours=2, min_rank=0.0)
    assert poses[5].status == "rejected"
    assert poses[5].error.startswith("inconsistent with the run: hand_2")
    assert sum(p.status == "matched" for p in poses) == len(poses) - 1


def test_numbered_parts_are_paired(model):
    """A frame whose hand_1 and hand_2 swap names is consistent (the pairing is optimal)."""
    poses = walk()
    p = poses[5].parts
    p["hand_1"], p["hand_2"] = p["hand_2"], p["hand_1"]
    dev = C.temporal_deviation(poses, k=1)
    assert dev[5]["hand_1"] == pytest.approx(0.0, abs=1e-12)
    assert dev[5]["hand_2"] == pytest.approx(0.0, abs=1e-12)
    # and with the side names of chirality, grouped by mirror_groups
    side = [Pose(q.frame, q.status, q.distance,
                 {{"hand_1": "left_hand", "hand_2": "right_hand"}.get(k, k): v
                  for k, v in q.parts.items()}, q.error, {}, dict(q.diagnostics)) for q in poses]
    dev = C.temporal_deviation(side, k=1, groups=C.mirror_groups(model))
    assert dev[5]["left_hand"] == pytest.approx(0.0, abs=1e-12)
    # without the groups the names are not paired: the swap shows
    dev = C.temporal_deviation(side, k=1)
    assert dev[5]["left_hand"] == pytest.approx(np.hypot(0.1, 0.7) / H, rel=1e-9)


def test_deviation_is_in_hull_heights():
    poses = walk(5)
    poses[2].parts["head"] = poses[2].parts["head"] + np.array([0.0, 0.0, 0.17])
    dev = C.temporal_deviation(poses, k=1)
    assert dev[2]["head"] == pytest.approx(0.1)
    # frames 1 and 3 see the wrong head in their only pair (k = 1): half of it
    assert dev[1]["head"] == pytest.approx(0.05)
    assert dev[0] == {}                    # no pair of neighbours around the first frame


def test_rank_decides_too(model):
    conf = [0.3] * 12
    conf[4] = 0.01                         # the lowest confidence of the run
    poses = walk(conf=conf)
    C.judge_sequence(poses, model, neighbours=2, min_rank=0.25)
    r = C.confidence_rank(walk(conf=conf))
    assert r[4] == 0.0 and r[0] == pytest.approx(1 / 12)
    assert poses[4].status == "rejected"
    assert "ranks" in poses[4].diagnostics["consistency"]["reasons"][0]


def test_run_lengths_against_hand_computed_medians(model):
    def curve(a, b, bend):
        m = (np.asarray(a) + np.asarray(b)) / 2 + np.array([0.0, 0.0, bend])
        return np.array([a, m, b])

    poses = []
    bends = [0.0, 0.1, 0.3]
    for i, bend in enumerate(bends):
        parts = walk_parts(0)
        curves = {c: curve(parts[u], parts[c], bend) for u, c in
                  (("torso", "hand_1"), ("torso", "hand_2"), ("torso", "head"),
                   ("torso", "crotch"), ("crotch", "foot_1"), ("crotch", "foot_2"))}
        if i == 2:
            del curves["hand_2"]           # an arc not matched in that frame
        poses.append(Pose(f"{i}", "matched", 0.1, parts, None, {},
                          {"height": H, "curves": curves}))

    def length(u, c, bend):
        a, b = walk_parts(0)[u], walk_parts(0)[c]
        m = (a + b) / 2 + np.array([0, 0, bend])
        return np.linalg.norm(m - a) + np.linalg.norm(b - m)

    L = C.run_lengths(poses, model)
    # hands pooled: frames 0, 1 (both hands, the same length by symmetry), frame 2 hand_1
    hand = [length("torso", "hand_1", b) for b in (0.0, 0.0, 0.1, 0.1, 0.3)]
    assert L["hand"] == pytest.approx(np.median(hand))
    assert L["head"] == pytest.approx(np.median([length("torso", "head", b) for b in bends]))
    assert L["foot"] == pytest.approx(np.median([length("crotch", "foot_1", b)
                                                 for b in bends for _ in (0, 1)]))
    r = C.length_ratios(poses[2], model, L)
    assert "hand_2" not in r
    assert r["hand_1"] == pytest.approx(length("torso", "hand_1", 0.3) / np.median(hand))


def test_unrelated_poses_are_left_as_they_are(model):
    rng = np.random.default_rng(3)
    poses = walk(10)
    for p in poses:                        # every frame a pose somewhere else
        off = rng.uniform(-2, 2, 3) * [1, 1, 0]
        p.parts = {k: v + off + rng.normal(0, 0.3, 3) for k, v in p.parts.items()}
    before = [(p.status, p.error) for p in poses]
    assert not C.coherent(poses)
    assert not C.judge_sequence(poses, model)
    assert [(p.status, p.error) for p in poses] == before
    assert all("consistency" not in p.diagnostics for p in poses)


def test_process_sequence_switch(model):
    up = np.array([0.0, 0.0, 1.0])
    off = process_sequence(walk(), model, up, track=False, sides=False, skeleton=False,
                           consistency=False)
    assert all(p.status == "rejected" for p in off.poses) and "consistency" not in off.stages
    on = process_sequence(walk(), model, up, track=False, sides=False, skeleton=False,
                          consistency={"neighbours": 2, "min_rank": 0.0})
    assert "consistency" in on.stages
    got = [p.status for p in on.poses]        # the ends: no pair of neighbours
    assert got[0] == got[-1] == "rejected" and set(got[1:-1]) == {"matched"}
    # a frame that failed is never touched
    poses = walk()
    poses[3] = Pose(poses[3].frame, "failed", None, {k: None for k in poses[3].parts}, "boom")
    C.judge_sequence(poses, model, neighbours=2, min_rank=0.0)
    assert poses[3].status == "failed" and poses[3].error == "boom"


def test_run_switch_keeps_the_best_guesses(tmp_path):
    """``run(consistency=True)`` on a synthetic 4-camera walk: the same parts as without it,
    statuses changed only for frames the gate judged, the values written to the file."""
    from topopose.synth.capture import synthetic_capture
    from topopose.batch import run
    from topopose.pose.pose import read_poses

    cap = synthetic_capture("human", frames=8, seed=1, cameras=4, size=(240, 180),
                            motion="walk")
    from topopose.sequence.follow import FollowOptions

    still = FollowOptions(enabled=False)      # the tracker refits the frames it tracks
    off = run(cap, resolution=48, progress=False, consistency=False, follow=still)
    on = run(cap, resolution=48, progress=False, consistency=True, output=tmp_path / "p.jsonl",
             follow=still)
    assert [p.frame for p in on.poses] == [p.frame for p in off.poses]
    for a, b in zip(off.poses, on.poses):
        assert a.parts.keys() == b.parts.keys()
        for k in a.parts:
            assert (a.parts[k] is None) == (b.parts[k] is None)
            if a.parts[k] is not None:
                assert np.allclose(a.parts[k], b.parts[k])
        if a.status != b.status:
            assert C.gated(a) and b.status in ("matched", "rejected")
    assert any("consistency" in p.diagnostics for p in read_poses(tmp_path / "p.jsonl"))


def test_a_part_held_at_its_prediction_is_not_matched(model):
    """A part the tracker held at its prediction (``diagnostics["predicted"]``) sits exactly
    where the neighbours predict it — a deviation of 0 that proves nothing: its frame is not
    matched by the consistency, and a matched one is rejected with the reason, in both modes,
    also at the run's ends (no pair of neighbours needed)."""
    for union in (False, True):
        poses = walk(status="matched")
        for i in (0, 5):
            assert "hand_1" in poses[i].parts
            poses[i].diagnostics["predicted"] = ["hand_1"]
        C.judge_sequence(poses, model, neighbours=2, min_rank=0.0, union=union)
        assert poses[5].diagnostics["consistency"]["deviation"] == pytest.approx(0.0, abs=1e-12)
        for i in (0, 5):
            assert poses[i].status == "rejected", (union, i)
            assert "hand_1 held at the tracked prediction" in poses[i].error
            assert poses[i].error.startswith("inconsistent with the run: ")
        assert all(p.status == "matched" for i, p in enumerate(poses) if i not in (0, 5))
        # a frame only the gate rejected is not matched either, its reason kept
        poses = walk()
        poses[5].diagnostics["predicted"] = ["hand_2"]
        C.judge_sequence(poses, model, neighbours=2, min_rank=0.0, union=union)
        assert poses[5].status == "rejected" and poses[5].error == GATED
        assert "hand_2 held" in poses[5].diagnostics["consistency"]["reasons"][0]
        assert poses[4].status == poses[6].status == "matched"


def test_union_keeps_the_gate_and_adds_consistent_frames(model):
    """``union=True`` (the run's default): every frame the gate matched stays matched, an
    inconsistent one too (its reasons recorded); a frame the gate alone rejected is matched
    when consistent and stays rejected when not; a frame rejected for another reason and a
    failed one are untouched. ``union=False`` (``--consistency``) rejects the inconsistent
    matched frame instead."""
    def run_of():
        poses = walk(14)
        for i in (2, 3, 8, 9):                   # the gate matched these
            poses[i].status, poses[i].error = "matched", None
        poses[3].parts["hand_1"] = poses[3].parts["torso"].copy()    # matched, inconsistent
        poses[7].parts["foot_2"] = poses[7].parts["head"].copy()     # gated, inconsistent
        poses[6].error = "hull: 2 pieces"        # rejected for another reason
        poses[12] = Pose(poses[12].frame, "failed", None, {k: None for k in poses[12].parts},
                         "boom")
        return poses

    expect = {i: "matched" for i in range(14)}
    expect.update({0: "rejected", 13: "rejected",       # the ends: as the gate decided
                   7: "rejected", 6: "rejected", 12: "failed"})
    poses = run_of()
    assert C.judge_sequence(poses, model, neighbours=2, min_rank=0.0, union=True)
    assert {i: p.status for i, p in enumerate(poses)} == expect
    assert poses[3].error is None and poses[3].diagnostics["consistency"]["reasons"]
    assert poses[6].error == "hull: 2 pieces" and poses[12].error == "boom"
    assert poses[7].error == GATED
    assert poses[5].diagnostics["consistency"]["gate"] == GATED     # what the gate said
    # the consistency instead of the gate: the inconsistent matched frame is rejected
    poses = run_of()
    C.judge_sequence(poses, model, neighbours=2, min_rank=0.0, union=False)
    assert {i: p.status for i, p in enumerate(poses)} == {**expect, 3: "rejected"}
    assert poses[3].error.startswith("inconsistent with the run: hand_1")


def test_union_is_the_default_and_leaves_unrelated_poses_alone(model):
    """``process_sequence`` (and so ``run``) decides ``matched`` by the union by default; a run
    of unrelated poses keeps the gate's statuses in every mode."""
    from topopose.sequence.motion import consistency_settings

    up = np.array([0.0, 0.0, 1.0])
    assert consistency_settings(None) == consistency_settings("union") == {"union": True}
    assert consistency_settings(True) == {} and consistency_settings(False) is None
    assert consistency_settings({"neighbours": 1}) == {"neighbours": 1}
    with pytest.raises(ValueError):
        consistency_settings("sometimes")

    def run_of():
        poses = walk(10)
        poses[4].status, poses[4].error = "matched", None
        poses[4].parts["hand_2"] = poses[4].parts["crotch"].copy()     # inconsistent
        return poses

    got = process_sequence(run_of(), model, up, track=False, sides=False, skeleton=False)
    assert "consistency" in got.stages
    assert [p.status for p in got.poses] == ["rejected"] + ["matched"] * 8 + ["rejected"]
    got = process_sequence(run_of(), model, up, track=False, sides=False, skeleton=False,
                           consistency=True)
    assert got.poses[4].status == "rejected"
    rng = np.random.default_rng(5)
    for mode in (None, True, False):
        poses = run_of()
        for p in poses:                         # every frame a pose somewhere else
            off = rng.uniform(-2, 2, 3) * [1, 1, 0]
            p.parts = {k: v + off + rng.normal(0, 0.3, 3) for k, v in p.parts.items()}
        before = [(p.frame, p.status, p.error) for p in poses]
        got = process_sequence(poses, model, up, track=False, sides=False, skeleton=False,
                               consistency=mode)
        assert [(p.frame, p.status, p.error) for p in got.poses] == before
        assert "consistency" not in got.stages


def test_run_default_is_the_union(tmp_path):
    """``run()`` by default: the same parts as ``consistency=False`` (the gate alone), every
    frame the gate matched still matched unless a part was held, the others changed only
    when the gate alone rejected them; the silhouette support recorded; a wrong option
    refused."""
    from topopose.synth.capture import synthetic_capture
    from topopose.errors import InputError
    from topopose.batch import run
    cap = synthetic_capture("human", frames=8, seed=1, cameras=4, size=(240, 180),
                            motion="walk")
    from topopose.sequence.follow import FollowOptions

    off = FollowOptions(enabled=False)      # the tracker's statuses are its own (test_tracker)
    gate = run(cap, resolution=48, progress=False, consistency=False, follow=off)
    union = run(cap, resolution=48, progress=False, follow=off)
    # the gate reads the silhouette support (frame.confidence.GateOptions): recorded in both
    assert any("unexplained" in p.diagnostics for p in gate.poses)
    assert any("unexplained" in p.diagnostics for p in union.poses)
    for a, b in zip(gate.poses, union.poses):
        assert a.frame == b.frame and a.parts.keys() == b.parts.keys()
        for k in a.parts:
            assert (a.parts[k] is None) == (b.parts[k] is None)
            if a.parts[k] is not None:
                assert np.allclose(a.parts[k], b.parts[k])
        if a.status == "matched" and not C.held_parts(a):
            assert b.status == "matched"
        if a.status != b.status:
            assert C.gated(a)
    with pytest.raises(InputError):
        run(cap, resolution=48, progress=False, consistency="sometimes", frames="0:1")
    # every sequence stage off: the per-frame results as the estimator gave them (no trim,
    # the gate's statuses), the raw per-frame run
    raw = run(cap, resolution=48, progress=False, track=False, sides=False, skeleton=False)
    for a, b in zip(gate.poses, raw.poses):
        assert "consistency" not in b.diagnostics
        assert "joints" not in b.diagnostics and not b.diagnostics.get("trimmed")
        assert a.status == b.status


def test_cli_consistency_switch():
    from topopose.cli import build_parser

    p = build_parser()
    assert p.parse_args(["run", "CAP"]).consistency is None           # the union (default)
    assert p.parse_args(["run", "CAP", "--consistency"]).consistency is True
    assert p.parse_args(["run", "CAP", "--no-consistency"]).consistency is False
