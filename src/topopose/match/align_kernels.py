"""Numba kernels of the tree alignments α, η (HA) and η⃗ (AHA) (thesis ch. 8–10).

Everything is iterated bottom-up over arrays; subsets of children are bitmasks.

Trees are described by *nodes*. A node is a vertex ``v`` seen with a parent
neighbour ``u`` (its children are then the other neighbours) or with no parent
(a root node, all neighbours are children):

* a rooted tree has one node per vertex (thesis §9.3);
* an unrooted tree has one node per directed edge plus one root node per vertex
  — the "adapted order of navigation" of Alg. 15, which lets every rooted
  version of the tree share its sub-results (Alg. 16–17, §10.4).

Nodes are numbered children first. An *item* is an arc, possibly a merged
chain, from an upper vertex ``a`` down to the vertex of a node: the pruned tree
``T(v, a)`` of §9.3.1. With merging, every ancestor (rooted) or every vertex on
the parent side (unrooted) is an upper vertex; without it, only the parent.

Tables (all float64):

* ``F[poff[p] + A, doff[d] + B]`` = alignment cost of the forest A ⊆ F(P, p)
  with the forest B ⊆ F(D, d) (Prop. 21 / 28);
* ``T[pi, di]`` = cost of the pruned trees of pattern item ``pi`` and data item
  ``di`` (Prop. 20 / 27).

``mode``: 0 = α (§8.8), 1 = η (Prop. 18–24), 2 = η⃗ / AHA (Prop. 25–28).

The kernels take each tree as one bundle of arrays, :class:`TreeArrays` (``p`` the pattern,
``d`` the data), the tables as one :class:`Tables` and the constraints as one
:class:`Constraints`. The bundles cross a kernel's boundary as plain tuples in the named
tuple's field order (Numba types a plain tuple on its dispatcher's fast path, a named tuple
on a slow one that costs microseconds per call), and each kernel names the fields at its top
(``P = TreeArrays(*p)``, free at run time).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from topopose.match.struct_kernels import _tz, build_struct, deletion_costs  # noqa: F401

ALPHA, ETA, AHA = 0, 1, 2

# event codes of a traceback (see align.py)
EV_MATCH, EV_PDEL, EV_DDEL, EV_PDELF, EV_DDELF, EV_PARC, EV_DARC, EV_MAP = range(8)
# state kinds
ST_F, ST_T, ST_TOP = 0, 1, 2


class TreeArrays(NamedTuple):
    """A tree in kernel form (:func:`build_struct`) with its deletion costs (:func:`deletion_costs`)."""

    node_v: np.ndarray      # vertex of each node
    ch_ptr: np.ndarray      # children of node k: ch_idx[ch_ptr[k]:ch_ptr[k + 1]]
    ch_idx: np.ndarray
    soff: np.ndarray        # row (column) of node k's forests in F: soff[k] + subset
    it_ptr: np.ndarray      # items of node k: it_ptr[k]:it_ptr[k + 1]
    it_node: np.ndarray     # node of each item
    it_up: np.ndarray       # upper vertex of each item
    it_w: np.ndarray        # weight (length) of each item
    item_of: np.ndarray     # item_of[k, a]: the item of node k with upper vertex a, or -1
    base: np.ndarray        # the item of node k with its parent as upper vertex
    delarc: np.ndarray      # cost of deleting each item's arc
    delsub: np.ndarray      # ... each item's pruned tree
    delfor: np.ndarray      # ... each forest soff[k] + subset
    roots: np.ndarray       # the root nodes


class Tables(NamedTuple):
    """The resize costs R and the tables F, T of :func:`forward`."""

    R: np.ndarray
    F: np.ndarray
    T: np.ndarray


class Constraints(NamedTuple):
    """Coordinate constraints (§12.2.1): constraint k covers the pattern items
    ``items[ptr[k]:ptr[k + 1]]`` with ``signs`` (+1: the image of the chain's upper end must be
    higher along ``up[k]``)."""

    ptr: np.ndarray
    items: np.ndarray
    signs: np.ndarray
    up: np.ndarray


@njit(cache=True)
def tree_arrays(st, delarc, delsub, delfor):
    """:class:`TreeArrays` (as a plain tuple) of a :func:`build_struct` result and the deletion costs."""
    (node_v, _, ch_ptr, ch_idx, soff, it_ptr, it_node, it_up, it_w, item_of, base, roots, _) = st
    return (node_v, ch_ptr, ch_idx, soff, it_ptr, it_node, it_up, it_w, item_of, base,
            delarc, delsub, delfor, roots)


@njit(cache=True)
def forward(mode, p, d, R, tie):
    """Fill the forest table F and the pruned-tree table T bottom-up (Alg. 14, 16, 17, 18).

    Also returns the decision tables FD, TD (the cheapest option of every cell,
    matches preferred on ties) that :func:`traceback` follows. Codes:
    F: 0 = A empty, 1 = a deleted, 2 = a aligned with child b (bit s),
    3 = b's arc deleted and A' = sub | a aligned with F(D, b), 4 = a's arc deleted
    and F(P, a) aligned with B' = sub; code = opt | s << 4 | sub << 8.
    T: 1 = resize, 2 = data child s (merge; α: data arc deleted), 3 = pattern
    child s (η: merge; AHA/α: pattern arc deleted), 4 = both deleted.

    ``tie``: an option replaces an earlier one only when cheaper by more than
    ``tie`` (a round-off margin), so that exact ties go to the options tried
    first — resize before merge before deletion — and not to rounding noise
    (|w − (w + s)| may come out below s).
    """
    P, D = TreeArrays(*p), TreeArrays(*d)
    pn = P.ch_ptr.shape[0] - 1
    dn = D.ch_ptr.shape[0] - 1
    F = np.empty((P.soff[pn], D.soff[dn]), np.float64)
    T = np.empty((P.it_ptr[pn], D.it_ptr[dn]), np.float64)
    FD = np.zeros((P.soff[pn], D.soff[dn]), np.int64)
    TD = np.zeros((P.it_ptr[pn], D.it_ptr[dn]), np.int64)
    for p in range(pn):
        pc0 = P.ch_ptr[p]
        npc = P.ch_ptr[p + 1] - pc0
        fp = P.soff[p]
        fullA = (np.int64(1) << npc) - 1
        for d in range(dn):
            dc0 = D.ch_ptr[d]
            ndc = D.ch_ptr[d + 1] - dc0
            fd = D.soff[d]
            nB = np.int64(1) << ndc
            fullB = nB - 1
            for B in range(nB):
                F[fp, fd + B] = D.delfor[fd + B]
            for A in range(1, fullA + 1):
                low = A & -A
                a = P.ch_idx[pc0 + _tz(low)]
                arest = A ^ low
                ai = P.base[a]
                fa = P.soff[a]
                full_a = (np.int64(1) << (P.ch_ptr[a + 1] - P.ch_ptr[a])) - 1
                dela = P.delsub[ai]
                darc = P.delarc[ai]
                rowr = fp + arest
                for B in range(nB):
                    best = np.inf
                    code = 0
                    bb = B
                    while bb:
                        lb = bb & -bb
                        s = _tz(lb)
                        b = D.ch_idx[dc0 + s]
                        bi = D.base[b]
                        v = F[rowr, fd + (B ^ lb)] + T[ai, bi]          # a aligned with b (line 3)
                        if v < best - tie:
                            best = v
                            code = 2 | (s << 4)
                        bb ^= lb
                    bb = B
                    while bb:
                        lb = bb & -bb
                        s = _tz(lb)
                        b = D.ch_idx[dc0 + s]
                        bi = D.base[b]
                        bb ^= lb
                        if D.ch_ptr[b + 1] == D.ch_ptr[b]:
                            continue    # b is a leaf: line 5 equals deleting b and A' (lines 1-2)
                        # b's arc deleted, A' ∋ a aligned with F(D, b) (line 5)
                        fb = D.soff[b] + (np.int64(1) << (D.ch_ptr[b + 1] - D.ch_ptr[b])) - 1
                        dbarc = D.delarc[bi]
                        sub = arest
                        while True:
                            v = F[fp + (arest ^ sub), fd + (B ^ lb)] + F[fp + (sub | low), fb] + dbarc
                            if v < best - tie:
                                best = v
                                code = 3 | (s << 4) | (sub << 8)
                            if sub == 0:
                                break
                            sub = (sub - 1) & arest
                    # a's arc deleted, F(P, a) aligned with B' ⊆ B (line 4); a leaf: same as line 2
                    sub = B if full_a != 0 else 0
                    while sub:
                        v = F[rowr, fd + (B ^ sub)] + F[fa + full_a, fd + sub] + darc
                        if v < best - tie:
                            best = v
                            code = 4 | (sub << 8)
                        sub = (sub - 1) & B
                    v = F[rowr, fd + B] + dela                          # a deleted (line 2)
                    if v < best - tie:
                        best = v
                        code = 1
                    F[fp + A, fd + B] = best
                    FD[fp + A, fd + B] = code
            # pruned trees (Prop. 20 / 27)
            ffull = F[fp + fullA, fd + fullB]
            for pi in range(P.it_ptr[p], P.it_ptr[p + 1]):
                pup = P.it_up[pi]
                for di in range(D.it_ptr[d], D.it_ptr[d + 1]):
                    best = R[pi, di] + ffull                            # line 2
                    code = 1
                    dup = D.it_up[di]
                    for s in range(ndc):                                # line 3
                        c = D.ch_idx[dc0 + s]
                        rest = D.delfor[fd + (fullB ^ (np.int64(1) << s))]
                        if mode == 0:
                            v = D.delarc[di] + T[pi, D.base[c]] + rest
                        else:
                            v = T[pi, D.item_of[c, dup]] + rest
                        if v < best - tie:
                            best = v
                            code = 2 | (s << 4)
                    for s in range(npc):                                # line 4
                        c = P.ch_idx[pc0 + s]
                        rest = P.delfor[fp + (fullA ^ (np.int64(1) << s))]
                        if mode == 1:
                            v = T[P.item_of[c, pup], di] + rest
                        else:
                            v = P.delarc[pi] + T[P.base[c], di] + rest
                        if v < best - tie:
                            best = v
                            code = 3 | (s << 4)
                    v = P.delsub[pi] + D.delsub[di]                     # line 1
                    if v < best - tie:
                        best = v
                        code = 4
                    T[pi, di] = best
                    TD[pi, di] = code
    return F, T, FD, TD


@njit(cache=True)
def _full(S, k):
    """Row or column of F of node k's whole forest of children."""
    return S.soff[k] + (np.int64(1) << (S.ch_ptr[k + 1] - S.ch_ptr[k])) - 1


