"""The gate's foot rule (topopose.frame.confidence.foot_rise, GateOptions.max_foot_rise).

Oracles: hand-made skeleton curves whose foot heights and arc lengths are computed by hand (and
the same curves turned and scaled); a constructed sequence in which the run's consistency
matches every frame the gate alone rejected except those whose foot the alignment put on an
arm.
"""
import math

import numpy as np
import pytest

from topopose.frame.confidence import GATE, GateOptions, foot_rise, gate_decision
from topopose.pose.model import load_model
from topopose.pose.pose import Pose
from topopose.sequence import consistency

UP = np.array([0.0, 0.0, 1.0])


def standing(x=0.0):
    """Curves of a subject standing at ``x``: the head and crotch arcs from the torso, one leg
    straight down to the floor, the other lifted sideways (a bend at 0.5 m)."""
    return {"head": [[x, 0, 1.4], [x, 0, 1.7]], "crotch": [[x, 0, 1.4], [x, 0, 0.9]],
            "hand_1": [[x, 0, 1.4], [x, 0.3, 1.35], [x, 0.35, 1.0]],
            "foot_1": [[x, 0.1, 0.9], [x, 0.1, 0.0]],
            "foot_2": [[x, -0.1, 0.9], [x, -0.4, 0.5], [x, -0.7, 0.3]]}


def on_arm(x=0.0):
    """The same subject with the legs together (one leg branch) and ``foot_2`` on the hanging
    arm's branch, which joins the trunk at the crotch's junction."""
    c = standing(x)
    c["foot_2"] = [[x, -0.1, 0.9], [x, -0.3, 1.0], [x, -0.35, 0.75]]
    return c


def test_foot_rise_by_hand():
    part, r = foot_rise(standing(), UP)
    lifted = 0.5 + math.hypot(0.3, 0.2)              # the lifted leg's arc
    assert part == "foot_2" and r == pytest.approx(0.3 / lifted)
    part, r = foot_rise(on_arm(), UP)
    arm = math.hypot(0.2, 0.1) + math.hypot(0.05, 0.25)     # the hanging arm's arc
    assert part == "foot_2" and r == pytest.approx(0.75 / arm)
    # the floor is the lowest point of every curve, a hand's too
    c = standing()
    c["hand_1"][-1] = [0, 0.35, -0.1]
    assert foot_rise(c, UP)[1] == pytest.approx(0.4 / lifted)
    # no foot, no curve: nothing to say
    assert foot_rise({"head": [[0, 0, 1], [0, 0, 2]]}, UP) == (None, None)
    assert foot_rise(None, UP) == (None, None)


def test_foot_rise_is_a_ratio_of_the_subject_as_it_is_turned_and_scaled():
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    for curves in (standing(), on_arm()):
        moved = {k: (2.5 * np.asarray(v, float) @ q.T + [1, -2, 3]).tolist()
                 for k, v in curves.items()}
        assert foot_rise(moved, q @ UP)[1] == pytest.approx(foot_rise(curves, UP)[1])
        # down instead of up: the feet are measured from the other side
        assert foot_rise(curves, -UP)[1] != pytest.approx(foot_rise(curves, UP)[1])


def _diag(curves, distance=0.5, shape=0.05):
    return {"confidence_features": {"distance": distance, "shape": shape}, "unexplained": 0.05,
            "curves": curves}


def test_a_foot_on_an_arm_is_rejected_whatever_else_the_gate_says():
    ok = ("matched", None)
    assert gate_decision("matched", None, _diag(standing()), up=UP) == ok
    st, why = gate_decision("matched", None, _diag(on_arm()), up=UP)
    assert st == "rejected" and why.startswith("anatomy: foot_2 ")
    # after the gate's own reason, which it keeps
    above = "AHA distance 0.600 above threshold T_d = 0.4"
    st, why = gate_decision("rejected", above, _diag(on_arm(), 2.0, 0.3), up=UP)
    assert st == "rejected" and why.startswith(above + "; confidence gate: ")
    assert why.split("; ")[-1].startswith("anatomy: foot_2")
    # off, or no up vector: the three features alone
    assert gate_decision("matched", None, _diag(on_arm()), GateOptions(max_foot_rise=None),
                         up=UP) == ok
    assert gate_decision("matched", None, _diag(on_arm())) == ok
    # the threshold decides: the lifted leg's rise passes the default and not a stricter one
    r = foot_rise(standing(), UP)[1]
    assert r < GATE.max_foot_rise
    assert gate_decision("matched", None, _diag(standing()), GateOptions(max_foot_rise=r - 0.01),
                         up=UP)[0] == "rejected"


