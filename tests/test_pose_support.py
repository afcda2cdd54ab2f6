"""topopose.frame.support: the silhouette the placed model leaves unexplained.

Oracles: a hand-built scene (a vertical cylinder seen by one pinhole camera; its silhouette
with and without an "arm" rectangle whose area share is computed by hand); a synthetic
4-camera capture of the human subject, whose right frame leaves little unexplained and
whose hand moved onto the trunk leaves its arm unexplained; the consistency rejecting a frame
above ``max_unexplained`` and ignoring frames without the value.
"""
import numpy as np
import pytest

from topopose.geometry.camera import Camera
from topopose.sequence import consistency as C
from topopose.frame.support import support_features

F, W, H = 500.0, 200, 240


def scene():
    """A vertical cylinder (radius 0.1, z ∈ [−0.5, 0.5]) on a 0.02 grid, a camera 5 m in
    front of it (looking along +y), the cylinder's axis as the model curve."""
    vs = 0.02
    origin = np.array([-0.2, -0.2, -0.6])
    ijk = np.indices((21, 21, 61)).reshape(3, -1).T
    X = origin + ijk * vs
    occ = ((np.hypot(X[:, 0], X[:, 1]) <= 0.1) & (np.abs(X[:, 2]) <= 0.5)).reshape(21, 21, 61)
    # camera: x_cam = x, y_cam = −z, z_cam = y + 5
    R = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    import cv2
    rvec = cv2.Rodrigues(R)[0].ravel()
    cam = Camera("c", (W, H), [[F, 0, W / 2], [0, F, H / 2], [0, 0, 1]], [0, 0, 0, 0], rvec,
                 [0, 0, 5.0])
    curve = np.column_stack([np.zeros(16), np.zeros(16), np.linspace(-0.4, 0.4, 16)])
    return occ, origin, vs, cam, curve