@njit(cache=True)
def top_value(p, d, F, tie):
    """min over the root pairs (Prop. 18, 22, 23, 25); ties (within ``tie``) to the first pair."""
    P, D = TreeArrays(*p), TreeArrays(*d)
    best = np.inf
    bp = P.roots[0]
    bd = D.roots[0]
    for pr in P.roots:
        for dr in D.roots:
            v = F[_full(P, pr), _full(D, dr)]
            if v < best - tie:
                best = v
                bp = pr
                bd = dr
    return best, bp, bd


@njit(cache=True)
def expand(state, limit, mode, p, d, tables, out):
    """Every option of one state whose cost is <= ``limit``.

    ``state`` is (kind, s1, s2, s3, s4): F state (p, A, d, B), T state (pi, di, 0, 0)
    or the top state. Writes into the buffers ``out`` = (cost, nsub, sub[., 2, 5], nev,
    ev[., 3, 3]) — sized by :func:`max_options` — each option's cost, its sub-states and the
    events it emits (codes EV_*); returns the number of options. The recurrences are those of
    :func:`forward`, term for term.
    """
    P, D = TreeArrays(*p), TreeArrays(*d)
    kind, s1, s2, s3, s4 = state
    R, F, T = tables
    cost, nsub, sub_, nev, ev = out
    nsub[:] = 0
    nev[:] = 0
    m = 0
    if kind == ST_TOP:
        for pr in P.roots:
            for dr in D.roots:
                fa = _full(P, pr) - P.soff[pr]
                fb = _full(D, dr) - D.soff[dr]
                v = F[P.soff[pr] + fa, D.soff[dr] + fb]
                if v <= limit:
                    cost[m] = v
                    nsub[m] = 1
                    sub_[m, 0, 0] = ST_F
                    sub_[m, 0, 1] = pr
                    sub_[m, 0, 2] = fa
                    sub_[m, 0, 3] = dr
                    sub_[m, 0, 4] = fb
                    nev[m] = 1
                    ev[m, 0, 0] = EV_MAP
                    ev[m, 0, 1] = P.node_v[pr]
                    ev[m, 0, 2] = D.node_v[dr]
                    m += 1
        return m
    if kind == ST_F:
        p = s1
        A = s2
        d = s3
        B = s4
        fp = P.soff[p]
        fd = D.soff[d]
        pc0 = P.ch_ptr[p]
        dc0 = D.ch_ptr[d]
        if A == 0:
            v = D.delfor[fd + B]
            if v <= limit:
                cost[m] = v
                if B != 0:
                    nev[m] = 1
                    ev[m, 0, 0] = EV_DDELF
                    ev[m, 0, 1] = d
                    ev[m, 0, 2] = B
                m += 1
            return m
        low = A & -A
        a = P.ch_idx[pc0 + _tz(low)]
        arest = A ^ low
        ai = P.base[a]
        fa = P.soff[a]
        full_a = (np.int64(1) << (P.ch_ptr[a + 1] - P.ch_ptr[a])) - 1
        rowr = fp + arest
        # line 2: a deleted
        v = F[rowr, fd + B] + P.delsub[ai]
        if v <= limit:
            cost[m] = v
            nsub[m] = 1
            sub_[m, 0, 0] = ST_F
            sub_[m, 0, 1] = p
            sub_[m, 0, 2] = arest
            sub_[m, 0, 3] = d
            sub_[m, 0, 4] = B
            nev[m] = 1
            ev[m, 0, 0] = EV_PDEL
            ev[m, 0, 1] = ai
            m += 1
        bb = B
        while bb:
            lb = bb & -bb
            b = D.ch_idx[dc0 + _tz(lb)]
            bi = D.base[b]
            v = F[rowr, fd + (B ^ lb)] + T[ai, bi]
            if v <= limit:
                cost[m] = v
                nsub[m] = 2
                sub_[m, 0, 0] = ST_F
                sub_[m, 0, 1] = p
                sub_[m, 0, 2] = arest
                sub_[m, 0, 3] = d
                sub_[m, 0, 4] = B ^ lb
                sub_[m, 1, 0] = ST_T
                sub_[m, 1, 1] = ai
                sub_[m, 1, 2] = bi
                m += 1
            fbm = (np.int64(1) << (D.ch_ptr[b + 1] - D.ch_ptr[b])) - 1
            sb = arest
            while fbm != 0:     # b a leaf: line 5 equals lines 1-2 (skipped, as in forward)
                v = F[fp + (arest ^ sb), fd + (B ^ lb)] + F[fp + (sb | low), D.soff[b] + fbm] + D.delarc[bi]
                if v <= limit:
                    cost[m] = v
                    nsub[m] = 2
                    sub_[m, 0, 0] = ST_F
                    sub_[m, 0, 1] = p
                    sub_[m, 0, 2] = arest ^ sb
                    sub_[m, 0, 3] = d
                    sub_[m, 0, 4] = B ^ lb
                    sub_[m, 1, 0] = ST_F
                    sub_[m, 1, 1] = p
                    sub_[m, 1, 2] = sb | low
                    sub_[m, 1, 3] = b
                    sub_[m, 1, 4] = fbm
                    nev[m] = 1
                    ev[m, 0, 0] = EV_DARC
                    ev[m, 0, 1] = bi
                    m += 1
                if sb == 0:
                    break
                sb = (sb - 1) & arest
            bb ^= lb
        sb = B if full_a != 0 else 0
        while sb:
            v = F[rowr, fd + (B ^ sb)] + F[fa + full_a, fd + sb] + P.delarc[ai]
            if v <= limit:
                cost[m] = v
                nsub[m] = 2
                sub_[m, 0, 0] = ST_F
                sub_[m, 0, 1] = p
                sub_[m, 0, 2] = arest
                sub_[m, 0, 3] = d
                sub_[m, 0, 4] = B ^ sb
                sub_[m, 1, 0] = ST_F
                sub_[m, 1, 1] = a
                sub_[m, 1, 2] = full_a
                sub_[m, 1, 3] = d
                sub_[m, 1, 4] = sb
                nev[m] = 2
                ev[m, 0, 0] = EV_PARC
                ev[m, 0, 1] = ai
                ev[m, 1, 0] = EV_MAP
                ev[m, 1, 1] = P.node_v[a]
                ev[m, 1, 2] = D.node_v[d]
                m += 1
            sb = (sb - 1) & B
        return m
    # T state
    pi = s1
    di = s2
    p = P.it_node[pi]
    d = D.it_node[di]
    pc0 = P.ch_ptr[p]
    npc = P.ch_ptr[p + 1] - pc0
    dc0 = D.ch_ptr[d]
    ndc = D.ch_ptr[d + 1] - dc0
    fp = P.soff[p]
    fd = D.soff[d]
    fullA = (np.int64(1) << npc) - 1
    fullB = (np.int64(1) << ndc) - 1
    v = R[pi, di] + F[fp + fullA, fd + fullB]
    if v <= limit:
        cost[m] = v
        nsub[m] = 1
        sub_[m, 0, 0] = ST_F
        sub_[m, 0, 1] = p
        sub_[m, 0, 2] = fullA
        sub_[m, 0, 3] = d
        sub_[m, 0, 4] = fullB
        nev[m] = 2
        ev[m, 0, 0] = EV_MATCH
        ev[m, 0, 1] = pi
        ev[m, 0, 2] = di
        ev[m, 1, 0] = EV_MAP
        ev[m, 1, 1] = P.node_v[p]
        ev[m, 1, 2] = D.node_v[d]
        m += 1
    dup = D.it_up[di]
    pup = P.it_up[pi]
    for s in range(ndc):
        c = D.ch_idx[dc0 + s]
        rest = fullB ^ (np.int64(1) << s)
        if mode == 0:
            tgt = D.base[c]
            v = D.delarc[di] + T[pi, tgt] + D.delfor[fd + rest]
        else:
            tgt = D.item_of[c, dup]
            v = T[pi, tgt] + D.delfor[fd + rest]
        if v <= limit:
            cost[m] = v
            nsub[m] = 1
            sub_[m, 0, 0] = ST_T
            sub_[m, 0, 1] = pi
            sub_[m, 0, 2] = tgt
            k = 0
            if rest != 0:
                ev[m, k, 0] = EV_DDELF
                ev[m, k, 1] = d
                ev[m, k, 2] = rest
                k += 1
            if mode == 0:
                ev[m, k, 0] = EV_DARC
                ev[m, k, 1] = di
                k += 1
            nev[m] = k
            m += 1
    for s in range(npc):
        c = P.ch_idx[pc0 + s]
        rest = fullA ^ (np.int64(1) << s)
        if mode == 1:
            tgt = P.item_of[c, pup]
            v = T[tgt, di] + P.delfor[fp + rest]
        else:
            tgt = P.base[c]
            v = P.delarc[pi] + T[tgt, di] + P.delfor[fp + rest]
        if v <= limit:
            cost[m] = v
            nsub[m] = 1
            sub_[m, 0, 0] = ST_T
            sub_[m, 0, 1] = tgt
            sub_[m, 0, 2] = di
            k = 0
            if rest != 0:
                ev[m, k, 0] = EV_PDELF
                ev[m, k, 1] = p
                ev[m, k, 2] = rest
                k += 1
            if mode != 1:
                ev[m, k, 0] = EV_PARC
                ev[m, k, 1] = pi
                k += 1
                ev[m, k, 0] = EV_MAP
                ev[m, k, 1] = P.node_v[p]
                ev[m, k, 2] = dup
                k += 1
            nev[m] = k
            m += 1
    v = P.delsub[pi] + D.delsub[di]
    if v <= limit:
        cost[m] = v
        nev[m] = 2
        ev[m, 0, 0] = EV_PDEL
        ev[m, 0, 1] = pi
        ev[m, 1, 0] = EV_DDEL
        ev[m, 1, 1] = di
        m += 1
    return m


