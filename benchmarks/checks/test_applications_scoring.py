"""benchmarks/applications.py's scoring: the points the detection benchmark compares (its
peers' and the truth's), the blame of its wrong decisions and its counts, on hand-made poses
with known answers."""
from types import SimpleNamespace

import numpy as np

import pytest

import applications


def test_peer_points_on_a_straight_branch():
    """A head straight above the torso moves down by HEAD_CENTRE_DROP; a hand at the end of a
    straight horizontal branch moves on along it by HAND_REACH; the crotch becomes the crotch
    curve's end; parts without a curve or unplaced stay as they are."""
    A = applications
    arm = np.c_[np.linspace(0.2, 0.8, 16), np.zeros(16), np.full(16, 1.4)]   # along +x
    crotch_curve = np.c_[np.zeros(16), np.zeros(16), np.linspace(1.3, 0.9, 16)]
    parts = {"torso": (0, 0, 1.3), "head": (0, 0, 1.7), "hand_1": (0.8, 0, 1.4),
             "hand_2": (-0.5, 0, 1.0), "crotch": (0.03, 0, 0.95), "foot_1": None}
    pose = SimpleNamespace(diagnostics={"curves": {"hand_1": arm, "crotch": crotch_curve}})
    cc, gp = A.peer_points(pose, parts)
    assert np.allclose(gp["head"], (0, 0, 1.7 - A.HEAD_CENTRE_DROP))
    assert np.allclose(gp["hand_1"], (0.8 + A.HAND_REACH, 0, 1.4))
    assert gp["hand_2"] == parts["hand_2"] and gp["crotch"] == parts["crotch"]
    assert np.allclose(cc["crotch"], (0, 0, 0.9))
    assert cc["hand_1"] == parts["hand_1"] and cc["foot_1"] is None
    # an unplaced head or crotch stays unplaced
    cc, gp = A.peer_points(pose, {**parts, "head": None, "crotch": None})
    assert gp["head"] is None and cc["crotch"] is None


def _gt_frame(body):
    """A gt.json frame of a built body, as capture/synth.py writes it."""
    return {"parts": {k: list(v) for k, v in body.parts.items()},
            "segments": {k: [list(s[0]), list(s[1])] for k, s in body.segments.items()},
            "joints": {k: list(v) for k, v in body.joints.items()}}


@pytest.mark.parametrize("flex", [0.0, 30.0])
def test_detection_truth_points_of_a_built_capsule_human(flex):
    """The detection benchmark's truth points (``pipeline_points``) on a built capsule human,
    against its kinematics: each hand and foot the middle of its last bone (wrist → hand end,
    ankle → toe joints), the crotch the pelvis ellipsoid's centre (exact with a straight spine;
    within the chord 2 · 4 cm · sin(flex / 2) when the spine bends, the body axis then being the spine's), the
    head the crown (the head ellipsoid's top), the alternative correspondence gt.json's own."""
    from topopose.synth.subjects import BUILD, HUMAN_DEFAULT

    A = applications
    body = BUILD["human"]({**HUMAN_DEFAULT, "spine_flex": flex, "pelvis_pitch": 20.0,
                           "sh_abd_l": 90.0, "elbow_r": 60.0})
    frame = _gt_frame(body)
    P = {k: np.asarray(v) for k, v in A.pipeline_points(frame).items()}
    J = body.joints
    for part, a, b in (("hand_1", "wrist_l", "hand_l"), ("hand_2", "wrist_r", "hand_r"),
                       ("foot_1", "ankle_l", "foot_l"), ("foot_2", "ankle_r", "foot_r")):
        assert np.allclose(P[part], (J[a] + J[b]) / 2)
        assert np.linalg.norm(P[part] - body.parts[part]) > 0.07      # not gt.json's point
    pelvis = next(p for p in body.prims if p.link == "pelvis" and p.kind == "ellipsoid")
    head = next(p for p in body.prims if p.link == "head" and p.kind == "ellipsoid")
    tol = 1e-9 + 2 * A.PELVIS_CENTRE * np.sin(np.radians(flex) / 2)   # the chord
    assert np.linalg.norm(P["crotch"] - pelvis.c) <= tol
    assert np.allclose(P["head"], head.c + head.axes[:, 2] * head.semi[2])
    F = A.pipeline_points(frame, former=True)
    for part in ("hand_1", "hand_2", "foot_1", "foot_2", "crotch"):
        assert np.allclose(F[part], body.parts[part])


