"""Reference implementations of the tree alignments, for the tests only.

* :func:`memo_distance` — a plain memoized-recursion transcription of the
  propositions as the thesis writes them (Prop. 18–24 for η, 25–28 for AHA, the
  same forest recurrence without merging for α), on frozensets, with the naive
  min over every rooted version for unrooted trees (§9.4.1, Prop. 22–23).
* :func:`exhaustive_distance` — an exhaustive search over deletion sets, cut
  sets, merge sets and isomorphisms (the edit-style definitions of §8.8, §9.2,
  §10.2, §9.6): a lower bound of every alignment recurrence (ALGORITHMS.md §7).
* :func:`alignment_cost` / :func:`check_alignment` — recompute the cost of a
  returned alignment from its arcs and deletions and check that it is a valid
  (asymmetric) homeomorphic alignment.

Trees here are (edges, root) with edges [(u, v, w), ...].
"""
from __future__ import annotations

import itertools
import math
import sys
from functools import lru_cache

import numpy as np

sys.setrecursionlimit(10000)


def gamma_abs(x, y):
    if math.isinf(x) and math.isinf(y):
        return 0.0
    if math.isinf(x) or math.isinf(y):
        return math.inf
    return abs(x - y)


def gamma_sq(x, y):
    g = gamma_abs(x, y)
    return g * g


def _adj(edges):
    adj = {}
    for u, v, w in edges:
        adj.setdefault(u, {})[v] = w
        adj.setdefault(v, {})[u] = w
    return adj


def _rooting(adj, root):
    par = {root: None}
    order = [root]
    for x in order:
        for y in adj[x]:
            if y not in par:
                par[y] = x
                order.append(y)
    ch = {v: tuple(y for y in adj[v] if y != par[v]) for v in par}
    return par, ch


