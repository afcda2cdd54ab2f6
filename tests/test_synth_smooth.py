"""``motion="random-smooth"``: a continuous motion through random poses (keyframes drawn as the
random poses are, eased by minimum jerk), its keyframes, speeds, volume and reproducibility."""
import json

import numpy as np
import pytest

from topopose.synth.capture import (KEY_DRIFT, KEY_INTERVAL, KEY_TURN, POSE_STREAM,
                                    ease_keyframes, min_jerk, synthetic_capture)
from topopose.synth.body import body_random, rig
from topopose.synth.subjects import HUMAN_DEFAULT
from topopose.errors import InputError

FPS = 25.0
SLOPE = 1.875          # the largest slope of 10u³ − 15u⁴ + 6u⁵: 30u²(1 − u)² at u = ½


@pytest.fixture(scope="module")
def body():
    """A 40-frame random motion of the body (two cameras, tiny images: the poses are tested)."""
    return synthetic_capture("body", frames=40, seed=14, cameras=2, size=(48, 36), noise=1,
                             motion="random-smooth", fps=FPS, build="average")


def test_min_jerk_and_easing_on_hand_made_keyframes():
    u = np.linspace(0, 1, 2001)
    s = min_jerk(u)
    assert s[0] == 0 and s[-1] == 1 and np.all(np.diff(s) >= 0)
    d = np.diff(s) / np.diff(u)
    assert abs(d.max() - SLOPE) < 1e-3 and d[0] < 1e-5 and d[-1] < 1e-5   # still at both ends
    assert abs(min_jerk(0.5) - 0.5) < 1e-15                               # symmetric
    # keyframes 0, 4, 10 with values 0, 8, 2; frames 0..10
    v = ease_keyframes([0.0, 8.0, 2.0], [0, 4, 10], 11)
    assert v[0] == 0 and v[4] == 8 and v[10] == 2
    assert abs(v[2] - 4.0) < 1e-12 and abs(v[7] - 5.0) < 1e-12          # half-way: the middle
    assert np.all(np.diff(v[:5]) > 0) and np.all(np.diff(v[4:]) < 0)    # no overshoot
    # a last keyframe beyond the sequence: the frames stop part-way
    w = ease_keyframes([[0.0, 1.0], [10.0, -1.0]], [0, 10], 6)
    assert w.shape == (6, 2) and abs(w[5, 0] - 5.0) < 1e-12 and abs(w[5, 1]) < 1e-12


def test_keyframes_are_the_random_draws_and_angles_eased(body):
    gt = body.options["gt"]
    keys, n = gt["synth"]["keyframes"], len(body.frames)
    assert keys[0] == 0 and keys[-1] >= n - 1 and len(keys) >= 3
    steps = np.diff(keys)
    assert np.all(steps >= round(KEY_INTERVAL[0] * FPS)) and np.all(steps <= round(KEY_INTERVAL[1] * FPS))
    rng = np.random.default_rng([14, POSE_STREAM])        # the poses of `random`, drawn in turn
    draws = [{**HUMAN_DEFAULT, **body_random(rng)} for _ in keys]
    poses = [gt["frames"][f]["pose"] for f in body.frames]
    names = sorted(draws[0])
    A = np.array([[p[a] for a in names] for p in poses])                 # (n, angles)
    for k, key in enumerate(keys):
        if key < n:
            assert poses[key] == draws[k]                                  # exactly the draw
    for k in range(len(keys) - 1):
        a, b = keys[k], min(keys[k + 1], n - 1)
        x0 = np.array([draws[k][m] for m in names])
        x1 = np.array([draws[k + 1][m] for m in names])
        seg = A[a:b + 1]
        assert np.all(seg >= np.minimum(x0, x1) - 1e-9) and np.all(seg <= np.maximum(x0, x1) + 1e-9)
        # the angular speed stays under the easing's peak: |Δ| × 1.875 / interval per frame
        bound = SLOPE * np.abs(x1 - x0) / (keys[k + 1] - keys[k]) + 1e-9
        assert np.all(np.abs(np.diff(seg, axis=0)) <= bound)
        # the motion leaves a keyframe still (velocity continuous, zero there): the first
        # frame's step is ≤ min_jerk(1/m) ≤ 10/m³ of the change, where linear easing gives 1/m
        m = keys[k + 1] - keys[k]
        assert np.all(np.abs(seg[1] - seg[0]) <= 10 * np.abs(x1 - x0) / m ** 3 + 1e-9)


def _yaw(R):
    R = np.asarray(R, float)
    return np.degrees(np.arctan2(R[1, 0], R[0, 0]))


def _chains():
    """Body joint-angle chains (the angles moving a limb's tip relative to the pelvis)."""
    spine = ["spine_flex", "spine_side", "spine_twist"]
    out = {"head": spine + ["neck_flex", "neck_side", "neck_twist"]}
    for s in "lr":
        out[f"arm_{s}"] = spine + [f"{k}_{s}" for k in ("sh_flex", "sh_abd", "sh_rot", "elbow",
                                                          "wrist_flex", "wrist_dev")]
        out[f"leg_{s}"] = [f"{k}_{s}" for k in ("hip_flex", "hip_abd", "hip_rot", "knee", "ankle")]
    return out


