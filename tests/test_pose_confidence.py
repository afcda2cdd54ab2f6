"""The fitted per-frame confidence (topopose.frame.confidence): its features on a hand-built
frame, the logistic fit against known coefficients, and the gate against ground truth — a clean
frame passes, the same frame with a swapped part assignment or an added spurious limb does not."""
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from topopose.hull import Volume
from topopose.hull.volume import add_rod
from topopose.match.tree import Tree
from topopose.pose import Pose
from topopose.frame import confidence as C
from topopose.pose.model import load_model


def test_features_of_a_hand_built_frame():
    """A 10-voxel-tall slab hull and a data tree whose lengths, heights and spurious branch
    are known by construction."""
    a = np.zeros((12, 12, 12), bool)
    a[1:11, 1:11, 1:11] = True                       # H = 10 voxels of 0.1 → 1.0
    vol = Volume(a, (0, 0, 0), 0.1)
    P = {"t": (0.5, 0.5, 0.7), "c": (0.5, 0.5, 0.4), "h": (0.5, 0.5, 1.0),
         "a1": (0.1, 0.5, 0.5), "a2": (0.9, 0.5, 0.5), "f1": (0.4, 0.5, 0.1),
         "f2": (0.6, 0.5, 0.3), "s": (0.5, 0.9, 0.7)}
    edges = [("t", "h", 0.3), ("t", "a1", 0.4), ("t", "a2", 0.4), ("t", "c", 0.3),
             ("c", "f1", 0.3), ("c", "f2", 0.2), ("t", "s", 0.1)]
    data = Tree(edges, positions={k: np.array(v) for k, v in P.items()})
    model = load_model("human")
    mapping = {"torso": "t", "crotch": "c", "head": "h", "hand_1": "a1", "hand_2": "a2",
               "foot_1": "f1", "foot_2": "f2"}
    pairs = [(["torso", "head"], ["t", "h"]), (["torso", "crotch"], ["t", "c"])]
    al = SimpleNamespace(mapping=mapping, pairs=pairs)
    f = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 0, al, 0.3,
                         {"h": 0.6, "a1": 0.2, "a2": 0.3, "f1": 0.25, "f2": 0.1, "t": 0.8,
                          "c": 0.9})
    assert f["distance"] == pytest.approx(0.5)
    assert f["thickness"] == pytest.approx(0.3)
    assert f["fat"] == pytest.approx(1000 * 0.001 / 1.0)
    assert f["spurious"] == 1 and f["spurious_length"] == pytest.approx(0.1 / 2.0)  # of the total
    ptot, dtot = model.tree.total_weight(), 2.0
    want = max(abs(math.log((0.3 / dtot) / (0.27 / ptot))), abs(math.log((0.3 / dtot) / (0.3 / ptot))))
    assert f["arc_dev"] == pytest.approx(want, abs=1e-4)
    # hull bottom at voxel 1 (z = 0.1), H = 1.0: head at 1.0 → 0.9 up; feet 0.0 and 0.2 up
    assert f["head_low"] == pytest.approx(0.1) and f["foot_high"] == pytest.approx(0.2)
    assert f["head_radius"] == 0.6 and f["end_radius"] == 0.3
    assert f["head_bend"] == pytest.approx(0.0, abs=1e-6) and f["head_offset"] == pytest.approx(0.0, abs=1e-6)
    assert f["head_reach"] == pytest.approx(0.3) and f["trunk"] == pytest.approx(0.3)
    # junction radii, head / torso; trunk +z, feet at (−0.1, −0.3) and (0.1, −0.1) from the
    # crotch: cosines −3/√10 and −1/√2; the hull below the crotch (z 0.4): 0.35 deep, capped at
    # 0.2 × H
    assert f["crotch_radius"] == 0.9 and f["torso_radius"] == 0.8
    assert f["head_torso"] == pytest.approx(0.75)
    assert f["hip_flex"] == pytest.approx(1 - (3 / math.sqrt(10) + 1 / math.sqrt(2)) / 2, abs=1e-4)
    assert f["crotch_room"] == pytest.approx(0.2)
    data.positions["c"] = np.array([0.5, 0.5, 0.17])       # samples 0.12, 0.07 in; 0.02 out
    k = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 0, al)
    assert k["crotch_room"] == pytest.approx(0.15) and k["head_torso"] == 0.0
    data.positions["c"] = np.array([0.5, 0.5, 0.4])
    # the placed parts (a head from the hull 0.3 beside the torso, at its height): bend 1,
    # offset 0.3 / H; without them, or with the head unplaced: 0
    placed = {"crotch": (0.5, 0.5, 0.4), "torso": (0.5, 0.5, 0.7), "head": (0.8, 0.5, 0.7)}
    q = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 0, al,
                         parts=placed)
    assert q["head_placed_bend"] == pytest.approx(1.0)
    assert q["head_placed_offset"] == pytest.approx(0.3)
    assert f["head_placed_bend"] == f["head_placed_offset"] == 0.0
    q = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 0, al,
                         parts={**placed, "head": None})
    assert q["head_placed_offset"] == 0.0
    # the head bent sideways by 90°: bend 1, offset = its distance from the trunk line
    data.positions["h"] = np.array([0.8, 0.5, 0.7])
    g = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 0, al)
    assert g["head_bend"] == pytest.approx(1.0) and g["head_offset"] == pytest.approx(0.3)
    assert g["head_low"] == pytest.approx(0.4)
    # a deleted limb's cost taken off: (0.2 − 0.12) / 0.4; without one, the whole distance
    m = C.frame_features(vol, int(a.sum()), data, model, (0, 0, 1), 0.2, 0.4, 1, al,
                         missing_cost=0.12)
    assert m["matched_distance"] == pytest.approx(0.2) and m["distance"] == pytest.approx(0.5)
    assert g["matched_distance"] == pytest.approx(0.5)


