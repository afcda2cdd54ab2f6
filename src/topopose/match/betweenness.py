"""Betweenness relations and the betweenness post-step (thesis §12.2.2).

``betweenness(P1, P2, P3, relation)`` tells whether P3 lies between P1 and P2:

* ``"c"`` — R_c, collinearity: P3 on the segment P1P2;
* ``"p"`` — R_p, the orthogonal projection of P3 on the line (P1P2) lies between P1 and P2;
* ``"b"`` — R_b, the thesis' choice: P3 inside the ball of diameter P1P2 minus its
  sphere, i.e. the angle P1 P3 P2 is greater than π/2;
* ``"u"`` — R_u: with δ(a, b, c) = |d(a, b) − d(b, c)|, b = P3 is between a = P1 and
  c = P2 iff δ(a, b, c) ≤ δ(b, c, a) and δ(a, b, c) ≤ δ(b, a, c);
* ``"i"`` — R_i, the intuitive near-betweenness: d(a, c) > d(b, c) and d(a, c) > d(b, a),
  or d(b, c) = d(b, a) ≠ d(a, c).

Every relation is false for coincident points (postulate D); R_u and R_i are
also false for three equidistant points (postulate D').

:func:`apply_betweenness` applies a constraint ``Constraint(kind="between",
parts=(m0, ..., mn), relation=...)`` after matching: among the co-optimal
alignments it picks one whose images P_i satisfy R(P_{i-1}, P_{i+1}, P_i) for
every i in 1..n−1.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from topopose.errors import InputError
from topopose.match import align_kernels as K
from topopose.match.tree import as_tree

RELATIONS = ("c", "p", "b", "u", "i")


def _close(x, y, scale):
    return abs(x - y) <= 1e-12 * max(scale, 1e-300)


def betweenness(P1, P2, P3, relation: str = "b") -> bool:
    """True when point P3 lies between P1 and P2 for relation R_c, R_p, R_b, R_u or R_i (§12.2.2).

    Examples
    --------
    >>> betweenness((0, 0, 0), (2, 0, 0), (1, 0.5, 0), "b")
    True
    >>> betweenness((0, 0, 0), (2, 0, 0), (1, 1.5, 0), "b")
    False
    """
    rel = (relation or "b").lower()
    if rel.startswith("r_"):
        rel = rel[2:]
    if rel not in RELATIONS:
        raise InputError(f"betweenness: relation {relation!r} is unknown; expected one of {RELATIONS}")
    a = np.asarray(P1, float).reshape(3)
    c = np.asarray(P2, float).reshape(3)
    b = np.asarray(P3, float).reshape(3)
    dab = float(np.linalg.norm(a - b))
    dbc = float(np.linalg.norm(b - c))
    dac = float(np.linalg.norm(a - c))
    scale = max(dab, dbc, dac)
    if scale == 0 or _close(dab, 0, scale) or _close(dbc, 0, scale) or _close(dac, 0, scale):
        return False
    if rel == "c":
        return _close(dab + dbc, dac, scale) or dab + dbc <= dac
    if rel == "p":
        t = float(np.dot(b - a, c - a)) / (dac * dac)
        return 0.0 <= t <= 1.0
    if rel == "b":
        return float(np.dot(a - b, c - b)) < -1e-12 * scale * scale
    if _close(dab, dbc, scale) and _close(dbc, dac, scale):
        return False               # equidistant: postulate D'
    if rel == "u":
        d_abc = abs(dab - dbc)
        d_bca = abs(dbc - dac)
        d_bac = abs(dab - dac)
        return d_abc <= d_bca and d_abc <= d_bac
    # R_i
    if dac > dbc and dac > dab and not _close(dac, dbc, scale) and not _close(dac, dab, scale):
        return True
    return _close(dbc, dab, scale) and not _close(dac, dbc, scale)


def satisfies(mapping, positions, parts, relation="b") -> bool:
    """Whether the images of ``parts`` satisfy the betweenness sequence (unmapped parts are skipped)."""
    for i in range(1, len(parts) - 1):
        ims = [mapping.get(parts[i - 1]), mapping.get(parts[i + 1]), mapping.get(parts[i])]
        if any(x is None for x in ims):
            continue
        pts = []
        for x in ims:
            p = positions.get(x)
            if p is None:
                raise InputError(f"data: vertex {x!r} has no position; betweenness needs positions")
            pts.append(p)
        if not betweenness(pts[0], pts[1], pts[2], relation):
            return False
    return True


def cooptimal_alignments(alignment, parts, limit: int = 5000):
    """Co-optimal alignments that differ in the images of ``parts``: a list of event lists.

    Walks the AND–OR graph of optimal options (§12.2.2: the matching "provides
    multiple matching possibilities"); keeps one solution per distinct
    assignment of ``parts`` at each state, at most ``limit`` per state.
    """
    ctx = alignment._ctx
    ctx.full()
    m = ctx.matcher
    pidx = {m._P.index[p] for p in parts}
    memo = {}

    def solve(state):
        if state in memo:
            return memo[state]
        val = ctx.value(state)
        lim = val + m.rtol * max(1.0, abs(val)) if math.isfinite(val) else math.inf
        out = {}
        for cost, subs, evs in ctx.expand(state, lim):
            lists = [solve(s) for s in subs]
            for combo in itertools.product(*lists):
                events = tuple(evs) + tuple(e for part in combo for e in part)
                key = frozenset((a, b) for t, a, b in events if t == K.EV_MAP and a in pidx)
                if key not in out:
                    out[key] = events
                if len(out) >= limit:
                    break
            if len(out) >= limit:
                break
        memo[state] = list(out.values())
        return memo[state]

    return solve((K.ST_TOP, 0, 0, 0, 0))


def apply_betweenness(alignment, pattern, data, constraint):
    """Choose, among co-optimal alignments, one satisfying a betweenness constraint (§12.2.2).

    Parameters
    ----------
    alignment : Alignment (from :func:`topopose.align` or a Matcher)
    pattern : the pattern tree (only checked for the part names)
    data : the data tree (its ``positions`` are used)
    constraint : Constraint(kind="between", parts=(m0, ..., mn), relation="b" by default)

    Returns
    -------
    Alignment
        ``alignment`` itself when it already satisfies the constraint, else a
        co-optimal alignment that does; when none does, ``alignment`` with
        ``diagnostics["betweenness"] = "unsatisfied"``.
    """
    if getattr(constraint, "kind", None) != "between":
        raise InputError(f"apply_betweenness: constraint {constraint!r} is not of kind 'between'")
    parts = tuple(constraint.parts)
    ptree = as_tree(pattern, name="pattern")
    if len(parts) < 3 or any(p not in set(ptree.vertices) for p in parts):
        raise InputError(f"apply_betweenness: constraint parts {parts!r} must be >= 3 pattern vertices")
    rel = constraint.relation or "b"
    positions = as_tree(data, name="data").positions
    if satisfies(alignment.mapping, positions, parts, rel):
        return alignment
    if alignment._ctx is None:
        alignment.diagnostics["betweenness"] = "unsatisfied"
        return alignment
    ctx = alignment._ctx
    for events in cooptimal_alignments(alignment, parts):
        ev = np.array(events, np.int64).reshape(-1, 3)
        cand = ctx.make(ctx.top, ev)
        if satisfies(cand.mapping, positions, parts, rel):
            cand.diagnostics["betweenness"] = "applied"
            return cand
    alignment.diagnostics["betweenness"] = "unsatisfied"
    return alignment
