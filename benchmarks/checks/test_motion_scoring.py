"""The signed joint bias in the body's frame (thesis §13.3.1: the kinematic skeleton's
joints against the truth): ``benchmarks/tracking.py``'s :func:`joint_bias` on the synthetic
body's rig joints and ``benchmarks/real_motion.py``'s :func:`signed_bias` against Pose2Sim's
markers. Oracle: joints moved by known offsets in a hand-built body frame, the whole scene
turned about the up axis (the bias must not change), mirror joints numbered the other way."""
import numpy as np

import real_motion
import tracking


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


# a body facing +y, its left towards −x (right-handed: left × up = forward), z up
RIG = {"Neck_head": (0, 0, 1.5), "Head_head": (0, 0, 1.6),
       "LeftArm_head": (-0.18, 0, 1.42), "RightArm_head": (0.18, 0, 1.42),
       "LeftForeArm_head": (-0.2, 0, 1.15), "RightForeArm_head": (0.2, 0, 1.15),
       "LeftHand_head": (-0.2, 0.05, 0.9), "RightHand_head": (0.2, 0.05, 0.9),
       "LeftUpLeg_head": (-0.1, 0, 0.95), "RightUpLeg_head": (0.1, 0, 0.95),
       "LeftLeg_head": (-0.1, 0.02, 0.5), "RightLeg_head": (0.1, 0.02, 0.5),
       "LeftFoot_head": (-0.1, 0, 0.08), "RightFoot_head": (0.1, 0, 0.08)}
# known offsets (outward, forward, up) in metres per joint base
MOVE = {"neck": (0.0, 0.02, -0.03), "shoulder": (0.03, -0.01, 0.02), "elbow": (-0.02, 0.04, 0.0),
        "wrist": (0.0, 0.0, 0.05), "hip": (-0.04, 0.01, -0.02), "knee": (0.01, 0.0, 0.03),
        "ankle": (0.0, 0.02, 0.0)}
STEM = {"shoulder": "Arm_head", "elbow": "ForeArm_head", "wrist": "Hand_head",
        "hip": "UpLeg_head", "knee": "Leg_head", "ankle": "Foot_head"}


def _moved(side, base):
    """The rig joint of ``base`` on ``side`` moved by MOVE in the body frame (left = −x)."""
    o, f, u = MOVE[base]
    name = "Neck_head" if base == "neck" else side + STEM[base]
    sg = -1.0 if side == "Left" else 1.0          # outward: −x on the left, +x on the right
    return np.asarray(RIG[name], float) + np.array([sg * o if base != "neck" else -o, f, u])


def test_joint_bias_recovers_known_offsets_in_any_heading():
    tr = tracking
    for turn in (0.0, 1.1, -2.5):
        R = _rot(turn)
        gj = {k: (R @ np.asarray(v, float)).tolist() for k, v in RIG.items()}
        names, P = ["neck"], [R @ _moved(None, "neck")]
        for base in STEM:                       # numbered the other way round: 1 = Right
            names += [f"{base}_1", f"{base}_2"]
            P += [R @ _moved("Right", base), R @ _moved("Left", base)]
        err, lengths = tr.joint_bias(names, np.array(P), gj, (0, 0, 1.0))
        for base, want in MOVE.items():
            for got in err[base]:
                assert np.allclose(got, want, atol=1e-9), (turn, base, got, want)
        ours, truth = lengths["shoulder width"]
        assert np.isclose(ours - truth, 2 * MOVE["shoulder"][0])
        ours, truth = lengths["hip width"]
        assert np.isclose(ours - truth, 2 * MOVE["hip"][0])
        thigh = np.linalg.norm(_moved("Left", "hip") - _moved("Left", "knee"))
        true_thigh = np.linalg.norm(np.subtract(RIG["LeftUpLeg_head"], RIG["LeftLeg_head"]))
        assert np.allclose(lengths["thigh"], (thigh, true_thigh))
        # no pelvis joint given: no neck–pelvis length
        assert "neck-pelvis" not in lengths


def test_real_signed_bias_recovers_known_offsets():
    rm = real_motion
    ours_of = {"Arm_head": "Shoulder", "ForeArm_head": "Elbow", "Hand_head": "Wrist",
               "UpLeg_head": "Hip", "Leg_head": "Knee", "Foot_head": "Ankle"}
    R = _rot(0.7)
    ref, markers = {"Neck": [R @ np.asarray(RIG["Neck_head"], float)],
                    "Head": [R @ np.asarray(RIG["Head_head"], float)]}, {}
    markers["Neck"] = R @ _moved(None, "neck")
    markers["Head"] = ref["Head"][0] + 0.0
    for base, stem in STEM.items():
        for side, s in (("Left", "L"), ("Right", "R")):
            ref[f"{s}{ours_of[stem]}"] = [R @ np.asarray(RIG[side + stem], float)]
        # sides unsure: numbered joints, 1 = the right one
        markers[f"{base}_1"] = R @ _moved("Right", base)
        markers[f"{base}_2"] = R @ _moved("Left", base)
    ref = {k: np.array(v) for k, v in ref.items()}
    out = rm.signed_bias([markers], ref, [0], (0, 0, 1.0))
    assert np.allclose(out["Neck"], 100 * np.array(MOVE["neck"]), atol=0.051)
    assert np.allclose(out["Head"], 0.0, atol=0.051)
    for base in STEM:
        for k in (base, "L" + base, "R" + base):
            assert np.allclose(out[k], 100 * np.array(MOVE[base]), atol=0.051), k


def test_real_toe_errors_pair_the_toes_with_the_big_toes_optimally():
    """Our toes 3 and 4 cm off Pose2Sim's big toes, named the wrong way round in one frame and
    missing in another: the median of the optimally paired distances, the missing frame left
    out."""
    rm = real_motion
    L, R = np.array([[0.1, 0.2, 0.0]] * 3), np.array([[-0.1, 0.2, 0.0]] * 3)
    ref = {"LBigToe": L, "RBigToe": R}
    up, side = np.array([0.0, 0.0, 0.03]), np.array([0.0, 0.04, 0.0])
    markers = [{"left_toe": L[0] + up, "right_toe": R[0] + side},
               {"left_toe": R[1] + side, "right_toe": L[1] + up},           # swapped names
               {"left_toe": L[2] + up, "right_toe": np.full(3, np.nan)}]   # a foot missing
    out = rm.toe_errors(markers, ref, [0, 1, 2])
    assert out["n"] == 4
    assert abs(out["median"] - 0.035) < 1e-9                 # median of 0.03, 0.04, 0.04, 0.03
    assert rm.toe_errors(markers, ref, [2]) == {"median": None, "n": 0}
