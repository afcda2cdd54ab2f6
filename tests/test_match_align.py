"""Alignments α, η (HA) and AHA: oracles on random tiny trees, golden cases, invariants.

Oracles (tests/match_reference.py):
* a plain memoized transcription of the propositions (Prop. 18–28, naive min over
  rootings for unrooted trees) must give exactly the same distance;
* an exhaustive search over deletion/cut/merge sets and isomorphisms is a lower bound
  (ALGORITHMS.md §7), usually equal;
* every returned alignment is re-checked: its cost recomputed from its arcs and
  deletions equals the distance, and its structure is a valid (asymmetric)
  homeomorphic alignment.
"""
import math

import numpy as np
import pytest

from match_reference import (alignment_cost, check_alignment, exhaustive_distance, gamma_sq,
                             memo_distance, random_tree, relabel)
from topopose import InputError
from topopose.match import Constraint, Matcher, Tree, align

METHODS = ["aha", "ha", "alignment"]
ROOTINGS = [(0, 0), (0, None), (None, None)]
CONFIGS = [(m, r, c) for m in METHODS for r in ROOTINGS + [(None, 0)] for c in (False, True)]


def _pair(rng):
    return (random_tree(rng, int(rng.integers(2, 6))), random_tree(rng, int(rng.integers(2, 8))))


def _check(al, P, D, method, pr, dr, gamma=None):
    rc = alignment_cost(al, P, D) if gamma is None else alignment_cost(al, P, D, gamma)
    assert rc == pytest.approx(al.distance, abs=1e-9), (al.pairs, al.deleted_pattern, al.deleted_data)
    check_alignment(al, P, D, method, pr, dr)


def test_memo_transcription_and_consistency_1080_pairs():
    """1080 random tiny pairs, 45 per (method, rooting, cut): equal to the memoized propositions.

    Rootings: rooted/rooted, rooted pattern/unrooted data, unrooted/unrooted and unrooted
    pattern/rooted data."""
    rng = np.random.default_rng(12345)
    for k in range(1080):
        P, D = _pair(rng)
        method, (pr, dr), cut = CONFIGS[k % len(CONFIGS)]
        al = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut)
        ref = memo_distance(P, D, method, pr, dr, cut)
        assert al.distance == pytest.approx(ref, abs=1e-9), (k, method, pr, dr, cut, P, D)
        _check(al, P, D, method, pr, dr)


def test_exhaustive_lower_bound_and_order_1000_pairs():
    """Exhaustive edit-style optimum <= every fast variant (mostly equal); η <= AHA <= α."""
    rng = np.random.default_rng(777)
    equal = total = 0
    for k in range(1000):
        P, D = _pair(rng)
        (pr, dr), cut = (ROOTINGS + [(None, 0)])[k % 4], bool((k // 4) % 2)
        d = {}
        for method in METHODS:
            al = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut)
            _check(al, P, D, method, pr, dr)
            d[method] = al.distance
        assert d["ha"] <= d["aha"] + 1e-9 <= d["alignment"] + 2e-9, (P, D, pr, dr, cut, d)
        method = METHODS[k % 3]
        ex = exhaustive_distance(P, D, method, pr, dr, cut)
        assert ex <= d[method] + 1e-9, (method, P, D, pr, dr, cut, ex, d[method])
        equal += abs(ex - d[method]) < 1e-9
        total += 1
    assert equal / total > 0.95


def test_squared_and_callable_gamma():
    rng = np.random.default_rng(5)
    for k in range(60):
        P, D = _pair(rng)
        method, (pr, dr), cut = CONFIGS[(7 * k) % len(CONFIGS)]
        al = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut, gamma="squared")
        assert al.distance == pytest.approx(memo_distance(P, D, method, pr, dr, cut, gamma_sq), abs=1e-9)
        _check(al, P, D, method, pr, dr, gamma_sq)
        cal = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut, gamma=lambda a, b: abs(a - b))
        ref = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut)
        assert cal.distance == pytest.approx(ref.distance, abs=1e-12)
    with pytest.raises(InputError, match="gamma"):
        align([(0, 1, 1.0)], [(0, 1, 1.0)], gamma=lambda a, b: a - b)      # not a metric
    with pytest.raises(InputError, match="gamma"):
        align([(0, 1, 1.0)], [(0, 1, 1.0)], gamma="cubic")


# ---------------------------------------------------------------------- golden cases (ALGORITHMS.md §7)
STAR = [("c", "a", 1.0), ("c", "b", 2.0), ("c", "d", 3.0), ("c", "e", 4.0)]


def _star_with_leaves():
    D = [(0, 1, 1.0), (0, 2, 2.0), (0, 3, 3.0), (0, 4, 4.0)]
    k = 5
    for leaf in (1, 2, 3, 4):
        for _ in range(4):
            D.append((leaf, k, 1.0))
            k += 1
    return D


