"""Per-frame helpers: cavity filling (topology: cavities go, tunnels stay)."""
import pytest
import numpy as np
from scipy import ndimage

from topopose.hull import Volume
from topopose.frame.placement import fill_cavities


def _cavities(a):
    bg, nb = ndimage.label(np.pad(~a, 1, constant_values=True))       # 6-adjacency
    return nb - 1


def test_fill_cavities_fills_pockets_keeps_tunnels():
    z, y, x = np.mgrid[:30, :30, :30]
    r = np.sqrt((x - 15) ** 2 + (y - 15) ** 2 + (z - 15) ** 2)
    shell = (r < 12) & (r > 6)                               # one cavity inside
    a = shell.copy()
    a[20:26, 3:6, 3:6] = True
    a[22, 4, 4] = False                                      # a one-voxel cavity in a block
    assert _cavities(a) == 2
    v = fill_cavities(Volume(a.copy(), (1, 2, 3), 0.5))
    assert _cavities(v.data) == 0 and v.diagnostics["cavities_filled"] == 2
    assert np.array_equal(v.data, ndimage.binary_fill_holes(a))
    np.testing.assert_allclose(v.origin, (1, 2, 3))
    # a tunnel (a ring) is not a cavity: nothing changes
    ring = np.zeros((20, 20, 5), bool)
    ring[3:17, 3:17, 1:4] = True
    ring[7:13, 7:13, :] = False
    w = fill_cavities(Volume(ring.copy(), (0, 0, 0), 1.0))
    assert np.array_equal(w.data, ring)
    assert fill_cavities(Volume(np.zeros((3, 3, 3), bool), (0, 0, 0), 1.0)).data.sum() == 0


def test_confidence_gate_default_is_on():
    """The gate is on by default with 4 and 8 cameras (measured in default_gate); an explicit
    choice wins, and the CLI's auto/on/off reach the run."""
    from types import SimpleNamespace

    from topopose.cli import build_parser
    from topopose.frame.estimate import FrameEstimator, default_gate

    assert default_gate(SimpleNamespace(cameras=[0] * 4)) and default_gate(SimpleNamespace(cameras=[0] * 8))
    from topopose.synth import synthetic_capture

    for n in (4, 8):
        cap = synthetic_capture("human", frames=1, cameras=n, size=(160, 120))
        assert FrameEstimator(cap, "human", 40).gate is True
        assert FrameEstimator(cap, "human", 40, gate=False).gate is False
        # the fitted confidence knows upright subjects: off without the coordinate constraints
        assert FrameEstimator(cap, "human", 40, constraints=False).gate is False
        assert FrameEstimator(cap, "human", 40, constraints=False, gate=True).gate is True
    p = build_parser()
    assert p.parse_args(["run", "C"]).confidence_gate == "auto"
    assert p.parse_args(["run", "C", "--confidence-gate", "off"]).confidence_gate == "off"


def test_off_axis_leaf_against_the_angle():
    """A head leaving the torso at a known angle from the axis crotch → torso: dropped exactly
    when the angle exceeds acos(min_cos) (oracle: the angle the test built)."""
    import math

    from topopose.match import Tree
    from topopose.frame.placement import off_axis_leaf

    mapping = {"crotch": 0, "torso": 1, "head": 2}
    for deg in (0, 20, 44, 46, 60, 90, 135, 180):
        a = math.radians(deg)
        pos = {0: (0.0, 0.0, 0.0), 1: (0.0, 0.0, 0.5),
               2: (0.3 * math.sin(a), 0.0, 0.5 + 0.3 * math.cos(a))}
        t = Tree([(0, 1, 0.5), (1, 2, 0.3)], positions=pos)
        for min_cos in (0.7, math.cos(math.radians(45))):
            want = deg > math.degrees(math.acos(min_cos))
            assert off_axis_leaf(t, mapping, "head", "torso", "crotch", min_cos) == want, deg
    # an unmatched part decides nothing
    assert not off_axis_leaf(t, {"torso": 1, "head": 2}, "head", "torso", "crotch", 0.7)


