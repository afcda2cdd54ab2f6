"""Synthetic captures: reproducibility, ground truth, separation flag, folder layout, noise,
motions, and round trips through load_capture and the visual hull."""
import json
import time
import tomllib

import numpy as np
import pytest

from topopose.capture import Camera, load_capture

from topopose.synth import synthesize, synthetic_capture
from topopose.synth.subjects import PARTS, dog, hand, human
from topopose.errors import InputError

SUBJECTS = ["human", "hand", "dog", "spider"]


@pytest.fixture(scope="module")
def caps():
    """One small capture per subject (random poses), shared by the tests of this module."""
    return {s: synthetic_capture(s, frames=3, seed=11, cameras=6, size=(320, 240)) for s in SUBJECTS}


def _on_segment(p, a, b):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0, 1)
    return np.linalg.norm(a + t * ab - p)


def test_same_seed_same_capture():
    a = synthetic_capture("human", frames=2, seed=5, cameras=3, size=(160, 120), noise=2)
    b = synthetic_capture("human", frames=2, seed=5, cameras=3, size=(160, 120), noise=2)
    c = synthetic_capture("human", frames=2, seed=6, cameras=3, size=(160, 120), noise=2)
    assert a.gt == b.gt
    for f in a.frames:
        assert all(np.array_equal(x, y) for x, y in zip(a.silhouettes(f), b.silhouettes(f)))
    for x, y in zip(a.cameras, b.cameras):
        assert np.array_equal(x.matrix, y.matrix) and np.array_equal(x.rotation, y.rotation)
    assert a.gt != c.gt
    assert not all(np.array_equal(x, y) for x, y in zip(a.silhouettes(0), c.silhouettes(0)))


@pytest.mark.parametrize("subject", SUBJECTS)
def test_gt_parts_and_joints_project_inside_silhouettes(caps, subject):
    cap = caps[subject]
    gt = cap.gt
    assert gt["subject"] == subject and gt["units"] == "m" and gt["up"] == "+z"
    assert gt["parts"] == PARTS[subject]
    assert gt["height"] > 0
    lo, hi = cap.volume
    for f in cap.frames:
        g = gt["frames"][f]
        assert set(g["parts"]) == set(PARTS[subject]) == set(g["segments"])
        assert isinstance(g["separated"], bool)
        pts = np.array(list(g["parts"].values()) + list(g["joints"].values()))
        assert np.all(pts >= lo - 1e-9) and np.all(pts <= hi + 1e-9)   # inside the volume
        for k, p in g["parts"].items():              # each part lies on its segment
            a, b = np.array(g["segments"][k])
            assert _on_segment(np.array(p), a, b) < 1e-5, k
        for cam, mask in zip(cap.cameras, cap.silhouettes(f)):
            px = np.round(cam.project(pts)).astype(int)
            h, w = mask.shape
            assert np.all((px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h))
            assert mask[px[:, 1], px[:, 0]].all(), (cam.name, f)


def test_body_surface_projects_inside_silhouettes(caps):
    """Surface points of the posed primitives land in the rendered masks (within 1 px)."""
    cap = caps["dog"]
    body = cap.options["bodies"][0]
    pts = body.surface_points(200)
    import cv2
    for cam, mask in zip(cap.cameras, cap.silhouettes(0)):
        px = np.round(cam.project(pts)).astype(int)
        dist = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 5)
        assert dist[px[:, 1], px[:, 0]].max() <= 1.0


def test_hand_forearm_crosses_the_volume_border(caps):
    cap = caps["hand"]
    lo, hi = cap.volume
    for f in cap.frames:
        g = cap.gt["frames"][f]
        arm = np.array(g["parts"]["arm"])
        assert np.min(np.abs(np.concatenate([arm - lo, hi - arm]))) < 1e-6   # on a face of the box
        w = np.array(g["joints"]["wrist"])
        assert np.all(w > lo) and np.all(w < hi)
        body = cap.options["bodies"][cap.frames.index(f)]
        fa = [p for p in body.prims if p.link == "forearm"][0]
        assert np.any(fa.b < lo) or np.any(fa.b > hi)          # the forearm ends outside