@njit(cache=True)
def max_options(p, d):
    """Buffer size for :func:`expand`: the most options any state can have."""
    P, D = TreeArrays(*p), TreeArrays(*d)
    mp = 0
    for k in range(P.ch_ptr.shape[0] - 1):
        mp = max(mp, P.ch_ptr[k + 1] - P.ch_ptr[k])
    md = 0
    for k in range(D.ch_ptr.shape[0] - 1):
        md = max(md, D.ch_ptr[k + 1] - D.ch_ptr[k])
    a = 2 + md + md * (np.int64(1) << max(mp - 1, 0)) + (np.int64(1) << md)
    b = 2 + md + mp
    c = P.roots.shape[0] * D.roots.shape[0]
    return max(a, max(b, c))


@njit(cache=True)
def option_buffers(maxo):
    return (np.empty(maxo, np.float64), np.zeros(maxo, np.int64), np.zeros((maxo, 2, 5), np.int64),
            np.zeros(maxo, np.int64), np.zeros((maxo, 3, 3), np.int64))


@njit(cache=True)
def state_value(state, p, d, tables, top):
    """The table value of a state (see :func:`expand`)."""
    P, D = TreeArrays(*p), TreeArrays(*d)
    kind, s1, s2, s3, s4 = state
    _, F, T = tables
    if kind == ST_F:
        return F[P.soff[s1] + s2, D.soff[s3] + s4]
    if kind == ST_T:
        return T[s1, s2]
    return top


