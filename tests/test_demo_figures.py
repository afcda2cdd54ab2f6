"""Demo pictures and figures: a typical and the worst frame are drawn, failed frames
sit in a band at the bottom (not at an arbitrary height), the threshold plot includes T_d,
part labels are spread apart."""
import numpy as np

from topopose.batch.demo import _pictured
from topopose.pose.pose import Pose
from topopose.batch.quality import Evaluation, FrameScore
from topopose.viz.figures import _history, _mpl, plot_quality
from topopose.viz.view import _label_positions


def _run(dists, quals):
    poses, scores = [], []
    for i, (d, q) in enumerate(zip(dists, quals)):
        st = "failed" if d is None else ("matched" if d < 0.4 else "rejected")
        poses.append(Pose(f"{i:06d}", st, d, {}))
        scores.append(FrameScore(f"{i:06d}", st, d, q))
    return poses, Evaluation(scores, [], 0.1)


def test_typical_and_worst_frames():
    poses, ev = _run([0.1, 0.2, 0.05, 0.3, None, 0.9], ["good", "good", "good", "misplaced", "none", "bad"])
    pics = dict(_pictured(poses, ev))
    assert pics["typical"].frame == "000000"          # median distance among the "good" frames
    assert pics["worst"].frame == "000004"            # the failed frame
    poses, ev = _run([0.1, 0.2, 0.9], ["good", "good", "bad"])
    assert dict(_pictured(poses, ev))["worst"].frame == "000002"
    poses, ev = _run([0.1], ["good"])
    assert [k for k, _ in _pictured(poses, ev)] == ["typical"]


def test_failed_frames_in_a_bottom_band_and_threshold_on_axis(tmp_path):
    plt = _mpl()
    fig, ax = plt.subplots()
    labels = ["good", "none", "good", "none"]
    _history(ax, ["0", "1", "2", "3"], [0.1, None, 0.3, None], {"good": "g", "none": "0.5"}, labels, 0.4)
    failed = [c for c in ax.collections if c.get_label().startswith("failed")]
    assert len(failed) == 1
    off = failed[0].get_offsets()
    assert np.allclose(off[:, 1], 0.03) and sorted(off[:, 0].tolist()) == [1, 3]   # axes fraction
    plt.close(fig)
    poses, ev = _run([0.05, 0.1, 0.12], ["good", "good", "good"])
    fig_path = plot_quality([("human", ev)], tmp_path / "q.png", threshold=0.8)
    assert fig_path.exists()


def test_quality_axis_includes_the_models_threshold(tmp_path, monkeypatch):
    import matplotlib.figure

    seen = {}
    real = matplotlib.figure.Figure.savefig

    def spy(self, *a, **k):
        seen["xlim"] = self.axes[1].get_xlim()
        return real(self, *a, **k)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    poses, ev = _run([0.05, 0.1, 0.12], ["good", "good", "good"])
    plot_quality([("human", ev)], tmp_path / "q.png", threshold=0.8)
    assert seen["xlim"][1] >= 0.8


def test_labels_spread_apart():
    pts = {"hand_1": np.array([0.0, 0.0, 1.0]), "hand_2": np.array([0.01, 0.0, 1.0]),
           "head": np.array([0.0, 0.0, 1.7]), "foot_1": np.array([0.1, 0.0, 0.0])}
    lab = {n: w for n, w, _ in _label_positions(pts)}
    ext = 1.7
    names = list(lab)
    for i in range(len(names)):
        for j in range(i):
            a, b = lab[names[i]], lab[names[j]]
            assert np.linalg.norm(a - b) >= 0.05 * ext, (names[i], names[j])