def test_logistic_fit_recovers_known_coefficients():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(4000, 3))
    w, b = np.array([1.5, -2.0, 0.0]), 0.5
    y = rng.random(4000) < 1 / (1 + np.exp(-(X @ w + b)))
    coef, icpt = C.fit_logistic(X, y, l2=1e-6)
    np.testing.assert_allclose(coef, w, atol=0.15)
    assert icpt == pytest.approx(b, abs=0.15)
    model = {"features": ["x", "y", "z"], "mean": [1, 0, 0], "scale": [2, 1, 1],
             "coef": [1.0, -1.0, 0.0], "intercept": 0.2}
    z = 0.2 + (3 - 1) / 2 - 0.5
    assert C.logistic_confidence({"x": 3, "y": 0.5, "z": 9}, model) == pytest.approx(1 / (1 + math.exp(-z)))


def test_tree_confidence_by_hand():
    # oracle: two stumps and a depth-2 tree walked by hand (left when x ≤ threshold)
    stump = lambda f, t, lo, hi: {"feature": [f, 0, 0], "threshold": [t, 0.0, 0.0],  # noqa: E731
                                  "left": [1, -1, -1], "right": [2, -1, -1], "value": [0, lo, hi]}
    deep = {"feature": [0, 1, 0, 0, 0], "threshold": [0.5, 2.0, 0, 0, 0],
            "left": [1, 3, -1, -1, -1], "right": [2, 4, -1, -1, -1], "value": [0, 0, 0.7, -0.2, 0.4]}
    model = {"kind": "trees", "features": ["a", "b"], "base": -0.1,
             "trees": [stump(0, 1.0, -1.0, 1.0), stump(1, 0.0, 0.3, -0.3), deep]}
    sig = lambda z: 1 / (1 + math.exp(-z))                                     # noqa: E731
    for a, b, z in [(1.0, 0.0, -0.1 - 1.0 + 0.3 + 0.7),     # a = threshold: left
                    (0.2, 2.5, -0.1 - 1.0 - 0.3 + 0.4),
                    (0.2, 2.0, -0.1 - 1.0 - 0.3 - 0.2),
                    (3.0, -1.0, -0.1 + 1.0 + 0.3 + 0.7)]:
        assert C.tree_confidence({"a": a, "b": b}, model) == pytest.approx(sig(z))
        assert C.model_confidence({"a": a, "b": b}, model) == C.tree_confidence({"a": a, "b": b}, model)


def test_tree_model_equals_sklearn():
    sk = pytest.importorskip("sklearn.ensemble")
    rng = np.random.default_rng(1)
    X = rng.normal(size=(600, 4))
    y = (X[:, 0] + X[:, 1] ** 2 - X[:, 2] * X[:, 3] + rng.normal(size=600) > 0.8).astype(int)
    gb = sk.GradientBoostingClassifier(n_estimators=40, max_depth=3, learning_rate=0.2,
                                       random_state=0).fit(X, y, sample_weight=rng.random(600) + 0.2)
    model = json.loads(json.dumps(C.trees_from_sklearn(gb, list("abcd"))))    # as stored
    # random inputs, and inputs exactly at the split thresholds (the ≤ side)
    thr = [t for tr in model["trees"] for t, l in zip(tr["threshold"], tr["left"]) if l >= 0]
    Xt = np.vstack([rng.normal(size=(300, 4)) * 2,
                    np.array(rng.choice(thr, size=(100, 4)), np.float32)])
    ours = [C.tree_confidence(dict(zip("abcd", x)), model) for x in Xt]
    np.testing.assert_allclose(ours, gb.predict_proba(Xt)[:, 1], rtol=0, atol=1e-12)