@njit(cache=True)
def traceback(mode, n_p, n_d, FD, TD, top_pr, top_dr, p, d):
    """One optimal alignment, following the decision tables of :func:`forward`.

    Returns events[k, 3] (codes EV_*), the same events that :func:`expand`
    emits for the chosen options.
    """
    P, D = TreeArrays(*p), TreeArrays(*d)
    # every state consumes a pattern or data edge (at most twice each), so these bounds hold
    cap = 8 * (n_p + n_d) + 16
    events = np.empty((2 * cap, 3), np.int64)
    ne = 0
    stack = np.empty((cap, 5), np.int64)
    # top: the chosen root pair
    events[0, 0] = EV_MAP
    events[0, 1] = P.node_v[top_pr]
    events[0, 2] = D.node_v[top_dr]
    ne = 1
    stack[0, 0] = ST_F
    stack[0, 1] = top_pr
    stack[0, 2] = (np.int64(1) << (P.ch_ptr[top_pr + 1] - P.ch_ptr[top_pr])) - 1
    stack[0, 3] = top_dr
    stack[0, 4] = (np.int64(1) << (D.ch_ptr[top_dr + 1] - D.ch_ptr[top_dr])) - 1
    sp = 1
    while sp > 0:
        if sp + 2 >= cap or ne + 4 >= 2 * cap:
            events[0, 0] = -1       # cannot happen (see the bound above); reported as an error
            return events[:1]
        sp -= 1
        kind = stack[sp, 0]
        if kind == ST_F:
            p = stack[sp, 1]
            A = stack[sp, 2]
            d = stack[sp, 3]
            B = stack[sp, 4]
            if A == 0:
                if B != 0:
                    events[ne, 0] = EV_DDELF
                    events[ne, 1] = d
                    events[ne, 2] = B
                    ne += 1
                continue
            code = FD[P.soff[p] + A, D.soff[d] + B]
            opt = code & 15
            s = (code >> 4) & 15
            sub = code >> 8
            low = A & -A
            a = P.ch_idx[P.ch_ptr[p] + _tz(low)]
            arest = A ^ low
            ai = P.base[a]
            if opt == 1:
                stack[sp, 0] = ST_F
                stack[sp, 1] = p
                stack[sp, 2] = arest
                stack[sp, 3] = d
                stack[sp, 4] = B
                sp += 1
                events[ne, 0] = EV_PDEL
                events[ne, 1] = ai
                ne += 1
            elif opt == 2:
                lb = np.int64(1) << s
                b = D.ch_idx[D.ch_ptr[d] + s]
                stack[sp, 0] = ST_F
                stack[sp, 1] = p
                stack[sp, 2] = arest
                stack[sp, 3] = d
                stack[sp, 4] = B ^ lb
                stack[sp + 1, 0] = ST_T
                stack[sp + 1, 1] = ai
                stack[sp + 1, 2] = D.base[b]
                sp += 2
            elif opt == 3:
                lb = np.int64(1) << s
                b = D.ch_idx[D.ch_ptr[d] + s]
                stack[sp, 0] = ST_F
                stack[sp, 1] = p
                stack[sp, 2] = arest ^ sub
                stack[sp, 3] = d
                stack[sp, 4] = B ^ lb
                stack[sp + 1, 0] = ST_F
                stack[sp + 1, 1] = p
                stack[sp + 1, 2] = sub | low
                stack[sp + 1, 3] = b
                stack[sp + 1, 4] = (np.int64(1) << (D.ch_ptr[b + 1] - D.ch_ptr[b])) - 1
                sp += 2
                events[ne, 0] = EV_DARC
                events[ne, 1] = D.base[b]
                ne += 1
            else:
                stack[sp, 0] = ST_F
                stack[sp, 1] = p
                stack[sp, 2] = arest
                stack[sp, 3] = d
                stack[sp, 4] = B ^ sub
                stack[sp + 1, 0] = ST_F
                stack[sp + 1, 1] = a
                stack[sp + 1, 2] = (np.int64(1) << (P.ch_ptr[a + 1] - P.ch_ptr[a])) - 1
                stack[sp + 1, 3] = d
                stack[sp + 1, 4] = sub
                sp += 2
                events[ne, 0] = EV_PARC
                events[ne, 1] = ai
                events[ne + 1, 0] = EV_MAP
                events[ne + 1, 1] = P.node_v[a]
                events[ne + 1, 2] = D.node_v[d]
                ne += 2
        else:
            pi = stack[sp, 1]
            di = stack[sp, 2]
            code = TD[pi, di]
            opt = code & 15
            s = code >> 4
            p = P.it_node[pi]
            d = D.it_node[di]
            npc = P.ch_ptr[p + 1] - P.ch_ptr[p]
            ndc = D.ch_ptr[d + 1] - D.ch_ptr[d]
            fullA = (np.int64(1) << npc) - 1
            fullB = (np.int64(1) << ndc) - 1
            if opt == 1:
                stack[sp, 0] = ST_F
                stack[sp, 1] = p
                stack[sp, 2] = fullA
                stack[sp, 3] = d
                stack[sp, 4] = fullB
                sp += 1
                events[ne, 0] = EV_MATCH
                events[ne, 1] = pi
                events[ne, 2] = di
                events[ne + 1, 0] = EV_MAP
                events[ne + 1, 1] = P.node_v[p]
                events[ne + 1, 2] = D.node_v[d]
                ne += 2
            elif opt == 2:
                c = D.ch_idx[D.ch_ptr[d] + s]
                rest = fullB ^ (np.int64(1) << s)
                stack[sp, 0] = ST_T
                stack[sp, 1] = pi
                stack[sp, 2] = D.base[c] if mode == 0 else D.item_of[c, D.it_up[di]]
                sp += 1
                if rest != 0:
                    events[ne, 0] = EV_DDELF
                    events[ne, 1] = d
                    events[ne, 2] = rest
                    ne += 1
                if mode == 0:
                    events[ne, 0] = EV_DARC
                    events[ne, 1] = di
                    ne += 1
            elif opt == 3:
                c = P.ch_idx[P.ch_ptr[p] + s]
                rest = fullA ^ (np.int64(1) << s)
                stack[sp, 0] = ST_T
                stack[sp, 1] = P.item_of[c, P.it_up[pi]] if mode == 1 else P.base[c]
                stack[sp, 2] = di
                sp += 1
                if rest != 0:
                    events[ne, 0] = EV_PDELF
                    events[ne, 1] = p
                    events[ne, 2] = rest
                    ne += 1
                if mode != 1:
                    events[ne, 0] = EV_PARC
                    events[ne, 1] = pi
                    events[ne + 1, 0] = EV_MAP
                    events[ne + 1, 1] = P.node_v[p]
                    events[ne + 1, 2] = D.it_up[di]
                    ne += 2
            else:
                events[ne, 0] = EV_PDEL
                events[ne, 1] = pi
                events[ne + 1, 0] = EV_DDEL
                events[ne + 1, 1] = di
                ne += 2
    return events[:ne]


