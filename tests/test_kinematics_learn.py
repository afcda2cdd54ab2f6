"""Learning the kinematic structure of a walking figure end to end (Mukasa §2, §3.1)."""
import json

import networkx as nx
import numpy as np
import pytest

from topopose.errors import InputError
from topopose.hull import Volume
from topopose.kinematics import joint_metrics, learn_structure
from topopose.synth.walker import walker_sequence
from topopose.synth.walker import voxelize_capsules, walker_pose
from topopose.pose import load_model


@pytest.fixture(scope="module")
def walker():
    seq = walker_sequence(frames=12, resolution=90, period=12)
    return seq, learn_structure(seq.volumes, frames=seq.frames)


def _reduced(tree):
    g = tree.to_networkx()
    for v in [v for v in g if g.degree(v) == 2]:
        a, b = list(g.neighbors(v))
        w = g.edges[a, v]["weight"] + g.edges[v, b]["weight"]
        g.remove_node(v)
        g.add_edge(a, b, weight=w)
    return g


def test_walker_structure_is_the_human_tree(walker):
    seq, res = walker
    assert res.status == "ok", res.message
    human = load_model("human").tree.to_networkx()
    learned = res.model.tree.to_networkx()
    assert nx.is_isomorphic(learned, human)
    # named after the built-in model through the isomorphism (head above torso ...)
    assert set(res.model.parts) == set(human.nodes)
    assert set(map(frozenset, learned.edges)) == set(map(frozenset, human.edges))
    # the full joint tree reduces (degree-2 joints removed) to the same tree, and the
    # reduced lengths are the sums of the segment lengths along each reduced edge
    red = _reduced(res.full)
    assert nx.is_isomorphic(red, human)
    for u, v, w in res.model.tree.edges:
        assert red.edges[u, v]["weight"] == pytest.approx(w, rel=1e-6)
    assert len(res.full.vertices) > 7          # joints were found along the limbs


def test_walker_joints_against_ground_truth(walker):
    seq, res = walker
    R, E = zip(*(joint_metrics(res.joints[f], seq.joints[f], seq.height) for f in range(len(seq.frames))))
    # the paper reaches R ≈ 0.6, E < 0.075 on a CG walker
    assert np.mean(R) >= 0.6
    assert np.mean(E) <= 0.06
    # end points: the learned hands/feet/head follow the figure's extremities
    for f in range(len(seq.frames)):
        J, P = res.joints[f], seq.parts[f]
        assert np.linalg.norm(J["head"] - P["head"]) < 0.1
        for a, b in (("foot_1", "foot_2"), ("hand_1", "hand_2")):
            d = min(np.linalg.norm(J[a] - P[a]) + np.linalg.norm(J[b] - P[b]),
                    np.linalg.norm(J[a] - P[b]) + np.linalg.norm(J[b] - P[a]))
            assert d < 0.25


def test_outputs_load_back(walker, tmp_path):
    seq, res = walker
    out = tmp_path / "walker.toml"
    res.model.save(out)
    m = load_model(str(out))
    assert m.root == "torso" and m.complete
    assert sorted(m.parts) == sorted(res.model.parts)
    full = res.full_model()
    full.save(tmp_path / "walker.joints.toml")
    assert len(load_model(str(tmp_path / "walker.joints.toml")).parts) == len(res.full.vertices)
    res.write_jsonl(tmp_path / "joints.jsonl")
    lines = [json.loads(x) for x in (tmp_path / "joints.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in lines] == seq.frames
    assert set(lines[0]["joints"]) == set(res.full.vertices)
    assert all(len(r["segments"]) == len(res.full.edges) for r in lines)


def test_no_coherent_interval_gives_a_message_and_a_partial_structure():
    # hands on the hips in every frame: every graph has loops
    vols = []
    for t in range(6):
        J, E, caps = walker_pose(t, period=6, stride=0.3)
        caps = [c for c in caps if not any(np.allclose(c[0], J[k]) or np.allclose(c[1], J[k])
                                            for k in ("elbow_l", "elbow_r", "wrist_l", "wrist_r"))]
        for s in "lr":
            elbow = J["shoulder_" + s] + np.array([0, 0.22 if s == "l" else -0.22, -0.25])
            caps += [(J["shoulder_" + s], elbow, 0.05), (elbow, J["pelvis"] + np.array([0, 0.15 if s == "l" else -0.15, 0.1]), 0.05)]
        lo, vs = np.array([-0.6, -0.6, -0.1]), 0.025
        vols.append(Volume(voxelize_capsules(caps, (48, 48, 80), lo, vs), lo, vs))
    res = learn_structure(vols)
    assert res.status == "no_coherent_interval"
    assert "no topologically coherent interval" in res.message
    assert res.model is not None and len(res.model.parts) >= 2     # the best partial structure
    assert not any(res.coherent)


def test_bad_input():
    with pytest.raises(InputError, match="no frame"):
        learn_structure([])
    empty = Volume(np.zeros((8, 8, 8), bool), (0, 0, 0), 1.0)
    with pytest.raises(InputError, match="000001"):
        learn_structure([Volume(np.ones((8, 8, 8), bool), (0, 0, 0), 1.0), empty])
    with pytest.raises(InputError, match="criterion"):
        seq = walker_sequence(frames=3, resolution=40)
        learn_structure(seq.volumes, criterion="magic", min_interval=3)


def test_cli_on_a_synthetic_capture(tmp_path, capsys):
    synth = pytest.importorskip("topopose.synth.capture")
    from topopose.cli import main

    cap = tmp_path / "walk"
    synth.synthesize(cap, subject="human", frames=8, motion="walk", cameras=6, size=(240, 180))
    out = tmp_path / "learned.toml"
    jl = tmp_path / "joints.jsonl"
    rc = main(["learn-model", str(cap), "--out", str(out), "--resolution", "80", "--joints", str(jl)])
    err = capsys.readouterr().err
    assert rc in (0, 1), err
    assert out.exists() and jl.exists()
    m = load_model(str(out))
    if rc == 0:
        assert nx.is_isomorphic(m.tree.to_networkx(), load_model("human").tree.to_networkx())
        assert len(load_model(str(tmp_path / "learned.joints.toml")).parts) > 7
    else:
        assert "no topologically coherent interval" in err
    assert len(jl.read_text().splitlines()) == 8
    # unusable input: exit 2 with the argument named
    rc = main(["learn-model", str(cap), "--out", str(tmp_path / "x.json")])
    assert rc == 2 and "--out" in capsys.readouterr().err
    rc = main(["learn-model", str(tmp_path / "nowhere"), "--out", str(out)])
    assert rc == 2 and "nowhere" in capsys.readouterr().err
