"""Pictures: a frame (hull, skeleton, data tree, labelled parts, model tree), distances per
frame, threshold study. Checked as images: size, not blank, part colours present."""
import cv2
import numpy as np
import pytest

from topopose.hull import Volume
from topopose.match import Tree
from topopose.pose import Pose, load_model
from topopose.frame.estimate import FrameDetail
from topopose.batch.quality import evaluate
from topopose.viz import plot_distances, plot_quality, render_frame
from topopose.geometry.axes import up_rotation
from topopose.viz.view import part_colours


def _stick_figure():
    a = np.zeros((30, 20, 40), bool)
    a[10, 10, 5:35] = True           # spine
    a[3:18, 10, 28] = True           # arms
    a[6, 10, 2:6] = a[14, 10, 2:6] = True
    vol = np.zeros_like(a)
    from scipy import ndimage
    vol = ndimage.binary_dilation(a, iterations=2)
    v = Volume(vol, origin=(0, 0, 0), voxel_size=0.05)
    pos = {0: (10, 10, 35), 1: (10, 10, 28), 2: (3, 10, 28), 3: (17, 10, 28), 4: (10, 10, 6),
           5: (6, 10, 2), 6: (14, 10, 2)}
    t = Tree([(1, 0, 7), (1, 2, 7), (1, 3, 7), (1, 4, 22), (4, 5, 4), (4, 6, 4)],
             positions={k: v.world(p) for k, p in pos.items()})
    names = {"head": 0, "torso": 1, "hand_1": 2, "hand_2": 3, "crotch": 4, "foot_1": 5,
             "foot_2": 6}
    pose = Pose("000003", "matched", 0.123, {n: t.positions[i] for n, i in names.items()})
    return v, a, t, pose


def test_render_frame_png_readable(tmp_path):
    v, skel, t, pose = _stick_figure()
    m = load_model("human")
    out = render_frame(tmp_path / "f.png", m, pose, FrameDetail(v, skel, t, None))
    img = cv2.imread(str(out))[:, :, ::-1]
    assert img.shape[0] >= 600 and img.shape[1] >= 1000 and img.std() > 10
    # every part colour appears (labelled markers in 3D and in the model tree)
    for p, c in part_colours(m.parts).items():
        rgb = (np.array(c[:3]) * 255).astype(int)
        close = np.abs(img.astype(int) - rgb).sum(axis=2) < 30
        assert close.sum() > 20, p


def test_up_rotation():
    for up in ([0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 0, -1], [0, -1, 0]):
        R = up_rotation(up)
        assert np.allclose(R @ up, [0, 0, 1]) and np.isclose(np.linalg.det(R), 1)


def test_distance_and_quality_figures(tmp_path):
    parts = ["head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"]
    pts = {p: [i * 0.3, 0, 1.0] for i, p in enumerate(parts)}
    segs = {p: [x, x] for p, x in pts.items()}
    gt = {"subject": "human", "height": 1.75, "parts": parts,
          "frames": {f"{i:06d}": {"parts": pts, "segments": segs} for i in range(10)}}
    rng = np.random.default_rng(0)
    poses = []
    for i in range(10):
        bad = i % 3 == 0
        d = {p: (np.array(x) + (1.0 if bad else 0.0)) for p, x in pts.items()}
        st = "failed" if i == 9 else "matched"
        poses.append(Pose(f"{i:06d}", st, None if st == "failed" else float(rng.uniform(0, 1)),
                          d if st != "failed" else {p: None for p in parts}))
    ev = evaluate(gt, poses)
    a = plot_distances(poses, tmp_path / "d.png", evaluation=ev, threshold=0.4)
    b = plot_quality([("50", ev), ("100", ev)], tmp_path / "q.png")
    for p in (a, b):
        img = cv2.imread(str(p))
        assert img is not None and img.std() > 5
    assert cv2.imread(str(b)).shape[0] > cv2.imread(str(a)).shape[0]


def test_rerun_optional(tmp_path):
    from topopose.errors import InputError
    from topopose.viz.rerun import require_rerun
    try:
        import rerun  # noqa: F401
    except ImportError:
        with pytest.raises(InputError, match=r"pip install topopose\[rerun\]"):
            require_rerun()
    else:
        assert require_rerun() is not None
