"""Coherent intervals (§2.2), deformation (§2.3.1), eq. 5 clustering, eq. 7–9 metrics."""
import itertools

import numpy as np
import pytest

from topopose.kinematics.deform import Deformer, two_hop_pairs
from topopose.kinematics.learn import joint_metrics
from topopose.kinematics.structure import (HUMAN_RULE, chains, coherence_rule, intervals,
                                           is_coherent, segment_chain, velocity_correlation)


def test_frequent_rule_reproduces_the_paper_human_rule():
    for common in ((3, 3, 3), (4, 3)):
        sigs = [(5, common, 0)] * 5 + [(6, (4, 3, 3), 0), (5, (5,), 0), (4, (4, 3), 1)]
        rule = coherence_rule(sigs, "frequent")
        assert rule == HUMAN_RULE
    assert coherence_rule([], "human") == HUMAN_RULE
    # a dog-like subject: 7 end points, junctions 4 (shoulders) + 4 (hips)
    rule = coherence_rule([(7, (4, 4), 0)] * 3 + [(7, (4, 3, 3), 0)], "frequent")
    assert rule[0] == 7 and (4, 4) in rule[1] and (4, 3, 3) in rule[1] and (6,) not in rule[1]
    # no loop-free frame at all
    assert coherence_rule([(5, (4, 3), 2)], "frequent") is None
    # star-like subjects: any loop-free graph with the usual number of end points
    spider = [(9, (9,), 0), (9, (5, 3, 3, 3, 3), 0), (9, (7, 3, 3), 0), (8, (8,), 0), (9, (9,), 1)]
    rule = coherence_rule(spider, "ends")
    assert [is_coherent(x, rule) for x in spider] == [True, True, True, False, False]


def test_coherence_and_intervals():
    rule = HUMAN_RULE
    sigs = [(5, (4, 3), 0), (5, (3, 3, 3), 0), (5, (4, 3), 1), (5, (5,), 0), (5, (4, 3), 0), (6, (4, 3, 3), 0)]
    flags = [is_coherent(s, rule) for s in sigs]
    assert flags == [True, True, False, False, True, False]
    assert intervals(flags) == [(0, 2), (4, 5)]
    assert intervals([]) == [] and intervals([True] * 3) == [(0, 3)]


def test_velocity_correlation_matches_eq5_written_out():
    rng = np.random.default_rng(0)
    traj = rng.normal(size=(9, 4, 3)).cumsum(0)
    R, en = velocity_correlation(traj)
    v = np.diff(traj, axis=0)
    for i, j in itertools.product(range(4), repeat=2):
        vi = v[:, i] - v[:, i].sum(0) / len(v)
        vj = v[:, j] - v[:, j].sum(0) / len(v)
        num = sum(float(a @ b) for a, b in zip(vi, vj))
        den = np.sqrt(sum(float(a @ a) for a in vi)) * np.sqrt(sum(float(b @ b) for b in vj))
        assert R[i, j] == pytest.approx(num / den)
    assert np.allclose(np.diag(R), 1)


def test_segment_chain_is_the_exhaustive_optimum():
    rng = np.random.default_rng(1)
    for trial in range(30):
        k = int(rng.integers(2, 8))
        A = rng.uniform(-1, 1, (k, k))
        R = (A + A.T) / 2
        tau = float(rng.uniform(-0.5, 0.5))

        def score(cuts):
            b = [0, *cuts, k]
            return sum((R[b[i]:b[i + 1], b[i]:b[i + 1]].sum() - np.trace(R[b[i]:b[i + 1], b[i]:b[i + 1]])) / 2
                       - tau * (b[i + 1] - b[i]) * (b[i + 1] - b[i] - 1) / 2 for i in range(len(b) - 1))

        best = max(score(list(c)) for r in range(k) for c in itertools.combinations(range(1, k), r))
        assert score(segment_chain(R, tau)) == pytest.approx(best)


