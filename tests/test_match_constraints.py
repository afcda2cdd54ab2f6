"""Coordinate constraints inside the recurrences (§12.2.1) and betweenness (§12.2.2)."""
import math

import numpy as np
import pytest

from match_reference import alignment_cost, check_alignment, memo_distance, random_tree
from topopose import InputError
from topopose.match import Constraint, Tree, align, apply_betweenness, betweenness

UP = np.array([0.0, 0.0, 1.0])


def _resize_ok(cons, pos):
    """Oracle: a pattern chain containing a constrained edge must keep its ends' order along +z."""
    def ok(chain, ja, j):
        for kind, a, b in cons:
            for x, y in zip(chain[:-1], chain[1:]):
                if {x, y} == {a, b}:
                    hu, hl = pos[ja][2], pos[j][2]
                    want = (hu > hl) if x == a else (hl > hu)
                    if kind == "below":
                        want = (hu < hl) if x == a else (hl < hu)
                    if not want:
                        return False
        return True
    return ok


def test_coordinate_constraints_match_the_oracle():
    rng = np.random.default_rng(99)
    configs = [(m, r, c) for m in ("aha", "ha", "alignment") for r in ((0, 0), (0, None), (None, None))
               for c in (False, True)]
    for k in range(180):
        P = random_tree(rng, int(rng.integers(2, 6)))
        D = random_tree(rng, int(rng.integers(2, 8)))
        pos = {v: rng.normal(size=3) for v in range(7)}
        cons = []
        for u, v, _ in P:
            if rng.random() < 0.6:
                cons.append((("above", "below")[int(rng.integers(2))], u, v) if rng.random() < 0.5
                            else (("above", "below")[int(rng.integers(2))], v, u))
        method, (pr, dr), cut = configs[k % len(configs)]
        Pt = Tree(P, root=pr, constraints=[Constraint(kind, (a, b)) for kind, a, b in cons])
        Dt = Tree(D, positions={v: pos[v] for v in range(len(D) + 1)}, root=dr)
        al = align(Pt, Dt, method=method, cut=cut)
        ref = memo_distance(P, D, method, pr, dr, cut, resize_ok=_resize_ok(cons, pos))
        assert al.distance == pytest.approx(ref, abs=1e-9) or (al.distance == ref == math.inf)
        if math.isfinite(al.distance):
            assert alignment_cost(al, P, D) == pytest.approx(al.distance, abs=1e-9)
            check_alignment(al, P, D, method, pr, dr)
            for pc, dp in al.pairs:     # every matched chain respects its constraints
                assert _resize_ok(cons, pos)(pc, dp[0], dp[-1])


def test_head_above_torso_fixes_a_swap():
    """A short leg-like branch up and a long head-like branch down: the constraint decides (§12.2.1)."""
    P = [("torso", "head", 0.2), ("torso", "hand", 0.5), ("torso", "foot", 0.3)]
    D = Tree([(0, 1, 0.3), (0, 2, 0.5), (0, 3, 0.2)],
             positions={0: [0, 0, 1.0], 1: [0, 0, 1.3], 2: [0.5, 0, 1.0], 3: [0, 0, 0.8]})
    free = align(Tree(P, root="torso"), D)
    assert free.mapping["head"] == 3
    con = align(Tree(P, root="torso", constraints=[Constraint("above", ("head", "torso"))]), D)
    assert con.mapping["head"] == 1 and con.mapping["foot"] == 3
    assert con.distance == pytest.approx(0.2)
    # an explicit axis and the up argument
    down = align(Tree(P, root="torso", constraints=[Constraint("above", ("head", "torso"), axis="-z")]), D)
    assert down.mapping["head"] == 3
    tilted = align(Tree(P, root="torso", constraints=[Constraint("below", ("head", "torso"))]), D,
                   up=(0, 0, -1))
    assert tilted.mapping["head"] == 1


# ---------------------------------------------------------------------- betweenness relations
def test_betweenness_relations_by_definition():
    a, c = np.array([0.0, 0, 0]), np.array([2.0, 0, 0])
    assert betweenness(a, c, [1, 0, 0], "c") and not betweenness(a, c, [1, 0.1, 0], "c")
    assert betweenness(a, c, [1.5, 3, 0], "p") and not betweenness(a, c, [2.5, 0.1, 0], "p")
    assert betweenness(a, c, [1, 0.9, 0], "b") and not betweenness(a, c, [1, 1.1, 0], "b")
    assert not betweenness(a, c, [1, 1.0, 0], "b")          # on the sphere: excluded
    assert not betweenness(a, a, [1, 0, 0], "b")            # coincident points
    # R_i, condition 1 and 2; R_u
    assert betweenness(a, c, [1, 1.5, 0], "i")              # ac longest side
    assert betweenness(a, [4.0, 0, 0], [2, 5, 0], "i")      # isosceles apex
    assert not betweenness(a, c, [1, math.sqrt(3), 0], "i")  # equilateral
    assert betweenness(a, c, [1, 0.2, 0], "u")
    with pytest.raises(InputError, match="relation"):
        betweenness(a, c, [1, 0, 0], "z")