def test_shipped_model_is_complete():
    m = C.CONFIDENCE_MODEL
    assert set(m["features"]) <= set(C.FEATURES)
    if m.get("kind") == "trees":
        k = len(m["features"])
        for t in m["trees"]:
            n = len(t["left"])
            assert all(len(t[x]) == n for x in ("feature", "threshold", "right", "value"))
            assert all(0 <= f < k for f in t["feature"]) and math.isfinite(m["base"])
            assert all(-1 == l == r or 0 < l < n and 0 < r < n
                       for l, r in zip(t["left"], t["right"]))               # noqa: E741
        assert C.MODEL_PATH.stat().st_size < 100000    # a few thousand nodes, not data
    else:
        assert len(m["coef"]) == len(m["mean"]) == len(m["scale"]) == len(m["features"])
        assert all(s > 0 for s in m["scale"]) and all(map(math.isfinite, m["coef"] + [m["intercept"]]))
        assert C.MODEL_PATH.stat().st_size < 4000       # a few numbers, not data
    assert 0 < m["min_confidence"] < 1 and C.MIN_CONFIDENCE == m["min_confidence"]
    assert "human" in m["models"] and isinstance(m["replaces_threshold"], bool)
    # a minimum per camera count; fewer cameras than any: the strictest; never below a
    # smaller camera count's (more cameras, a confidence more often right)
    by = {int(k): v for k, v in m["min_confidence_by_cameras"].items()}
    assert max(by.values()) == m["min_confidence"] == C.min_confidence_for(1)
    for k in by:
        assert C.min_confidence_for(k) == C.min_confidence_for(k + 1) == by[k]
    assert C.min_confidence_for(None) == m["min_confidence"]


@pytest.fixture(scope="module")
def clean():
    """Three frames of the capsule human, limbs apart, 8 cameras, noise 1, 100³: every part
    right by ground truth (the oracle)."""
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator
    from topopose.batch.quality import evaluate

    cap = synthetic_capture("human", frames=3, seed=4, cameras=8, noise=1, separated=True,
                            margin=0.06)
    est = FrameEstimator(cap, "human", 100, gate=True)
    out = [est.estimate(f, detail=True) for f in cap.frames]
    ev = evaluate(cap.gt, [p for p, _ in out], model=est.model,
                  tolerance=0.08 * cap.gt["height"])
    assert all(s.quality == "good" for s in ev.frames)
    return cap, est, out


def test_clean_frames_pass_the_gate(clean):
    cap, est, out = clean
    assert est.min_confidence == C.min_confidence_for(8) <= C.MIN_CONFIDENCE
    passed = [p.status == "matched" and p.diagnostics["confidence"] >= est.min_confidence
              for p, _ in out]
    # confidences 0.89, 0.808, 0.98 against the 8-camera minimum 0.81 when refitted (2026-11):
    # the minimum is chosen for precision 0.95, held-out right 8-camera frames pass ~3 in 4
    conf = [p.diagnostics["confidence"] for p, _ in out]
    assert sum(passed) >= 2 and min(conf) >= 0.75, conf
    assert set(out[0][0].diagnostics["confidence_factors"]) == {"fitted", "hull", "size"}


def test_swapped_head_and_hand_fail_the_gate(clean):
    """The same frames with the head's and a hand's data vertices exchanged (a wrong pose whose
    AHA distance is unchanged) fall below the gate."""
    from topopose.frame.thickness import vertex_radii

    cap, est, out = clean
    for pose, det in out:
        al = det.alignment
        radii = vertex_radii(det.volume, det.data, est.thickness_reach)
        for hand in ("hand_1", "hand_2"):
            m = dict(al.mapping)
            m["head"], m[hand] = m[hand], m["head"]
            sw = SimpleNamespace(mapping=m, pairs=al.pairs)
            f = C.frame_features(det.volume, int(det.volume.data.sum()), det.data, est.model,
                                 est.up, pose.distance, est.threshold, 0, sw, 0.0, radii)
            c = C.fitted_confidence(f, det.volume.diagnostics.get("largest_share", 1.0))
            assert c["confidence"] < est.min_confidence, (pose.frame, hand, f, c)


