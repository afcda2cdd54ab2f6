"""The subject's own lengths (two-pass matching) on synthetic data trees."""
import numpy as np
import pytest

from topopose.match import Matcher, Tree
from topopose.pose import load_model
from topopose.sequence.subject import edge_lengths, subject_model


def _body_tree(rng, lengths):
    """A data tree shaped like a human with the given edge lengths (± 5 %), positions for the
    coordinate constraints (z up)."""
    L = {k: v * rng.uniform(0.95, 1.05) for k, v in lengths.items()}
    pos = {0: [0, 0, 1.4], 1: [0, 0, 1.4 + L["head"]], 2: [-L["hand"], 0, 1.4],
           3: [L["hand"], 0, 1.4], 4: [0, 0, 1.4 - L["crotch"]],
           5: [-0.1, 0, 1.4 - L["crotch"] - L["foot"]], 6: [0.1, 0, 1.4 - L["crotch"] - L["foot"]]}
    edges = [(0, 1, L["head"]), (0, 2, L["hand"]), (0, 3, L["hand"]), (0, 4, L["crotch"]),
             (4, 5, L["foot"]), (4, 6, L["foot"])]
    return Tree(edges, positions={k: np.array(v, float) for k, v in pos.items()}).normalized()


def test_learned_lengths_are_the_subject_medians():
    """Frames of a subject whose neck+head is much shorter than the model's: the learned model
    carries the subject's ratios (the oracle: the lengths the trees were built with)."""
    model = load_model("human")
    true = {"head": 0.12, "hand": 0.7, "crotch": 0.45, "foot": 1.0}
    rng = np.random.default_rng(0)
    mt = Matcher(model.pattern(), "aha", up=(0, 0, 1))
    samples = []
    for _ in range(9):
        d = _body_tree(rng, true)
        al = mt.align(d)
        samples.append(edge_lengths(model, al, d))
    learned = subject_model(model, samples, min_frames=5)
    w = {tuple(sorted((u, v))): x for u, v, x in learned.tree.edges}
    ratio = w[("foot_1", "crotch") if ("foot_1", "crotch") in w else ("crotch", "foot_1")]
    assert w[("head", "torso")] / ratio == pytest.approx(0.12, rel=0.05)
    assert w[("hand_1", "torso")] / ratio == pytest.approx(0.7, rel=0.05)
    assert w[("hand_2", "torso")] == w[("hand_1", "torso")]          # pooled
    assert w[("crotch", "torso")] / ratio == pytest.approx(0.45, rel=0.05)
    # total kept (only ratios matter)
    assert sum(x for *_, x in learned.tree.edges) == pytest.approx(
        sum(x for *_, x in model.tree.edges))
    assert subject_model(model, samples[:4], min_frames=5) is None

