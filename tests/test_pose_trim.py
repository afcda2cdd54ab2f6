"""The hands' trim out of the hull's phantom volume (:mod:`topopose.frame.trim`), on hand-made
geometry: a box trunk and a cylinder arm rendered into four cameras (two facing pairs), the
arm's skeleton curve continued past the hand along one pair's rays in front of the trunk (inside
every silhouette: phantom volume), or a real forearm that is rendered."""
import cv2
import numpy as np

from _capture_testutils import camera_at
from topopose.pose.pose import Pose
from topopose.frame.trim import apply_trim, evidence_end, trim_pose, trimmed_curves

J = np.array([0.0, 0.0, 0.2])          # the curves' junction (chest)
A = np.array([0.1, 0.25, 0.6])         # the arm's top, above the trunk, in front of it
H = np.array([0.1, 0.25, 0.1])         # the real hand, in front of the chest
E = np.array([-0.1, 0.25, 0.1])        # the phantom end: along the ±x rays, before the trunk
CAMS = [camera_at([4, 0, 0.1], "x+"), camera_at([0, 4, 0.1], "y+"),
        camera_at([-4, 0, 0.1], "x-"), camera_at([0, -4, 0.1], "y-")]


def _cylinder(a, b, r, step=0.005):
    a, b = np.asarray(a, float), np.asarray(b, float)
    g = np.arange(-r, r + step, step)
    disk = np.array([(x, y) for x in g for y in g if x * x + y * y <= r * r])
    d = (b - a) / np.linalg.norm(b - a)
    u = np.cross(d, [1.0, 0, 0] if abs(d[0]) < 0.9 else [0, 1.0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(d, u)
    t = np.arange(0, np.linalg.norm(b - a) + step, step)
    return (a + t[:, None, None] * d + disk[None, :, :1] * u + disk[None, :, 1:] * v).reshape(-1, 3)


def _render(extra=()):
    """Silhouettes of the trunk box and the arm (and ``extra`` cylinders), points projected and
    closed."""
    g = np.arange(-0.15, 0.1501, 0.005)
    box = np.array([(x, y, z) for x in g for y in g[(g >= -0.1) & (g <= 0.1)]
                    for z in np.arange(-0.3, 0.3001, 0.005)])
    pts = np.vstack([box, _cylinder(A, H, 0.04)] + [_cylinder(a, b, 0.04) for a, b in extra])
    out = []
    for cam in CAMS:
        uv = np.rint(cam.project(pts)).astype(int)
        m = np.zeros((480, 640), np.uint8)
        ok = (uv[:, 0] >= 0) & (uv[:, 0] < 640) & (uv[:, 1] >= 0) & (uv[:, 1] < 480)
        m[uv[ok, 1], uv[ok, 0]] = 1
        out.append(cv2.morphologyEx(m, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0)
    return out


def _polyline(*pts, n=16):
    from topopose.frame.curves import resample
    dense = np.vstack([np.linspace(a, b, 50) for a, b in zip(pts, pts[1:])])
    return resample(dense, n)


def _pose(end, via=(A, H)):
    curves = {"hand_1": _polyline(J, *via, end) if not np.allclose(end, via[-1])
              else _polyline(J, *via),
              "crotch": _polyline(J, [0.0, 0.0, -0.3]), "head": _polyline(J, [0.0, 0.0, 0.3])}
    parts = {"torso": J, "hand_1": np.asarray(end, float), "crotch": np.array([0.0, 0, -0.3]),
             "head": np.array([0.0, 0, 0.3])}
    # voxel edge 0.02: hull_litres / 1000 / hull_voxels = 0.02³
    return Pose("000000", "matched", 1.0, parts,
                diagnostics={"curves": curves, "hull_litres": 8.0, "hull_voxels": 1000})


def test_silhouettes_hold_the_phantom_extension():
    """The oracle's premise: E (and the tube H → E) lies inside every silhouette."""
    sils = _render()
    for cam, s in zip(CAMS, sils):
        for p in np.linspace(H, E, 9):
            u, v = np.rint(cam.project(p[None])[0]).astype(int)
            assert s[v, u], (cam.name, p)


def test_phantom_extension_is_trimmed_back_to_the_hand():
    sils = _render()
    q = trim_pose(_pose(E), CAMS, sils)
    assert q.diagnostics["trimmed"] == ["hand_1"]
    assert np.linalg.norm(q.parts["hand_1"] - H) < 0.05
    assert np.allclose(q.diagnostics["curves"]["hand_1"][-1], q.parts["hand_1"])
    assert np.allclose(q.diagnostics["curves"]["hand_1"][0], J)
    assert np.array_equal(q.parts["crotch"], [0.0, 0, -0.3])     # other parts untouched


def test_real_hand_and_real_forearm_are_kept():
    sils = _render()
    p = _pose(H)
    assert trim_pose(p, CAMS, sils) is p
    F = np.array([-0.35, 0.25, 0.1])       # a real forearm past the trunk's side: rendered
    p = _pose(F)
    assert trim_pose(p, CAMS, _render(extra=[(H, F)])) is p


def test_evidence_end_on_dense_curves():
    """:func:`evidence_end` directly: the tube's last explained-nothing point is the hand; a
    curve ending at the hand ends there."""
    from scipy.ndimage import distance_transform_edt

    deps = [distance_transform_edt(s) for s in _render()]
    others = [_polyline(J, [0.0, 0.0, -0.3], n=64), _polyline(J, [0.0, 0.0, 0.3], n=64)]
    curve = _polyline(J, A, H, E, n=64)
    j, r = evidence_end(curve, others, CAMS, deps, 0.02)
    assert j < 63 and np.linalg.norm(curve[j] - H) < 0.06
    assert 0 < r < 0.06                                 # at most the arm's radius, 0.04
    j, r = evidence_end(_polyline(J, A, H, n=64), others, CAMS, deps, 0.02)
    assert np.linalg.norm(_polyline(J, A, H, n=64)[j] - H) < 0.06 and j > 55


def test_apply_trim_moves_only_a_part_still_at_its_curve_end():
    """The sequence stage applies what the frame recorded, once the identities are settled: a
    part the tracking moved elsewhere (held, snapped) keeps its place and curve."""
    p = _pose(E)
    cut = trimmed_curves(p.diagnostics["curves"], p.parts, CAMS, _render(), 0.02)
    assert list(cut) == ["hand_1"]
    rec = Pose(p.frame, p.status, p.distance, p.parts,
               diagnostics={**p.diagnostics, "trim": {q: c.tolist() for q, c in cut.items()}})
    q = apply_trim(rec)
    assert q.diagnostics["trimmed"] == ["hand_1"]
    assert np.allclose(q.parts["hand_1"], cut["hand_1"][-1]) and np.allclose(
        q.diagnostics["curves"]["hand_1"], cut["hand_1"])
    held = Pose(p.frame, p.status, p.distance, {**p.parts, "hand_1": H + [0, 0, 0.2]},
                diagnostics=rec.diagnostics)
    assert apply_trim(held) is held
    assert apply_trim(p) is p                   # nothing recorded


def test_compared_views_take_the_small_maps_of_upsampled_masks():
    """A silhouette upsampled from a small map (``person``): trimmed on the small map with the
    camera scaled to it, the same way as at full size."""
    from topopose.capture.background import UpsampledMask
    from topopose.frame.support import compared_views

    masks = []
    for s in _render():
        small = np.ascontiguousarray(s[::2, ::2]).astype(np.uint8)
        m = cv2.resize(small, (640, 480), interpolation=cv2.INTER_NEAREST).astype(bool)
        m = m.view(UpsampledMask)
        m.small = small
        masks.append(m)
    cams, sils = compared_views(CAMS, masks)
    assert [c.size for c in cams] == [(320, 240)] * 4 and sils[0].shape == (240, 320)
    assert np.allclose(cams[0].project(H[None]), (CAMS[0].project(H[None]) - 0.5) / 2, atol=1e-9)
    out = trim_pose(_pose(E), cams, sils)       # half the pixels: a pixel is 1.6 cm there
    assert np.linalg.norm(out.parts["hand_1"] - H) < 0.08 < np.linalg.norm(E - H) / 2


def test_process_sequence_applies_the_recorded_trim_unless_off():
    from topopose.pose.model import load_model
    from topopose.sequence.motion import process_sequence

    m = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    p = _pose(E)
    cut = trimmed_curves(p.diagnostics["curves"], p.parts, CAMS, _render(), 0.02)
    rec = Pose(p.frame, p.status, p.distance, p.parts,
               diagnostics={**p.diagnostics, "trim": {q: c.tolist() for q, c in cut.items()}})
    kw = dict(track=False, sides=False, skeleton=False)
    a = process_sequence([rec], m, up, **kw)
    assert "trim" in a.stages and a.poses[0].diagnostics["trimmed"] == ["hand_1"]
    assert np.linalg.norm(a.poses[0].parts["hand_1"] - H) < 0.05
    b = process_sequence([p], m, up, **kw)
    c = process_sequence([rec], m, up, trim=False, **kw)
    for r in (b, c):
        assert "trim" not in r.stages and np.allclose(r.poses[0].parts["hand_1"], E)


def test_the_estimator_records_the_trim_and_keeps_the_frame():
    """``FrameEstimator`` records ``diagnostics["trim"]`` from the silhouettes it carved the hull
    from; the frame's parts and confidence are those of ``trim=False``."""
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    cap = synthetic_capture("body", frames=4, seed=41, cameras=4, size=(320, 240), noise=1,
                            motion="walk")         # its last frame's hand_2 runs on: trimmed
    on, off = FrameEstimator(cap, "human", 60), FrameEstimator(cap, "human", 60, trim=False)
    seen = 0
    for f in cap.frames:
        a, b = on.estimate(f), off.estimate(f)
        assert "trim" not in b.diagnostics
        assert a.status == b.status and a.distance == b.distance
        assert {k: None if v is None else list(v) for k, v in a.parts.items()} == \
               {k: None if v is None else list(v) for k, v in b.parts.items()}
        assert a.diagnostics.get("confidence") == b.diagnostics.get("confidence")
        for q, c in (a.diagnostics.get("trim") or {}).items():
            seen += 1
            full = np.asarray(a.diagnostics["curves"][q])
            assert np.allclose(c[0], full[0], atol=1e-4)            # from the same junction
            s_full = np.linalg.norm(np.diff(full, axis=0), axis=1).sum()
            s_cut = np.linalg.norm(np.diff(np.asarray(c), axis=0), axis=1).sum()
            assert s_cut < s_full
    assert seen == 1
    assert "trim" in on.estimate(cap.frames[-1]).timings_ms


def test_silhouette_depth_equals_the_whole_images_transform():
    """The depth over the silhouette's box (+ one pixel) is the whole image's exact Euclidean
    distance transform (SciPy) there, for blobs inside the image and touching its edges."""
    from scipy.ndimage import distance_transform_edt

    from topopose.frame.trim import disks, silhouette_depth

    rng = np.random.default_rng(3)
    for k in range(12):
        m = np.zeros((90, 70), np.uint8)
        for _ in range(3):
            c = (int(rng.integers(-10, 80)), int(rng.integers(-10, 100)))
            cv2.ellipse(m, c, (int(rng.integers(3, 30)), int(rng.integers(3, 30))),
                        float(rng.uniform(0, 180)), 0, 360, 1, -1)
        full = distance_transform_edt(m)
        dep, (x0, y0) = silhouette_depth(m > 0)
        h, w = dep.shape
        assert np.allclose(dep, full[y0:y0 + h, x0:x0 + w], atol=1e-4)
        assert not full[:y0].any() and not full[y0 + h:].any()     # nothing deep outside it
        assert not full[:, :x0].any() and not full[:, x0 + w:].any()
    cam = CAMS[0]
    pts = np.array([H, E, A, J])
    sil = _render()[0]
    assert np.allclose(disks(pts, cam, silhouette_depth(sil))[1],
                       disks(pts, cam, distance_transform_edt(sil))[1], atol=1e-4)