def test_no_jumps_bounded_by_the_angular_speed(body):
    """Every joint's step between frames ≤ lever × (the angles' steps along the longest chain,
    the shoulder's dependent raise included: × 1.3, + the heading's step) + the root's step,
    the lever being the build's height; and the heading and root turn and drift no faster
    than the easing allows. The unrelated random poses jump far beyond the same bound."""
    gt = body.options["gt"]
    fr = [gt["frames"][f] for f in body.frames]
    H = gt["height"]
    keys = gt["synth"]["keyframes"]
    shortest = np.min(np.diff(keys))
    chains = _chains()
    names = sorted(fr[0]["joints"])
    assert set(names) >= {f"{b}_{e}" for b in rig().names for e in ("head", "tail")}
    X = np.array([[f["joints"][j] for j in names] for f in fr])
    step = np.linalg.norm(np.diff(X, axis=0), axis=2).max(axis=1)
    for i in range(len(fr) - 1):
        p, q = fr[i], fr[i + 1]
        dyaw = abs((_yaw(q["placement"]["R"]) - _yaw(p["placement"]["R"]) + 180) % 360 - 180)
        dt = np.subtract(q["placement"]["t"], p["placement"]["t"])
        assert dyaw <= SLOPE * KEY_TURN / shortest + 1e-9
        assert np.all(np.abs(dt[:2]) <= SLOPE * KEY_DRIFT / shortest + 1e-9)
        dang = max(sum(abs(q["pose"][a] - p["pose"][a]) for a in c) for c in chains.values())
        bound = H * np.radians(1.3 * dang + dyaw) + np.linalg.norm(dt) + 1e-9
        assert step[i] <= bound, (i, step[i], bound)
    assert step.max() < 0.25                 # 25 fps: a fast hand (≤ 6 m/s), never a jump
    iid = synthetic_capture("body", frames=4, seed=14, cameras=1, size=(32, 24), motion="random",
                            build="average").options["gt"]
    Y = np.array([[iid["frames"][f]["joints"][j] for j in names] for f in sorted(iid["frames"])])
    assert np.linalg.norm(np.diff(Y, axis=0), axis=2).max(axis=1).min() > 0.25


def test_inside_the_volume_grounded_and_reproducible(body):
    lo, hi = body.volume
    assert np.allclose(lo, (-1.25, -1.25, -0.05)) and np.allclose(hi, (1.25, 1.25, 2.45))  # not grown
    for b in body.options["bodies"]:
        vlo, vhi = b.extent()
        assert abs(vlo[2]) < 1e-9                                      # on the floor
        assert np.all(vlo[:2] >= lo[:2] + 0.06 - 1e-9) and np.all(vhi <= hi - 0.06 + 1e-9)
    again = synthetic_capture("body", frames=40, seed=14, cameras=2, size=(48, 36), noise=1,
                              motion="random-smooth", fps=FPS, build="average")
    assert json.dumps(again.options["gt"]) == json.dumps(body.options["gt"])
    assert all(np.array_equal(x, y) for f in body.frames
               for x, y in zip(body.masks[f], again.masks[f]))
    other = synthetic_capture("body", frames=3, seed=15, cameras=1, size=(32, 24),
                              motion="random-smooth", build="average")
    assert other.options["gt"]["frames"]["000000"]["pose"] != body.options["gt"]["frames"]["000000"]["pose"]
    # the subject turns and moves: not a pose sequence standing still
    P = np.array([body.options["gt"]["frames"][f]["placement"]["t"] for f in body.frames])
    assert np.linalg.norm(P[-1, :2] - P[0, :2]) > 0.0 and np.ptp(P[:, 0]) + np.ptp(P[:, 1]) > 0.02


def test_capsule_human_random_smooth_and_arguments(tmp_path):
    cap = synthetic_capture("human", frames=30, seed=3, cameras=1, size=(32, 24),
                            motion="random-smooth")
    lo, hi = cap.volume
    X = np.array([[cap.gt["frames"][f]["joints"][j] for j in sorted(cap.gt["frames"]["000000"]["joints"])]
                  for f in cap.frames])
    assert np.all(X >= lo) and np.all(X <= hi)
    assert np.linalg.norm(np.diff(X, axis=0), axis=2).max() < 0.25
    assert cap.gt["synth"]["motion"] == "random-smooth" and cap.gt["synth"]["keyframes"][0] == 0
    for kw in ({"subject": "dog"}, {"subject": "human", "separated": True}):
        with pytest.raises(InputError):
            synthetic_capture(**{"frames": 2, "cameras": 1, "size": (32, 24),
                                 "motion": "random-smooth", **kw})
    from topopose.cli import main
    assert main(["synth", str(tmp_path / "c"), "--frames", "2", "--cameras", "1", "--size",
                 "32x24", "--motion", "random-smooth"]) == 0
    gt = json.loads((tmp_path / "c" / "gt.json").read_text())
    assert gt["synth"]["motion"] == "random-smooth" and len(gt["frames"]) == 2