def silhouette(arm=False):
    """The cylinder's projection (10 px half-width, 50 px half-height around the centre),
    plus a 60 × 12 px arm on its side."""
    S = np.zeros((H, W), bool)
    S[H // 2 - 50:H // 2 + 50, W // 2 - 10:W // 2 + 10] = True
    if arm:
        S[H // 2 - 30:H // 2 - 18, W // 2 + 10:W // 2 + 70] = True
    return S


def test_cylinder_explained_and_an_arm_unexplained():
    occ, origin, vs, cam, curve = scene()
    np.testing.assert_allclose(cam.project(np.array([[0.1, 0, 0.5]])), [[W / 2 + 10, H / 2 - 50]])
    parts = {"head": curve[-1]}
    bare = support_features({"head": curve}, parts, [cam], [silhouette()], occ, origin, vs)
    assert bare["unexplained"] < 0.03          # the rendered cylinder covers its silhouette
    assert bare["outside"] < 0.2
    arm = support_features({"head": curve}, parts, [cam], [silhouette(True)], occ, origin, vs)
    S = silhouette(True)
    share = 12 * 60 / S.sum()                    # the arm's share of the silhouette, by hand
    # the arm is unexplained but for the dilation next to the body (0.25 × 10 px)
    assert share * 0.8 < arm["unexplained"] < share * 1.05, (arm["unexplained"], share)
    # two cameras, one sees the arm: the frame's value is the worst camera's
    two = support_features({"head": curve}, parts, [cam, cam], [silhouette(), S], occ, origin,
                           vs)
    assert two["unexplained"] == pytest.approx(arm["unexplained"])
    assert two["unexplained_mean"] == pytest.approx((arm["unexplained"]
                                                     + bare["unexplained"]) / 2)


@pytest.fixture(scope="module")
def synthetic_frame():
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    cap = synthetic_capture("human", frames=3, seed=5, cameras=4, size=(320, 240),
                            separated=True)
    est = FrameEstimator(cap, "human", 64, gate=False, support=True)
    for f in cap.frames:
        p, det = est.estimate(f, detail=True)
        if p.status == "matched" and p.diagnostics.get("curves"):
            return cap, f, p, det
    pytest.fail("no matched frame in the synthetic capture (seed 5, 4 cameras, 64³)")


def test_estimator_records_it_and_a_hand_on_the_trunk_raises_it(synthetic_frame):
    cap, f, p, det = synthetic_frame
    u = p.diagnostics["unexplained"]
    vol = det.volume
    curves = p.diagnostics["curves"]
    args = (list(cap.cameras), cap.silhouettes(f), vol.data, vol.origin, vol.voxel_size)
    again = support_features(curves, p.parts, *args)
    assert again["unexplained"] == pytest.approx(u, abs=1e-4)
    assert u < 0.15                               # a right frame: its limbs explained
    # the hand moved onto the trunk: its arm's curve collapsed to the torso
    torso = np.asarray(p.parts["torso"], float)
    moved = dict(curves, hand_1=np.repeat(torso[None], 16, axis=0))
    parts = dict(p.parts, hand_1=torso)
    worse = support_features(moved, parts, *args)
    assert worse["unexplained"] > u + 0.05, (u, worse["unexplained"])


def test_consistency_rejects_an_unexplained_frame():
    from test_consistency import walk
    from topopose.pose.model import load_model

    model = load_model("human")
    poses = walk()
    for i, p in enumerate(poses):
        p.diagnostics["unexplained"] = 0.3 if i == 5 else 0.05
    del poses[7].diagnostics["unexplained"]           # not recorded: not judged by it
    assert C.judge_sequence(poses, model, neighbours=2, min_rank=0.0, max_unexplained=0.1)
    assert poses[5].status == "rejected"
    assert "unexplained" in poses[5].diagnostics["consistency"]["reasons"][0]
    assert poses[5].diagnostics["consistency"]["unexplained"] == 0.3
    for i in (4, 6, 7):
        assert poses[i].status == "matched", poses[i].diagnostics["consistency"]


def test_per_frame_support_test_judges_each_frame_alone():
    """``judge_support``: matched frames above the limit rejected (parts kept), those within
    kept, frames without the value and failed ones untouched; ``gate=False`` also matches a
    frame the confidence gate alone rejected when it is within the limit, not one rejected for
    another reason."""
    from test_consistency import GATED, walk_parts
    from topopose.pose.pose import Pose

    def pose(i, status, u, error=None):
        p = Pose(f"{i}", status, 0.2, walk_parts(i), error, {}, {"height": 1.7})
        if u is not None:
            p.diagnostics["unexplained"] = u
        return p

    poses = [pose(0, "matched", 0.05), pose(1, "matched", 0.081), pose(2, "matched", None),
             pose(3, "rejected", 0.02, GATED), pose(4, "rejected", 0.02, "hull: 2 pieces"),
             pose(5, "failed", 0.9, "boom"), pose(6, "matched", 0.08)]
    before = [dict(p.parts) for p in poses]
    assert C.judge_support(poses) == 1                  # default limit MAX_UNEXPLAINED = 0.08
    assert [p.status for p in poses] == ["matched", "rejected", "matched", "rejected",
                                         "rejected", "failed", "matched"]
    assert "0.08 of a silhouette unexplained" in poses[1].error
    assert all(p.parts.keys() == b.keys() and all(np.array_equal(p.parts[k], b[k]) for k in b)
               for p, b in zip(poses, before))
    assert C.judge_support(poses, gate=False) == 1      # only frame 3 changes now
    assert poses[3].status == "matched" and poses[3].diagnostics["support_gate"] == GATED
    assert poses[4].status == "rejected"
    assert C.judge_support(poses, max_unexplained=0.04) == 2      # frames 0 (0.05), 6 (0.08)
    assert [p.status for p in poses] == ["rejected", "rejected", "matched", "matched",
                                         "rejected", "failed", "rejected"]


def test_run_support_switch(synthetic_frame, tmp_path):
    """``run(support_test=True)``: every matched frame within the limit, the others rejected
    for it or left as without the switch; the same parts either way."""
    from topopose.batch import run
    cap = synthetic_frame[0]
    off = run(cap, resolution=64, progress=False, gate=False, track=False, sides=False,
              skeleton=False, support=True)
    on = run(cap, resolution=64, progress=False, gate=False, track=False, sides=False,
             skeleton=False, support_test=True, output=tmp_path / "p.jsonl")
    assert any(a.status != b.status for a, b in zip(off.poses, on.poses))   # it did judge
    for a, b in zip(off.poses, on.poses):
        u = a.diagnostics.get("unexplained")
        want = ("rejected" if a.status == "matched" and u is not None
                and u > C.MAX_UNEXPLAINED else a.status)
        assert b.status == want, (a.frame, a.status, u, b.status)
        assert all((a.parts[k] is None) == (b.parts[k] is None) for k in a.parts)


def test_cli_support_flags():
    from topopose.cli import build_parser

    p = build_parser()
    assert p.parse_args(["run", "CAP"]).support is None
    assert p.parse_args(["run", "--support", "CAP"]).support is True
    assert p.parse_args(["run", "CAP", "--support-replace"]).support == "replace"
