"""benchmarks/phantom.py's tests of a wrong part (beyond / phantom / aligned), on hand-made
geometry: four cameras in two facing pairs, a true hand, and our hand moved along one pair's
rays (the phantom extension) or across them."""
import numpy as np
from scipy.ndimage import distance_transform_edt

from _benchmarks import load_benchmark
from _capture_testutils import camera_at


def _scene():
    """Cameras on ±x (a facing pair) and ±y; the true hand at T. The ±x cameras see only a
    small blob around T's image (the hand against the background: T 2 px from the border); the
    ±y cameras see a wide trunk rectangle around both T and the phantom end (deep inside)."""
    cams = [camera_at([4, 0, 0], "x+"), camera_at([0, 4, 0], "y+"),
            camera_at([-4, 0, 0], "x-"), camera_at([0, -4, 0], "y-")]
    T = np.array([0.0, 0.2, 0.1])
    dts = []
    for cam in cams:
        m = np.zeros((480, 640), bool)
        u, v = cam.project(T[None])[0]
        if cam.name.startswith("x"):
            yy, xx = np.mgrid[:480, :640]
            m = (xx - u) ** 2 + (yy - v) ** 2 <= 2.5 ** 2
        else:
            m[100:400, 150:500] = True
        dts.append(distance_transform_edt(m))
    return cams, dts, T


def test_extension_along_a_facing_pair_is_the_phantom_mechanism():
    ph = load_benchmark("phantom")
    cams, dts, T = _scene()
    ours = T + np.array([0.3, 0.0, 0.0])          # 0.3 m along the x cameras' rays
    curve = np.linspace([0.0, 0.0, 0.3], T, 8).tolist() + np.linspace(T, ours, 9)[1:].tolist()
    seg = (T - [0, 0, 0.05], T + [0, 0, 0.05])
    r = ph.part_mechanism(ours, curve, seg, T, cams, dts, tol=0.1)
    assert r["beyond"] and r["phantom"] and r["aligned"]
    assert abs(r["extension"] - 0.3) < 0.01
    assert r["n_background"] == 2                 # the two x cameras
    assert max(r["ray_angle"][0], r["ray_angle"][2]) < 5


def test_error_across_the_rays_is_not_aligned_and_a_short_curve_not_beyond():
    ph = load_benchmark("phantom")
    cams, dts, T = _scene()
    ours = T + np.array([0.0, 0.0, -0.3])         # across every ray (straight down)
    curve = np.linspace([0.0, 0.7, -0.2], ours, 16)  # never near the true hand before its end
    seg = (T - [0, 0, 0.05], T + [0, 0, 0.05])
    r = ph.part_mechanism(ours, curve, seg, T, cams, dts, tol=0.1)
    assert not r["aligned"] and not r["beyond"]
    assert min(r["ray_angle"]) > 60