def test_spurious_limb_fails_the_fitted_gate(clean):
    """A 0.45 m rod added to the hull at chest height, pointing away from the arms (a limb the
    subject does not have): the fitted confidence no longer matches the frame, which keeps its
    best guess; the default gate, which reads the silhouettes (the rod is in none), matches it
    when its parts are right by ground truth (the alignment left the rod out)."""
    from topopose.batch.quality import evaluate
    from topopose.frame.confidence import gate_decision
    from topopose.frame.estimate import FrameEstimator

    cap, default, out = clean
    est = FrameEstimator(cap, "human", 100, gate=True, gate_rule=False)
    k = next(i for i, (p, _) in enumerate(out) if p.status == "matched")
    frame = cap.frames[k]
    gt = cap.gt["frames"][frame]
    torso = np.asarray(gt["parts"]["torso"], float)
    hands = [np.asarray(gt["parts"][h], float) for h in ("hand_1", "hand_2")]
    dirs = [np.array([math.cos(t), math.sin(t), 0.0])
            for t in np.linspace(0, 2 * math.pi, 16, endpoint=False)]
    d = max(dirs, key=lambda u: min(np.linalg.norm(torso + 0.4 * u - h) for h in hands))
    hull = est.hull
    est.hull = lambda name: add_rod(hull(name), torso, d, 0.45)
    try:
        bad = est.estimate(frame)
    finally:
        del est.hull
    assert bad.diagnostics["confidence"] < est.min_confidence
    # the best guess is kept (the head, given the rod across the body axis, may be left
    # unplaced by the leaf-axis rule, pose/estimate.py LEAF_AXIS)
    assert bad.status == "rejected"
    assert sum(x is not None for x in bad.parts.values()) >= len(bad.parts) - 1
    hull = default.hull
    default.hull = lambda name: add_rod(hull(name), torso, d, 0.45)
    try:
        p = default.estimate(frame)
    finally:
        del default.hull
    right = evaluate(cap.gt, [p], model=est.model, tolerance=0.08 * cap.gt["height"]).frames[0]
    assert (p.status == "matched") == (right.quality == "good")
    assert (p.status, p.error) == gate_decision(p.status, p.error, p.diagnostics)


def test_time_factors_are_told_not_applied_to_the_fitted_confidence():
    from topopose.pose.pose import Pose

    ps = []
    for i in range(6):
        x = i * 0.01 + (1.0 if i == 3 else 0.0)           # a coherent walk, frame 3 jumps 1 m
        parts = {"head": np.array([x, 0, 1.7]), "hand_1": np.array([x, -0.5, 1.0])}
        ps.append(Pose(f"{i:02d}", "matched", 0.1, parts, None, {},
                       {"confidence": 0.97, "height": 1.7, "hull_voxels": 1000,
                        "confidence_factors": {"fitted": 0.97, "hull": 1.0, "size": 1.0}}))
    C.temporal_confidence(ps, {p.frame: i for i, p in enumerate(ps)})
    assert ps[3].diagnostics["confidence_factors"]["time"] < 0.01       # told
    assert all(p.status == "matched" and p.diagnostics["confidence"] == 0.97 for p in ps)


def _frame(scale=1.0, spurious=False):
    """A hand-built frame with every model arc matched (lengths known), scaled by ``scale``
    (hull, positions and tree weights alike); ``spurious``: an unmatched branch added."""
    a = np.zeros((12, 12, 12), bool)
    a[1:11, 1:11, 1:11] = True
    vol = Volume(a, (0.3 * scale, -0.2 * scale, 0.0), 0.1 * scale)
    P = {"t": (0.5, 0.5, 0.7), "c": (0.5, 0.5, 0.4), "h": (0.55, 0.5, 1.0),
         "a1": (0.1, 0.5, 0.5), "a2": (0.9, 0.5, 0.6), "f1": (0.4, 0.5, 0.1),
         "f2": (0.6, 0.5, 0.3), "s": (0.5, 0.9, 0.7)}
    edges = [("t", "h", 0.3), ("t", "a1", 0.6), ("t", "a2", 0.4), ("t", "c", 0.3),
             ("c", "f1", 0.8), ("c", "f2", 0.8)] + ([("t", "s", 0.5)] if spurious else [])
    off = np.array([0.3, -0.2, 0.0])
    data = Tree([(u, v, w * scale) for u, v, w in edges],
                positions={k: scale * (np.array(v) + off) for k, v in P.items()
                           if spurious or k != "s"})
    model = load_model("human")
    mapping = {"torso": "t", "crotch": "c", "head": "h", "hand_1": "a1", "hand_2": "a2",
               "foot_1": "f1", "foot_2": "f2"}
    pairs = [(["torso", "head"], ["t", "h"]), (["torso", "crotch"], ["t", "c"]),
             (["torso", "hand_1"], ["t", "a1"]), (["torso", "hand_2"], ["t", "a2"]),
             (["crotch", "foot_1"], ["c", "f1"]), (["crotch", "foot_2"], ["c", "f2"])]
    al = SimpleNamespace(mapping=mapping, pairs=pairs)
    radii = {"h": 0.6, "a1": 0.2, "a2": 0.3, "f1": 0.25, "f2": 0.1}
    return vol, int(a.sum()), data, model, al, radii


