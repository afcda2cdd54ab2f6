"""The real recording's synthetic twin (``benchmarks/real_twin.py``): its inverse
kinematics, its turned cameras and its scoring, each against an oracle — a pose the rig itself
made, a point carried by the same turn, markers moved by a known offset."""
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import real_twin

BENCH = Path(__file__).resolve().parents[1]

REC = BENCH / "data" / "pose2sim_balancing"


@pytest.fixture(scope="module")
def rt():
    return real_twin


def test_inverse_kinematics_recovers_a_pose_of_the_rig(rt):
    from topopose.synth.body import BUILDS

    poser = rt.Poser(BUILDS["average"])
    pose = {"spine_flex": 15.0, "spine_side": -8.0, "neck_flex": 10.0, "sh_flex_l": 40.0,
            "sh_abd_l": 30.0, "elbow_l": 50.0, "sh_abd_r": 70.0, "elbow_r": 20.0,
            "hip_flex_l": 35.0, "knee_l": 45.0, "hip_abd_r": 20.0, "knee_r": 10.0,
            "ankle_l": 10.0}
    R = Rotation.from_euler("zx", [35.0, 6.0], degrees=True).as_matrix()
    t = np.array([0.4, -0.2, 0.1])
    P = poser.points(pose, R, t)
    g = {m: P[k] for k, (_rp, m, _w) in enumerate(rt.IK_MARKERS)}
    fitted, R2, t2, _x, rms = rt.fit_pose(poser, g)
    assert rms < 0.005
    Q = poser.points(fitted, R2, t2)
    assert np.abs(Q - P).max() < 0.01
    # a wrong target (the left wrist 10 cm off) is not reached: the residual says so
    bad = {**g, "LWrist": g["LWrist"] + np.array([0.0, 0.1, 0.0])}
    assert rt.fit_pose(poser, bad)[4] > 0.01


def test_turned_cameras_see_the_turned_scene(rt):
    centre = np.array([0.3, -0.1, 0.0])
    four, eight = rt.twin_cameras(REC, "4", centre), rt.twin_cameras(REC, "8", centre)
    assert len(four) == 4 and len(rt.twin_cameras(REC, "6", centre)) == 6 and len(eight) == 8
    assert four[0].size == (544, 960)                     # the person masks' half size
    Rz = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    X = np.array([[0.2, 0.1, 1.0], [0.5, -0.3, 0.2], [0.0, 0.4, 1.6]])
    for cam, turned in zip(eight[:4], eight[4:]):
        carried = (X - centre) @ Rz.T + centre
        np.testing.assert_allclose(turned.project(carried), cam.project(X), atol=1e-6)
        # the optical centre turned by 45° about the vertical through the centre
        np.testing.assert_allclose(turned.center, Rz @ (cam.center - centre) + centre, atol=1e-9)
        assert not np.allclose(turned.project(X), cam.project(X), atol=1.0)


def test_truth_against_reference_is_the_markers_distance(rt):
    rng = np.random.default_rng(3)
    names = ["Head", "Neck"] + [f"{s}{m}" for s in "LR" for m in
                                ("Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle")]
    ref = {n: rng.normal(size=(5, 3)) for n in names}
    assert rt.truth_vs_reference(ref, ref, 5)["mpjpe"] == pytest.approx(0.0, abs=1e-12)
    moved = {n: v + np.array([0.0, 0.02, 0.0]) for n, v in ref.items()}
    s = rt.truth_vs_reference(moved, ref, 5)
    assert s["mpjpe"] == pytest.approx(0.02, abs=1e-9)
    assert s["per_joint"]["Neck"] == pytest.approx(0.02, abs=1e-9)


def test_twin_silhouettes_hold_the_body(rt):
    from topopose.synth.body import BUILDS, pose_body

    body = pose_body({"sh_abd_l": 60.0, "elbow_r": 30.0}, BUILDS["average"]).transformed(
        np.eye(3), np.array([0.0, 0.0, 0.0]))
    cams = rt.twin_cameras(REC, "4", np.zeros(3))
    cap = rt.twin_capture([body], cams, noise=0, dilate=0, fps=60.0)
    fat = rt.twin_capture([body], cams, noise=0, dilate=3, fps=60.0)
    noisy = [rt.twin_capture([body], cams, noise=2, dilate=0, fps=60.0, seed=s) for s in (0, 1)]
    for ci, cam in enumerate(cams):
        m = cap.masks["000000"][ci]
        assert m.shape == (960, 544) and m.any()
        for j in ("Neck_head", "Spine1_head", "LeftUpLeg_head"):      # inside the body
            u, v = np.round(cam.project(body.joints[j][None])[0]).astype(int)
            assert m[v, u]
        assert fat.masks["000000"][ci].sum() > m.sum()
        assert (fat.masks["000000"][ci] >= m).all()
        assert not np.array_equal(noisy[0].masks["000000"][ci], noisy[1].masks["000000"][ci])
    assert cap.fps == 60.0 and cap.frames == ["000000"]