def test_betweenness_postulates_on_random_triangles():
    rng = np.random.default_rng(4)
    for _ in range(2000):
        p = rng.normal(size=(3, 3))
        for rel in "cpbui":
            # postulate A: symmetry in the two ends
            assert betweenness(p[0], p[1], p[2], rel) == betweenness(p[1], p[0], p[2], rel)
        for rel in "bui":
            # postulate C: at most one of the three points is between the two others
            n = sum(betweenness(p[i], p[j], p[k], rel) for i, j, k in ((0, 1, 2), (0, 2, 1), (1, 2, 0)))
            assert n <= 1
        for rel in "ui":
            # postulate B': at least one of them (distinct, not equidistant)
            n = sum(betweenness(p[i], p[j], p[k], rel) for i, j, k in ((0, 1, 2), (0, 2, 1), (1, 2, 0)))
            assert n == 1
        # inclusions R_c ⊂ R_b ⊂ R_p, and postulate I for R_i
        if betweenness(p[0], p[1], p[2], "b"):
            assert betweenness(p[0], p[1], p[2], "p")
        if betweenness(p[0], p[1], p[2], "i"):
            assert betweenness(p[0], p[1], p[2], "p")


def _hand(perm_x, lengths):
    """Incomplete hand data tree: fingers at x = perm_x, similar lengths."""
    pos = {0: [0.0, -1.0, 0.0], 1: [0.0, 0.0, 0.0]}
    edges = [(0, 1, math.inf)]
    for k, (x, w) in enumerate(zip(perm_x, lengths)):
        edges.append((1, 2 + k, w))
        pos[2 + k] = [float(x), 1.0, 0.0]
    return Tree(edges, positions=pos, root=0)


FINGERS = ("thumb", "index", "middle", "ring", "little")


def test_apply_betweenness_orders_similar_fingers():
    model = Tree([("arm", "palm", math.inf)] + [("palm", f, 1.0) for f in FINGERS], root="arm")
    between = Constraint("between", FINGERS, relation="b")
    rng = np.random.default_rng(0)
    for trial in range(12):
        xs = rng.permutation(5).astype(float)
        D = _hand(xs, 1.0 + 0.05 * rng.random(5))
        al = align(model, D, method="aha")
        fixed = apply_betweenness(al, model, D, between)
        assert fixed.distance == pytest.approx(al.distance)
        got = [D.positions[fixed.mapping[f]][0] for f in FINGERS]
        assert got == sorted(got) or got == sorted(got, reverse=True)
        # the model's own constraint does the same inside align()
        m2 = Tree(model.edges, root="arm", constraints=[between])
        auto = align(m2, D, method="aha")
        got2 = [D.positions[auto.mapping[f]][0] for f in FINGERS]
        assert got2 == sorted(got2) or got2 == sorted(got2, reverse=True)
        # every finger's alternatives are the five fingertips
        assert all(set(al.alternatives[f]) == {2, 3, 4, 5, 6} for f in FINGERS)


def test_apply_betweenness_keeps_a_satisfied_alignment_and_reports_failure():
    model = Tree([("arm", "palm", math.inf)] + [("palm", f, 1.0) for f in FINGERS[:3]], root="arm")
    D = _hand([0, 1, 2], [1.0, 1.0, 1.0])
    al = align(model, D)
    c = Constraint("between", FINGERS[:3])
    out = apply_betweenness(al, model, D, c)
    got = [D.positions[out.mapping[f]][0] for f in FINGERS[:3]]
    assert got in ([0, 1, 2], [2, 1, 0])
    # fingers of different lengths: only one co-optimal assignment, which may not satisfy it
    D2 = Tree([(0, 1, math.inf), (1, 2, 1.0), (1, 3, 2.0), (1, 4, 3.0)],
              positions={0: [0, -1, 0], 1: [0, 0, 0], 2: [0, 1, 0], 3: [1, 1, 0], 4: [2, 1, 0]}, root=0)
    model2 = Tree([("arm", "palm", math.inf), ("palm", "a", 1.0), ("palm", "b", 3.0), ("palm", "c", 2.0)],
                  root="arm")
    res = apply_betweenness(align(model2, D2), model2, D2, Constraint("between", ("a", "b", "c")))
    assert res.diagnostics.get("betweenness") == "unsatisfied"
    with pytest.raises(InputError):
        apply_betweenness(al, model, D, Constraint("above", ("arm", "palm")))


def test_permutations_of_identical_limbs_are_all_alternatives():
    """Four identical limbs: each maps to every data limb in some co-optimal alignment (§12.2.2)."""
    P = Tree([("c", f"l{k}", 1.0) for k in range(4)], root="c")
    D = [(0, k, 1.0 + 0.01 * k) for k in range(1, 5)]
    al = align(P, D)
    for k in range(4):
        assert set(al.alternatives[f"l{k}"]) == {1, 2, 3, 4}