def _walk(options):
    """14 frames of a walk (2 cm a frame) that the gate alone rejects (above T_d, arcs out of
    proportion), decided by ``options``; frames 5 to 8 have ``foot_2``'s curve on an arm, the
    parts of every frame agree with their neighbours."""
    above = "AHA distance 0.900 above threshold T_d = 0.4"
    poses = []
    for i in range(14):
        x = 0.02 * i
        parts = {k: np.asarray(v[-1], float) for k, v in standing(x).items() if k != "crotch"}
        parts.update(torso=np.array([x, 0, 1.4]), crotch=np.array([x, 0, 0.9]),
                     hand_2=np.array([x, 0.5, 1.2]))
        diag = {"confidence_features": {"distance": 2.0, "shape": 0.3}, "unexplained": 0.05,
                "curves": on_arm(x) if 5 <= i <= 8 else standing(x)}
        st, why = gate_decision("rejected", above, diag, options, up=UP)
        poses.append(Pose(f"{i:06d}", st, 0.9, parts, why, {},
                          {**diag, "height": 1.7, "confidence": 0.3}))
    return poses


def test_the_runs_consistency_does_not_match_a_foot_on_an_arm():
    """The run's consistency matches the frames the gate alone rejected when their neighbours
    agree (all but the run's ends); with the foot rule, frames 5 to 8, whose foot is on an
    arm, agree as well and stay rejected."""
    model = load_model("human")
    inner = {i: "matched" for i in range(1, 13)}
    ends = {0: "rejected", 13: "rejected"}
    for options, expect in ((GateOptions(max_foot_rise=None), {**inner, **ends}),
                            (GATE, {**inner, **ends, **{i: "rejected" for i in (5, 6, 7, 8)}})):
        poses = _walk(options)
        assert all(p.status == "rejected" for p in poses)
        assert consistency.judge_sequence(poses, model, neighbours=2, min_rank=0.0, union=True)
        assert {i: p.status for i, p in enumerate(poses)} == expect
    assert all(poses[i].error.split("; ")[-1].startswith("anatomy: foot_2") for i in (5, 6, 7, 8))


def test_a_clean_frame_stays_matched_and_its_foot_put_on_an_arm_is_caught():
    """A capsule-human frame with its limbs apart, right by ground truth: matched, its feet
    low for their legs. The same frame with ``foot_2``'s curve running where the alignment
    would put a foot on an arm's branch (from the crotch's junction up the trunk to the torso's,
    then along ``hand_1``'s arc) is rejected by the rule."""
    from topopose.batch.quality import evaluate
    from topopose.frame.estimate import FrameEstimator
    from topopose.synth.capture import synthetic_capture

    cap = synthetic_capture("human", frames=1, seed=4, cameras=8, noise=1, separated=True,
                            margin=0.06)
    est = FrameEstimator(cap, "human", 100)
    p = est.estimate(cap.frames[0])
    ev = evaluate(cap.gt, [p], model=est.model, tolerance=0.08 * cap.gt["height"])
    assert ev.frames[0].quality == "good" and p.status == "matched", p.error
    curves = p.diagnostics["curves"]
    assert foot_rise(curves, cap.up_vector)[1] < 0.2       # standing feet
    moved = dict(curves)
    moved["foot_2"] = np.vstack([np.asarray(curves["crotch"], float)[::-1],
                                 np.asarray(curves["hand_1"], float)]).tolist()
    diag = {**p.diagnostics, "curves": moved}
    st, why = gate_decision("matched", None, diag, up=cap.up_vector)
    assert st == "rejected" and why.startswith("anatomy: foot_2"), why
    assert gate_decision("matched", None, p.diagnostics, up=cap.up_vector) == ("matched", None)
