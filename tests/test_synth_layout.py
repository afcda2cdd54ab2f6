"""Synthetic captures like the real recording's: phone cameras in facing pairs and leaning,
balancing subjects (``topopose.synth.capture`` ``layout``, ``lean``; the confidence benchmark's set-up 4r)."""
import numpy as np

from topopose.synth.capture import camera_ring, synthetic_capture

VOL = (np.array([-1.25, -1.25, -0.05]), np.array([1.25, 1.25, 2.45]))


def _azimuths(cams):
    c = (VOL[0] + VOL[1]) / 2
    return np.array([np.degrees(np.arctan2(cam.center[1] - c[1], cam.center[0] - c[0]))
                     for cam in cams])


def test_ring_default_unchanged_and_pairs_face_each_other():
    ring = camera_ring(VOL, 4, rng=np.random.default_rng(5))
    same = camera_ring(VOL, 4, rng=np.random.default_rng(5), layout="ring")
    assert all(np.allclose(a.matrix, b.matrix) and np.allclose(a.translation, b.translation) for a, b in zip(ring, same))
    for seed in range(8):
        az = _azimuths(camera_ring(VOL, 4, rng=np.random.default_rng(seed), layout="pairs"))
        gap = lambda i, j: abs((az[j] - az[i] + 180) % 360 - 180)  # noqa: E731
        assert 30 <= gap(0, 1) <= 90 and 30 <= gap(2, 3) <= 90          # within a pair
        assert gap(0, 2) >= 150 and gap(1, 3) >= 120                   # the pairs face each other
    even = _azimuths(ring)
    assert all(abs((even[(i + 1) % 4] - even[i]) % 360 - 90) <= 10 for i in range(4))


def _pelvis(j):
    a = np.subtract(j["LHipJoint_tail"], j["RHipJoint_tail"])
    b = np.subtract(j["Hips_tail"], j["Hips_head"])
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return np.stack([a, b, np.cross(a, b)])


def test_lean_tilts_the_pelvis_within_the_range():
    """Oracle: the world's up in pelvis coordinates, from an upright frame (lean 0: the pelvis
    differs by a yaw only); a leaning frame's pelvis up is tilted by lean/3 … lean degrees."""
    up0 = synthetic_capture("body", frames=2, seed=1, cameras=1, size=(32, 32), build="average")
    g0 = up0.options["gt"]["frames"]
    coef = [np.linalg.solve(_pelvis(f["joints"]).T, [0, 0, 1.0]) for f in g0.values()]
    assert np.allclose(coef[0], coef[1], atol=1e-4)        # gt.json: 6 decimals
    cap = synthetic_capture("body", frames=6, seed=2, cameras=1, size=(32, 32), lean=45,
                            build="average")
    assert cap.options["gt"]["synth"]["lean"] == 45
    for f in cap.options["gt"]["frames"].values():
        u = _pelvis(f["joints"]).T @ coef[0]
        tilt = np.degrees(np.arccos(u[2] / np.linalg.norm(u)))
        assert 15 - 0.5 <= tilt <= 45 + 0.5
        lo = min(p[2] for p in f["joints"].values())
        assert 0 <= lo < 0.15           # grounded: the mesh touches the floor, joints inside