def _star_subdivided(half=False):
    D, k = [], 5
    for leaf, w in zip((1, 2, 3, 4), (1.0, 2.0, 3.0, 4.0)):
        D += [(0, k, w / 2 if half else w - 1.0), (k, leaf, w / 2 if half else 1.0)]
        k += 1
    return D


GOLDEN_ROOTS = [("c", 0), ("c", None), (None, None), ("a", 1)]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("roots", GOLDEN_ROOTS)
def test_golden_star_with_extra_leaves(method, roots):
    pr, dr = roots
    D = _star_with_leaves()
    with_cut = align(STAR, D, method=method, pattern_root=pr, data_root=dr, cut=True)
    assert with_cut.distance == pytest.approx(0.0, abs=1e-12)
    assert len(with_cut.cut_data) == 16 and not with_cut.deleted_data
    assert with_cut.mapping == {"c": 0, "a": 1, "b": 2, "d": 3, "e": 4}
    without = align(STAR, D, method=method, pattern_root=pr, data_root=dr, cut=False)
    assert without.distance == pytest.approx(16.0)
    assert align(STAR, STAR, method=method, pattern_root=pr, data_root=pr).distance == 0.0


@pytest.mark.parametrize("roots", GOLDEN_ROOTS)
def test_golden_subdivided_star(roots):
    pr, dr = roots
    for method in ("aha", "ha"):
        al = align(STAR, _star_subdivided(), method=method, pattern_root=pr, data_root=dr)
        assert al.distance == pytest.approx(0.0, abs=1e-12)
        al = align(STAR, _star_subdivided(half=True), method=method, pattern_root=pr, data_root=dr)
        assert al.distance == pytest.approx(0.0, abs=1e-12)
        assert sorted(al.merged_data) == [5, 6, 7, 8]
        assert al.arc("c", "e") == [0, 8, 4]
        assert al.mapping == {"c": 0, "a": 1, "b": 2, "d": 3, "e": 4}
    assert align(STAR, _star_subdivided(), method="alignment", pattern_root=pr, data_root=dr).distance > 0


def test_identical_trees_distance_zero_and_identity_mapping():
    rng = np.random.default_rng(3)
    for k in range(40):
        n = int(rng.integers(2, 9))
        T = random_tree(rng, n, integer=False)      # distinct real weights: a unique optimum
        for method in METHODS:
            for pr, dr in [(0, 0), (0, None), (None, None)]:
                al = align(T, T, method=method, pattern_root=pr, data_root=dr)
                assert al.distance == pytest.approx(0.0, abs=1e-12)
                if pr is not None:
                    assert al.mapping == {v: v for v in range(n)}


def test_invariance_to_relabelling_and_child_order():
    rng = np.random.default_rng(11)
    for k in range(60):
        P, D = _pair(rng)
        method, (pr, dr), cut = CONFIGS[(5 * k) % len(CONFIGS)]
        base = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut).distance
        pp = {v: f"p{x}" for v, x in zip(range(5), rng.permutation(5))}
        dp = {v: 100 + int(x) for v, x in zip(range(7), rng.permutation(7))}
        P2, D2 = relabel(P, pp, rng), relabel(D, dp, rng)
        al = align(P2, D2, method=method, pattern_root=None if pr is None else pp[pr],
                   data_root=None if dr is None else dp[dr], cut=cut)
        assert al.distance == pytest.approx(base, abs=1e-9)
        _check(al, P2, D2, method, None if pr is None else pp[pr], None if dr is None else dp[dr])


# ---------------------------------------------------------------------- mapping, alternatives, Matcher
def test_matcher_reuse_matches_align():
    rng = np.random.default_rng(8)
    P = random_tree(rng, 5)
    m = Matcher(Tree(P, root=0), method="aha", cut=True)
    for _ in range(20):
        D = random_tree(rng, int(rng.integers(2, 8)))
        assert m.align(D).distance == pytest.approx(align(P, D, pattern_root=0, cut=True).distance)


def test_alternatives_cover_relabelled_optima():
    """Relabelling the data gives another co-optimal alignment: its mapping is an alternative."""
    rng = np.random.default_rng(21)
    for k in range(40):
        P, D = _pair(rng)
        method, (pr, dr), cut = CONFIGS[(11 * k) % len(CONFIGS)]
        al = align(P, D, method=method, pattern_root=pr, data_root=dr, cut=cut)
        alts = al.alternatives
        for v, img in al.mapping.items():
            if img is not None:
                assert alts[v][0] == img
        for _ in range(3):
            perm = {v: int(x) for v, x in zip(range(7), rng.permutation(7))}
            inv = {b: a for a, b in perm.items()}
            other = align(P, relabel(D, perm, rng), method=method, pattern_root=pr,
                          data_root=None if dr is None else perm[dr], cut=cut)
            for v, img in other.mapping.items():
                if img is not None:
                    assert inv[img] in alts[v], (P, D, method, pr, dr, cut, v, alts, other.mapping)