def test_separated_flag_on_constructed_poses():
    T = {"sh_abd_l": 90, "sh_abd_r": 90}
    cases = [
        (human({}), False, ("chest", "upperarm_l")),          # arms hanging against the chest
        (human(T), True, None),                               # T-pose
        (human({**T, "hip_abd_l": 20, "hip_abd_r": 20}), True, None),
        (human({**T, "hip_abd_l": -8, "hip_abd_r": -8}), False, ("shin_l", "shin_r")),  # crossed
        (human({**T, "sh_flex_l": 0, "elbow_l": 150}), False, ("upperarm_l", "forearm_l")),
        (hand({f"{f}_{j}": 80 for f in ("index", "middle", "ring", "little")
               for j in ("mcp", "pip", "dip")}), False, None),  # fist: fingers touch each other
        (hand({"index_spread": 6, "ring_spread": -6, "little_spread": -6}), True, None),
        (dog({}), True, None),
        (dog({"swing_fl": -45, "swing_rl": 45, "bend_rl": 0, "bend_fl": 0}), False,
         ("fl2", "rl2")),                                      # front and rear legs cross
    ]
    for body, expect, pair in cases:
        assert body.separated() is expect, (body.subject, body.min_gap())
        if pair is not None:
            bad = {tuple(sorted((a, b))) for g, a, b in body.clearances() if g < body.margin}
            assert tuple(sorted(pair)) in bad, bad


@pytest.mark.parametrize("subject", SUBJECTS)
def test_separated_sampling(subject):
    cap = synthetic_capture(subject, frames=3, seed=2, cameras=2, size=(96, 72), separated=True)
    for f, body in zip(cap.frames, cap.options["bodies"]):
        assert cap.gt["frames"][f]["separated"] is True
        assert body.min_gap() >= body.margin


def test_limb_margin_separates_distinct_limbs_only():
    """``margin=``: distinct limbs keep the wide clearance, one limb's bones (parent/child,
    grandparent/grandchild links) keep the subject's anatomical one; recorded in gt.json."""
    cap = synthetic_capture("human", frames=3, seed=4, cameras=2, size=(96, 72), separated=True,
                            margin=0.075)
    assert cap.gt["synth"]["limb_margin"] == 0.075 and cap.gt["synth"]["margin"] == 0.02
    for f, body in zip(cap.frames, cap.options["bodies"]):
        g = cap.gt["frames"][f]
        assert g["separated"] is True and g["limb_gap"] >= 0.075 and g["gap"] >= 0.02
        for gap, a, b in body.clearances():        # an independent check of every pair
            assert gap >= body.required_margin(a, b) - 1e-9, (a, b, gap)
    body = cap.options["bodies"][0]
    assert body.required_margin("chest", "upperarm_l") == 0.02          # parent/child
    assert body.required_margin("chest", "head") == 0.02                # grandparent (neck)
    assert body.required_margin("hand_l", "head") == 0.075              # distinct limbs
    assert body.required_margin("thigh_l", "thigh_r") == 0.075          # siblings
    # the default is unchanged: every non-adjacent pair against the anatomical margin
    plain = human({})
    assert plain.limb_margin is None and plain.required_margin("hand_l", "head") == plain.margin
    # the wide margin decides at the closest pair of distinct limbs, and only there
    g = body.limb_gap()
    assert g == min(c for c, a, b in body.clearances() if body.required_margin(a, b) > 0.02)
    body.limb_margin = g - 1e-3
    assert body.separated()
    body.limb_margin = g + 1e-3
    assert not body.separated()
    with pytest.raises(InputError, match="margin"):
        synthetic_capture("human", frames=1, cameras=2, size=(96, 72), separated=True, margin=-1)


def test_folder_layout_and_calibration(tmp_path):
    out = synthesize(tmp_path / "cap", "human", frames=2, seed=3, cameras=3, size=(160, 120))
    files = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    expect = ["calibration.toml", "capture.toml", "gt.json"] + [
        f"silhouettes/cam_{c:02d}/{f:06d}.png" for c in (1, 2, 3) for f in (0, 1)]
    assert files == sorted(expect)
    calib = tomllib.loads((out / "calibration.toml").read_text())
    assert set(calib) == {"cam_01", "cam_02", "cam_03", "metadata"}
    mem = synthetic_capture("human", frames=2, seed=3, cameras=3, size=(160, 120))
    pts = np.random.default_rng(0).uniform(-0.5, 0.5, (20, 3)) + [0, 0, 1]
    for name, ref in zip(("cam_01", "cam_02", "cam_03"), mem.cameras):
        t = calib[name]
        assert t["name"] == name and t["size"] == [160, 120] and t["fisheye"] is False
        assert np.shape(t["matrix"]) == (3, 3) and len(t["distortions"]) == 4
        assert len(t["rotation"]) == 3 and len(t["translation"]) == 3
        cam = Camera(t["name"], t["size"], t["matrix"], t["distortions"], t["rotation"], t["translation"])
        assert np.allclose(cam.project(pts), ref.project(pts), atol=1e-9)
    assert any(np.any(np.array(calib[c]["distortions"]) != 0) for c in ("cam_01", "cam_02", "cam_03"))
    opts = tomllib.loads((out / "capture.toml").read_text())["capture"]
    assert opts["up"] == "+z" and opts["units"] == "m" and opts["fps"] == 25
    assert len(opts["volume"]["min"]) == 3 and len(opts["volume"]["max"]) == 3
    gt = json.loads((out / "gt.json").read_text())
    assert gt == json.loads(json.dumps(mem.gt))
    import cv2
    img = cv2.imread(str(out / "silhouettes/cam_02/000001.png"), cv2.IMREAD_UNCHANGED)
    assert img.dtype == np.uint8 and img.shape == (120, 160)
    assert set(np.unique(img)) == {0, 255}
    assert np.array_equal(img > 127, mem.silhouettes(1)[1])