@njit(cache=True)
def cooptimal_pairs(mode, tol, n_p, n_d, p, d, tables, top):
    """Every (pattern vertex, data vertex) pair that some co-optimal alignment maps.

    Walks the graph of states reachable from the top through options whose
    cost is within ``tol`` (relative) of the state's value; returns
    (alt[n_p, n_d] bool, matched[n_p] bool) where ``matched`` marks pattern
    vertices that end a matched arc in the walk.
    """
    P, D = TreeArrays(*p), TreeArrays(*d)
    _, F, T = tables
    seenF = np.zeros(F.shape, np.bool_)
    seenT = np.zeros(T.shape, np.bool_)
    alt = np.zeros((n_p, n_d), np.bool_)
    matched = np.zeros(n_p, np.bool_)
    out = option_buffers(max_options(p, d))
    _, nsub, sub_, nev, ev = out
    cap = F.shape[0] * F.shape[1] + T.shape[0] * T.shape[1] + 2   # every state is pushed once at most
    stack = np.empty((cap, 5), np.int64)
    stack[0, 0] = ST_TOP
    sp = 1
    while sp > 0:
        sp -= 1
        state = (stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4])
        val = state_value(state, p, d, tables, top)
        limit = val + tol * max(1.0, abs(val)) if val < np.inf else np.inf
        nopt = expand(state, limit, mode, p, d, tables, out)
        for o in range(nopt):
            for e in range(nev[o]):
                if ev[o, e, 0] == EV_MAP:
                    alt[ev[o, e, 1], ev[o, e, 2]] = True
                elif ev[o, e, 0] == EV_MATCH:
                    pi = ev[o, e, 1]
                    matched[P.node_v[P.it_node[pi]]] = True
                    matched[P.it_up[pi]] = True
            for s in range(nsub[o]):
                k = sub_[o, s, 0]
                if k == ST_F:
                    r = P.soff[sub_[o, s, 1]] + sub_[o, s, 2]
                    c = D.soff[sub_[o, s, 3]] + sub_[o, s, 4]
                    if seenF[r, c]:
                        continue
                    seenF[r, c] = True
                else:
                    if seenT[sub_[o, s, 1], sub_[o, s, 2]]:
                        continue
                    seenT[sub_[o, s, 1], sub_[o, s, 2]] = True
                for t in range(5):
                    stack[sp, t] = sub_[o, s, t]
                sp += 1
    return alt, matched


