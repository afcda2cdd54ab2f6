"""Alignments of edge-weighted trees: α, homeomorphic alignment η and AHA (thesis ch. 8–10).

* α — alignment of weighted trees (Jiang et al. transposed to arcs, §8.8);
* η — homeomorphic alignment, mergings of degree-2 vertices on both trees
  (§9.1–9.2, Prop. 18–23, Alg. 14–17; HA paper §3.3–4);
* η⃗ (``"aha"``) — asymmetric homeomorphic alignment, mergings only in the data
  tree (§10.1–10.4, Prop. 25–28, Alg. 18).

Each method works on rooted/rooted, rooted/unrooted (Alg. 17) and
unrooted/unrooted (Alg. 15–16) pairs and takes the cut operation (§9.6,
Prop. 24): removing whole subtrees of the data tree is free.

Cost function γ (§8.2.2): ``"abs"`` = |w − w′| (default), ``"squared"`` =
(w − w′)², or a callable γ(w, w′) that must be a translation-invariant metric.
Infinite weights (the limb crossing the capture border, §7.3.3.1) follow one
convention for every γ: γ(inf, inf) = 0 — the infinite limb matched to the
infinite limb — and γ(inf, finite) = γ(finite, inf) = inf, so an infinite arc
can be neither deleted nor matched with a finite path (cutting an infinite data
arc stays free).

Coordinate constraints (§12.2.1) are applied inside the recurrences: resizing a
constrained model arc to a data path costs +inf when the path's end positions
violate the constraint.

For η, a merged model chain that contains a constrained edge is checked with
the images of the chain's two ends (the end on the side of ``parts[0]`` plays
``parts[0]``).

The alignment itself (not only its cost) is returned: the matched pairs of
(merged) arcs, the deleted and cut edges, and a vertex mapping. A pattern vertex
maps to the data vertex at the end of the data path its arc is matched with (the
root to the data root); the two ends of a deleted (contracted) pattern arc share
their data vertex; a vertex merged away (η) or inside a deleted subtree maps to
None, and so does everything when no arc at all is matched. Among equal-cost
options the recurrences prefer resizing, then merging, then deleting, within a
round-off margin, so that exact ties (frequent with |w − w′|, e.g. a spurious
branch on a leaf) do not depend on rounding.

The hot loops live in :mod:`topopose.match.align_kernels`; :class:`Matcher`
prepares everything that depends on the model once, then aligns data trees.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from topopose.errors import InputError
from topopose.match import align_kernels as K
from topopose.match.tree import Tree, as_tree

METHODS = {"alignment": K.ALPHA, "alpha": K.ALPHA, "ha": K.ETA, "eta": K.ETA, "aha": K.AHA}
METHOD_NAMES = {K.ALPHA: "alignment", K.ETA: "ha", K.AHA: "aha"}
MAX_DEGREE = 14
_NO_POS = np.zeros((0, 3))
# A pattern arc between two junctions (both ends of degree > 1) that carries a coordinate
# constraint is never deleted (contracted): its constraint says one end lies strictly above the
# other, and a contracted arc puts both ends on one data vertex. Without it the human model's
# trunk (torso above crotch, model weight 0.074 of 1) is contracted for that little cost, the
# shoulders' and the hips' junctions become one, and the four limbs are told apart by their
# lengths alone: on the real recording (studies/real_align.py, 4 cameras) hands went onto
# the toes and feet onto a wrist or the arm ends (errors ~1 m, frames 3, 6, 7, 89, 94, 95).
# Leaf arcs are unaffected (a deleted leaf arc is a missing part, not a contraction). Measured
# in studies/real_align.py (docs/accuracy.md). The default of
# FrameEstimator(keep_junctions=None); Matcher and align() keep the thesis' AHA (False).


# ---------------------------------------------------------------------- cost function
def _gamma_abs(x, y):
    with np.errstate(invalid="ignore"):
        g = np.abs(x - y)
    g[np.isnan(g)] = 0.0          # inf - inf: the infinite limb matched to the infinite limb
    return g


def _gamma_sq(x, y):
    with np.errstate(invalid="ignore"):
        g = (x - y) ** 2
    g[np.isnan(g)] = 0.0
    return g


def make_gamma(gamma) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """A vectorized γ(w, w′) (broadcasting arrays) from ``"abs"``, ``"squared"`` or a callable.

    A callable must be a translation-invariant metric on non-negative reals
    (§8.2.2); it is spot-checked and called on finite pairs only (the infinite
    cases follow the module's convention).
    """
    if isinstance(gamma, str):
        key = gamma.lower()
        if key in ("abs", "absolute", "l1"):
            return _gamma_abs
        if key in ("squared", "sq", "square", "l2sq"):
            return _gamma_sq
        raise InputError(f"align: gamma={gamma!r} is unknown; expected 'abs', 'squared' or a callable")
    if not callable(gamma):
        raise InputError(f"align: gamma must be 'abs', 'squared' or a callable, got {type(gamma).__name__}")
    try:
        checks = [float(gamma(0.0, 0.0)), float(gamma(1.5, 1.5)), float(gamma(0.0, 1.0)),
                  float(gamma(1.0, 0.0)), float(gamma(2.0, 3.0)), float(gamma(0.25, 0.5)),
                  float(gamma(0.0, 0.25))]
    except Exception as exc:  # noqa: BLE001 - report any failure of the user's function
        raise InputError(f"align: gamma callable failed on (0.0, 1.0): {exc}") from None
    z0, z1, a, b, c, d, e = checks
    ok = (abs(z0) < 1e-12 and abs(z1) < 1e-12 and a > 0 and abs(a - b) <= 1e-9 * max(1, a)
          and abs(a - c) <= 1e-9 * max(1, a) and abs(d - e) <= 1e-9 * max(1, d) and all(
              math.isfinite(x) and x >= 0 for x in checks))
    if not ok:
        raise InputError("align: gamma callable must be a translation-invariant metric "
                         "(γ(w,w)=0, γ(w,w')=γ(w',w)>0 for w≠w', γ(w+x,w'+x)=γ(w,w'))")
    vec = np.frompyfunc(lambda x, y: float(gamma(x, y)), 2, 1)

    def g(x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        out = np.zeros(x.shape, float)
        fx = np.isfinite(x)
        fy = np.isfinite(y)
        both = fx & fy
        if both.any():
            out[both] = vec(x[both], y[both]).astype(float)
        out[fx != fy] = np.inf
        return out

    return g


# ---------------------------------------------------------------------- prepared trees
class _Prepared:
    """A tree in kernel form: node/item arrays, ids, edge lookup."""

    __slots__ = ("ids", "index", "n", "root", "node_v", "node_par", "ch_ptr", "ch_idx",
                 "soff", "it_ptr", "it_node", "it_up", "it_w", "item_of", "base", "roots", "nxt",
                 "delarc", "delsub", "delfor", "edge_key", "positions", "_lists")

    def __init__(self, tree: Tree, root, merge: bool, name: str, edge_keys: bool = True):
        self.ids = list(tree.vertices)
        self.index = {v: i for i, v in enumerate(self.ids)}
        self.n = len(self.ids)
        if root is not None and root not in self.index:
            raise InputError(f"{name}: root {root!r} is not a vertex of the tree")
        self.root = root
        m = len(tree.edges)
        eu = np.empty(m, np.int64)
        ev = np.empty(m, np.int64)
        ew = np.empty(m, np.float64)
        idx = self.index
        for e, (u, v, w) in enumerate(tree.edges):
            eu[e] = idx[u]
            ev[e] = idx[v]
            ew[e] = w
        if m:
            deg = np.bincount(np.concatenate([eu, ev]), minlength=self.n)
            if deg.max() > MAX_DEGREE:
                bad = self.ids[int(deg.argmax())]
                raise InputError(f"{name}: vertex {bad!r} has degree {int(deg.max())}; "
                                 f"the alignments handle degree <= {MAX_DEGREE}")
        r = -1 if root is None else idx[root]
        s = K.build_struct(self.n, eu, ev, ew, r, merge)
        (self.node_v, self.node_par, self.ch_ptr, self.ch_idx, self.soff, self.it_ptr, self.it_node,
         self.it_up, self.it_w, self.item_of, self.base, self.roots, self.nxt) = s
        self.edge_key = None
        if edge_keys:
            self.edge_key = {}
            for u, v, _ in tree.edges:
                self.edge_key[(idx[u], idx[v])] = (u, v)
                self.edge_key[(idx[v], idx[u])] = (u, v)
        self.positions = tree.positions

    def set_costs(self, delarc, zero):
        self.delarc = delarc
        self.delsub, self.delfor = K.deletion_costs(self.ch_ptr, self.ch_idx, self.soff, self.it_ptr,
                                                    self.base, delarc, zero)

    def arrays(self) -> tuple:
        """The tree as the kernels take it: the fields of a :class:`~.align_kernels.TreeArrays`."""
        return tuple(K.TreeArrays(self.node_v, self.ch_ptr, self.ch_idx, self.soff, self.it_ptr, self.it_node,
                                  self.it_up, self.it_w, self.item_of, self.base, self.delarc, self.delsub,
                                  self.delfor, self.roots))

    def lists(self):
        """Python-list copies of the arrays the traceback details walk (fast scalar access)."""
        try:
            return self._lists
        except AttributeError:
            self._lists = (self.nxt.tolist(), self.it_up.tolist(), self.it_node.tolist(),
                           self.node_v.tolist(), self.ch_ptr.tolist(), self.ch_idx.tolist(),
                           self.base.tolist())
            return self._lists

    def path(self, a, b):
        """Vertex indices of the path a → b."""
        out = [a]
        nxt = self.lists()[0]
        while a != b:
            a = nxt[a][b]
            out.append(a)
        return out

    def subtree_edges(self, k):
        """Edges (index pairs, parent first) below node k."""
        _, _, _, node_v, ch_ptr, ch_idx, _ = self.lists()
        out = []
        stack = [k]
        while stack:
            x = stack.pop()
            vx = node_v[x]
            for q in range(ch_ptr[x], ch_ptr[x + 1]):
                c = ch_idx[q]
                out.append((vx, node_v[c]))
                stack.append(c)
        return out

    def item_edges(self, it):
        """Edges of the pruned tree of item ``it``: its chain, then the subtree below."""
        _, it_up, it_node, node_v, _, _, _ = self.lists()
        k = it_node[it]
        path = self.path(it_up[it], node_v[k])
        return list(zip(path[:-1], path[1:])) + self.subtree_edges(k)

    def forest_edges(self, k, mask):
        _, _, _, _, ch_ptr, ch_idx, base = self.lists()
        out = []
        c0 = ch_ptr[k]
        t = 0
        while mask:
            if mask & 1:
                out.extend(self.item_edges(base[ch_idx[c0 + t]]))
            mask >>= 1
            t += 1
        return out

    def arc_ends(self, it):
        _, it_up, it_node, node_v, _, _, _ = self.lists()
        return it_up[it], node_v[it_node[it]]


# ---------------------------------------------------------------------- result
class Alignment:
    """An optimal alignment of a pattern (model) tree with a data tree.

    Attributes
    ----------
    distance : float
        α, η or η⃗ (with or without cut) — the cost of this alignment.
    mapping : dict
        Pattern vertex -> data vertex, or None when the vertex was deleted or
        merged away. The two ends of a deleted (contracted) pattern arc share
        one data vertex.
    arcs : dict
        Pattern edge (u, v), as oriented in the pattern's edge list -> the data
        path (list of data vertices, from the image of u to the image of v) it
        is matched with — a merged chain when longer than one edge — or None
        when the pattern edge was deleted.
    pairs : list of (pattern path, data path)
        The matched pairs of (merged) arcs, each as a vertex list, upper end first.
    deleted_pattern, deleted_data, cut_data : list of edges (u, v)
        Edges deleted (contracted, cost γ(w, 0)) or cut away for free (§9.6).
    merged_pattern, merged_data : list of vertices
        Degree-2 vertices removed by merging (interior of matched chains).
    alternatives : dict
        Pattern vertex -> every data vertex it maps to in some co-optimal
        alignment (computed on first access).
    pattern_root, data_root : the roots used (the chosen ones for unrooted trees).

    Everything but ``distance`` and ``mapping`` is computed on first access.
    """

    _LAZY = ("arcs", "pairs", "deleted_pattern", "deleted_data", "cut_data", "merged_pattern",
             "merged_data")

    def __init__(self, distance, method, cut, mapping, pattern_root=None, data_root=None,
                 diagnostics=None, ctx=None, events=None, **detail):
        self.distance = distance
        self.method = method
        self.cut = cut
        self.mapping = mapping
        self.pattern_root = pattern_root
        self.data_root = data_root
        self.diagnostics = {} if diagnostics is None else diagnostics
        self._ctx = ctx
        self._events = events
        self._alternatives = None
        self._detail = detail or None

    def _details(self, name):
        if self._detail is None:
            self._detail = {}
        if name not in self._detail:
            if name in ("deleted_pattern", "deleted_data", "cut_data"):
                self._detail.update(self._ctx.deletions(self))
            else:
                self._detail.update(self._ctx.details(self))
        return self._detail

    def __getattr__(self, name):
        if name in Alignment._LAZY:
            return self._details(name)[name]
        raise AttributeError(name)

    def __repr__(self):
        return (f"Alignment(method={self.method!r}, cut={self.cut}, distance={self.distance!r}, "
                f"mapping={self.mapping!r})")

    @property
    def alternatives(self) -> dict:
        """Pattern vertex -> list of data vertices it maps to in some co-optimal alignment.

        Co-optimal: within the matcher's relative tolerance ``rtol`` of the
        optimum at every step (§12.2.2 uses these sets for betweenness). The
        list starts with ``mapping[v]`` when that is not None.
        """
        if self._alternatives is None:
            self._alternatives = self._ctx.alternatives(self) if self._ctx is not None else {
                k: ([] if v is None else [v]) for k, v in self.mapping.items()}
        return self._alternatives

    def arc(self, u, v):
        """The data path matched with pattern edge u–v (oriented u → v), or None."""
        arcs = self.arcs
        if (u, v) in arcs:
            return arcs[(u, v)]
        path = arcs.get((v, u))
        return None if path is None else path[::-1]

    def report(self) -> str:
        """A readable summary: distance, vertex mapping, arcs, deletions."""
        lines = [f"{self.method}{' with cut' if self.cut else ''}: distance {self.distance:.6g}"
                 f" (pattern root {self.pattern_root!r}, data root {self.data_root!r})"]
        for p, d in self.mapping.items():
            lines.append(f"  {p!s:>12} -> {'-' if d is None else d}")
        for (u, v), path in self.arcs.items():
            lines.append(f"  arc {u}-{v}: {'deleted' if path is None else ' '.join(map(str, path))}")
        if self.deleted_data:
            lines.append(f"  data edges deleted: {len(self.deleted_data)}")
        if self.cut_data:
            lines.append(f"  data edges cut: {len(self.cut_data)}")
        if self.merged_data:
            lines.append(f"  data vertices merged: {' '.join(map(str, self.merged_data))}")
        return "\n".join(lines)


class _Context:
    """One data tree against a matcher: the traceback now, the full tables on demand.

    The fast path keeps only the traceback; the tables (needed by
    ``alternatives`` and by the betweenness post-step) are recomputed the first
    time they are asked for.
    """

    def __init__(self, matcher, tree, root, arrays, arc_cost=None):
        self.matcher = matcher
        self.tree = tree
        self.root = root
        self.arrays = arrays        # ids, index, n, eu, ev, ew
        self.arc_cost = arc_cost    # extra resize cost (Matcher.align)
        self.D = None

    # -------------------------------------------------------------- full tables
    def struct(self):
        """The data tree's node/item arrays only (enough for the details of a traceback)."""
        if self.D is not None:
            return self.D
        if getattr(self, "_S", None) is None:
            m = self.matcher
            ids, index, n, eu, ev, ew = self.arrays
            S = _Prepared.__new__(_Prepared)
            S.ids, S.index, S.n, S.root, S.edge_key, S.positions = ids, index, n, self.root, None, \
                self.tree.positions
            r = -1 if self.root is None else index[self.root]
            (S.node_v, S.node_par, S.ch_ptr, S.ch_idx, S.soff, S.it_ptr, S.it_node, S.it_up, S.it_w,
             S.item_of, S.base, S.roots, S.nxt) = K.build_struct(n, eu, ev, ew, r, m.mode != K.ALPHA)
            self._S = S
        return self._S

    def full(self):
        if self.D is not None:
            return self
        m = self.matcher
        P = m._P
        ids, index, n, eu, ev, ew = self.arrays
        D = _Prepared.__new__(_Prepared)
        D.ids, D.index, D.n, D.root, D.edge_key, D.positions = ids, index, n, self.root, None, self.tree.positions
        r = -1 if self.root is None else index[self.root]
        if m._gcode is None:
            st = K.build_struct(n, eu, ev, ew, r, m.mode != K.ALPHA)
            (D.node_v, D.node_par, D.ch_ptr, D.ch_idx, D.soff, D.it_ptr, D.it_node, D.it_up, D.it_w,
             D.item_of, D.base, D.roots, D.nxt) = st
            D.set_costs(m.gamma(np.zeros_like(D.it_w), D.it_w), m.cut)
            R = m._resize_costs(D, self.tree)
        else:
            pos = m._positions(self.tree, ids) if m._cons.ptr.shape[0] > 1 else _NO_POS
            st, D.delarc, D.delsub, D.delfor, R = K.data_side(m.mode, m.cut, m._gcode, n, eu, ev, ew, r,
                                                              P.it_w, tuple(m._cons), pos)
            (D.node_v, D.node_par, D.ch_ptr, D.ch_idx, D.soff, D.it_ptr, D.it_node, D.it_up, D.it_w,
             D.item_of, D.base, D.roots, D.nxt) = st
        if self.arc_cost is not None:
            R = R + arc_cost_matrix(self.arc_cost, P, D)
        PA, DA = m._pattern_arrays, D.arrays()
        self.F, self.T, self.FD, self.TD = K.forward(m.mode, PA, DA, R, m._tie(ew))
        self.top, self.pr, self.dr = K.top_value(PA, DA, self.F, m._tie(ew))
        self.R = R
        self.D = D
        self.kargs = (PA, DA, tuple(K.Tables(R, self.F, self.T)))
        return self

    def traceback(self):
        self.full()
        PA, DA, _ = self.kargs
        return K.traceback(self.matcher.mode, self.matcher._P.node_v.shape[0], self.D.n, self.FD, self.TD,
                           self.pr, self.dr, PA, DA)

    def args(self):
        """(pattern, data, tables) as the kernels take them."""
        return self.full().kargs

    # -------------------------------------------------------------- results
    def make(self, top, events) -> Alignment:
        """The Alignment of a traceback: distance and vertex mapping now, the rest lazily."""
        m = self.matcher
        P = m._P
        pids, dids = P.ids, self.arrays[0]
        maps = {}
        ends = []
        contracted = []
        p_root = d_root = None
        it_node_p, node_v_p, it_up_p = P.it_node, P.node_v, P.it_up
        for a_, b_, c_ in events.tolist():
            if a_ == K.EV_MAP:
                if p_root is None:
                    p_root, d_root = pids[b_], dids[c_]
                maps[b_] = c_
            elif a_ == K.EV_MATCH:
                ends.append(int(it_up_p[b_]))
                ends.append(int(node_v_p[it_node_p[b_]]))
            elif a_ == K.EV_PARC:
                contracted.append((int(it_up_p[b_]), int(node_v_p[it_node_p[b_]])))
        group = list(range(P.n))

        def find(x):
            while group[x] != x:
                group[x] = group[group[x]]
                x = group[x]
            return x

        for x, y in contracted:
            group[find(x)] = find(y)
        live = {find(x) for x in ends}
        mapping = {}
        for i, pv in enumerate(pids):
            j = maps.get(i)
            mapping[pv] = dids[j] if (j is not None and find(i) in live) else None
        al = Alignment(float(top), m.method, m.cut, mapping,
                       pattern_root=m.pattern_root if m.pattern_root is not None else p_root,
                       data_root=self.root if self.root is not None else d_root, ctx=self, events=events)
        return al

    def details(self, al) -> dict:
        """Matched pairs, arcs and merged vertices, from the MATCH events only."""
        m = self.matcher
        P = m._P
        D = self.struct()
        pids, dids = P.ids, self.arrays[0]
        edge_key = P.edge_key
        arcs = dict.fromkeys(dict.fromkeys(edge_key.values()))
        pairs, merged_p, merged_d = [], [], []
        for et, a, b in al._events.tolist():
            if et != K.EV_MATCH:
                continue
            pchain = P.path(*P.arc_ends(a))
            dpath = D.path(*D.arc_ends(b))
            merged_p.extend(pids[x] for x in pchain[1:-1])
            merged_d.extend(dids[x] for x in dpath[1:-1])
            did = [dids[j] for j in dpath]
            pairs.append(([pids[x] for x in pchain], did))
            for x, y in zip(pchain[:-1], pchain[1:]):
                key = edge_key[(x, y)]
                arcs[key] = did if key == (pids[x], pids[y]) else did[::-1]
        return dict(arcs=arcs, pairs=pairs, merged_pattern=merged_p, merged_data=merged_d)

    def deletions(self, al) -> dict:
        """Deleted pattern / data edges and cut data edges."""
        P = self.matcher._P
        dids = self.arrays[0]
        del_p, del_d, cut_d = [], [], []
        for kind, _, u, v in self.records_from_events(al._events.tolist()):
            if kind == 2:
                del_p.append(P.edge_key[(u, v)])
            elif kind == 3:
                del_d.append((dids[u], dids[v]))
            elif kind == 4:
                cut_d.append((dids[u], dids[v]))
        return dict(deleted_pattern=del_p, deleted_data=del_d, cut_data=cut_d)

    def alternatives(self, al: Alignment) -> dict:
        m = self.matcher
        P = m._P
        args = self.args()
        alt, _ = K.cooptimal_pairs(m.mode, m.rtol, P.n, self.D.n, *args, self.top)
        dids = self.arrays[0]
        out = {}
        for i, pv in enumerate(P.ids):
            got = [dids[j] for j in np.flatnonzero(alt[i])]
            cur = al.mapping.get(pv)
            if cur is not None:
                if cur in got:
                    got.remove(cur)
                got.insert(0, cur)
            out[pv] = got
        return out

    def records_from_events(self, events) -> np.ndarray:
        """Every edge once, as (kind, pair, u, v): kind 0 / 1 = pattern / data edge of matched
        pair ``pair`` (path order, upper end first), 2 = deleted pattern edge, 3 = deleted
        data edge, 4 = cut data edge."""
        m = self.matcher
        P, D = m._P, self.struct()
        ddk = 4 if m.cut else 3
        rec = []
        npair = 0
        for et, a, b in events:
            if et == K.EV_MATCH:
                pc = P.path(*P.arc_ends(a))
                dp = D.path(*D.arc_ends(b))
                rec += [(0, npair, x, y) for x, y in zip(pc[:-1], pc[1:])]
                rec += [(1, npair, x, y) for x, y in zip(dp[:-1], dp[1:])]
                npair += 1
            elif et == K.EV_PDEL:
                rec += [(2, -1, x, y) for x, y in P.item_edges(a)]
            elif et == K.EV_PDELF:
                rec += [(2, -1, x, y) for x, y in P.forest_edges(a, b)]
            elif et == K.EV_PARC:
                rec.append((2, -1, *P.arc_ends(a)))
            elif et == K.EV_DDEL:
                rec += [(ddk, -1, x, y) for x, y in D.item_edges(a)]
            elif et == K.EV_DDELF:
                rec += [(ddk, -1, x, y) for x, y in D.forest_edges(a, b)]
            elif et == K.EV_DARC:
                rec.append((3, -1, *D.arc_ends(a)))
        return rec

    # -------------------------------------------------------------- states
    def expand(self, state, limit):
        """Options of a state within ``limit``: list of (cost, substates, events)."""
        PA, DA, tables = self.args()
        bufs = K.option_buffers(K.max_options(PA, DA))
        k = K.expand(tuple(state), limit, self.matcher.mode, PA, DA, tables, bufs)
        cost, nsub, sub_, nev, ev = bufs
        return [(float(cost[o]), [tuple(int(x) for x in sub_[o, s]) for s in range(nsub[o])],
                 [tuple(int(x) for x in ev[o, e]) for e in range(nev[o])]) for o in range(k)]

    def value(self, state):
        PA, DA, tables = self.args()
        return float(K.state_value(tuple(state), PA, DA, tables, self.top))


# ---------------------------------------------------------------------- matcher
def _parse_up(up, name="up"):
    try:
        u = np.asarray(up, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InputError(f"align: {name} must be 3 numbers, got {up!r}") from None
    nrm = float(np.linalg.norm(u))
    if not np.all(np.isfinite(u)) or nrm == 0:
        raise InputError(f"align: {name} must be a finite non-zero vector, got {up!r}")
    return u / nrm


def _axis_vector(axis, default):
    if axis is None:
        return default
    if isinstance(axis, str):
        s = axis.strip().lower()
        sign = -1.0 if s.startswith("-") else 1.0
        s = s.lstrip("+-")
        if s not in ("x", "y", "z"):
            raise InputError(f"constraint: axis {axis!r} must be like '+z', '-y' or a 3-vector")
        v = np.zeros(3)
        v["xyz".index(s)] = sign
        return v
    return _parse_up(axis, "constraint axis")


def _model_parts(obj):
    """Tree, root and constraints of a pattern given as a Tree, a model, or an edge list."""
    tree = as_tree(obj, name="pattern")
    root = tree.root
    cons = list(tree.constraints)
    if not isinstance(obj, Tree) and hasattr(obj, "tree"):
        if root is None:
            root = getattr(obj, "root", None)
        for c in getattr(obj, "constraints", None) or []:
            if c not in cons:
                cons.append(c)
    return tree, root, cons


class Matcher:
    """Align one pattern (model) tree with many data trees.

    Everything that depends only on the pattern — its node/item arrays, its
    deletion costs, its constraints — is prepared once here; :meth:`align`
    then does the data-dependent work (thesis §11.4: one model, thousands of
    data trees).

    Parameters
    ----------
    pattern : Tree, model (object with ``.tree``) or list of (u, v, weight)
    method : ``"aha"`` (η⃗, ch. 10), ``"ha"`` (η, ch. 9) or ``"alignment"`` (α, §8.8)
    cut : allow free removal of data subtrees (§9.6, Prop. 24)
    gamma : ``"abs"``, ``"squared"`` or a callable translation-invariant metric
    pattern_root : vertex or None; default the tree's own root (None: unrooted)
    up : the up vector for coordinate constraints without an axis (§12.2.1)
    rtol : relative tolerance defining co-optimal alternatives
    keep_junctions : forbid deleting (contracting) a pattern arc between two junctions that
        carries a coordinate constraint (the per-frame estimator's ``keep_junctions``, on by default); default off. A
        data tree too small to keep it (every alignment infinite) gets the thesis' alignment,
        flagged ``diagnostics["junctions_contracted"]``

    Examples
    --------
    >>> P = Tree([("c", "a", 1.0), ("c", "b", 2.0)], root="c")
    >>> D = Tree([(0, 1, 1.0), (0, 2, 0.5), (2, 3, 1.5)])
    >>> r = Matcher(P, "aha").align(D)
    >>> round(r.distance, 9), r.mapping
    (0.0, {'c': 0, 'a': 1, 'b': 3})
    """

    def __init__(self, pattern, method: str = "aha", cut: bool = False, gamma="abs",
                 pattern_root=None, up=(0.0, 0.0, 1.0), rtol: float = 1e-9,
                 keep_junctions: bool = False):
        if not isinstance(method, str) or method.lower() not in METHODS:
            raise InputError(f"align: method={method!r} is unknown; expected 'aha', 'ha' or 'alignment'")
        self.mode = METHODS[method.lower()]
        self.method = METHOD_NAMES[self.mode]
        self.cut = bool(cut)
        self.gamma = make_gamma(gamma)
        self._gcode = {id(_gamma_abs): 0, id(_gamma_sq): 1}.get(id(self.gamma))
        self.rtol = float(rtol)
        tree, root, cons = _model_parts(pattern)
        if pattern_root is not None:
            root = pattern_root
        self.pattern = tree
        self.up = _parse_up(up)
        self._P = _Prepared(tree, root, merge=(self.mode == K.ETA), name="pattern")
        P = self._P
        P.set_costs(self.gamma(P.it_w, np.zeros_like(P.it_w)), False)
        self.pattern_root = root
        pw = P.it_w[np.isfinite(P.it_w)]
        self._wmax = float(pw.max()) if pw.size else 0.0
        self._constraints = self._prepare_constraints(cons)
        cc = [c for c in self._constraints if len(c[0])]
        self._cons = K.Constraints(
            np.cumsum([0] + [len(c[0]) for c in cc]).astype(np.int64),
            np.concatenate([c[0] for c in cc]).astype(np.int64) if cc else np.zeros(0, np.int64),
            np.concatenate([c[1] for c in cc]).astype(float) if cc else np.zeros(0),
            np.array([c[2] for c in cc], float).reshape(-1, 3))
        self.betweenness = [c for c in cons if getattr(c, "kind", None) == "between"]
        self.contractible = None    # keep_junctions: the thesis' AHA (a fallback)
        if keep_junctions:
            kept = self.constrained_junction_arcs()
            if kept:
                self.contractible = Matcher(pattern, method, cut, gamma, pattern_root, up, rtol)
                delarc = P.delarc.copy()
                delarc[kept] = np.inf
                P.set_costs(delarc, False)
        self._pattern_arrays = P.arrays()

    def constrained_junction_arcs(self) -> list:
        """Pattern items (arcs) whose both ends are junctions (degree > 1) and which carry a
        coordinate constraint (the per-frame estimator's ``keep_junctions``, on by default)."""
        P = self._P
        adj = self.pattern.adjacency()
        out = []
        for _, _, _, c in self._constraints:
            a, b = P.index[c.parts[0]], P.index[c.parts[1]]
            if len(adj[c.parts[0]]) > 1 and len(adj[c.parts[1]]) > 1:
                out += [it for it in range(len(P.it_up))
                        if {int(P.it_up[it]), int(P.node_v[P.it_node[it]])} == {a, b}]
        return out

    # ------------------------------------------------------------------ constraints
    def _prepare_constraints(self, cons):
        """Per coordinate constraint: (pattern items, signs, up vector) (§12.2.1)."""
        P = self._P
        out = []
        for c in cons:
            kind = getattr(c, "kind", None)
            if kind == "between":
                parts = tuple(c.parts)
                if len(parts) < 3 or any(x not in P.index for x in parts):
                    raise InputError(f"pattern constraint {c!r}: 'between' needs >= 3 parts of the tree")
                continue
            if kind not in ("above", "below"):
                raise InputError(f"pattern constraint {c!r}: kind must be 'above', 'below' or 'between'")
            parts = tuple(c.parts)
            if len(parts) != 2 or any(x not in P.index for x in parts):
                raise InputError(f"pattern constraint {c!r}: parts must be two vertices of the pattern")
            a, b = P.index[parts[0]], P.index[parts[1]]
            if (a, b) not in P.edge_key:
                raise InputError(f"pattern constraint {c!r}: {parts[0]!r}–{parts[1]!r} is not a pattern edge")
            upv = _axis_vector(c.axis, self.up)
            items, signs = [], []
            for it in range(len(P.it_up)):
                chain = P.path(int(P.it_up[it]), int(P.node_v[P.it_node[it]]))
                for x, y in zip(chain[:-1], chain[1:]):
                    if (x, y) == (a, b) or (x, y) == (b, a):
                        # a is the upper end of the chain: want h(up image) > h(low image) for "above"
                        s = 1.0 if x == a else -1.0
                        items.append(it)
                        signs.append(s if kind == "above" else -s)
                        break
            out.append((np.array(items, np.int64), np.array(signs), upv, c))
        return out

    # ------------------------------------------------------------------ data
    def _resize_costs(self, D, tree):
        P = self._P
        R = self.gamma(P.it_w[:, None], D.it_w[None, :])
        if self._cons.ptr.shape[0] > 1 and len(D.it_w):
            pos = self._positions(tree, D.ids)
            low = D.node_v[D.it_node]
            for items, signs, upv, _ in self._constraints:
                if len(items) == 0:
                    continue
                h = pos @ upv
                hd = h[D.it_up] - h[low]
                bad = (signs[:, None] * hd[None, :]) <= 0
                sub = R[items]
                sub[bad] = np.inf
                R[items] = sub
        return R

    def align(self, data, data_root=None, arc_cost=None) -> Alignment:
        """Align the pattern with ``data`` (Tree or edge list); ``data_root`` None: the tree's own root.

        ``arc_cost``, optional: a callable ``f(p_up, p_low, d_up, d_low)`` — the vertex ids of
        the upper and lower end of every pattern arc (``p_*``, length m) and of every data path
        (``d_*``, length n) — returning an (m, n) array of non-negative costs added to γ when
        that pattern arc is resized to that data path (e.g. a thickness term,
        :func:`topopose.frame.estimate.thickness_arc_cost`); +inf forbids. The distance then
        includes it.
        """
        tree = data if isinstance(data, Tree) else as_tree(data, name="data")
        root = data_root if data_root is not None else tree.root
        ids = tree.vertices
        index = {v: i for i, v in enumerate(ids)}
        n = len(ids)
        if root is not None and root not in index:
            raise InputError(f"data: root {root!r} is not a vertex of the tree")
        edges = tree.edges
        eu = np.array([index[e[0]] for e in edges], np.int64)
        ev = np.array([index[e[1]] for e in edges], np.int64)
        ew = np.array([e[2] for e in edges], np.float64)
        if len(edges):
            deg = np.bincount(eu, minlength=n) + np.bincount(ev, minlength=n)
            if deg.max() > MAX_DEGREE:
                raise InputError(f"data: vertex {ids[int(deg.argmax())]!r} has degree {int(deg.max())}; "
                                 f"the alignments handle degree <= {MAX_DEGREE}")
        ctx = _Context(self, tree, root, (ids, index, n, eu, ev, ew), arc_cost)
        if self._gcode is None or arc_cost is not None:   # the tables are built in several steps
            events = ctx.traceback()
            top = ctx.top
        else:
            pos = self._positions(tree, ids) if self._cons.ptr.shape[0] > 1 else _NO_POS
            top, events = K.align_data(self.mode, self.cut, self._gcode, self._tie(ew), n, eu, ev, ew,
                                       -1 if root is None else index[root], self._pattern_arrays,
                                       tuple(self._cons), pos)
        if events.shape[0] and events[0, 0] < 0:  # pragma: no cover - the bound in traceback
            raise RuntimeError("align: traceback overflow")
        al = ctx.make(top, events)
        if self.contractible is not None and not math.isfinite(al.distance):
            al = self.contractible.align(data, data_root, arc_cost)
            if math.isfinite(al.distance):
                al.diagnostics["junctions_contracted"] = True
        return al

    def _tie(self, ew):
        """Round-off margin of the tie-breaking: 1e-12 of the largest finite weight involved."""
        fin = ew[np.isfinite(ew)]
        big = max(self._wmax, float(fin.max()) if fin.size else 0.0, 1e-300)
        g = float(self.gamma(np.array([big]), np.array([0.0]))[0]) if self._gcode is None else \
            (big if self._gcode == 0 else big * big)
        return 1e-12 * g * (self._P.n + len(ew) + 1)

    @staticmethod
    def _positions(tree, ids):
        pos = np.empty((len(ids), 3))
        for i, v in enumerate(ids):
            p = tree.positions.get(v)
            if p is None:
                raise InputError(f"data: vertex {v!r} has no position; the pattern's coordinate "
                                 "constraints need data positions")
            pos[i] = p
        return pos


def arc_cost_matrix(arc_cost, P, D) -> np.ndarray:
    """The (pattern items × data items) matrix of a user ``arc_cost`` (:meth:`Matcher.align`)."""
    p_up = [P.ids[i] for i in P.it_up]
    p_low = [P.ids[i] for i in P.node_v[P.it_node]]
    d_up = [D.ids[i] for i in D.it_up]
    d_low = [D.ids[i] for i in D.node_v[D.it_node]]
    C = np.asarray(arc_cost(p_up, p_low, d_up, d_low), dtype=float)
    if C.shape != (len(p_up), len(d_up)):
        raise InputError(f"align: arc_cost returned shape {C.shape}, expected "
                         f"{(len(p_up), len(d_up))} (pattern arcs × data paths)")
    return C


def align(pattern, data, method: str = "aha", pattern_root=None, data_root=None, cut: bool = False,
          gamma="abs", up=(0.0, 0.0, 1.0), rtol: float = 1e-9) -> Alignment:
    """Align a pattern (model) tree with a data tree (thesis ch. 8–10, §12.2).

    Parameters
    ----------
    pattern, data : Tree, model (object with ``.tree``) or list of (u, v, weight)
    method : ``"aha"`` (asymmetric homeomorphic alignment η⃗, ch. 10), ``"ha"``
        (homeomorphic alignment η, ch. 9) or ``"alignment"`` (α, §8.8)
    pattern_root, data_root : vertex or None (None: the tree's own ``root``;
        unrooted when that is None too). Rooted/rooted (Alg. 14, 18),
        rooted/unrooted (Alg. 17) and unrooted/unrooted (Alg. 15–16).
    cut : free removal of data subtrees (§9.6, Prop. 24)
    gamma : ``"abs"`` (|w−w′|), ``"squared"`` or a callable metric
    up : up vector of coordinate constraints with no axis (§12.2.1)
    rtol : relative tolerance of the co-optimal ``alternatives``

    Returns
    -------
    Alignment

    Examples
    --------
    >>> P = [("t", "h", 1.0), ("t", "a", 2.0), ("t", "b", 3.0), ("t", "c", 4.0)]
    >>> D = [(0, 1, 1.0), (0, 2, 2.0), (0, 3, 2.0), (3, 4, 1.0), (0, 5, 4.0)]
    >>> align(P, D, method="aha").distance
    0.0
    """
    m = _cached_matcher(pattern, method, cut, gamma, pattern_root, up, rtol)
    al = m.align(data, data_root=data_root)
    for c in m.betweenness:
        from topopose.match.betweenness import apply_betweenness

        al = apply_betweenness(al, m.pattern, as_tree(data, name="data"), c)
    return al


#: the Matchers of the last patterns :func:`align` saw (bounded LRU keyed by content)
_MATCHERS: "OrderedDict" = None
MATCHER_CACHE_SIZE = 16


def _pattern_key(pattern):
    """Content key of a pattern: its edges, root and constraints (None when unhashable)."""
    tree, root, cons = _model_parts(pattern)
    try:
        key = (tuple((u, v, float(w)) for u, v, w in tree.edges), tuple(tree.vertices), root,
               tuple(repr(c) for c in cons))
        hash(key)
    except TypeError:
        return None
    return key


def _cached_matcher(pattern, method, cut, gamma, pattern_root, up, rtol) -> Matcher:
    """The :class:`Matcher` of this pattern and these options, reused across calls: the plain
    ``align(model, tree)`` called again and again with one model prepares the model once."""
    global _MATCHERS
    from collections import OrderedDict

    if _MATCHERS is None:
        _MATCHERS = OrderedDict()
    pkey = _pattern_key(pattern)
    try:
        key = (pkey, method, bool(cut), gamma, pattern_root, tuple(np.ravel(up).tolist())
               if not isinstance(up, str) else up, float(rtol))
        hash(key)
    except TypeError:
        key = None
    if pkey is None or key is None:
        return Matcher(pattern, method=method, cut=cut, gamma=gamma, pattern_root=pattern_root, up=up,
                       rtol=rtol)
    m = _MATCHERS.get(key)
    if m is None:
        m = Matcher(pattern, method=method, cut=cut, gamma=gamma, pattern_root=pattern_root, up=up,
                    rtol=rtol)
        _MATCHERS[key] = m
        while len(_MATCHERS) > MATCHER_CACHE_SIZE:
            _MATCHERS.popitem(last=False)
    else:
        _MATCHERS.move_to_end(key)
    return m