# ---------------------------------------------------------------------------- memoized transcription
def _memo(P_edges, D_edges, method="aha", cut=False, gamma=gamma_abs, resize_ok=None, P_single=None,
          D_single=None):
    """The memoized recurrences; returns top(rP, rD) = η(P^rP, D^rD).

    Pruned trees are keyed by their (upper vertex, vertex) and forests by
    (vertex, set of child vertices): these do not depend on where the tree is
    rooted, so one memo serves every rooted version (Prop. 22 then takes the min).
    """
    Pa, Da = _adj(P_edges), _adj(D_edges)
    if not Pa:
        Pa = {P_single: {}}
    if not Da:
        Da = {D_single: {}}

    def hop(adj, x, y):            # next vertex from x towards y
        if y in adj[x]:
            return y
        par = {y: None}
        order = [y]
        for u in order:
            for v in adj[u]:
                if v not in par:
                    par[v] = u
                    order.append(v)
        return par[x]

    def chain(adj, a, v):          # vertices from a down to v
        out = [a]
        while out[-1] != v:
            out.append(hop(adj, out[-1], v))
        return out

    def wpath(adj, a, v):
        c = chain(adj, a, v)
        return sum(adj[x][y] for x, y in zip(c[:-1], c[1:]))

    def kids(adj, v, up):          # children of v when its parent side is towards `up`
        p = hop(adj, v, up) if up is not None else None
        return frozenset(y for y in adj[v] if y != p)

    mergeP = method == "ha"
    mergeD = method in ("ha", "aha")

    @lru_cache(maxsize=None)
    def delP_tree(i, ia):
        return delP_forest(i, kids(Pa, i, ia)) + gamma(wpath(Pa, ia, i), 0.0)

    @lru_cache(maxsize=None)
    def delP_forest(i, A):
        return sum(delP_tree(c, i) for c in A)

    @lru_cache(maxsize=None)
    def delD_tree(j, ja):
        if cut:
            return 0.0
        return delD_forest(j, kids(Da, j, ja)) + gamma(0.0, wpath(Da, ja, j))

    @lru_cache(maxsize=None)
    def delD_forest(j, B):
        if cut:
            return 0.0
        return sum(delD_tree(c, j) for c in B)

    def resize(ia, i, ja, j):
        if resize_ok is not None and not resize_ok(chain(Pa, ia, i), ja, j):
            return math.inf
        return gamma(wpath(Pa, ia, i), wpath(Da, ja, j))

    @lru_cache(maxsize=None)
    def tree(i, ia, j, ja):                                   # Prop. 20 / 27
        CI, CJ = kids(Pa, i, ia), kids(Da, j, ja)
        best = delP_tree(i, ia) + delD_tree(j, ja)            # line 1
        best = min(best, resize(ia, i, ja, j) + forest(i, CI, j, CJ))   # line 2
        for jc in CJ:                                         # line 3
            if mergeD:
                v = tree(i, ia, jc, ja) + delD_forest(j, CJ - {jc})
            else:   # α: the data arc is deleted, one subtree kept
                v = gamma(0.0, Da[ja][j]) + tree(i, ia, jc, j) + delD_forest(j, CJ - {jc})
            best = min(best, v)
        for ic in CI:                                         # line 4
            if mergeP:
                v = tree(ic, ia, j, ja) + delP_forest(i, CI - {ic})
            else:   # AHA (and α): the pattern arc is deleted, one subtree kept
                v = gamma(Pa[ia][i], 0.0) + tree(ic, i, j, ja) + delP_forest(i, CI - {ic})
            best = min(best, v)
        return best

    def subsets(S):
        S = list(S)
        for r in range(len(S) + 1):
            for c in itertools.combinations(S, r):
                yield frozenset(c)

    @lru_cache(maxsize=None)
    def forest(i, A, j, B):                                   # Prop. 21 / 28, literally
        if not A and not B:
            return 0.0
        best = math.inf
        for b in B:                                           # line 1
            best = min(best, forest(i, A, j, B - {b}) + delD_tree(b, j))
        for a in A:                                           # line 2
            best = min(best, forest(i, A - {a}, j, B) + delP_tree(a, i))
        for a in A:                                           # line 3
            for b in B:
                best = min(best, forest(i, A - {a}, j, B - {b}) + tree(a, i, b, j))
        for a in A:                                           # line 4
            Ka = kids(Pa, a, i)
            for Bp in subsets(B):
                best = min(best, forest(i, A - {a}, j, B - Bp) + forest(a, Ka, j, Bp) + gamma(Pa[i][a], 0.0))
        for b in B:                                           # line 5
            Kb = kids(Da, b, j)
            for Ap in subsets(A):
                best = min(best, forest(i, A - Ap, j, B - {b}) + forest(i, Ap, b, Kb) + gamma(0.0, Da[j][b]))
        return best

    def top(rP, rD):                                          # Prop. 18 / 25 (and 24 with cut)
        return forest(rP, kids(Pa, rP, None), rD, kids(Da, rD, None))

    return top


def memo_rooted(P_edges, rP, D_edges, rD, method="aha", cut=False, gamma=gamma_abs, resize_ok=None):
    """η / η⃗ / α of two rooted trees, literally by Prop. 18–21 / 24 / 25–28."""
    return _memo(P_edges, D_edges, method, cut, gamma, resize_ok, rP, rD)(rP, rD)


def _vertices(edges, root):
    vs = []
    for u, v, _ in edges:
        for x in (u, v):
            if x not in vs:
                vs.append(x)
    if not vs:
        vs = [root]
    return vs


def memo_distance(P_edges, D_edges, method="aha", pattern_root=None, data_root=None, cut=False,
                  gamma=gamma_abs, resize_ok=None):
    """Prop. 22 / 23: the min over every rooted version of the unrooted trees (§9.4.1)."""
    pr = [pattern_root] if pattern_root is not None else _vertices(P_edges, pattern_root)
    dr = [data_root] if data_root is not None else _vertices(D_edges, data_root)
    top = _memo(P_edges, D_edges, method, cut, gamma, resize_ok, pr[0], dr[0])
    return min(top(a, b) for a in pr for b in dr)