@njit(cache=True)
def gamma_code(code, x, y):
    """γ for the built-in codes: 0 = |x − y|, 1 = (x − y)²; γ(inf, inf) = 0, γ(inf, finite) = inf."""
    if x == np.inf:
        return 0.0 if y == np.inf else np.inf
    if y == np.inf:
        return np.inf
    d = abs(x - y)
    return d if code == 0 else d * d


@njit(cache=True)
def resize_matrix(code, p_it_w, d_it_w):
    R = np.empty((p_it_w.shape[0], d_it_w.shape[0]), np.float64)
    for i in range(p_it_w.shape[0]):
        for j in range(d_it_w.shape[0]):
            R[i, j] = gamma_code(code, p_it_w[i], d_it_w[j])
    return R


@njit(cache=True)
def apply_constraints(R, cons, pos, it_up, it_node, node_v):
    """Resize cost +inf where a data path's end positions violate a constraint of ``cons``
    (:class:`Constraints`, §12.2.1). ``pos`` (n, 3): the data vertices' positions; ``it_up``,
    ``it_node``, ``node_v``: the data tree's items and nodes (:func:`build_struct`).
    """
    cons = Constraints(*cons)
    nd = it_up.shape[0]
    for k in range(cons.ptr.shape[0] - 1):
        h = np.empty(pos.shape[0], np.float64)
        for v in range(pos.shape[0]):
            h[v] = pos[v, 0] * cons.up[k, 0] + pos[v, 1] * cons.up[k, 1] + pos[v, 2] * cons.up[k, 2]
        for q in range(cons.ptr[k], cons.ptr[k + 1]):
            pi = cons.items[q]
            s = cons.signs[q]
            for di in range(nd):
                if s * (h[it_up[di]] - h[node_v[it_node[di]]]) <= 0.0:
                    R[pi, di] = np.inf