def test_leaf_axis_and_tip_fraction_in_the_estimator():
    """Capsule human, limbs apart: the default keeps every upright head; an impossible cosine
    drops it (missing, diagnostics "off_axis"); tip_fraction 0 leaves the head at its data
    vertex, 0.5 half way to the full tip."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator
    from topopose.batch.quality import evaluate

    cap = synthetic_capture("human", frames=2, seed=3, noise=0, separated=True)
    poses = {}
    off = {"head_from_hull": 0, "spine": False}   # the head from the alignment, the tip rule alone
    for key, kw in {"hull": {"resolution": 100}, "default": off, "drop": {"leaf_axis": 1.01, **off},
                    "t0": {"tip_fraction": 0.0, **off},
                    "t05": {"tip_fraction": 0.5, **off}}.items():
        kw = {"resolution": 60, **kw}       # the head from the hull needs a finer grid
        est = FrameEstimator(cap, "human", **kw)
        poses[key] = [est.estimate(f, detail=True) for f in cap.frames]
    for key in ("default", "hull"):
        ev = evaluate(cap.gt, [p for p, _ in poses[key]])
        for (p, _d), f in zip(poses[key], ev.frames):
            assert "off_axis" not in p.diagnostics and f.right["head"], f.errors
            assert ("from_hull" in p.diagnostics) == (key == "hull")
    for p, _d in poses["drop"]:
        assert p.parts["head"] is None and p.diagnostics["off_axis"] == ["head"]
    for (p1, _), (p0, d0), (ph, _) in zip(poses["default"], poses["t0"], poses["t05"]):
        v = d0.alignment.mapping["head"]
        np.testing.assert_allclose(p0.parts["head"], d0.data.positions[v])
        np.testing.assert_allclose(ph.parts["head"], 0.5 * (p0.parts["head"] + p1.parts["head"]))


def test_missing_cost_is_the_deleted_leaf_arcs_weight():
    """A data star lacking one of the model's three limbs: the alignment deletes that limb's
    arc (γ(w, 0) = w), and the distance without it is Σ |w − w'| of the matched arcs."""
    from topopose.match import align
    from topopose.match.tree import Tree
    from topopose.frame.thickness import missing_cost

    pattern = Tree([("c", "a", 0.4), ("c", "b", 0.35), ("c", "d", 0.25)])
    al = align(pattern, Tree([("x", "p", 0.42), ("x", "q", 0.33)]), method="aha",
               pattern_root="c", data_root="x")
    assert al.mapping["d"] is None
    assert missing_cost(pattern, al) == pytest.approx(0.25)
    assert al.distance - missing_cost(pattern, al) == pytest.approx(0.02 + 0.02)
    # every limb matched: nothing to take off
    full = align(pattern, Tree([("x", "p", 0.42), ("x", "q", 0.33), ("x", "r", 0.2)]),
                 method="aha", pattern_root="c", data_root="x")
    assert all(v is not None for v in full.mapping.values())
    assert missing_cost(pattern, full) == 0.0


def test_short_limb_drops_a_hand_shorter_than_the_ratio_of_the_leg():
    """A hand whose tree path from the torso is below the ratio × the longest crotch → foot
    path is named (the shorter of two); otherwise, or with the torso or the legs unmatched,
    None. Oracle: the path lengths the test built."""
    from topopose.match import Tree
    from topopose.frame.placement import short_limb

    def tree(arm1, arm2, leg=1.0):
        # torso 0, crotch 1, feet 2, 3 (legs leg and 0.8 leg), hands 4, 5 (via a shoulder 6)
        return Tree([(0, 1, 0.3), (1, 2, leg), (1, 3, 0.8 * leg), (0, 6, 0.1), (6, 4, arm1 - 0.1),
                     (0, 5, arm2)])

    m = {"torso": 0, "crotch": 1, "foot_1": 2, "foot_2": 3, "hand_1": 4, "hand_2": 5}
    args = (("hand_1", "hand_2"), "torso", "crotch", ("foot_1", "foot_2"))
    assert short_limb(tree(0.8, 0.7), m, *args, 0.35) is None           # both arms long
    assert short_limb(tree(0.8, 0.3), m, *args, 0.35) == "hand_2"       # 0.3 < 0.35 × 1.0
    assert short_limb(tree(0.3, 0.8), m, *args, 0.35) == "hand_1"
    assert short_limb(tree(0.3, 0.2), m, *args, 0.35) == "hand_2"       # the shorter one
    assert short_limb(tree(0.8, 0.4), m, *args, 0.35) is None           # 0.4 ≥ 0.35
    assert short_limb(tree(0.8, 0.4, leg=2.0), m, *args, 0.35) == "hand_2"   # the longest leg
    assert short_limb(tree(0.8, 0.3), {**m, "torso": None}, *args, 0.35) is None
    assert short_limb(tree(0.8, 0.3), {**m, "foot_1": None, "foot_2": None}, *args, 0.35) is None


