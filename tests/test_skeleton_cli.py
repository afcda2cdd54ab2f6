"""`topopose tree` and `topopose tree --stats` (DESIGN.md, Command line; thesis §11.4.1)."""
import json
import math

import numpy as np
import pytest

from topopose.cli import main
from topopose.hull import Volume
from topopose.match import Tree


def y_volume():
    s = np.zeros((9, 9, 3), bool)
    for j in range(5):
        s[4, j, 1] = True
    for d in range(1, 4):
        s[4 - d, 4 + d, 1] = s[4 + d, 4 + d, 1] = True
    return s


def test_tree_command(tmp_path, capsys):
    Volume(y_volume(), origin=(1, 0, 0), voxel_size=0.1).save(tmp_path / "sk.npz")
    assert main(["tree", str(tmp_path / "sk.npz"), "--out", str(tmp_path / "t.json")]) == 0
    t = Tree.load(tmp_path / "t.json")
    assert t.n_vertices == 4
    np.testing.assert_allclose(sorted(w for *_, w in t.edges),
                               sorted([0.4, 0.3 * math.sqrt(2), 0.3 * math.sqrt(2)]))
    assert "4 vertices" in capsys.readouterr().out
    assert main(["tree", str(tmp_path / "sk.npz"), "--out", str(tmp_path / "c.json"),
                 "--weight", "count", "--border"]) == 0
    d = json.loads((tmp_path / "c.json").read_text())
    assert sorted(str(e[2]) for e in d["edges"]) == ["2.0", "2.0", "inf"]
    assert d["root"] == d["diagnostics"]["border_vertex"]


def test_tree_command_bad_input(tmp_path, capsys):
    block = np.zeros((6, 6, 6), bool)
    block[2:4, 2:4, 2:4] = True
    Volume(block, (0, 0, 0), 1.0).save(tmp_path / "block.npz")
    assert main(["tree", str(tmp_path / "block.npz"), "--out", str(tmp_path / "t.json")]) == 2
    err = capsys.readouterr().err
    assert "block.npz" in err and "not a curve skeleton" in err
    Volume(np.zeros((4, 4, 4), bool), (0, 0, 0), 1.0).save(tmp_path / "empty.npz")
    assert main(["tree", str(tmp_path / "empty.npz"), "--out", str(tmp_path / "t.json")]) == 2
    assert "no voxel" in capsys.readouterr().err
    np.savez(tmp_path / "ints.npz", volume=np.ones((3, 3, 3), np.uint8))
    assert main(["tree", str(tmp_path / "ints.npz"), "--out", str(tmp_path / "t.json")]) == 2
    assert "boolean" in capsys.readouterr().err
    assert main(["tree", str(tmp_path / "block.npz")]) == 2
    assert not (tmp_path / "t.json").exists()


def test_tree_stats_command(tmp_path, capsys):
    synth = pytest.importorskip("topopose.synth.capture")
    cap = synth.synthesize(tmp_path / "cap", subject="human", frames=3, seed=1)
    out = tmp_path / "stats.png"
    assert main(["tree", "--stats", str(cap), "--out", str(out), "--resolutions", "40,60"]) == 0
    assert out.exists() and out.stat().st_size > 1000
    table = (tmp_path / "stats.md").read_text()
    assert "| 40 | 3 | 0 |" in table and "| 60 | 3 | 0 |" in table
    raw = json.loads((tmp_path / "stats.json").read_text())
    assert set(raw) == {"40", "60"}
    for r in raw.values():
        assert len(r["n_vertices"]) == 3 and all(n >= 2 for n in r["n_vertices"])
        assert all(1 <= d <= n - 1 for d, n in zip(r["max_degree"], r["n_vertices"]))
    assert "| resolution |" in capsys.readouterr().out
    assert main(["tree", "--stats", str(cap), "--resolutions", "a,b"]) == 2