@njit(cache=True)
def data_side(mode, cut, code, n, eu, ev, ew, root, p_it_w, cons, pos):
    """Data tree structure, deletion costs and resize costs for a built-in γ."""
    st = build_struct(n, eu, ev, ew, root, mode != ALPHA)
    d_it_w = st[8]
    ni = d_it_w.shape[0]
    d_delarc = np.empty(ni, np.float64)
    for i in range(ni):
        d_delarc[i] = gamma_code(code, 0.0, d_it_w[i])
    d_delsub, d_delfor = deletion_costs(st[2], st[3], st[4], st[5], st[10], d_delarc, cut)
    R = resize_matrix(code, p_it_w, d_it_w)
    if cons[0].shape[0] > 1:
        apply_constraints(R, cons, pos, st[7], st[6], st[0])
    return st, d_delarc, d_delsub, d_delfor, R


@njit(cache=True)
def align_data(mode, cut, code, tie, n, eu, ev, ew, root, p, cons, pos):
    """All the data-dependent work of one alignment in one call (built-in γ): the data tree
    (``n`` vertices, edges ``eu``–``ev`` of weight ``ew``, ``root`` or -1) against the pattern
    ``p`` (:class:`TreeArrays`) under the constraints ``cons`` (:class:`Constraints`; ``pos``
    the data vertices' positions).

    Returns (top, events) — see :func:`traceback`.
    """
    P = TreeArrays(*p)
    st, delarc, delsub, delfor, R = data_side(mode, cut, code, n, eu, ev, ew, root, P.it_w, cons, pos)
    d = tree_arrays(st, delarc, delsub, delfor)
    F, T, FD, TD = forward(mode, p, d, R, tie)
    top, pr, dr = top_value(p, d, F, tie)
    events = traceback(mode, P.node_v.shape[0], n, FD, TD, pr, dr, p, d)
    return top, events