# ---------------------------------------------------------------------------- exhaustive search
def _contract(vertices, edges, dele):
    """Contract the edges whose index is in ``dele``; return (group of each vertex, new edges)."""
    g = {v: v for v in vertices}

    def find(x):
        while g[x] != x:
            x = g[x]
        return x

    for k in dele:
        u, v, _ = edges[k]
        g[find(u)] = find(v)
    new = [(find(u), find(v), w) for k, (u, v, w) in enumerate(edges) if k not in dele]
    return {v: find(v) for v in vertices}, new


def _merge(vertices, edges, merged):
    """Merge on each vertex of ``merged`` (each must have degree 2)."""
    es = list(edges)
    vs = [v for v in vertices if v not in merged]
    for m in merged:
        inc = [e for e in es if m in (e[0], e[1])]
        if len(inc) != 2:
            return None
        (a1, b1, w1), (a2, b2, w2) = inc
        x = a1 if b1 == m else b1
        y = a2 if b2 == m else b2
        es = [e for e in es if e not in inc] + [(x, y, w1 + w2)]
    return vs, es


def _deg(vertices, edges):
    d = {v: 0 for v in vertices}
    for u, v, _ in edges:
        d[u] += 1
        d[v] += 1
    return d


def _canon(adj, v, parent):
    return "(" + "".join(sorted(_canon(adj, c, v) for c in adj[v] if c != parent)) + ")"


def _iso_cost(Pv, Pe, Dv, De, pr, dr, gamma):
    """Min over isomorphisms of the summed resize costs (rooted at pr/dr, or not when None)."""
    if len(Pv) != len(Dv):
        return math.inf
    Pa, Da = _adj(Pe), _adj(De)
    for v in Pv:
        Pa.setdefault(v, {})
    for v in Dv:
        Da.setdefault(v, {})

    @lru_cache(maxsize=None)
    def canP(u, pu):
        return _canon(Pa, u, pu)

    @lru_cache(maxsize=None)
    def canD(x, px):
        return _canon(Da, x, px)

    @lru_cache(maxsize=None)
    def cost(u, pu, x, px):
        cu = [c for c in Pa[u] if c != pu]
        cx = [c for c in Da[x] if c != px]
        if len(cu) != len(cx):
            return math.inf
        best = math.inf
        for perm in itertools.permutations(cx):
            s = 0.0
            for c, c2 in zip(cu, perm):
                if canP(c, u) != canD(c2, x):
                    s = math.inf
                    break
                s += gamma(Pa[u][c], Da[x][c2]) + cost(c, u, c2, x)
                if s >= best:
                    break
            best = min(best, s)
        return best

    if pr is not None:
        rootsP = [pr]
    else:
        rootsP = [Pv[0]]
    rootsD = [dr] if dr is not None else list(Dv)
    best = math.inf
    for a in rootsP:
        for b in rootsD:
            if canP(a, None) == canD(b, None):
                best = min(best, cost(a, None, b, None))
    return best


def _variants(vertices, edges, root, merge, cut, deleted_cost):
    """Every (vertices, edges, root, cost) reachable by cut, deletions and mergings."""
    out = {}
    n = len(vertices)
    adj = _adj(edges)
    for v in vertices:
        adj.setdefault(v, {})
    if cut:
        kept_sets = []
        vs = list(vertices)
        for r in range(1, n + 1):
            for S in itertools.combinations(vs, r):
                S = set(S)
                if root is not None and root not in S:
                    continue
                # connected?
                start = next(iter(S))
                seen = {start}
                st = [start]
                while st:
                    x = st.pop()
                    for y in adj[x]:
                        if y in S and y not in seen:
                            seen.add(y)
                            st.append(y)
                if seen == S:
                    kept_sets.append(S)
    else:
        kept_sets = [set(vertices)]
    for S in kept_sets:
        sub = [e for e in edges if e[0] in S and e[1] in S]
        sv = [v for v in vertices if v in S]
        m = len(sub)
        for r in range(m + 1):
            for dele in itertools.combinations(range(m), r):
                dcost = sum(deleted_cost(sub[k][2]) for k in dele)
                grp, ce = _contract(sv, sub, set(dele))
                cv = sorted(set(grp.values()), key=str)
                croot = grp[root] if root is not None else None
                if merge:
                    deg = _deg(cv, ce)
                    cand = [v for v in cv if deg[v] == 2 and v != croot]
                    msets = [c for rr in range(len(cand) + 1) for c in itertools.combinations(cand, rr)]
                else:
                    msets = [()]
                for ms in msets:
                    res = _merge(cv, ce, set(ms))
                    if res is None:
                        continue
                    mv, me = res
                    key = (tuple(sorted(map(str, mv))), tuple(sorted((str(min(a, b, key=str)),
                                                                      str(max(a, b, key=str)), w)
                                                                     for a, b, w in me)), str(croot))
                    if key not in out or out[key][3] > dcost:
                        out[key] = (mv, me, croot, dcost)
    return list(out.values())


