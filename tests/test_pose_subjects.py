"""End to end on synthetic captures of every built-in subject: silhouettes → hull → D6I1D →
data tree → AHA → parts, scored against the synthetic ground truth with the classes of thesis
§13.2.2 (not just "it runs")."""

from topopose.pose import FrameEstimator, load_model
from topopose.pose.quality import FP_CLASSES, TP_CLASSES, evaluate

FRAMES = 4


def _run(subject, noise, tolerance=None, resolution=100, seed=11, threshold=None):
    from topopose.capture import synthetic_capture

    cap = synthetic_capture(subject=subject, frames=FRAMES, seed=seed, noise=noise,
                            separated=True, cameras=8)
    est = FrameEstimator(cap, subject, resolution, threshold=threshold, tolerance=tolerance)
    poses = [est.estimate(f) for f in cap.frames]
    return cap, est, poses


def test_human_noise1_default_settings_good_matchings():
    """The thesis' main case (dancer, §13.2.2.1): limbs separated, noisy silhouettes, 100³."""
    cap, est, poses = _run("human", noise=1)
    assert est.tolerance == 1 and est.threshold == load_model("human").threshold
    ev = evaluate(cap.gt, poses)
    tp = [f for f in ev.frames if f.status == "matched" and f.quality in TP_CLASSES]
    fp = [f for f in ev.frames if f.status == "matched" and f.quality in FP_CLASSES]
    assert len(tp) >= FRAMES - 1, [(f.frame, f.status, f.quality, f.errors) for f in ev.frames]
    assert not fp
    for f in tp:                                  # positions, not just labels
        ends = ["head", "hand_1", "hand_2", "foot_1", "foot_2"]
        assert max(f.errors[p] for p in ends if p in f.errors) < 0.1 * cap.gt["height"]
        assert all(f.errors[p] < 0.15 * cap.gt["height"] for p in ("torso", "crotch"))


def test_human_without_coordinate_constraints_still_matches():
    cap, est, _ = _run("human", noise=0, tolerance=0)
    free = FrameEstimator(cap, load_model("human", constraints=False), 100, tolerance=0)
    ev = evaluate(cap.gt, [free.estimate(f) for f in cap.frames])
    assert sum(f.quality in TP_CLASSES for f in ev.frames) >= FRAMES - 1


def test_dog_front_and_back_told_apart():
    cap, est, poses = _run("dog", noise=0, tolerance=0, seed=12)
    ev = evaluate(cap.gt, poses)
    ok = [f for f in ev.frames if f.quality in TP_CLASSES]
    assert len(ok) >= FRAMES - 1, [(f.frame, f.quality, f.errors) for f in ev.frames]
    for f in ok:
        assert f.right["head"] and f.right["tail"] and f.right["shoulders"] and f.right["hips"]


def test_spider_legs_found():
    cap, est, poses = _run("spider", noise=0, tolerance=0)
    ev = evaluate(cap.gt, poses)
    done = [f for f in ev.frames if f.status != "failed"]
    assert len(done) >= FRAMES - 1
    legs = [f"leg_{i}" for i in range(1, 9)]
    right = sum(bool(f.right[p]) for f in done for p in legs)
    assert right >= 0.75 * 8 * len(done)          # eight legs, paired optimally with gt
    assert all(f.quality != "bad" for f in done)


def test_hand_incomplete_model_rooted_at_the_arm():
    """Incomplete model (§12.1.1): both trees rooted at the infinite limb, so the arm part is
    the data tree's border vertex — right in every processed frame — and the palm follows."""
    cap, est, poses = _run("hand", noise=0, tolerance=0)
    assert est.model.root == "arm" and not est.model.complete
    fingers = ["thumb", "index", "middle", "ring", "little"]
    ev = evaluate(cap.gt, poses, groups=[fingers])      # up to finger order
    done = [f for f in ev.frames if f.status != "failed"]
    assert done, [p.error for p in poses]
    for f in done:
        assert f.right["arm"], (f.frame, f.errors)
    assert sum(bool(f.right["palm"]) for f in done) >= len(done) / 2
    assert all(f.quality != "bad" for f in done)