def test_human_feet_below_the_crotch():
    """The human model's feet-below-crotch constraints (models/human.toml): a subject on one leg,
    the other leg not seen, an arm out and raised as long as a leg. Without the constraints the
    cheapest alignment hangs the missing foot on the raised arm's end (above the crotch); with
    them no foot's image lies above the crotch's image."""
    from topopose.pose import load_model

    # data: torso junction T (1.3 m), head, one hand down, a long raised arm (leg-long), the
    # crotch C (0.9 m) with one leg to the floor
    pos = {"T": [0, 0, 1.3], "H": [0, 0, 1.6], "h1": [0.1, 0.3, 0.7], "arm": [-0.9, 0.0, 1.55],
           "C": [0, 0, 0.9], "f1": [0, 0.1, 0.05]}
    edges = [("T", "H", 0.3), ("T", "h1", 0.7), ("T", "arm", 0.95), ("T", "C", 0.4),
             ("C", "f1", 0.9)]
    D = Tree(edges, positions={k: np.array(v, float) for k, v in pos.items()})
    with_c, without = load_model("human"), load_model("human", constraints=False)
    feet = ("foot_1", "foot_2")
    al0 = align(without.tree, D, method="aha", up=UP)
    al1 = align(with_c.tree, D, method="aha", up=UP)
    assert any(al0.mapping.get(f) == "arm" for f in feet)          # the failure the rule fixes
    c = al1.mapping.get("crotch")
    for f in feet:
        v = al1.mapping.get(f)
        if v is not None and c is not None:
            assert pos[v][2] < pos[c][2]
    assert not any(al1.mapping.get(f) == "arm" for f in feet)


def test_constrained_junction_arc_is_never_contracted():
    """KEEP_CONSTRAINED_JUNCTIONS: a human-like pattern (trunk torso above crotch, 0.3) on a data
    star of four limbs from one junction (two up of 1.0, two down of 0.7). Contracting the trunk
    costs 0.3 and the four limbs 4 × 0.3 (hands 0.7 on the 1.0 branches, feet 1.0 on the 0.7
    ones, the feet below): 1.5. Kept, the trunk needs a data path of its own: torso on the
    junction, crotch on a down leaf (|0.3 − 0.7|), hands 0.6, both feet deleted (2.0) and the
    other down branch (0.7): 3.7 — and the leaf-torso alternative ties (hands deleted 1.4, trunk
    |0.3 − 1.0|, feet 0.6, an up branch 1.0)."""
    from topopose.match import Matcher
    from topopose.match.tree import Constraint, Tree

    P = Tree([("torso", "hand_1", 0.7), ("torso", "hand_2", 0.7), ("torso", "crotch", 0.3),
              ("crotch", "foot_1", 1.0), ("crotch", "foot_2", 1.0)], root="torso",
             constraints=[Constraint("above", ("torso", "crotch")),
                          Constraint("above", ("crotch", "foot_1")),
                          Constraint("above", ("crotch", "foot_2"))])
    D = Tree([("c", "u1", 1.0), ("c", "u2", 1.0), ("c", "d1", 0.7), ("c", "d2", 0.7)],
             positions={"c": (0, 0, 1), "u1": (-0.5, 0, 1.9), "u2": (0.5, 0, 1.9),
                        "d1": (-0.2, 0, 0.3), "d2": (0.2, 0, 0.3)})
    off = Matcher(P, "aha", keep_junctions=False).align(D)
    assert off.distance == pytest.approx(1.5)
    assert off.mapping["torso"] == off.mapping["crotch"] == "c"
    assert {off.mapping["foot_1"], off.mapping["foot_2"]} == {"d1", "d2"}
    on = Matcher(P, "aha", keep_junctions=True).align(D)
    assert on.distance == pytest.approx(3.7)
    assert on.mapping["torso"] != on.mapping["crotch"]
    assert ("torso", "crotch") not in on.deleted_pattern
    # the thesis' AHA stays the Matcher's default; an unconstrained trunk stays contractible
    assert Matcher(P, "aha").align(D).distance == pytest.approx(1.5)
    free = Tree(P.edges, root="torso", constraints=P.constraints[1:])
    assert Matcher(free, "aha", keep_junctions=True).align(D).distance == pytest.approx(1.5)
    # a single data vertex cannot keep the trunk (every alignment infinite): the thesis'
    # alignment then, flagged (every pattern arc deleted: 0.7 + 0.7 + 0.3 + 1 + 1)
    one = Tree([], vertices=["c"], positions={"c": (0, 0, 1)})
    assert math.isinf(Matcher(P, "aha", keep_junctions=True)._P.delarc.max())
    al = Matcher(P, "aha", keep_junctions=True).align(one)
    assert al.distance == pytest.approx(3.7) and al.diagnostics.get("junctions_contracted")
    assert "junctions_contracted" not in on.diagnostics