@pytest.mark.parametrize("subject", SUBJECTS)
def test_round_trip_load_capture(tmp_path, subject):
    mem = synthetic_capture(subject, frames=2, seed=4, cameras=3, size=(200, 150))
    synthesize(tmp_path / subject, subject, frames=2, seed=4, cameras=3, size=(200, 150))
    cap = load_capture(tmp_path / subject)
    assert cap.frames == mem.frames
    assert [c.name for c in cap.cameras] == [c.name for c in mem.cameras]
    assert np.allclose(cap.volume[0], mem.volume[0]) and np.allclose(cap.volume[1], mem.volume[1])
    assert cap.up == "+z" and cap.fps == 25
    for f in cap.frames:
        for a, b in zip(cap.silhouettes(f), mem.silhouettes(f)):
            assert np.array_equal(a, b)
    assert cap.gt["frames"] == json.loads(json.dumps(mem.gt["frames"]))


@pytest.mark.parametrize("subject", SUBJECTS)
def test_round_trip_visual_hull_contains_gt(tmp_path, subject):
    from topopose.hull import visual_hull

    synthesize(tmp_path / subject, subject, frames=2, seed=8, cameras=8, size=(320, 240))
    cap = load_capture(tmp_path / subject)
    from scipy import ndimage
    for f in cap.frames:
        vol = visual_hull(cap, f, resolution=80)
        assert vol.data.any()
        dist = ndimage.distance_transform_edt(~vol.data)
        for k, p in cap.gt["frames"][f]["parts"].items():
            idx = np.round((np.array(p) - vol.origin) / vol.voxel_size).astype(int)
            idx = np.clip(idx, 0, np.array(vol.data.shape) - 1)   # "arm" lies on the border
            assert dist[tuple(idx)] <= 2.0, (subject, f, k, dist[tuple(idx)])


def test_noise_levels_are_monotonic():
    clean = synthetic_capture("human", frames=3, seed=9, cameras=4, size=(320, 240))
    diffs = []
    for level in (1, 2, 3):
        noisy = synthetic_capture("human", frames=3, seed=9, cameras=4, size=(320, 240), noise=level)
        assert noisy.gt["frames"] == clean.gt["frames"]
        diffs.append(sum(int((a ^ b).sum()) for f in clean.frames
                         for a, b in zip(clean.silhouettes(f), noisy.silhouettes(f))))
    assert 0 < diffs[0] < diffs[1] < diffs[2], diffs


def test_thickness_and_dress():
    from topopose.synth.capture import camera_ring
    from topopose.synth.geometry import ray_table, render
    from topopose.synth.subjects import human_random

    pose = human_random(np.random.default_rng(0))
    thin, thick = human(pose), human(pose, thickness=1.25)
    assert all(np.allclose(thin.joints[k], thick.joints[k]) for k in thin.joints)
    cams = camera_ring((np.array([-1.2, -1.2, -1.1]), np.array([1.2, 1.2, 1.3])), 3, (240, 180),
                       np.random.default_rng(1))
    for cam in cams:
        tab = ray_table(cam)
        a, b = render(cam, tab, thin.prims), render(cam, tab, thick.prims)
        assert b.sum() > 1.1 * a.sum() and not (a & ~b).any()   # a thick coat covers the body
    dress = human({"sh_abd_l": 90, "sh_abd_r": 90, "hip_abd_l": 20, "hip_abd_r": 20}, thickness=1.5)
    assert not dress.separated()                                 # the dress joins the legs
    with pytest.raises(InputError):
        synthetic_capture("human", frames=1, cameras=1, size=(64, 48), thickness=1.5, separated=True)