def test_matched_shape_features_by_hand():
    """``shape`` (L1 of the matched arcs' length shares against the model's), ``shape_max``
    (largest |log| ratio), ``limb_sym`` (|log| of the arms' and of the legs' length ratio),
    ``spurious_share`` (data weight outside the matched arcs), computed by hand."""
    vol, n, data, model, al, radii = _frame()
    f = C.frame_features(vol, n, data, model, (0, 0, 1), 0.2, 0.4, 0, al, 0.0, radii)
    pw = {(u, v): w for u, v, w in model.tree.edges}
    pl = [pw[("torso", "head")], pw[("torso", "crotch")], pw[("torso", "hand_1")],
          pw[("torso", "hand_2")], pw[("crotch", "foot_1")], pw[("crotch", "foot_2")]]
    dl = [0.3, 0.3, 0.6, 0.4, 0.8, 0.8]
    ds, ps = np.array(dl) / sum(dl), np.array(pl) / sum(pl)
    assert f["shape"] == pytest.approx(np.abs(ds - ps).sum(), abs=1e-4)
    assert f["shape_max"] == pytest.approx(np.abs(np.log(ds / ps)).max(), abs=1e-4)
    assert f["limb_sym"] == pytest.approx(math.log(0.6 / 0.4), abs=1e-4)
    assert f["spurious_share"] == pytest.approx(0.0, abs=1e-6)
    g = C.frame_features(vol, n, *_frame(spurious=True)[2:3], model, (0, 0, 1), 0.2, 0.4, 0,
                         al, 0.0, radii)
    # an unmatched (e.g. phantom-volume) branch: the matched shape is unchanged, arc_dev is not
    for k in ("shape", "shape_max", "limb_sym"):
        assert g[k] == pytest.approx(f[k], abs=1e-6), k
    assert g["spurious_share"] == pytest.approx(0.5 / 3.7, abs=1e-4)
    assert g["arc_dev"] != pytest.approx(f["arc_dev"], abs=1e-3)


def test_features_and_confidence_do_not_depend_on_scale():
    """The same frame twice as large (hull, positions, arc lengths; the AHA distance of
    normalized trees is unchanged): every feature and the confidence are the same."""
    f1, f2 = [C.frame_features(*(lambda v, n, d, m, al, r: (v, n, d, m, (0, 0, 1), 0.3, 0.4, 0,
                                                            al, 0.0, r))(*_frame(s, True)))
              for s in (1.0, 2.0)]
    for k in C.FEATURES:
        assert f2[k] == pytest.approx(f1[k], abs=2e-5), k
    assert C.fitted_confidence(f1, 1.0) == C.fitted_confidence(f2, 1.0)


def test_the_fitted_confidence_decides_instead_of_the_distance_threshold():
    """With the gate on, a frame rejected for its AHA distance alone is matched when its
    confidence reaches the minimum (the distance is one of its features); without the gate the
    threshold stands; other rejections stand either way; the best guess is kept."""
    vol, n, data, model, al, radii = _frame()
    err = "AHA distance 0.900 above threshold T_d = 0.4"
    args = (vol, n, data, model, (0, 0, 1), 0.9, model.threshold, 0)
    st, e, d = C.judge_frame(*args, "rejected", err, C.Gate(min_confidence=0.0),
                             aligned=C.Aligned(al))
    assert (st, e) == ("matched", None) and C.replaces_threshold()
    st, e, d = C.judge_frame(*args, "rejected", err, C.Gate(min_confidence=1.0),
                             aligned=C.Aligned(al))
    assert st == "rejected" and e == f"{err}; confidence 0.00 below 1"   # both reasons
    from topopose.sequence.track import gated_only

    assert not gated_only(Pose("f", st, 0.9, {}, e))   # not a frame only the gate rejected
    assert C.judge_frame(*args, "rejected", err, C.Gate(min_confidence=None),
                         aligned=C.Aligned(al))[:2] == ("rejected", err)
    other = "3 parts unmatched (head, hand_1, hand_2)"
    assert C.judge_frame(*args, "rejected", other, C.Gate(min_confidence=0.0),
                         aligned=C.Aligned(al))[:2] == ("rejected", other)
    assert not C.distance_only("AHA distance inf above threshold T_d = 0.4")
    # a T_d chosen by the caller (not the model's own) stands
    chosen = (vol, n, data, model, (0, 0, 1), 0.9, model.threshold / 2, 0)
    assert C.judge_frame(*chosen, "rejected", err, C.Gate(min_confidence=0.0),
                         aligned=C.Aligned(al))[:2] == ("rejected", err)


