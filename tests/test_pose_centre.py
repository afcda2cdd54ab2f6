"""The limbs' curves onto the silhouettes' centre lines (:mod:`topopose.frame.centre`), on
hand-made geometry: a cylinder limb (radius 5 cm, along x) seen by pinhole cameras around it,
its silhouettes exact (a pixel is in when its ray passes within the radius of the axis), a
skeleton curve displaced off the axis."""
import numpy as np

from _capture_testutils import camera_at
from topopose.frame.centre import centre_offsets, scan_widths
from topopose.sequence.kinematic_fit import centred_curves

A, B = np.array([-0.4, 0.0, 0.0]), np.array([0.4, 0.0, 0.0])     # the limb's axis
RADIUS = 0.05
VOXEL = 0.02
SIZE = (400, 300)
# around the limb (perpendicular to it), not in facing pairs: 0°, 70°, 150°, 230°
CAMS = [camera_at([0.3, 3 * np.cos(a), 3 * np.sin(a)], f"c{i}", size=SIZE, f=600.0)
        for i, a in enumerate(np.radians([0, 70, 150, 230]))]


def _rays(cam):
    """Unit world directions (H, W, 3) of every pixel's ray."""
    u, v = np.meshgrid(np.arange(SIZE[0]), np.arange(SIZE[1]))
    x = np.stack([u, v, np.ones_like(u)], axis=-1).astype(float) @ np.linalg.inv(cam.matrix).T
    d = x @ cam.R            # camera → world: Rᵀ x
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _segment_mask(cam, a, b, r):
    """Exact silhouette of the cylinder a–b (radius r, round ends): pixels whose ray passes
    within r of the segment (sampled every 5 mm along it)."""
    o = cam.center
    d = _rays(cam)
    best = np.full(d.shape[:2], np.inf)
    for t in np.linspace(0.0, 1.0, 161):
        p = a + t * (b - a) - o
        along = d @ p
        best = np.minimum(best, np.sqrt(np.maximum(p @ p - along ** 2, 0.0)))
    return best <= r


def _curve(shift):
    """16 samples along the inner part of the axis, moved by ``shift``."""
    t = np.linspace(0.2, 0.8, 16)[:, None]
    return A + t * (B - A) + np.asarray(shift, float)


def _axis_distance(points):
    return np.hypot(points[:, 1], points[:, 2])


def _radius(p):
    return np.full(len(p), RADIUS)


def test_a_displaced_curve_comes_back_to_the_axis():
    masks = [_segment_mask(c, A, B, RADIUS) for c in CAMS]
    curve = _curve([0.0, 0.03, -0.02])                       # 3.6 cm off the axis
    off = centre_offsets({"hand_1": curve}, CAMS, masks, _radius, 0.2, VOXEL)
    moved = curve + off["hand_1"]
    assert _axis_distance(curve).min() > 0.035
    assert _axis_distance(moved).max() < 0.5 * VOXEL        # onto the axis (within half a voxel)
    assert np.allclose(moved[:, 0], curve[:, 0], atol=1e-3)  # across the curve only
    # the kinematic fit's curves: the limb's moved, the others as they were
    other = {"head": curve.copy()}
    got = centred_curves({"hand_1": curve, **other}, {**off, "head": off["hand_1"]}, ["hand_1"])
    assert np.allclose(got["hand_1"], moved) and np.allclose(got["head"], curve)


def test_three_cameras_in_general_position_suffice():
    cams = CAMS[:3]
    masks = [_segment_mask(c, A, B, RADIUS) for c in cams]
    curve = _curve([0.0, -0.02, 0.025])
    off = centre_offsets({"foot_2": curve}, cams, masks, _radius, 0.2, VOXEL)
    assert _axis_distance(curve + off["foot_2"]).max() < 0.5 * VOXEL


def test_a_view_where_the_limb_meets_a_blob_gives_no_observation():
    """A thick cylinder (a trunk) alongside the limb, touching it in one view (its silhouette one
    blob with the limb's): that view's run is too wide, so with three views the two others alone decide (the
    curve still comes to the axis: the blob's view, accepted, would pull it sideways); with
    the blob in two of them one view is left and nothing moves."""
    curve = _curve([0.0, 0.03, -0.02])
    cams = CAMS[:3]
    clean = [_segment_mask(c, A, B, RADIUS) for c in cams]

    def blob(cam):      # a trunk (radius 0.2) beside the limb, as this camera sees it
        side = np.cross(B - A, cam.center)
        side /= np.linalg.norm(side)
        return _segment_mask(cam, A + 0.22 * side, B + 0.22 * side, 0.2)

    one = [clean[0] | blob(cams[0]), clean[1], clean[2]]
    assert (one[0] & ~clean[0]).sum() > 1000
    off = centre_offsets({"hand_1": curve}, cams, one, _radius, 0.2, VOXEL)
    assert _axis_distance(curve + off["hand_1"]).max() < 0.5 * VOXEL
    two = [clean[0] | blob(cams[0]), clean[1] | blob(cams[1]), clean[2]]
    assert centre_offsets({"hand_1": curve}, cams, two, _radius, 0.2, VOXEL) == {}