def exhaustive_distance(P_edges, D_edges, method="aha", pattern_root=None, data_root=None, cut=False,
                        gamma=gamma_abs):
    """Edit-style optimum: deletion sets × cut sets × merge sets × isomorphisms (a lower bound)."""
    Pv = _vertices(P_edges, pattern_root)
    Dv = _vertices(D_edges, data_root)
    Pvar = _variants(Pv, P_edges, pattern_root, method == "ha", False, lambda w: gamma(w, 0.0))
    Dvar = _variants(Dv, D_edges, data_root, method in ("ha", "aha"), cut, lambda w: gamma(0.0, w))
    best = sum(gamma(w, 0.0) for _, _, w in P_edges) + (0.0 if cut else sum(gamma(0.0, w) for _, _, w in D_edges))

    def shape(vs, es):
        a = _adj(es)
        for v in vs:
            a.setdefault(v, {})
        return sorted(_canon(a, v, None) for v in vs)

    Dshapes = [(shape(v, e), (v, e, r, c)) for v, e, r, c in Dvar]
    for pv, pe, pr, pc in Pvar:
        ps = shape(pv, pe)
        for ds, (dv, de, dr, dc) in Dshapes:
            if pc + dc >= best or len(dv) != len(pv) or ds != ps:
                continue
            if pr is None and dr is not None:
                c = _iso_cost(dv, de, pv, pe, dr, None, gamma)   # symmetric γ: swap roles
            else:
                # rooted pattern with unrooted data: the root maps to any unmerged data vertex
                c = _iso_cost(pv, pe, dv, de, pr, dr, gamma)
            best = min(best, pc + dc + c)
    return best


# ---------------------------------------------------------------------------- checking a result
def alignment_cost(al, P_edges, D_edges, gamma=gamma_abs):
    """Cost recomputed from the returned arcs and deletions (cuts are free)."""
    Pw = {frozenset((u, v)): w for u, v, w in P_edges}
    Dw = {frozenset((u, v)): w for u, v, w in D_edges}
    c = 0.0
    for pc, dp in al.pairs:
        wp = sum(Pw[frozenset(e)] for e in zip(pc[:-1], pc[1:]))
        wd = sum(Dw[frozenset(e)] for e in zip(dp[:-1], dp[1:]))
        c += gamma(wp, wd)
    c += sum(gamma(Pw[frozenset(e)], 0.0) for e in al.deleted_pattern)
    c += sum(gamma(0.0, Dw[frozenset(e)]) for e in al.deleted_data)
    return c