def test_short_arm_and_trunk_blend_in_the_estimator():
    """Capsule human, limbs apart: the default short-arm ratio drops no hand (its arms are
    longer than the legs' half); an impossible ratio drops one (missing, diagnostics
    "short_arm", a "missing limb" frame); trunk_blend=1 puts the torso at 0.6 of crotch → head."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator

    cap = synthetic_capture("human", frames=2, seed=3, noise=0, separated=True)
    default = FrameEstimator(cap, "human", 60)
    drop = FrameEstimator(cap, "human", 60, short_arm=5.0)
    line = FrameEstimator(cap, "human", 60, trunk_blend=1.0)
    assert default.short_arm is not None and default.trunk_blend is not None
    assert FrameEstimator(cap, "human", 60, short_arm=0, trunk_blend=False).short_arm is None
    for f in cap.frames:
        p = default.estimate(f)
        assert "short_arm" not in p.diagnostics
        assert all(x is not None for x in p.parts.values())
        q = drop.estimate(f)
        assert q.diagnostics["short_arm"] and len(q.diagnostics["short_arm"]) == 1
        h = q.diagnostics["short_arm"][0]
        assert h.startswith("hand") and q.parts[h] is None and q.diagnostics["missing"] == [h]
        r = line.estimate(f)
        c, hd = np.asarray(r.parts["crotch"]), np.asarray(r.parts["head"])
        assert np.allclose(r.parts["torso"], c + 0.6 * (hd - c))


def test_placed_missing_counts_a_head_from_the_hull_as_placed():
    """``body`` heavy build, seed 41, all poses, frame 0 (an arm on the body): the alignment
    leaves the head and that hand unmatched, the head is placed from the hull. Counted on the
    placed parts (default) the frame is matched, one hand missing — right by its ground truth
    (the oracle: ``evaluate`` at 0.08 × height); counted on the alignment's, or without the head
    from the hull, two parts are missing and the frame is rejected."""
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator
    from topopose.pose import load_model
    from topopose.batch.quality import evaluate

    cap = synthetic_capture(subject="body", frames=12, seed=41, noise=1, separated=False,
                            cameras=8, build="heavy")
    f = cap.frames[0]
    p = FrameEstimator(cap, "human", 100, gate=False).estimate(f)
    assert p.status == "matched", p.error
    assert len(p.diagnostics["missing"]) == 2 and "head" in p.diagnostics["missing"]
    assert p.diagnostics["from_hull"] == ["head"]
    assert sum(x is None for x in p.parts.values()) == 1
    ev = evaluate(cap.gt, [p], model=load_model("human"), tolerance=0.08 * cap.gt["height"],
                  junction_factor=1.0)
    assert ev.frames[0].quality == "missing limb"
    for kw in ({"placed_missing": False}, {"head_from_hull": 0}):
        q = FrameEstimator(cap, "human", 100, gate=False, **kw).estimate(f)
        assert q.status == "rejected" and "parts unmatched" in q.error, kw


def test_head_ball_needs_enough_cameras():
    """The head-ball check of the head from the hull (tips.HEAD_BALL) applies from its minimum
    number of cameras on (few cameras inflate the trunk); an explicit value always applies."""
    from topopose.synth import synthetic_capture
    from topopose.frame.estimate import FrameEstimator
    from topopose.frame.tips import HEAD_BALL

    ball, reach, voxels, cams = HEAD_BALL["human"]
    for n in (cams - 2, cams, 8):
        cap = synthetic_capture("human", frames=1, cameras=n, size=(160, 120))
        est = FrameEstimator(cap, "human", 40)
        assert est.head_ball == ((ball, reach, voxels) if n >= cams else None)
        assert FrameEstimator(cap, "human", 40, head_ball=0.5).head_ball == (0.5, reach, voxels)
        assert FrameEstimator(cap, "human", 40, head_ball=0).head_ball is None
        assert FrameEstimator(cap, "human", 40, hand_trunk=0).hand_trunk is None
        assert FrameEstimator(cap, "human", 40).hand_trunk[2] > 0