def test_two_rigid_sticks_are_cut_at_their_joint():
    # a chain of 10 nodes: nodes 0-4 on a stick rotating about node 0, nodes 5-9 on a second
    # stick hinged at the end of the first with its own oscillation
    T = 20
    traj = np.zeros((T, 10, 3))
    for t in range(T):
        a = 0.4 * np.sin(2 * np.pi * t / T)
        b = 0.8 * np.sin(2 * np.pi * t / T * 1.7 + 1.0)
        d1 = np.array([np.cos(a), np.sin(a), 0])
        d2 = np.array([np.cos(a + b), np.sin(a + b), 0])
        for i in range(5):
            traj[t, i] = 0.1 * (i + 0.5) * d1
        for i in range(5):
            traj[t, 5 + i] = 0.5 * d1 + 0.1 * (i + 0.5) * d2
    R, _ = velocity_correlation(traj)
    cuts = segment_chain(R, 0.9)
    # the hinge lies between nodes 4 and 5; nodes just past it move almost like the hinge
    # (eq. 5 compares velocities), so the cut may come one or two nodes late
    assert cuts and all(5 <= c <= 7 for c in cuts)
    # one stick alone is never cut
    assert segment_chain(velocity_correlation(traj[:, :5])[0], 0.9) == []


def test_chains_of_a_tree():
    # a "T": 0-1-2-3 with 4-5 hanging on 2
    E = np.array([[0, 1], [1, 2], [2, 3], [2, 4], [4, 5]])
    ch = sorted(sorted(c) for c in chains(6, E))
    assert ch == [[0, 1, 2], [2, 3], [2, 4, 5]]
    pairs = {tuple(p) for p in two_hop_pairs(6, E)}
    assert (0, 2) in pairs and (1, 3) in pairs and (3, 4) in pairs and (0, 3) not in pairs


def test_deformer_follows_a_rigid_motion_and_keeps_lengths():
    # an "L" chain of nodes, the target is the same graph rotated and shifted
    P = np.array([[0, 0, 0]] + [[0.05 * i, 0, 0] for i in range(1, 8)] + [[0.35, 0.05 * i, 0] for i in range(1, 6)], float)
    E = np.array([[i, i + 1] for i in range(12)])
    c, s = np.cos(0.15), np.sin(0.15)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    target = P @ Rz.T + np.array([0.03, -0.02, 0.01])
    D = Deformer(P, E, sigma=(0.05, 0.01), steps=30)
    from scipy.spatial import cKDTree

    from scipy.spatial import cKDTree

    # nodes land on the target graph; like any nearest-point (ICP-like) deformation they
    # may slide along it by up to about one node spacing (0.05)
    for ends in (None, target[[0, -1]]):
        q = D.fit(P, target, target_ends=ends)
        assert cKDTree(target).query(q)[0].max() < 0.035
        assert np.abs(q - target).max() < 0.06
    # the end nodes come closer to the target's ends with the end-point force
    e0 = np.linalg.norm(D.fit(P, target)[[0, -1]] - target[[0, -1]], axis=1).sum()
    e1 = np.linalg.norm(q[[0, -1]] - target[[0, -1]], axis=1).sum()
    assert e1 < e0
    # the springs keep the node spacing (eq. 4)
    L0 = np.linalg.norm(np.diff(P, axis=0), axis=1)
    L1 = np.linalg.norm(np.diff(D.fit(P, target), axis=0), axis=1)
    assert np.abs(L1 - L0).max() < 0.015
    L2 = np.linalg.norm(np.diff(q, axis=0), axis=1)
    assert np.abs(L2 - L0).max() < 0.025


def test_joint_metrics_by_hand():
    truth = {"a": [0, 0, 0], "b": [1, 0, 0], "c": [2, 0, 0], "d": [3, 0, 0]}
    # node n0 near a; n1 between b and c but nearer c; nothing near d
    nodes = {"n0": [0.1, 0, 0], "n1": [1.6, 0, 0]}
    R, E = joint_metrics(nodes, truth, height=2.0)
    # mutual nearest pairs: (a, n0), (c, n1); b's nearest node n1 prefers c; d -> n1 prefers c
    assert R == pytest.approx(2 / 4)
    assert E == pytest.approx((0.1 + 0.6 + 0.4 + 1.4) / 4 / 2.0)
