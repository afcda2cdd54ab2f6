"""Pose clustering by betweenness relations (thesis §13.3.2.2).

"For each frame where an output pose is provided, we compute the set of all betweenness
relations between three parts of the subject. Two poses are considered similar if their
betweenness relation sets are similar enough (the cardinality of their intersection over the
cardinality of their union)."

* :func:`relation_set`: the triples (A, B, C) with B between A and C for R_b (§12.2.2.1;
  symmetric in A and C, so each is stored once with A < C), over the parts with a position.
* :func:`similarity_matrix`: Jaccard |A ∩ B| / |A ∪ B| of every pair of frames. A tree cannot
  tell numbered limbs apart (hand_1 / hand_2 may swap between frames), so the similarity is the
  best one over the renumberings of numbered parts (parts ``name_1, name_2, ...`` sharing a
  base name) when there are at most ``max_renumberings`` of them (human: 2! × 2! = 4), and the
  plain one otherwise. A frame with a part unplaced (a missing limb) is compared with another
  on the triples whose three parts both frames placed (``defined``): an unplaced part is not
  known, not "between nothing" — counted as absent relations, one missing hand made a kick
  frame a cluster of its own (``benchmarks/applications.py``: K found +5 in one of 3 runs).
* :func:`cluster_poses`: average-linkage hierarchical clustering (SciPy) of 1 − similarity;
  cut at ``threshold``, at ``clusters`` clusters, or automatically at the best mean silhouette
  (``auto="silhouette"``, default) or at the largest gap between successive merge heights
  (``auto="gap"``); one medoid frame per cluster.
* :func:`adjusted_rand_index`: Hubert & Arabie's ARI from the contingency table.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field

import numpy as np

from topopose.errors import InputError


def triples(parts) -> list:
    """Every (A, B, C) with A < C (list order) and B distinct from both: the possible relations."""
    parts = list(parts)
    n = len(parts)
    return [(parts[a], parts[b], parts[c]) for a in range(n) for c in range(a + 1, n)
            for b in range(n) if b != a and b != c]


def relation_set(positions: dict, relation: str = "b") -> frozenset:
    """The betweenness relations of one pose: ``{(A, B, C): B between A and C}`` (A before C in
    the order of ``positions``; parts without position are left out).

    Examples
    --------
    >>> sorted(relation_set({"a": (0, 0, 0), "b": (1, 0.1, 0), "c": (2, 0, 0)}))
    [('a', 'b', 'c')]
    """
    from topopose.match.betweenness import betweenness

    pts = {k: np.asarray(v, float) for k, v in positions.items() if v is not None}
    return frozenset(t for t in triples(pts) if betweenness(pts[t[0]], pts[t[2]], pts[t[1]], relation))


def numbered_groups(parts) -> list:
    """Groups of numbered parts sharing a base name: ``[["hand_1", "hand_2"], ...]``."""
    groups = {}
    for p in parts:
        m = re.fullmatch(r"(.+?)_?(\d+)", p)
        if m:
            groups.setdefault(m.group(1), []).append(p)
    return [g for g in groups.values() if len(g) > 1]


def renumberings(parts, limit: int = 24) -> list:
    """Permutations of ``parts`` (as index arrays) that swap numbered parts within their group;
    only the identity when there are more than ``limit``."""
    parts = list(parts)
    groups = numbered_groups(parts)
    if math.prod(math.factorial(len(g)) for g in groups) > limit:
        groups = []
    idx = {p: i for i, p in enumerate(parts)}
    out = []
    for combo in itertools.product(*(itertools.permutations(g) for g in groups)):
        perm = np.arange(len(parts))
        for g, pg in zip(groups, combo):
            for a, b in zip(g, pg):
                perm[idx[a]] = idx[b]
        out.append(perm)
    return out


def relation_matrix(frames_parts: list, parts: list, relation: str = "b") -> np.ndarray:
    """Boolean (frames × triples) matrix of the relations of each frame (triples of ``parts``)."""
    T = triples(parts)
    col = {t: i for i, t in enumerate(T)}
    M = np.zeros((len(frames_parts), len(T)), bool)
    for f, pos in enumerate(frames_parts):
        for t in relation_set({p: pos.get(p) for p in parts}, relation):
            M[f, col[t]] = True
    return M


def _permuted_columns(parts, perm) -> np.ndarray:
    """Column index of each triple after renaming parts[i] -> parts[perm[i]]."""
    T = triples(parts)
    col = {t: i for i, t in enumerate(T)}
    name = {p: parts[perm[i]] for i, p in enumerate(parts)}
    order = {p: i for i, p in enumerate(parts)}
    out = np.empty(len(T), np.int64)
    for i, (a, b, c) in enumerate(T):
        a2, b2, c2 = name[a], name[b], name[c]
        if order[a2] > order[c2]:
            a2, c2 = c2, a2
        out[i] = col[(a2, b2, c2)]
    return out


def defined_matrix(frames_parts: list, parts: list) -> np.ndarray:
    """Boolean (frames × triples) matrix: whether the frame placed all three parts of a triple."""
    have = np.array([[pos.get(p) is not None for p in parts] for pos in frames_parts], bool)
    idx = {p: i for i, p in enumerate(parts)}
    T = np.array([[idx[a], idx[b], idx[c]] for a, b, c in triples(parts)], np.int64).reshape(-1, 3)
    return have[:, T].all(axis=2)


def similarity_matrix(M: np.ndarray, parts=None, max_renumberings: int = 24,
                      defined: np.ndarray = None) -> np.ndarray:
    """Jaccard similarity |A ∩ B| / |A ∪ B| of the rows of a relation matrix (1 for two empty
    sets), best over the renumberings of numbered ``parts`` (see the module docstring).
    ``defined`` (:func:`defined_matrix`; None: every triple): each pair of frames is compared
    on the triples both define."""
    A = M.astype(np.float64)
    V = np.ones_like(A) if defined is None else defined.astype(np.float64)
    perms = renumberings(parts, max_renumberings) if parts is not None else [None]
    best = None
    for perm in perms:
        cols = None if perm is None else np.argsort(_permuted_columns(list(parts), perm))
        B, VB = (A, V) if cols is None else (A[:, cols], V[:, cols])
        inter = A @ B.T
        union = A @ VB.T + V @ B.T - inter
        with np.errstate(invalid="ignore", divide="ignore"):
            S = np.where(union > 0, inter / np.maximum(union, 1e-300), 1.0)
        best = S if best is None else np.maximum(best, S)
    return np.maximum(best, best.T)


def adjusted_rand_index(a, b) -> float:
    """Adjusted Rand index of two labelings (Hubert & Arabie 1985), from the contingency table.

    Examples
    --------
    >>> adjusted_rand_index([0, 0, 1, 1], [1, 1, 0, 0])
    1.0
    >>> round(adjusted_rand_index([0, 0, 0, 1, 1, 1], [0, 0, 1, 1, 2, 2]), 4)
    0.2424
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        raise InputError(f"adjusted_rand_index: labelings of different lengths {a.shape} {b.shape}")
    _, ia = np.unique(a, return_inverse=True)
    _, ib = np.unique(b, return_inverse=True)
    C = np.zeros((ia.max() + 1, ib.max() + 1), np.int64)
    np.add.at(C, (ia, ib), 1)

    def c2(x):
        x = np.asarray(x, np.float64)
        return float((x * (x - 1) / 2).sum())

    n = a.size
    s_ij, s_a, s_b = c2(C), c2(C.sum(1)), c2(C.sum(0))
    total = n * (n - 1) / 2
    expected = s_a * s_b / total if total else 0.0
    top = 0.5 * (s_a + s_b)
    if top == expected:
        return 1.0
    return float((s_ij - expected) / (top - expected))


