"""Quality classes (thesis §13.2.2) on hand-made ground truth; pose JSONL; TRC/CSV exports."""
import numpy as np
import pytest

from topopose.errors import InputError
from topopose.pose import Pose, load_model, read_poses, write_poses
from topopose.pose.export import read_trc, write_csv, write_trc, y_up_rotation
from topopose.batch.quality import classify, evaluate, point_segment_distance

PARTS = ["head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"]
# a T-pose-ish ground truth, segments of length 0.2 along the limbs
GT_PTS = {"head": [0, 0, 1.7], "torso": [0, 0, 1.4], "crotch": [0, 0, 0.9],
          "hand_1": [-0.8, 0, 1.4], "hand_2": [0.8, 0, 1.4], "foot_1": [-0.15, 0, 0.0],
          "foot_2": [0.15, 0, 0.0]}


def _gt(n=1):
    segs = {}
    for p, x in GT_PTS.items():
        x = np.asarray(x, float)
        d = np.array([0, 0, 0.1]) if p in ("head", "torso", "crotch") else np.sign(x) * [0.1, 0, 0]
        if p.startswith("foot"):
            d = np.array([0, 0, 0.1])
        segs[p] = [(x - d).tolist(), (x + d).tolist()]
    fr = {"parts": GT_PTS, "segments": segs, "separated": True}
    return {"subject": "human", "units": "m", "up": "+z", "height": 1.75, "parts": PARTS,
            "frames": {f"{i:06d}": fr for i in range(n)}}


def _pose(frame, parts, status="matched", distance=0.1):
    return Pose(frame, status, distance, {p: (None if v is None else np.asarray(v, float))
                                          for p, v in parts.items()})


def test_point_segment_distance_against_sampling():
    rng = np.random.default_rng(1)
    for _ in range(50):
        p, a, b = rng.normal(size=(3, 3))
        ts = np.linspace(0, 1, 20001)
        brute = np.min(np.linalg.norm(a + ts[:, None] * (b - a) - p, axis=1))
        assert abs(point_segment_distance(p, a, b) - brute) < 1e-4


def test_classify_table():
    assert classify(7, 7, 0) == "good"
    assert classify(7, 6, 0) == "missing limb"
    assert classify(7, 4, 0) == "partial"
    assert classify(7, 7, 1) == "misplaced"
    assert classify(7, 7, 4) == "bad"
    assert classify(7, 1, 0) == "none" and classify(7, 0, 0) == "none"


def test_classes_and_optimal_pairing():
    gt = _gt(6)
    exact = dict(GT_PTS)
    swapped = dict(GT_PTS, hand_1=GT_PTS["hand_2"], hand_2=GT_PTS["hand_1"])   # numbering is free
    one_missing = dict(GT_PTS, foot_2=None)
    arm_leg = dict(GT_PTS, hand_1=GT_PTS["foot_1"], foot_1=GT_PTS["hand_1"])   # a real confusion
    off = dict(GT_PTS, head=[0, 0, 1.7 + 0.3])       # 0.2 beyond the segment end > 0.175
    allbad = {p: [5, 5, 5] for p in PARTS}
    poses = [_pose("000000", exact, distance=0.05), _pose("000001", swapped, distance=0.1),
             _pose("000002", one_missing, distance=0.2), _pose("000003", arm_leg, distance=0.3),
             _pose("000004", off, distance=0.15), _pose("000005", allbad, distance=0.9)]
    ev = evaluate(gt, poses)
    q = [f.quality for f in ev.frames]
    assert q == ["good", "good", "missing limb", "misplaced", "misplaced", "bad"]
    assert ev.frames[1].assignment["hand_1"] == "hand_2"
    assert ev.tolerance == pytest.approx(0.175)
    # a bigger tolerance forgives the head
    assert evaluate(gt, poses, tolerance=0.25).frames[4].quality == "good"
    # threshold study: TP/frames, FP/frames, FP/(TP+FP)
    r = ev.rates(0.2)
    assert (r["tp"], r["fp"]) == (3, 1) and r["tp_rate"] == pytest.approx(3 / 6)
    assert r["fp_per_match"] == pytest.approx(1 / 4)
    assert ev.rates(0.12)["fp_per_match"] == 0.0
    assert ev.best_threshold(0.02) == pytest.approx(0.1)
    c = ev.curves()
    assert np.all(np.diff(c["tp_rate"]) >= 0) and c["tp_rate"][-1] == pytest.approx(3 / 6)


def test_best_threshold_and_rejected_parts_never_count():
    gt = _gt(3)
    two_missing_wrong = dict(GT_PTS, foot_1=None, foot_2=None, head=[3, 3, 3])
    poses = [_pose("000000", GT_PTS, distance=0.1),
             _pose("000001", two_missing_wrong, status="rejected", distance=0.05),
             Pose("000002", "failed", None, {p: None for p in PARTS}, "hull: broken")]
    ev = evaluate(gt, poses)
    assert [f.quality for f in ev.frames] == ["good", "misplaced", "none"]
    # frame 1 misses 2 parts: the method rejects it at any threshold, so it is no FP
    assert ev.rates(2.0)["fp"] == 0 and ev.best_threshold() == pytest.approx(0.1)
    assert ev.at_status()["tp"] == 1


def test_missing_gt_frame_is_input_error():
    with pytest.raises(InputError, match="no ground truth for frame"):
        evaluate(_gt(1), [_pose("000009", GT_PTS)])


