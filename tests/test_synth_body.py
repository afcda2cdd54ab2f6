"""The ``body`` subject (MakeHuman mesh posed by skinning): exact silhouettes, ground truth inside
the mesh, reproducibility, proportions, and a pipeline run on it."""
import json

import numpy as np
import pytest

from topopose.geometry.camera import Camera
from topopose.synth.capture import camera_ring, synthetic_capture
from topopose.synth.body import (BUILDS, HEIGHT_RANGE, body_mesh, body_random,
                                         bone_transforms, dominant_bones, make_build, pose_body,
                                         rig, skin)
from topopose.synth.geometry import ray_table


def brute_force_silhouette(cam, vertices, faces):
    """Möller–Trumbore ray/triangle test of every pixel's ray against every triangle."""
    tab = ray_table(cam)
    w, h = cam.size
    D = tab.directions().reshape(-1, 3)
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    e1, e2 = (v1 - v0).T, (v2 - v0).T
    s = (tab.origin - v0).T
    q = np.cross(s.T, e1.T).T
    tq = np.einsum("kt,kt->t", e2, q)
    hit = np.zeros(len(D), bool)
    for i in range(0, len(D), 64):
        dx, dy, dz = (D[i:i + 64, k:k + 1] for k in range(3))
        px, py, pz = dy * e2[2] - dz * e2[1], dz * e2[0] - dx * e2[2], dx * e2[1] - dy * e2[0]
        det = px * e1[0] + py * e1[1] + pz * e1[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            u = (px * s[0] + py * s[1] + pz * s[2]) * inv
            v = (dx * q[0] + dy * q[1] + dz * q[2]) * inv
            t = tq * inv
        hit[i:i + 64] = np.any((det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0), axis=1)
    return hit.reshape(h, w)


def winding_number(points, vertices, faces):
    """Generalized winding number (solid angles, Van Oosterom–Strackee) of a closed mesh."""
    out = []
    for x in points:
        a, b, c = (vertices[faces[:, k]] - x for k in range(3))
        la, lb, lc = (np.linalg.norm(y, axis=1) for y in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
               + np.einsum("ij,ij->i", c, a) * lb)
        out.append(np.sum(2 * np.arctan2(num, den)) / (4 * np.pi))
    return np.array(out)


def test_rest_pose_skinning_gives_the_rest_mesh():
    r = rig()
    build = make_build("average", None)
    A, t, u = bone_transforms(None, build)
    assert np.allclose(skin(A / u, t / u), r.vertices, atol=1e-9)
    # every bone moved by one rigid motion: the mesh moves rigidly (weights sum to 1)
    R = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    A = np.repeat(R[None], len(r.names), 0)
    t = np.repeat(np.array([[0.3, -0.2, 1.0]]), len(r.names), 0)
    assert np.allclose(skin(A, t), r.vertices @ R.T + t[0], atol=1e-5)
    # the mesh is closed (every edge in two triangles): inside tests are meaningful
    f = r.faces
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
    assert set(np.unique(np.unique(e, axis=0, return_counts=True)[1])) == {2}
    dom, names = dominant_bones()
    assert dom.shape == (len(r.vertices),) and len(names) == 31 and dom.max() < 31
    assert names[dom[r.tips["crown"]]] == "Head"


@pytest.mark.parametrize("seed", [8])
def test_silhouettes_equal_brute_force_ray_triangle(seed):
    rng = np.random.default_rng(seed)
    body = pose_body(body_random(rng), make_build("random", rng))
    lo, hi = body.extent()
    cams = camera_ring((lo - 0.05, hi + 0.05), 2, (40, 56), rng)   # camera 2 is distorted
    assert np.all(cams[0].distortions == 0) and np.any(cams[1].distortions != 0)
    for c in cams:
        K = c.matrix.copy()
        K[:2, :2] *= 2.0
        cam = Camera(c.name, c.size, K, c.distortions, c.rotation, c.translation)  # fills it
        mask = body.render(cam, ray_table(cam))
        ref = brute_force_silhouette(cam, body.vertices, body.faces)
        assert 120 < ref.sum() < 0.9 * ref.size
        assert np.array_equal(mask, ref)


def test_segments_lie_inside_the_mesh():
    """Rule: every point of every part segment is inside the mesh (winding number ≈ 1), except
    the surface end points (crown, fingertips, toe tips: mesh vertices), where only the points
    up to 90 % of the way are tested. The parts lie on their segments."""
    rng = np.random.default_rng(5)
    s = np.linspace(0, 1, 11)
    for build in list(BUILDS) + ["random"]:
        body = pose_body(body_random(rng), make_build(build, rng))
        V, F = body.vertices, body.faces
        for part, (a, b) in body.segments.items():
            surface_end = part in ("head", "hand_1", "hand_2", "foot_1", "foot_2")
            ss = s[s <= 0.9] if surface_end else s
            w = winding_number(a + ss[:, None] * (b - a), V, F)
            assert np.all(w > 0.5), (build, part, w)
            p = body.parts[part]
            d = np.linalg.norm(np.cross(p - a, b - a)) / np.linalg.norm(b - a)
            assert d < 1e-9 and -1e-9 <= (p - a) @ (b - a) <= (b - a) @ (b - a) + 1e-9
        for k in ("crown", "fingertip_l", "fingertip_r", "toe_l", "toe_r"):
            assert np.min(np.linalg.norm(V - body.joints[k], axis=1)) < 1e-12


def test_proportions_within_the_height_range():
    heights = []
    for seed in range(40):
        build = make_build("random", np.random.default_rng(seed))
        heights.append(build["height"])
    heights.append(BUILDS["child"]["height"])
    assert HEIGHT_RANGE[0] <= min(heights) and max(heights) <= HEIGHT_RANGE[1]
    assert max(heights) - min(heights) > 0.6
    for build in ("child", "heavy"):
        b = make_build(build, None)
        V = pose_body(None, b).vertices          # the rest (A-)pose stands at the build height
        assert np.ptp(V[:, 2]) == pytest.approx(b["height"], abs=1e-9)
    trunk = np.isin(rig().dominant, [rig().index(n) for n in ("Spine", "Spine1")])
    heavy, lean = (pose_body({}, make_build(n, None)).vertices[trunk] for n in ("heavy", "lean"))
    assert np.ptp(heavy[:, 0]) > 1.3 * np.ptp(lean[:, 0])    # girth: deeper trunk


def test_seeded_synth_is_reproducible_and_reposable():
    kw = dict(frames=2, seed=4, cameras=3, size=(96, 72), noise=1)
    a, b = synthetic_capture("body", **kw), synthetic_capture("body", **kw)
    assert json.dumps(a.options["gt"]) == json.dumps(b.options["gt"])
    assert all(np.array_equal(x, y) for f in a.frames for x, y in zip(a.masks[f], b.masks[f]))
    c = synthetic_capture("body", **{**kw, "seed": 5})
    assert c.options["gt"]["height"] != a.options["gt"]["height"]
    gt = json.loads(json.dumps(a.options["gt"]))            # as read back from gt.json
    for i, f in enumerate(a.frames):
        V, F = body_mesh(gt, f)
        assert np.array_equal(V, a.options["bodies"][i].vertices)
    g = gt["frames"]["000000"]
    assert set(g["parts"]) == {"head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"}
    assert "LeftHand_head" in g["joints"] and "RightToeBase_tail" in g["joints"]
    assert {"separated", "gap", "pose", "placement"} <= set(g)


def test_walk_is_smooth_and_grounded():
    cap = synthetic_capture("body", frames=6, seed=2, cameras=2, size=(64, 48), motion="walk",
                            build="average")
    bodies = cap.options["bodies"]
    for b in bodies:
        assert abs(b.extent()[0][2]) < 1e-9                          # feet on the floor
        lo, hi = b.extent()
        vlo, vhi = cap.volume
        assert np.all(lo >= vlo) and np.all(hi <= vhi)
    J = [np.array([b.joints[k] for k in sorted(b.joints)]) for b in bodies]
    steps = [np.max(np.linalg.norm(q - p, axis=1)) for p, q in zip(J, J[1:])]
    assert max(steps) < 0.25       # 25 fps, 1.2 m/s: a swinging foot or hand, no jumps


def test_cli_synth_body_and_pipeline_run(tmp_path):
    from topopose.cli import main

    out = tmp_path / "body"
    assert main(["synth", str(out), "--subject", "body", "--build", "child", "--frames", "2",
                 "--size", "320x240", "--separated", "--seed", "1"]) == 0
    gt = json.loads((out / "gt.json").read_text())
    assert gt["subject"] == "body" and gt["height"] == pytest.approx(1.36)
    assert gt["synth"]["build"]["name"] == "child"
    assert all(f["separated"] for f in gt["frames"].values())
    poses = tmp_path / "poses.jsonl"
    assert main(["run", str(out), "--model", "human", "--resolution", "60",
                 "--output", str(poses)]) in (0, 1)
    assert len(poses.read_text().splitlines()) == 1 + 2          # header line + 2 frames
    assert main(["synth", str(tmp_path / "x"), "--subject", "human", "--build", "child"]) == 2


def test_silhouettes_with_triangles_crossing_the_camera_plane():
    """A camera beside the body, looking along it: triangles behind it and crossing its plane."""
    import cv2

    rng = np.random.default_rng(3)
    body = pose_body(body_random(rng), make_build("average", rng))
    C = np.array([0.35, 0.0, 0.0])                 # in front of the pelvis, looking left (+y)
    f = np.array([0.0, 1.0, 0.0])
    right = np.cross(f, [0.0, 0.0, 1.0])
    R = np.stack([right, np.cross(f, right), f])
    K = np.array([[20.0, 0, 19.5], [0, 20.0, 14.5], [0, 0, 1]])
    for dist in (np.zeros(4), np.array([-0.05, 0.01, 5e-4, -3e-4])):
        cam = Camera("side", (40, 30), K, dist, cv2.Rodrigues(R)[0].ravel(), -R @ C)
        z = (body.vertices @ cam.R.T + cam.translation)[body.faces][:, :, 2]
        assert np.sum((z.min(1) <= 0) & (z.max(1) > 0)) > 20
        ref = brute_force_silhouette(cam, body.vertices, body.faces)
        assert ref.sum() > 100
        assert np.array_equal(body.render(cam, ray_table(cam)), ref)


@pytest.mark.parametrize("family", ["feet_out", "feet_in", "twist", "crouch", "kneel", "one_leg",
                                    "arms_crossed", "lying"])
def test_pose_families_pose_what_they_name(family):
    """Each pose family of the body's random poses (``synthetic_capture(pose=...)``) holds the
    angles its name promises, re-posable from gt.json; ``lying`` lays the trunk down."""
    from topopose.errors import InputError

    cap = synthetic_capture("body", frames=3, seed=5, cameras=2, size=(64, 48), build="average",
                            pose=family)
    assert cap.gt["synth"]["pose"] == family
    for name, f in cap.gt["frames"].items():
        p = f["pose"]
        if family in ("feet_out", "feet_in"):
            sg = 1 if family == "feet_out" else -1
            assert all(0 <= sg * p[f"hip_rot_{s}"] <= 40 for s in "lr")
        elif family == "twist":
            assert 30 <= abs(p["spine_twist"]) <= 70
        elif family == "crouch":
            assert all(p[f"hip_flex_{s}"] >= 70 and p[f"knee_{s}"] >= 90 for s in "lr")
        elif family == "kneel":
            assert any(p[f"knee_{s}"] >= 80 and p[f"hip_flex_{s}"] <= 15 for s in "lr")
        elif family == "one_leg":
            assert any(p[f"hip_flex_{s}"] >= 50 or p[f"hip_abd_{s}"] >= 30 for s in "lr")
        elif family == "arms_crossed":
            assert all(p[f"sh_rot_{s}"] <= -65 and p[f"elbow_{s}"] >= 100 for s in "lr")
        else:
            crotch, torso = (np.asarray(f["parts"][k], float) for k in ("crotch", "torso"))
            axis = (torso - crotch) / np.linalg.norm(torso - crotch)
            assert abs(axis[2]) < 0.5                    # the trunk nearer horizontal than upright
        V, _ = body_mesh(cap.gt, name)
        assert V[:, 2].min() == pytest.approx(0.0, abs=1e-6)          # grounded
    with pytest.raises(InputError):
        synthetic_capture("body", frames=1, cameras=2, size=(64, 48), pose="cartwheel")
    with pytest.raises(InputError):
        synthetic_capture("human", frames=1, cameras=2, size=(64, 48), pose="kneel")