def test_symmetric_limbs_have_both_alternatives():
    human = Tree([("torso", "head", 0.2), ("torso", "hand_1", 0.7), ("torso", "hand_2", 0.7),
                  ("torso", "crotch", 0.5), ("crotch", "foot_1", 0.9), ("crotch", "foot_2", 0.9)],
                 root="torso")
    D = [(0, 1, 0.2), (0, 2, 0.3), (2, 3, 0.4), (0, 4, 0.7), (0, 5, 0.5), (5, 6, 0.9), (5, 7, 0.9)]
    al = align(human, D, method="aha")
    assert al.distance == pytest.approx(0.0, abs=1e-12)
    assert set(al.alternatives["hand_1"]) == {3, 4} and set(al.alternatives["hand_2"]) == {3, 4}
    assert set(al.alternatives["foot_1"]) == {6, 7}
    assert al.alternatives["head"] == [1] and al.alternatives["torso"] == [0]
    assert al.arc("torso", "hand_1") in ([0, 2, 3], [0, 4])


def test_infinite_limbs():
    """γ(inf, inf) = 0: the infinite model limb matches the infinite data limb (hand model, §12.1)."""
    hand = Tree([("arm", "palm", math.inf)] + [("palm", f, 1.0) for f in "timrl"], root="arm")
    D = [(0, 1, 0.3), (1, 2, math.inf)] + [(2, 3 + k, 1.0 + 0.1 * k) for k in range(5)] + [(3, 9, 0.1)]
    for method in METHODS:
        al = align(hand, D, method=method, data_root=0, cut=True)
        assert math.isfinite(al.distance)
        assert al.mapping["arm"] == 0
        if method != "alignment":
            assert al.mapping["palm"] == 2 and al.arc("arm", "palm") == [0, 1, 2]
    # no infinite data limb: the infinite model arc cannot be matched nor deleted
    assert align(hand, [(0, 1, 1.0), (1, 2, 1.0)], data_root=0).distance == math.inf


# ---------------------------------------------------------------------- bad input
def test_bad_input():
    good = [(0, 1, 1.0), (1, 2, 1.0)]
    with pytest.raises(InputError, match="cycle"):
        align([(0, 1, 1.0), (1, 2, 1.0), (2, 0, 1.0)], good)
    with pytest.raises(InputError, match="disconnected"):
        align(good, Tree([(0, 1, 1.0), (2, 3, 1.0)]))
    with pytest.raises(InputError, match="weight"):
        align([(0, 1, -1.0)], good)
    with pytest.raises(InputError, match="weight"):
        align(good, [(0, 1, float("nan"))])
    with pytest.raises(InputError, match="root"):
        align(good, good, pattern_root=7)
    with pytest.raises(InputError, match="root"):
        align(good, good, data_root="x")
    with pytest.raises(InputError, match="method"):
        align(good, good, method="edit")
    with pytest.raises(InputError, match="up"):
        align(good, good, up=(0, 0, 0))
    with pytest.raises(InputError, match="not a pattern edge"):
        align(Tree(good, constraints=[Constraint("above", (0, 2))]), good)
    with pytest.raises(InputError, match="position"):
        align(Tree(good, constraints=[Constraint("above", (0, 1))]), good)
    with pytest.raises(InputError, match="degree"):
        align(good, [(0, k, 1.0) for k in range(1, 17)])


def test_cli_match(tmp_path, capsys):
    from topopose.cli import main

    t = Tree([(0, 1, 0.3), (1, 2, 0.2), (2, 7, 0.5), (1, 3, 0.7), (1, 4, 0.5), (4, 5, 0.9), (4, 6, 0.9)],
             positions={0: [0, 0, 1.8], 1: [0, 0, 1.5], 2: [0.2, 0, 1.5], 7: [0.7, 0, 1.5],
                        3: [-0.7, 0, 1.5], 4: [0, 0, 1.0], 5: [0.2, 0, 0.1], 6: [-0.2, 0, 0.1]})
    p = tmp_path / "tree.json"
    t.save(p)
    assert main(["match", "human", str(p), "--method", "aha"]) == 0
    out = capsys.readouterr().out
    assert "distance" in out and "head -> 0" in out


def test_exact_ties_prefer_the_unmerged_match():
    """A spurious branch s on a leaf: deleting it and merging through the leaf both cost s with
    |w − w′|; rounding must not decide — the leaf keeps its own vertex (ties go to resize)."""
    rng = np.random.default_rng(17)
    for _ in range(50):
        w = float(rng.uniform(1, 10))
        s = float(rng.uniform(0, 0.1))
        P = Tree([(0, 1, float(rng.uniform(1, 10))), (1, 2, w), (1, 3, float(rng.uniform(1, 10)))], root=0)
        D = [(0, 1, P.edges[0][2]), (1, 2, w), (1, 3, P.edges[2][2]), (2, 9, s), (0, 8, s)]
        for method in ("aha", "ha"):
            al = align(P, D, method=method)
            assert al.distance == pytest.approx(2 * s)
            assert al.mapping == {0: 0, 1: 1, 2: 2, 3: 3}
