"""Options as data: the per-frame estimator, the sequence stage and the batch run each take one
frozen dataclass of grouped options; keyword arguments by name map onto its fields, unknown
names are refused, and the defaults are what the stages do without options."""
import dataclasses

import numpy as np
import pytest

from topopose.batch.options import RunOptions
from topopose.frame.options import EstimatorOptions, PlacementOptions
from topopose.sequence.options import SequenceOptions, SkeletonFitOptions


def test_estimator_options_by_name_land_in_their_group():
    o = EstimatorOptions.of(spine=False, tolerance=0, thinning="ack3", gate=True, trim=False)
    assert o.placement.spine is False and o.hull.tolerance == 0
    assert o.thinning.method == "ack3" and o.confidence.gate is True and o.records.trim is False
    assert o == dataclasses.replace(
        EstimatorOptions(), placement=PlacementOptions(spine=False),
        hull=dataclasses.replace(o.hull), thinning=dataclasses.replace(o.thinning),
        confidence=dataclasses.replace(o.confidence), records=dataclasses.replace(o.records))
    assert EstimatorOptions.of(**o.flat()) == o                  # flat() is of()'s inverse
    assert EstimatorOptions.of(trim=None) == EstimatorOptions()  # None: unchanged
    with pytest.raises(TypeError, match="no option 'spline'"):
        EstimatorOptions.of(spline=False)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.hull.tolerance = 1


def test_sequence_and_run_options_by_name():
    s = SequenceOptions.of(girdle=False, max_gap=0, smooth=5, track=False)
    assert s.skeleton_fit.girdle is False and s.gaps.max_gap == 0
    assert s.smoothing.smooth == 5 and s.track is False
    assert SequenceOptions.of(track=None).track is True
    with pytest.raises(TypeError, match="no option 'grdle'"):
        SequenceOptions.of(grdle=False)
    r = RunOptions.of(workers=2, trc="m.trc", constraints=False, trim=False, smooth=0,
                      centre=None)
    assert r.parallel.workers == 2 and r.exports.trc == "m.trc"
    assert r.estimator.alignment.constraints is False
    assert r.sequence.trim is False and r.estimator.records.trim is True   # run's trim: the sequence's
    assert r.sequence.smoothing.smooth == 0 and r.centre is True
    with pytest.raises(TypeError):
        RunOptions.of(nonsense=1)


def test_no_module_switches_left_in_the_fit():
    """The sequence stage's tuning lives in its options: the kinematic fit's modules hold no
    module-level switch that a caller could flip."""
    import re
    from pathlib import Path

    import topopose.sequence as seq

    switch = re.compile(r"^[A-Z][A-Z0-9_]+ *= *(True|False|None)\b", re.M)
    for f in Path(seq.__file__).parent.glob("*.py"):
        assert not switch.search(f.read_text()), f
    assert SkeletonFitOptions().girdle is True and SkeletonFitOptions().bend is None


def test_estimator_takes_options_or_names_alike():
    from topopose.synth import synthetic_capture
    from topopose.frame import FrameEstimator

    cap = synthetic_capture(subject="human", frames=1, seed=4, separated=True)
    f = cap.frames[0]
    a = FrameEstimator(cap, "human", 40, options=EstimatorOptions.of(trim=False, spine=False))
    b = FrameEstimator(cap, "human", 40, trim=False, spine=False)
    assert a.options == b.options and a.trim is False and not a.spine
    p, q = a.estimate(f), b.estimate(f)
    assert p.status == q.status and p.distance == q.distance
    assert all((x is None and y is None) or np.array_equal(x, y)
               for x, y in zip(p.parts.values(), q.parts.values()))
    assert "trim" not in p.diagnostics


def test_fit_sequence_options_equal_names():
    """``fit_sequence(poses, model, options)`` and the same options by name give the same
    joints; a changed option changes them (the options reach the fit)."""
    from topopose.synth import synthetic_capture
    from topopose.batch import run
    from topopose.pose import load_model
    from topopose.sequence.kinematic_fit import fit_sequence
    from topopose.sequence.track import track

    cap = synthetic_capture(subject="body", frames=4, seed=2, motion="walk", cameras=6)
    model = load_model("human")
    poses = track(run(cap, model, 48, progress=False, track=False, sides=False,
                      skeleton=False, gate=False, threshold=1e9).poses, model)
    opts = SequenceOptions.of(quantile=50, smooth=0)
    a, _, _ = fit_sequence(poses, model, opts)
    b, _, _ = fit_sequence(poses, model, quantile=50, smooth=0)
    c, _, _ = fit_sequence(poses, model, smooth=0)
    joints = [p.joints for p in a if p.joints]
    assert joints, "nothing fitted: the check below would be empty"
    assert all(all(np.array_equal(x.joints[k], y.joints[k]) for k in x.joints)
               for x, y in zip(a, b))
    assert any(not np.allclose(x.joints[k], y.joints[k])
               for x, y in zip(a, c) if x.joints for k in x.joints)