def test_a_limb_cut_off_scores_below_the_intact_frame(clean):
    """The hull with one forearm cut off (its voxels within 0.3 m of the hand's ground truth
    erased, as a segmentation network that loses a hand would): each frame's confidence falls
    below the intact frame's."""
    cap, est, out = clean
    hull = est.hull
    for pose, det in out:
        gt = np.asarray(cap.gt["frames"][pose.frame]["parts"]["hand_1"], float)

        def cut(name, gt=gt):
            vol = hull(name)
            idx = np.argwhere(vol.data)
            x = vol.origin + idx * vol.voxel_size
            gone = idx[np.linalg.norm(x - gt, axis=1) < 0.3]
            vol.data[tuple(gone.T)] = False
            vol.diagnostics.pop("bbox", None)
            vol.diagnostics["voxels"] = int(vol.data.sum())
            return vol

        est.hull = cut
        try:
            bad = est.estimate(pose.frame)
        finally:
            del est.hull
        assert bad.diagnostics["confidence"] < pose.diagnostics["confidence"], pose.frame


def test_add_rod_voxels():
    """The spurious rod: at each half-voxel step a 3 × 3 square in the grid's first two axes,
    one voxel along the third; along +x from the centre voxel for 4.6 voxel sizes (centres
    10–14, hand-counted: voxels 9–15 × 9–11), and stopped 2 voxels before the border."""
    vol = Volume(np.zeros((20, 20, 20), bool), np.zeros(3), 0.5)
    add_rod(vol, np.array([5.0, 5.0, 5.0]), np.array([1.0, 0.0, 0.0]), 2.3)
    expected = np.zeros((20, 20, 20), bool)
    expected[9:16, 9:12, 10] = True
    assert np.array_equal(vol.data, expected)
    assert vol.diagnostics["voxels"] == 21
    add_rod(vol, np.array([5.0, 5.0, 5.0]), np.array([0.0, 1.0, 0.0]), 100.0)
    assert vol.data[9:12, 9:19, 10].all() and not vol.data[:, 19:, :].any()


def test_part_trust_unplaces_the_part_that_explains_the_doubt(clean, monkeypatch):
    """Per-part trust (judge_frame ``drop_parts``): under a confidence that doubts a frame
    only for its thickest hand or foot (a logistic model on ``end_radius`` alone, the
    frame's own value far below its minimum, the next-thickest end's far above), the frame is
    matched without exactly that part — found by the radii themselves, the oracle — whose
    guess is kept; without per-part trust the same frame is rejected with every part."""
    from topopose.frame.estimate import FrameEstimator, vertex_radii

    cap, est, out = clean
    pose, det = out[0]
    radii = vertex_radii(det.volume, det.data, est.thickness_reach)
    ends = {p: radii[v] for p, v in det.alignment.mapping.items()
            if v is not None and p.rstrip("_12") in ("hand", "foot")}
    (p1, r1), (_, r2) = sorted(ends.items(), key=lambda kv: -kv[1])[:2]
    assert r1 > r2
    model = {"models": ["human"], "replaces_threshold": True, "features": ["end_radius"],
             "mean": [(r1 + r2) / 2], "scale": [(r1 - r2) / 20], "coef": [-1.0],
             "intercept": 0.0, "min_confidence": 0.5, "min_confidence_by_cameras": {}}
    monkeypatch.setattr(C, "CONFIDENCE_MODEL", model)
    whole = FrameEstimator(cap, "human", 100, gate=True, gate_rule=False, min_confidence=0.5,
                           part_trust=False).estimate(cap.frames[0])
    assert whole.status == "rejected" and whole.diagnostics["confidence"] < 0.5
    assert all(x is not None for x in whole.parts.values())
    trusted = FrameEstimator(cap, "human", 100, gate=True, gate_rule=False,
                             min_confidence=0.5).estimate(cap.frames[0])
    assert trusted.status == "matched", trusted.error
    assert trusted.diagnostics["untrusted"] == p1 and trusted.parts[p1] is None
    assert trusted.diagnostics["confidence"] >= 0.5 > trusted.diagnostics["confidence_all_parts"]
    assert np.allclose(trusted.diagnostics["untrusted_guess"], whole.parts[p1], atol=1e-5)
    assert all(np.allclose(trusted.parts[p], whole.parts[p]) for p in whole.parts if p != p1)


def test_untrusted_part_needs_one_part_above_the_rest():
    """The part named is the single best one reaching the minimum; a tie or nothing above the
    minimum names none (brute force over small tables)."""
    assert C.untrusted_part({"head": 0.8, "hand_1": 0.6}, 0.7) == "head"
    assert C.untrusted_part({"hand_1": 0.8, "hand_2": 0.8, "head": 0.1}, 0.7) is None
    assert C.untrusted_part({"hand_1": 0.69, "foot_1": 0.5}, 0.7) is None
    assert C.untrusted_part({}, 0.7) is None
    rng = np.random.default_rng(0)
    for _ in range(200):
        cs = {p: float(x) for p, x in zip(C.DROP_PARTS, rng.choice([0.2, 0.5, 0.8, 0.9], 5))}
        got = C.untrusted_part(cs, 0.75)
        top = [p for p, c in cs.items() if c == max(cs.values())]
        assert got == (top[0] if len(top) == 1 and cs[top[0]] >= 0.75 else None)


