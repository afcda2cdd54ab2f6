"""Shared types: Tree validation and JSON round trip, Volume I/O, CLI error handling."""
import json
import math

import numpy as np
import pytest

import topopose as tp
from topopose.cli import main
from topopose.match import Tree


def test_tree_json_round_trip(tmp_path):
    t = Tree([(0, 1, 0.5), (1, 2, math.inf), (1, 3, 0.25)],
             positions={0: [0, 0, 1], 1: [0, 0, 0], 2: [1, 0, 0], 3: [0, 1, 0]},
             labels={0: "head"}, root=1)
    p = tmp_path / "t.json"
    t.save(p)
    d = json.loads(p.read_text())
    assert d["edges"][1][2] == "inf" and d["root"] == 1
    u = Tree.load(p)
    assert u.vertices == t.vertices and u.root == 1 and u.labels[0] == "head"
    assert [(a, b) for a, b, _ in u.edges] == [(a, b) for a, b, _ in t.edges]
    assert u.edges[1][2] == math.inf
    np.testing.assert_allclose(u.positions[2], [1, 0, 0])


def test_tree_networkx_round_trip():
    t = Tree([("a", "b", 1.0), ("b", "c", 2.0)], root="a")
    u = Tree.from_networkx(t.to_networkx())
    assert sorted(u.edges) == sorted(t.edges) and u.root == "a"


def test_normalized_keeps_infinite():
    t = Tree([("a", "b", 2.0), ("b", "c", 6.0), ("b", "d", math.inf)]).normalized()
    w = {frozenset((u, v)): x for u, v, x in t.edges}
    assert w[frozenset("ab")] == 0.25 and w[frozenset("bc")] == 0.75 and math.isinf(w[frozenset("bd")])


@pytest.mark.parametrize("edges, root, word", [
    ([(0, 1, 1), (1, 2, 1), (2, 0, 1)], None, "cycle"),
    ([(0, 1, 1), (2, 3, 1)], None, "disconnected"),
    ([(0, 1, -1)], None, ">= 0"),
    ([(0, 1, float("nan"))], None, ">= 0"),
    ([(0, 1, 1)], 7, "root"),
    ([(0, 1, "heavy")], None, "weight"),
])
def test_tree_rejects_bad_input(edges, root, word):
    with pytest.raises(tp.InputError, match=word):
        Tree(edges, root=root)


def test_tree_json_errors_name_the_file(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"vertices": {}, "edges": [[0, 1]]}')
    with pytest.raises(tp.InputError, match=r"bad\.json.*edges\[0\]"):
        Tree.load(p)


def test_volume_io_and_errors(tmp_path):
    v = tp.Volume(np.eye(3, dtype=bool)[:, :, None].repeat(2, 2), [1, 2, 3], 0.5)
    v.save(tmp_path / "v.npz")
    w = tp.Volume.load(tmp_path / "v.npz")
    assert (w.data == v.data).all() and w.voxel_size == 0.5
    np.testing.assert_allclose(w.world([1, 0, 0]), [1.5, 2, 3])
    np.savez(tmp_path / "bad.npz", volume=np.zeros((3, 3)))
    with pytest.raises(tp.InputError, match="3D"):
        tp.Volume.load(tmp_path / "bad.npz")


def test_cli_input_error_is_one_line_exit_2(tmp_path, capsys):
    (tmp_path / "t.json").write_text("not json")
    np.savez(tmp_path / "v.npz", volume=np.zeros((3, 3, 3), dtype=np.uint8))
    assert main(["skeleton", str(tmp_path / "v.npz"), "--out", str(tmp_path / "s.npz")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "v.npz" in err and "boolean" in err