@pytest.mark.parametrize("subject,motion,fps", [("human", "walk", 25), ("dog", "trot", 50),
                                                ("hand", "grasp", 25), ("spider", "walk", 25)])
def test_motion_is_smooth(subject, motion, fps):
    n = 24
    cap = synthetic_capture(subject, frames=n, seed=3, cameras=1, size=(64, 48), motion=motion, fps=fps)
    fr = cap.gt["frames"]
    names = list(fr)
    joints = sorted(fr[names[0]]["joints"])
    X = np.array([[fr[f]["joints"][j] for j in joints] for f in names])      # (n, J, 3)
    v = np.linalg.norm(np.diff(X, axis=0), axis=2) * fps                      # m/s
    scale = cap.gt["height"]
    assert v.max() < 6.0 * scale, v.max()                                     # bounded velocities
    acc = np.linalg.norm(np.diff(X, 2, axis=0), axis=2) * fps * fps
    assert acc.max() < 120.0 * scale, acc.max()                               # no jumps
    if motion == "grasp":                       # fingers open and close, the wrist stays
        assert np.ptp(X[:, joints.index("wrist")], axis=0).max() < 0.03
        tip = X[:, joints.index("index_tip")]
        assert np.linalg.norm(tip - tip[0], axis=1).max() > 0.02


def test_walk_and_trot_translate_the_body():
    cap = synthetic_capture("human", frames=25, seed=1, cameras=1, size=(64, 48), motion="walk")
    fr = cap.gt["frames"]
    P = np.array([fr[f]["joints"]["pelvis"] for f in cap.frames])
    d = np.linalg.norm(P[-1, :2] - P[0, :2])
    assert 0.9 < d < 1.5                                        # ≈ 1.2 m/s for 24/25 s
    assert abs(np.ptp(P[:, 2])) < 0.08                          # the pelvis stays at hip height
    seps = [fr[f]["separated"] for f in cap.frames]
    assert any(seps) and not all(seps)                          # arms brush the chest sometimes
    lo, hi = cap.volume
    for f in cap.frames:
        pts = np.array(list(fr[f]["joints"].values()))
        assert np.all(pts >= lo) and np.all(pts <= hi)
    dog_cap = synthetic_capture("dog", frames=10, seed=1, cameras=1, size=(64, 48), motion="trot")
    H = np.array([dog_cap.gt["frames"][f]["joints"]["hips"] for f in dog_cap.frames])
    assert np.linalg.norm(H[-1, :2] - H[0, :2]) > 0.4


def test_long_walk_grows_the_volume():
    cap = synthetic_capture("human", frames=64, seed=2, cameras=1, size=(32, 24), motion="walk")
    lo, hi = cap.volume
    assert np.max(hi[:2] - lo[:2]) > 3.3            # default 2.5 m; the path is 3.1 m long
    for f in cap.frames[::10]:
        pts = np.array(list(cap.gt["frames"][f]["joints"].values()))
        assert np.all(pts >= lo) and np.all(pts <= hi)


def test_bad_arguments_raise_input_error():
    for kw in ({"subject": "cat"}, {"motion": "walk", "subject": "hand"}, {"frames": 0},
               {"noise": 4}, {"size": (8, 8)}, {"thickness": 9.0}, {"cameras": 0},
               {"motion": "walk", "separated": True}):
        with pytest.raises(InputError):
            synthetic_capture(**{"frames": 1, "cameras": 1, "size": (32, 24), **kw})


def test_cli_synth(tmp_path, capsys):
    from topopose.cli import main

    out = tmp_path / "c"
    assert main(["synth", str(out), "--subject", "dog", "--frames", "2", "--cameras", "2",
                 "--size", "120x90", "--noise", "1", "--separated"]) == 0
    cap = load_capture(out)
    assert len(cap.frames) == 2 and len(cap.cameras) == 2 and cap.cameras[0].size == (120, 90)
    assert cap.gt["synth"]["separated"] and cap.gt["synth"]["noise"] == 1
    assert all(g["separated"] for g in cap.gt["frames"].values())
    assert main(["synth", str(tmp_path / "d"), "--subject", "hand", "--motion", "walk"]) == 2
    assert "motion" in capsys.readouterr().err


def test_generation_speed():
    synthetic_capture("human", frames=1, cameras=1, size=(64, 48))        # warm up (compile)
    t = time.perf_counter()
    synthetic_capture("human", frames=10, seed=0, cameras=8, size=(640, 480))
    took = time.perf_counter() - t
    assert took < 12.0, took        # ≈ 1 s unloaded; generous bound for a shared machine