def test_trunk_samples_and_other_parts_are_left():
    masks = [_segment_mask(c, A, B, RADIUS) for c in CAMS]
    curve = _curve([0.0, 0.03, -0.02])
    # a head's curve is no limb; a limb as thick as the trunk (its radius the largest) stays
    assert centre_offsets({"head": curve}, CAMS, masks, _radius, 0.2, VOXEL) == {}
    assert centre_offsets({"hand_1": curve}, CAMS, masks, _radius, RADIUS, VOXEL) == {}


def test_scan_widths_on_a_hand_made_band():
    m = np.zeros((50, 60), bool)
    m[:, 20:31] = True                                     # columns 20–30 inside: 11 px wide
    uv = np.array([[25.0, 10.0], [22.0, 30.0], [5.0, 5.0]])
    nrm = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 0.0]])
    lo, hi = scan_widths(m, uv, nrm, np.array([20.0, 20.0, 20.0]))
    assert np.allclose(hi[:2] - lo[:2], 11.0, atol=0.51)
    assert abs(0.5 * (hi[0] + lo[0]) - 0.0) <= 0.51        # 25 is the band's middle
    assert abs(0.5 * (hi[1] + lo[1]) + 3.0) <= 0.51        # along −x: the middle 3 px back
    assert np.isnan(lo[2]) and np.isnan(hi[2])             # outside the silhouette
    lo, hi = scan_widths(m, uv[:1], nrm[:1], np.array([3.0]))
    assert np.isnan(hi[0])                                  # a crossing beyond the scan


def test_the_estimator_records_the_offsets_and_keeps_the_frame():
    """``FrameEstimator(centre=True)`` records ``diagnostics["centred"]``; the frame's status,
    parts, confidence and curves are those of ``centre=False``."""
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    cap = synthetic_capture("body", frames=3, seed=41, cameras=4, size=(320, 240), noise=1,
                            motion="walk")
    on, off = FrameEstimator(cap, "human", 60, centre=True), FrameEstimator(cap, "human", 60)
    seen = 0
    for f in cap.frames:
        a, b = on.estimate(f), off.estimate(f)
        assert "centred" not in b.diagnostics
        assert a.status == b.status and a.distance == b.distance
        assert {k: None if v is None else list(v) for k, v in a.parts.items()} == \
               {k: None if v is None else list(v) for k, v in b.parts.items()}
        da = {k: v for k, v in a.diagnostics.items() if k not in ("centred", "centred_trim")}
        assert repr(da) == repr(b.diagnostics)
        for q, o in (a.diagnostics.get("centred") or {}).items():
            o = np.asarray(o)
            assert o.shape == np.asarray(a.diagnostics["curves"][q]).shape
            seen += int((np.abs(o).sum(axis=1) > 0).sum())
    assert seen > 0
    assert "centre" in on.estimate(cap.frames[-1]).timings_ms


def test_trim_and_relabel_carry_the_offsets_with_their_curves():
    """The sequence stage: a trimmed hand takes its trimmed curve's offsets (none recorded:
    none), a relabelled part its own, and the fit's curves add them to the limbs only."""
    from topopose.sequence.kinematic_fit import frame_curves, kinematic_tree
    from topopose.pose.model import load_model
    from topopose.pose.pose import Pose
    from topopose.sequence.track import relabel
    from topopose.frame.trim import apply_trim

    model = load_model("human")
    tree = kinematic_tree(model)
    full, cut = _curve([0, 0, 0]), _curve([0, 0, 0])[:8]
    cut16 = np.vstack([cut, np.repeat(cut[-1:], 8, axis=0)])
    o_full, o_cut = np.full((16, 3), 0.01), np.full((16, 3), 0.02)
    parts = {"hand_1": full[-1], "hand_2": full[-1] + 1.0}
    diag = {"curves": {"hand_1": full, "hand_2": full + 1.0},
            "trim": {"hand_1": cut16}, "centred": {"hand_1": o_full, "hand_2": o_full},
            "centred_trim": {"hand_1": o_cut}}
    p = apply_trim(Pose("000000", "matched", 1.0, parts, diagnostics=diag))
    assert p.diagnostics["trimmed"] == ["hand_1"]
    assert np.allclose(p.diagnostics["centred"]["hand_1"], o_cut)
    got = frame_curves(p, tree, spine=0.0)
    assert np.allclose(got["hand_1"], cut16 + o_cut)
    assert np.allclose(got["hand_2"], full + 1.0 + o_full)
    # no offsets for the trimmed curve: the old ones are dropped, not added to another curve
    q = apply_trim(Pose("000000", "matched", 1.0, parts,
                        diagnostics={**diag, "centred_trim": {}}))
    assert "hand_1" not in q.diagnostics["centred"]
    assert np.allclose(frame_curves(q, tree, spine=0.0)["hand_1"], cut16)
    r = relabel(p, {"hand_1": "hand_2", "hand_2": "hand_1"})
    assert np.allclose(r.diagnostics["centred"]["hand_2"], o_cut)
    assert np.allclose(frame_curves(r, tree, spine=0.0)["hand_2"], cut16 + o_cut)
