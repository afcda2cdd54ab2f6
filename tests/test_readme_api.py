"""The README's Python snippet gives the distance the CLI gives for the same frame (the data
tree normalized alike), and the plain ``align(model, tree)`` reuses the model's Matcher."""
import re
from pathlib import Path

import pytest

import topopose as tp
from topopose.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def _snippet():
    text = README.read_text()
    part = text[text.index("## Python API"):]
    return re.search(r"```python\n(.*?)```", part, re.S).group(1)


def test_readme_snippet_distance_equals_cli(tmp_path, capsys):
    from topopose.synth import synthesize

    cap_dir = synthesize(tmp_path / "cap", subject="human", frames=2, seed=4, cameras=8,
                         size=(240, 180), separated=True)
    code = _snippet().replace('"CAPTURE"', repr(str(cap_dir))).replace('"000012"', '"000001"')
    ns = {}
    exec(code, ns)                                    # the README's lines, as a user runs them
    res = ns["res"]
    vol, skel, tree = tmp_path / "v.npz", tmp_path / "s.npz", tmp_path / "t.json"
    assert main(["hull", str(cap_dir), "--frame", "000001", "--resolution", "100", "--out", str(vol)]) == 0
    assert main(["skeleton", str(vol), "--out", str(skel)]) == 0
    assert main(["tree", str(skel), "--out", str(tree)]) == 0
    capsys.readouterr()
    assert main(["match", "human", str(tree)]) == 0
    out = capsys.readouterr().out
    cli = float(re.search(r"distance ([0-9.eE+-]+)", out).group(1))
    assert res.distance == pytest.approx(cli, rel=1e-4, abs=1e-6), (res.distance, cli)
    assert ns["pose"].status in ("matched", "rejected")


def test_plain_align_reuses_the_models_matcher():
    import importlib

    A = importlib.import_module("topopose.match.align")

    model = tp.load_model("human")
    D = tp.Tree([(0, 1, 0.2), (0, 2, 0.3), (0, 3, 0.3), (0, 4, 0.1), (4, 5, 0.4), (4, 6, 0.4)])
    A._MATCHERS = None
    tree = model.pattern()
    tree.constraints = []                     # no coordinate constraints: no positions needed
    r1 = tp.align(tree, D)
    m = next(iter(A._MATCHERS.values()))
    r2 = tp.align(tp.Tree(list(tree.edges), vertices=list(tree.vertices), root=tree.root), D)  # a copy
    assert len(A._MATCHERS) == 1 and next(iter(A._MATCHERS.values())) is m
    assert r1.distance == r2.distance == A.Matcher(tree).align(D).distance
    tp.align(tree, D, method="ha")            # other options: another entry
    assert len(A._MATCHERS) == 2
    for i in range(A.MATCHER_CACHE_SIZE + 3):  # bounded
        tp.align([("a", "b", 1.0 + i), ("a", "c", 1.0)], D)
    assert len(A._MATCHERS) == A.MATCHER_CACHE_SIZE