def test_head_doubt_is_the_confidence_with_a_typical_head():
    """head_doubt: the fitted confidence with the head's features at the model's typical
    values, hand-computed for a logistic model on head_bend and end_radius; None without
    typical values."""
    model = {"models": ["human"], "features": ["head_bend", "end_radius"], "mean": [0.5, 0.3],
             "scale": [0.25, 0.1], "coef": [-2.0, 1.0], "intercept": 0.5, "min_confidence": 0.5,
             "typical_head": {"head_bend": 0.1}}
    f = {"head_bend": 1.2, "end_radius": 0.4, "fat": 0.05, "lost": 0.0}
    sig = lambda z: 1.0 / (1.0 + math.exp(-z))                          # noqa: E731
    whole = C.fitted_confidence(f, 1.0, model=model)["confidence"]
    assert whole == pytest.approx(sig(0.5 - 2.0 * (1.2 - 0.5) / 0.25 + (0.4 - 0.3) / 0.1), abs=1e-4)
    got = C.head_doubt(f, 1.0, model=model)["confidence"]
    assert got == pytest.approx(sig(0.5 - 2.0 * (0.1 - 0.5) / 0.25 + (0.4 - 0.3) / 0.1), abs=1e-4)
    assert C.head_doubt(f, 1.0, model={**model, "typical_head": {}}) is None
    assert set(C.HEAD_FEATURES) <= set(C.FEATURES)


def test_head_doubt_unplaces_the_head_only_when_a_typical_head_is_trusted(clean, monkeypatch):
    """Under a confidence that depends on the head's bend alone (a logistic model, the clean
    frame's own bend far below its mean, the typical bend far above), no part's removal
    explains the doubt (a removed head has bend 0), the typical head does: with
    ``head_doubt="any"`` the frame is matched without its head, whose guess is kept; by
    default (the alignment matched this head), with the typical bend equal to the frame's own,
    or with head_doubt=False, it is rejected with every part."""
    from topopose.frame.estimate import FrameEstimator

    cap, est, out = clean
    assert out[0][1].alignment.mapping.get("head") is not None
    hb = out[0][0].diagnostics["confidence_features"]["head_bend"]
    model = {"models": ["human"], "replaces_threshold": True, "features": ["head_bend"],
             "mean": [hb + 0.5], "scale": [0.05], "coef": [1.0], "intercept": 0.0,
             "min_confidence": 0.5, "min_confidence_by_cameras": {},
             "typical_head": {"head_bend": hb + 1.0}}
    monkeypatch.setattr(C, "CONFIDENCE_MODEL", model)

    def run(**kw):
        return FrameEstimator(cap, "human", 100, gate=True, gate_rule=False, min_confidence=0.5,
                              **kw).estimate(cap.frames[0])

    off = run(head_doubt=False)
    assert off.status == "rejected" and all(x is not None for x in off.parts.values())
    assert run().status == "rejected"              # default: a matched head is not doubted
    on = run(head_doubt="any")
    assert on.status == "matched", on.error
    assert on.diagnostics["untrusted"] == "head" and on.parts["head"] is None
    assert on.diagnostics["confidence_factors"]["fitted"] == pytest.approx(
        1.0 / (1.0 + math.exp(-10.0)), abs=1e-4)
    assert on.diagnostics["confidence_all_parts"] < 0.5
    assert np.allclose(on.diagnostics["untrusted_guess"], off.parts["head"], atol=1e-5)
    assert all(np.allclose(on.parts[p], off.parts[p]) for p in off.parts if p != "head")
    monkeypatch.setattr(C, "CONFIDENCE_MODEL", {**model, "typical_head": {"head_bend": hb}})
    assert run(head_doubt="any").status == "rejected"