def check_alignment(al, P_edges, D_edges, method, pattern_root=None, data_root=None):
    """Structural validity of a returned alignment; raises AssertionError."""
    Pset = [frozenset((u, v)) for u, v, _ in P_edges]
    Dset = [frozenset((u, v)) for u, v, _ in D_edges]
    used_p = [frozenset(e) for pc, _ in al.pairs for e in zip(pc[:-1], pc[1:])]
    used_p += [frozenset(e) for e in al.deleted_pattern]
    assert sorted(map(sorted, map(list, used_p)), key=str) == sorted(map(sorted, map(list, Pset)), key=str), \
        "every pattern edge is matched or deleted exactly once"
    used_d = [frozenset(e) for _, dp in al.pairs for e in zip(dp[:-1], dp[1:])]
    used_d += [frozenset(e) for e in al.deleted_data] + [frozenset(e) for e in al.cut_data]
    assert sorted(map(sorted, map(list, used_d)), key=str) == sorted(map(sorted, map(list, Dset)), key=str), \
        "every data edge is matched, deleted or cut exactly once"
    if method != "ha":
        assert all(len(pc) == 2 for pc, _ in al.pairs), "no merging on the pattern side"
    if method == "alignment":
        assert all(len(dp) == 2 for _, dp in al.pairs), "no merging for α"
    # contract the deleted edges, drop the cut ones: the matched pairs must then form an isomorphism
    Pv = _vertices(P_edges, pattern_root)
    Dv = _vertices(D_edges, data_root)

    def groups(vs, dels):
        g = {v: v for v in vs}

        def find(x):
            while g[x] != x:
                x = g[x]
            return x

        for u, v in dels:
            g[find(u)] = find(v)
        return find

    fP = groups(Pv, al.deleted_pattern)
    fD = groups(Dv, al.deleted_data)
    vmap = {}
    for pc, dp in al.pairs:
        for a, b in ((pc[0], dp[0]), (pc[-1], dp[-1])):
            ga, gb = fP(a), fD(b)
            assert vmap.setdefault(ga, gb) == gb, "a pattern vertex maps to two data vertices"
    assert len(set(vmap.values())) == len(vmap), "two pattern vertices map to one data vertex"
    # the interior of chains must be of degree 2 once deletions/cuts are applied
    if al.pairs:
        Dkeep = [e for e in D_edges if frozenset((e[0], e[1])) not in
                 {frozenset(x) for x in al.deleted_data + al.cut_data}]
        degD = {}
        for u, v, _ in Dkeep:
            degD[fD(u)] = degD.get(fD(u), 0) + 1
            degD[fD(v)] = degD.get(fD(v), 0) + 1
        for _, dp in al.pairs:
            for x in dp[1:-1]:
                assert degD.get(fD(x)) == 2, "merged data vertex of degree != 2"
        Pkeep = [e for e in P_edges if frozenset((e[0], e[1])) not in
                 {frozenset(x) for x in al.deleted_pattern}]
        degP = {}
        for u, v, _ in Pkeep:
            degP[fP(u)] = degP.get(fP(u), 0) + 1
            degP[fP(v)] = degP.get(fP(v), 0) + 1
        for pc, _ in al.pairs:
            for x in pc[1:-1]:
                assert degP.get(fP(x)) == 2, "merged pattern vertex of degree != 2"
    if pattern_root is not None and data_root is not None and al.pairs:
        assert vmap.get(fP(pattern_root), fD(data_root)) == fD(data_root), "roots must match"
    # mapping consistency: every mapped pattern vertex of a matched chain end maps into its image group
    for pc, dp in al.pairs:
        for a, b in ((pc[0], dp[0]), (pc[-1], dp[-1])):
            m = al.mapping[a]
            assert m is not None and fD(m) == fD(b), "mapping disagrees with the matched arcs"


# ---------------------------------------------------------------------------- random trees
def random_tree(rng, n, wmax=4, integer=True, max_deg=None):
    """Random labelled tree with n vertices (ids 0..n-1) and small integer (or real) weights."""
    edges = []
    deg = [0] * n
    for v in range(1, n):
        cand = [u for u in range(v) if max_deg is None or deg[u] < max_deg]
        u = int(rng.choice(cand))
        w = float(rng.integers(0, wmax + 1)) if integer else float(rng.random() * wmax)
        edges.append((u, v, w))
        deg[u] += 1
        deg[v] += 1
    return edges


def relabel(edges, perm, shuffle_rng=None):
    out = [(perm[u], perm[v], w) if (shuffle_rng is None or shuffle_rng.random() < 0.5)
           else (perm[v], perm[u], w) for u, v, w in edges]
    if shuffle_rng is not None:
        idx = shuffle_rng.permutation(len(out))
        out = [out[i] for i in idx]
    return out


def as_np(x):
    return np.asarray(x, dtype=float)
