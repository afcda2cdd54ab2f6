"""Topologically coherent intervals, graph similarity, and rigid parts from node motion.

Mukasa et al. §2.2 (coherent intervals), §2.3 (initial frame by graph similarity,
clustering by velocity cross-correlation, eq. 5–6) and §2.4 (integration per branch).
"""
from __future__ import annotations

from collections import Counter

import numpy as np
from scipy.spatial import cKDTree

#: The paper's rule for a human (§2.2): five end points; branch points 4+3 or 3+3+3.
HUMAN_RULE = (5, {(4, 3), (3, 3, 3)})


# --------------------------------------------------------------------------- §2.2
def _splits(sig: tuple) -> set:
    """Branch-degree multisets reachable by splitting one branch point of degree d >= 4
    into two adjacent ones of degrees a, b >= 3 with a + b - 2 = d."""
    out = set()
    for i, d in enumerate(sig):
        rest = sig[:i] + sig[i + 1:]
        for a in range(3, d):
            b = d + 2 - a
            if b >= 3:
                out.add(tuple(sorted(rest + (a, b), reverse=True)))
    return out


def _merges(sig: tuple) -> set:
    out = set()
    for i in range(len(sig)):
        for j in range(i + 1, len(sig)):
            rest = tuple(x for k, x in enumerate(sig) if k not in (i, j))
            out.add(tuple(sorted(rest + (sig[i] + sig[j] - 2,), reverse=True)))
    return out


def coherence_rule(signatures, rule="frequent"):
    """The admissible tree signatures of a sequence (Mukasa §2.2, generalized).

    Parameters
    ----------
    signatures : list of (end points, branch degrees, loops) per frame (``PERG.signature``).
    rule : ``"frequent"`` | ``"human"`` | ``"ends"`` | (end points, set of branch-degree tuples)
        ``"human"`` is the paper's rule (5 end points; branch degrees 4+3 or 3+3+3).
        ``"frequent"`` generalizes it to any subject: S* = the most frequent loop-free
        signature of the sequence; admitted are S* and the signatures one *split* away
        from it (a junction of degree d seen as two adjacent junctions of degrees a + b − 2
        = d: the pERG "is not necessarily symmetric", §2.2) or one *merge* away, as long as
        the merged junction's degree stays ≤ max(4, the highest degree of S*). For a human
        whose most frequent signature is 4+3 or 3+3+3 this is exactly the paper's rule; for
        a dog it admits shoulders+hips 4+4 and their split variant 4+3+3.

        ``"ends"``: any loop-free graph with the most frequent number of end points (for
        star-like subjects such as a spider, whose many-limbed junction splits in many ways).

    Returns
    -------
    (end points, set of branch-degree tuples, or None for any) or None when no frame is
    loop-free.
    """
    if rule == "human":
        return HUMAN_RULE
    if rule == "ends":
        ends = [e for e, b, loops in signatures if loops == 0 and e >= 2]
        return (Counter(ends).most_common(1)[0][0], None) if ends else None
    if isinstance(rule, tuple):
        return int(rule[0]), {tuple(sorted(s, reverse=True)) for s in rule[1]}
    trees = [(e, b) for e, b, loops in signatures if loops == 0 and e >= 2]
    if not trees:
        return None
    (e, b), _ = Counter(trees).most_common(1)[0]
    top = max(4, max(b, default=3))
    allowed = {b} | _splits(b) | {m for m in _merges(b) if max(m) <= top}
    return e, allowed


def is_coherent(sig, rule) -> bool:
    e, b, loops = sig
    return rule is not None and loops == 0 and e == rule[0] and (rule[1] is None or tuple(b) in rule[1])


def intervals(flags) -> list:
    """Maximal runs ``(start, stop)`` (stop exclusive) of True in ``flags``."""
    out, start = [], None
    for i, f in enumerate(list(flags) + [False]):
        if f and start is None:
            start = i
        elif not f and start is not None:
            out.append((start, i))
            start = None
    return out


# --------------------------------------------------------------------------- §2.3
def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric mean nearest-point distance of two node sets, each centred on its mean."""
    a = a - a.mean(0)
    b = b - b.mean(0)
    return 0.5 * (cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean())


def velocity_correlation(traj: np.ndarray) -> np.ndarray:
    """Cross-correlation r(i, j) of node velocities over an interval (eq. 5–6).

    Parameters
    ----------
    traj : (T, n, 3) node positions over T frames.

    Returns
    -------
    (n, n) matrix; velocity vectors are compared by their dot product.
    """
    v = np.diff(traj, axis=0)
    vc = v - v.mean(0)
    num = np.einsum("tid,tjd->ij", vc, vc)
    en = np.sqrt(np.maximum(np.diag(num), 0))
    den = np.outer(en, en)
    return np.where(den > 0, num / np.maximum(den, 1e-300), 0.0), en


def segment_chain(R: np.ndarray, tau: float) -> list:
    """Cut a chain of nodes into contiguous rigid pieces (clustering by eq. 5).

    Maximizes Σ_pieces Σ_{i<j in piece} (r(i, j) − τ) by dynamic programming: the
    neighbouring-node clustering of §2.3 made robust by using every pair of the piece.

    Returns
    -------
    list of cut positions c (a cut between chain nodes c − 1 and c).
    """
    k = len(R)
    S = np.asarray(R, float) - tau
    np.fill_diagonal(S, 0.0)
    C = S.cumsum(0).cumsum(1)

    def gain(a, b):  # piece [a, b)
        b1 = b - 1
        tot = C[b1, b1] - (C[a - 1, b1] if a else 0) - (C[b1, a - 1] if a else 0) + (C[a - 1, a - 1] if a else 0)
        return 0.5 * tot

    best = np.full(k + 1, -np.inf)
    best[0] = 0.0
    arg = np.zeros(k + 1, int)
    for b in range(1, k + 1):
        for a in range(b):
            g = best[a] + gain(a, b)
            if g > best[b] + 1e-12:
                best[b], arg[b] = g, a
    cuts, b = [], k
    while b > 0:
        a = arg[b]
        if a > 0:
            cuts.append(a)
        b = a
    return sorted(cuts)


def chains(n: int, edges: np.ndarray, keys: set | None = None) -> list:
    """Chains of a tree between key nodes (default: nodes of degree != 2), as node lists."""
    adj = [[] for _ in range(n)]
    for a, b in edges:
        adj[a].append(int(b))
        adj[b].append(int(a))
    if keys is None:
        keys = {v for v in range(n) if len(adj[v]) != 2}
    out, seen = [], set()
    for s in sorted(keys):
        for u in adj[s]:
            if (s, u) in seen:
                continue
            ch, prev, cur = [s], s, u
            while cur not in keys:
                ch.append(cur)
                nxt = [w for w in adj[cur] if w != prev]
                prev, cur = cur, nxt[0]
            ch.append(cur)
            seen.add((s, u))
            seen.add((cur, ch[-2]))
            out.append(ch)
    return out