def test_head_doubt_by_default_for_a_head_the_alignment_left_unmatched(clean, monkeypatch):
    """judge_frame on the clean frame with the alignment's head taken out (the head placed
    from the hull alone, its features 0): under a confidence that wants the head's bend near a
    typical 1.0 (a logistic model) no part's removal reaches the minimum, the typical head
    does — the default head doubt matches the frame without its head; off, it is rejected."""
    cap, est, out = clean
    pose, det = out[0]
    al = det.alignment
    al2 = SimpleNamespace(mapping={**al.mapping, "head": None},
                          pairs=[(pp, dp) for pp, dp in al.pairs if pp[-1] != "head"])
    model = {"models": ["human"], "replaces_threshold": True, "features": ["head_bend"],
             "mean": [0.5], "scale": [0.05], "coef": [1.0], "intercept": 0.0,
             "min_confidence": 0.5, "min_confidence_by_cameras": {},
             "typical_head": {"head_bend": 1.0}}
    monkeypatch.setattr(C, "CONFIDENCE_MODEL", model)
    dg = pose.diagnostics

    def judge(doubt):
        return C.judge_frame(det.volume, dg["hull_voxels"], det.data, est.model, est.up,
                             pose.distance, est.threshold, 1, "matched", None,
                             C.Gate(min_confidence=0.5, drop_parts=C.DROP_PARTS, doubt_head=doubt),
                             aligned=C.Aligned(al2, parts=pose.parts))

    status, error, diag = judge(False)
    assert status == "rejected" and diag["confidence_features"]["head_bend"] == 0.0
    status, error, diag = judge(True)
    assert status == "matched" and diag["untrusted"] == "head", error
    assert diag["confidence_factors"]["fitted"] == pytest.approx(1 / (1 + math.exp(-10)), abs=1e-4)


def _diag(distance, shape, unexplained):
    d = {"confidence_features": {"distance": distance, "shape": shape}}
    if unexplained is not None:
        d["unexplained"] = unexplained
    return d


def test_the_gate_decides_on_constructed_frames():
    """The gate's rule (``GateOptions``): within T_d matched; above it matched only with the
    silhouettes explained and the arcs in proportion; frames the alignment did not place are
    left as they are; a rejection's reason keeps the AHA distance's and names the gate's."""
    from topopose.frame.confidence import GATE, GateOptions, gate_decision

    above = "AHA distance 0.600 above threshold T_d = 0.4"
    ok = ("matched", None)
    u_far, near = GATE.far_unexplained, GATE.max_distance
    assert gate_decision("matched", None, _diag(near, 0.5, GATE.max_unexplained)) == ok  # T_d
    assert gate_decision("matched", None, _diag(near, 0.5, None)) == ok      # not measured
    st, why = gate_decision("matched", None, _diag(near, 0.1, GATE.max_unexplained + 0.01))
    assert st == "rejected" and why.startswith("confidence gate: silhouette unexplained")
    assert gate_decision("rejected", above, _diag(1.5, GATE.far_shape, u_far)) == ok  # in proportion
    st, why = gate_decision("rejected", above, _diag(1.5, 0.05, u_far + 0.01))
    assert st == "rejected" and why.startswith(above + "; confidence gate:") and "unexplained" in why
    st, why = gate_decision("rejected", above, _diag(1.5, GATE.far_shape + 0.01, 0.05))
    assert st == "rejected" and "proportions" in why
    st, why = gate_decision("rejected", above, _diag(1.5, 0.05, None))         # not measured
    assert st == "rejected" and "no silhouette support" in why
    for frame in (("failed", "hull: empty"), ("rejected", "2 parts unmatched (hand_1, foot_2)"),
                  ("rejected", "hull split: the largest component holds 60 %")):
        assert gate_decision(*frame, _diag(0.1, 0.0, 0.0)) == frame
    st, why = gate_decision("rejected", above, _diag(1.5, 0.0, 0.05), unplaced=4)  # trunk alone
    assert st == "rejected" and "4 parts without a position" in why
    assert gate_decision("rejected", above, _diag(1.5, 0.05, 0.05), unplaced=1) == ok
    strict = GateOptions(max_distance=0.5, far_shape=0.1)
    assert gate_decision("matched", None, _diag(0.7, 0.5, 0.05), strict)[0] == "rejected"
    assert gate_decision("matched", None, _diag(0.7, 0.1, 0.05), strict) == ok


def test_the_gate_is_the_estimators_decision():
    """A synthetic capsule-human frame: the estimator's status is the gate's decision on its own
    diagnostics (support measured), and the fitted confidence decides with ``gate_rule=False``."""
    from topopose.frame.confidence import gate_decision
    from topopose.frame.estimate import FrameEstimator
    from topopose.synth.capture import synthetic_capture

    cap = synthetic_capture("human", frames=2, seed=5, cameras=4, noise=1)
    est = FrameEstimator(cap, "human", 60)
    ungated = FrameEstimator(cap, "human", 60, gate=False, support=True)
    for f in cap.frames:
        p, q = est.estimate(f), ungated.estimate(f)
        assert "unexplained" in p.diagnostics
        st, why = gate_decision(q.status, q.error, q.diagnostics, unplaced=sum(
            x is None for x in q.parts.values()), up=cap.up_vector)
        assert (p.status, p.error is None) == (st, why is None)
    assert FrameEstimator(cap, "human", 60, gate_rule=False).gate_rule is None