def test_poses_jsonl_round_trip_and_truncated_tail(tmp_path):
    poses = [_pose("000001", dict(GT_PTS, head=None), distance=0.25),
             Pose("000000", "failed", None, {p: None for p in PARTS}, "hull: x.png unreadable",
                  {"hull": 1.5})]
    f = tmp_path / "p.jsonl"
    write_poses(f, poses)
    back = read_poses(f)
    assert [p.frame for p in back] == ["000000", "000001"]
    assert back[1].parts["head"] is None and np.allclose(back[1].parts["hand_1"], GT_PTS["hand_1"])
    assert back[0].error == "hull: x.png unreadable" and back[0].distance is None
    with open(f, "a") as fh:
        fh.write('{"frame": "000002", "sta')        # interrupted mid-write
    with pytest.raises(InputError, match="line 3"):
        read_poses(f)
    assert len(read_poses(f, strict=False)) == 2


def test_trc_and_csv(tmp_path):
    poses = [_pose("000000", GT_PTS), _pose("000001", GT_PTS, status="rejected"),
             _pose("000002", dict(GT_PTS, head=None))]
    trc = write_trc(tmp_path / "p.trc", poses, PARTS, fps=50, units="cm", up="+z")
    names, times, a = read_trc(trc)
    assert names == PARTS and np.allclose(times, [0, 0.02, 0.04])
    R = y_up_rotation("+z")
    assert np.allclose(R @ [0, 0, 1], [0, 1, 0]) and np.isclose(np.linalg.det(R), 1)
    for up in ("+x", "-x", "+y", "-y", "+z", "-z"):
        Ru = y_up_rotation(up)
        v = np.zeros(3)
        v["xyz".index(up[1])] = 1 if up[0] == "+" else -1
        assert np.allclose(Ru @ v, [0, 1, 0]) and np.isclose(np.linalg.det(Ru), 1)
    assert np.allclose(a[0, 0], R @ np.asarray(GT_PTS["head"]) * 0.01)   # cm → m, y up
    assert np.isnan(a[1]).all()                                        # rejected: empty row
    assert np.isnan(a[2, 0]).all() and not np.isnan(a[2, 1]).any()
    text = trc.read_text().splitlines()
    assert text[0].startswith("PathFileType\t4") and text[2].split("\t")[4] == "m"
    csvp = write_csv(tmp_path / "p.csv", poses, PARTS)
    rows = csvp.read_text().splitlines()
    assert rows[0].split(",")[:6] == ["frame", "status", "distance", "head_x", "head_y", "head_z"]
    assert rows[1].split(",")[3:6] == ["0.000000", "0.000000", "1.700000"]
    assert rows[2].split(",")[3] == ""


def test_c3d_optional(tmp_path):
    from topopose.pose.export import require_c3d
    try:
        import c3d  # noqa: F401
    except ImportError:
        with pytest.raises(InputError, match=r"pip install topopose\[c3d\]"):
            require_c3d()
    else:
        from topopose.pose.export import write_c3d
        import warnings
        write_c3d(tmp_path / "p.c3d", [_pose("000000", dict(GT_PTS, head=None)), _pose("000001", GT_PTS)],
                  PARTS, fps=50, units="m")
        with open(tmp_path / "p.c3d", "rb") as fh, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = c3d.Reader(fh)
            assert [str(x).strip() for x in r.point_labels] == PARTS
            frames = [pts for _, pts, _ in r.read_frames()]
        assert frames[0][0, 3] < 0                                   # missing head: invalid
        assert np.allclose(frames[1][0, :3], np.array(GT_PTS["head"]) * 1000, atol=0.5)  # mm


def test_model_interchangeable_groups_used_for_dog():
    dog = load_model("dog")
    groups = dog.interchangeable()
    assert ["paw_1", "paw_2"] in groups and ["paw_3", "paw_4"] in groups


def test_evaluate_tolerance_relative_absolute_and_junctions(tmp_path, capsys):
    """--tolerance is a fraction of gt height, the same for every part; --tolerance-m is
    absolute; the thesis default (0.1 × height, junctions 1.5×) stays without either."""
    from topopose.batch.quality import evaluation_tolerance

    gt = _gt(1)                                  # height 1.75
    assert evaluation_tolerance(gt, 0.08) == pytest.approx((0.14, 1.0))
    assert evaluation_tolerance(gt, None, 0.05) == pytest.approx((0.05, 1.0))
    assert evaluation_tolerance(gt) == pytest.approx((0.175, 1.5))
    assert evaluation_tolerance(gt, 0.08, junction_factor=2) == pytest.approx((0.14, 2.0))
    with pytest.raises(InputError):
        evaluation_tolerance(gt, 0.08, 0.05)
    with pytest.raises(InputError):
        evaluation_tolerance({"frames": {}}, 0.08)
    # the head 0.12 beyond its segment end, the torso 0.16 off its segment
    pts = dict(GT_PTS, head=[0, 0, 1.8 + 0.12], torso=[0.16, 0, 1.4])
    pose = [_pose("000000", pts)]
    for (rel, ab, jf), want in {(0.08, None, None): {"head": True, "torso": False},
                                (0.06, None, None): {"head": False, "torso": False},
                                (None, 0.13, None): {"head": True, "torso": False},
                                (None, 0.11, None): {"head": False, "torso": False},
                                (0.08, None, 1.5): {"head": True, "torso": True},
                                (None, None, None): {"head": True, "torso": True}}.items():
        tol, f = evaluation_tolerance(gt, rel, ab, jf)
        fs = evaluate(gt, pose, tolerance=tol, junction_factor=f).frames[0]
        assert {p: fs.right[p] for p in want} == want, (rel, ab, jf)