def silhouette(D: np.ndarray, labels) -> float:
    """Mean silhouette of a labelling over a distance matrix (0 for one cluster)."""
    labels = np.asarray(labels)
    ks = np.unique(labels)
    if ks.size < 2 or ks.size >= labels.size:
        return 0.0
    s = np.zeros(labels.size)
    for i in range(labels.size):
        same = labels == labels[i]
        if same.sum() <= 1:
            continue
        a = D[i, same].sum() / (same.sum() - 1)
        b = min(D[i, labels == k].mean() for k in ks if k != labels[i])
        s[i] = (b - a) / max(a, b) if max(a, b) > 0 else 0.0
    return float(s.mean())


@dataclass
class Clustering:
    """Result of :func:`cluster_poses`: ``labels`` per frame (0..K−1, None for frames without
    pose), ``medoids`` (frame name per cluster), ``k``, the ``method`` of the cut, the ``linkage``
    matrix and the (frames × frames) ``similarity`` of the clustered frames."""

    frames: list
    labels: list
    medoids: list
    k: int
    method: str
    linkage: np.ndarray | None = None
    similarity: np.ndarray | None = None
    used: list = field(default_factory=list)


def cluster_poses(poses, *, clusters=None, threshold=None, auto="silhouette", relation="b",
                  parts=None, max_renumberings=24, matched_only=True) -> Clustering:
    """Cluster the frames of a sequence by their betweenness relation sets (thesis §13.3.2.2).

    Parameters
    ----------
    poses : list of :class:`~topopose.pose.Pose` (or dicts frame/status/parts)
    clusters : int, optional
        Number of clusters (SciPy ``fcluster`` criterion ``maxclust``).
    threshold : float, optional
        Cut the average-linkage dendrogram at this distance 1 − similarity.
    auto : "silhouette" or "gap"
        Without ``clusters`` and ``threshold``: cut at the K in 2..min(20, n−1) of best mean
        silhouette (default), or in the middle of the largest gap between successive merge
        heights. Measured in ``benchmarks/applications.py``: the gap rule often stops at two
        clusters when one group of poses stands apart; the silhouette finds K within ±1.
    relation : betweenness relation (R_b by default, the thesis' choice)
    parts : the parts to use (default: those of the first pose)
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    from topopose._paths import check_number

    clusters = check_number(clusters, "clusters", low=1, integer=True)
    threshold = check_number(threshold, "threshold", low=0)
    frames, plist, status = [], [], []
    for p in poses:
        frames.append(p.frame if hasattr(p, "frame") else p["frame"])
        status.append(p.status if hasattr(p, "status") else p.get("status", "matched"))
        plist.append(p.parts if hasattr(p, "parts") else p["parts"])
    if parts is None:
        parts = list(plist[0]) if plist else []
    used = [i for i, s in enumerate(status)
            if (s == "matched" or not matched_only)
            and sum(plist[i].get(q) is not None for q in parts) >= 3]
    labels = [None] * len(frames)
    if len(used) < 2:
        for j, i in enumerate(used):
            labels[i] = 0
        return Clustering(frames, labels, [frames[i] for i in used[:1]], len(used[:1]), "trivial",
                          used=used)
    fp = [plist[i] for i in used]
    M = relation_matrix(fp, list(parts), relation)
    S = similarity_matrix(M, list(parts), max_renumberings, defined_matrix(fp, list(parts)))
    D = 1.0 - S
    np.fill_diagonal(D, 0.0)
    Z = linkage(squareform(D, checks=False), method="average")
    if clusters is not None:
        lab = fcluster(Z, t=int(clusters), criterion="maxclust")
        method = f"clusters={int(clusters)}"
    elif threshold is not None:
        lab = fcluster(Z, t=float(threshold), criterion="distance")
        method = f"threshold={float(threshold):g}"
    elif auto == "gap":
        h = np.concatenate([[0.0], Z[:, 2]])
        g = int(np.argmax(np.diff(h)))
        cut = 0.5 * (h[g] + h[g + 1])
        lab = fcluster(Z, t=cut, criterion="distance")
        method = f"gap (cut at {cut:.3f})"
    elif auto == "silhouette":
        best = None
        for k in range(2, min(20, len(used) - 1) + 1):
            lk = fcluster(Z, t=k, criterion="maxclust")
            s = silhouette(D, lk)
            if best is None or s > best[0] + 1e-12:
                best = (s, lk, k)
        lab = best[1] if best else np.ones(len(used), int)
        method = f"silhouette ({best[0]:.3f})" if best else "silhouette"
    else:
        raise InputError(f"cluster: auto must be 'gap' or 'silhouette', got {auto!r}")
    # clusters numbered by their first frame
    _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    lab = rank[inv]
    medoids = []
    for k in range(first.size):
        m = np.flatnonzero(lab == k)
        medoids.append(frames[used[int(m[np.argmin(D[np.ix_(m, m)].sum(1))])]])
    for j, i in enumerate(used):
        labels[i] = int(lab[j])
    return Clustering(frames, labels, medoids, int(first.size), method, Z, S, used)


def _model_edges(poses):
    from topopose.pose.model import load_model

    for p in poses:
        name = (getattr(p, "diagnostics", None) or {}).get("model")
        if name:
            try:
                return load_model(name).tree.edges
            except InputError:
                return []
    return []


def cluster_figure(poses, result: Clustering, out, up="+z") -> None:
    """Medoid poses side by side (2D projections: the main horizontal axis against up, with the
    model's edges as sticks) above a timeline of the frames coloured by cluster."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from topopose.apps.detect import up_frame

    R = up_frame(up)
    byframe = {p.frame: p for p in poses}
    edges = _model_edges(poses)
    k = max(result.k, 1)
    cmap = plt.get_cmap("tab10" if k <= 10 else "tab20")
    fig = plt.figure(figsize=(min(2.0 * k + 1, 16), 4.2), dpi=80)
    gs = fig.add_gridspec(2, k, height_ratios=[4, 1])
    for c, fr in enumerate(result.medoids):
        ax = fig.add_subplot(gs[0, c])
        pos = {q: R @ np.asarray(v, float) for q, v in byframe[fr].parts.items() if v is not None}
        P = np.array(list(pos.values()))
        hv = P[:, :2] - P[:, :2].mean(0)
        w = np.linalg.svd(hv, full_matrices=False)[2][0] if len(P) > 1 else np.array([1.0, 0.0])
        xy = {q: (float(v[:2] @ w), float(v[2])) for q, v in pos.items()}
        for u, v, _ in edges:
            if u in xy and v in xy:
                ax.plot([xy[u][0], xy[v][0]], [xy[u][1], xy[v][1]], "-", color=cmap(c % cmap.N), lw=2)
        for q, (x, y) in xy.items():
            ax.plot(x, y, "o", color="k", ms=3)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        n = sum(lab == c for lab in result.labels)
        ax.set_title(f"cluster {c}\nmedoid {fr} ({n})", fontsize=8)
    ax = fig.add_subplot(gs[1, :])
    lab = np.array([-1 if v is None else v for v in result.labels])
    colours = np.array([(0.85, 0.85, 0.85, 1.0) if v < 0 else cmap(v % cmap.N) for v in lab])
    ax.imshow(colours[None, :, :], aspect="auto", interpolation="nearest")
    ax.set_yticks([])
    ax.set_xlabel(f"frame (grey: no pose); {result.k} clusters, {result.method}", fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