def test_detection_truth_points_of_the_body_rig():
    """``body`` frames (rig joints recorded) take the rig points of BODY_PART_JOINTS, feet the
    foot bone's end (mid-foot) — the alternative correspondence keeps gt.json's feet."""
    A = applications
    joints = {j: [float(i), 0.0, 0.0] for i, j in enumerate(A.BODY_PART_JOINTS.values())}
    parts = {k: [0.0, 0.0, -1.0] for k in ("head", "torso", "crotch", "hand_1", "hand_2",
                                           "foot_1", "foot_2")}
    P = A.pipeline_points({"parts": parts, "joints": joints})
    for part, j in A.BODY_PART_JOINTS.items():
        assert P[part] == joints[j]
    assert A.BODY_PART_JOINTS["foot_1"] == "LeftFoot_tail"
    F = A.pipeline_points({"parts": parts, "joints": joints}, former=True)
    assert F["foot_1"] == parts["foot_1"] and F["hand_1"] == joints["LeftHand_tail"]
    # a rig point missing: not a body frame, gt.json's parts
    del joints["LeftFoot_tail"]
    assert A.pipeline_points({"parts": parts, "joints": joints})["hand_1"] == parts["hand_1"]



def test_error_blame_mean_and_median_of_the_blamed_offsets():
    """The detection benchmark's blame table (thesis §13.3.2.1): each wrong decision
    counts for every part it is blamed on (``none`` when no single part fixes it), right
    decisions for nothing; per part the mean and the median of the blamed parts' offsets along
    up — the median stays with the typical offset where one gross mismatch (a hand on a foot's
    branch, −1.2 m) drags the mean. Oracle: numpy on the hand-listed offsets."""
    A = applications

    def row(value, truth, blame=None, **dz):
        d = {"m0": value, "truth": truth}
        if blame is not None:
            d["blame"] = blame
        return {"detect": {"q": d}, "part_offsets": {k: [v, abs(v)] for k, v in dz.items()}}

    rows = [row(True, False, ["hand_1"], hand_1=-0.02, head=0.01),
            row(False, True, ["hand_2", "head"], hand_2=-0.03, head=0.04),
            row(True, False, ["hand_1"], hand_1=-1.2),
            row(False, True, [], hand_1=0.5),               # no single part: "none"
            row(True, True, None, hand_1=-2.0)]             # right: not counted
    b = A.error_blame(rows, "q")
    assert set(b) == {"hand", "head", "none"}
    assert b["hand"]["n"] == 3 and b["head"]["n"] == 1 and b["none"]["n"] == 1
    assert np.isclose(b["hand"]["dz_mean"], np.mean([-0.02, -0.03, -1.2]))
    assert np.isclose(b["hand"]["dz_median"], -0.03)
    assert np.isclose(b["head"]["dz_median"], 0.04) and b["none"]["dz_median"] is None


def test_applications_counts_on_the_frames_the_support_keeps():
    """benchmarks/applications.py: ``supported`` keeps a frame within the limit or without the
    value (as ``judge_support``); the counts on the kept frames by hand."""
    A = applications

    def row(u, v, t):
        return {"unexplained": u, "detect": {"p": {"truth": t, "m0": v}}}

    rows = [row(0.02, True, True), row(0.2, True, False), row(None, False, True),
            row(0.08, True, False), row(0.09, False, False)]
    assert [A.supported(r, 0.08) for r in rows] == [True, False, True, True, False]
    c = A.detection_counts(rows, "p", keep=lambda r, d: A.supported(r, 0.08))
    assert (c["tp"], c["fp"], c["fn"], c["tn"]) == (1, 1, 1, 0)
    assert c["precision"] == 0.5 and c["recall"] == 0.5
