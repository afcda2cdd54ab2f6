"""`topopose hull` on a capture folder, and the synth → folder → load → hull round trip."""
from __future__ import annotations

import math

import numpy as np
import pytest

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import load_capture
from topopose.cli import main
from topopose.hull import Volume, visual_hull
from topopose.hull.hull import VOLUME_FIT


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    cams = ring(n=4, size=(200, 150), f=250)
    frames = {f"{i:06d}": capsule_masks(cams, (0.1 * i, 0, 0.6), (0.1 * i, 0.2, 1.3), 0.15)
              for i in range(2)}
    return write_capture(tmp_path_factory.mktemp("cli") / "cap", cams, frames,
                         capture_toml='[capture]\nunits = "m"\n')


def test_cli_hull_writes_volume(folder, tmp_path, capsys):
    out = tmp_path / "v.npz"
    assert main(["hull", str(folder), "--frame", "000001", "--resolution", "40",
                 "--out", str(out)]) == 0
    assert "voxels" in capsys.readouterr().out
    vol = Volume.load(out)
    ref = visual_hull(load_capture(folder), "000001", resolution=40)
    assert np.array_equal(vol.data, ref.data) and np.allclose(vol.origin, ref.origin)
    # 40 voxels along the fitted volume's longest side, the grid a margin beyond it
    assert max(vol.data.shape) == 40 + 2 * math.ceil(VOLUME_FIT.margin * 38 - 1e-9)
    # frame by index, tolerance and refocus options
    assert main(["hull", str(folder), "--frame", "0", "--resolution", "32", "--tolerance", "1",
                 "--refocus", "--out", str(out)]) == 0
    assert Volume.load(out).data.sum() > 0


def test_cli_hull_bad_frame_exit_2(folder, tmp_path, capsys):
    assert main(["hull", str(folder), "--frame", "nope", "--out", str(tmp_path / "v.npz")]) == 2
    assert "nope" in capsys.readouterr().err


def test_synth_folder_round_trip(tmp_path):
    synth = pytest.importorskip("topopose.synth.capture")
    mem = synth.synthetic_capture("human", frames=2, seed=3, size=(320, 240))
    root = synth.synthesize(tmp_path / "s", "human", frames=2, seed=3, size=(320, 240))
    cap = load_capture(root)
    assert cap.frames == mem.frames and cap.volume is not None
    for f in cap.frames:
        a = visual_hull(cap, f, resolution=64)
        b = visual_hull(mem, f, resolution=64)
        assert np.array_equal(a.data, b.data) and a.data.sum() > 300
        # every ground-truth part lies in (or next to) the hull
        gt = mem.options["gt"]["frames"][f]["parts"]
        occ = np.argwhere(a.data)
        for name, p in gt.items():
            d = np.linalg.norm(a.world(occ) - np.asarray(p), axis=1).min()
            assert d < 2 * a.voxel_size, (f, name, d)
