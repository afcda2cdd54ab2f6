"""Kinematic structure from a sequence of visual hulls (Mukasa et al., ELCVIA 2009).

:func:`learn_structure` runs the paper's off-line process (§2, steps 2–7) on a list of
volumes; :func:`learn_model` does the same on a capture (visual hull per frame first).

1. per frame, the pERG (:func:`topopose.kinematics.reeb.perg`, §2.1);
2. topologically coherent intervals (§2.2; :func:`~.structure.coherence_rule`);
3. the initial model: the pERG of the coherent frame most similar to all other coherent
   frames (§2.3); it is deformed frame after frame (:class:`~.deform.Deformer`, §2.3.1),
   each time starting from the already-deformed frame most similar to the target
   ("updating initial model based on correlation of pERG"). This implementation tracks
   *one* initial model over the whole sequence, coherent and incoherent frames alike: the
   node correspondence between intervals then comes for free, and the deformation into
   incoherent frames is the fit of §2.5;
4. per coherent interval, the nodes of every chain (branch) of the model are clustered
   into rigid pieces by velocity cross-correlation (eq. 5–6): the piecewise kinematic
   structures (§2.3);
5. integration (§2.4): for every branch, the most detailed piecewise structure (most
   joints) among the intervals;
6. per frame, the joints (piece boundaries), end points and junctions of the integrated
   structure are read off the deformed model (§2.5).

The result is a joint tree (every joint a vertex) and its homeomorphic reduction (end
points and junctions only; edge length = sum of the median segment lengths along it),
written as a model tree usable by ``topopose run``. When the reduced tree is isomorphic to
a built-in model (human, dog, spider) its parts take that model's names (and the model's
"above"/"below" constraints that hold in ≥ 95 % of the frames), so that ``topopose run``
and ``topopose evaluate`` can use it as they use the built-in one.

Additions to the paper, each documented where it is made: Hilaga's T-sets and
farthest-point base points for the Reeb graph (:mod:`.reeb`), an end-point force in the
deformation (:class:`~.deform.Deformer`), contiguous-piece clustering by dynamic
programming over all pairs of a chain (:func:`~.structure.segment_chain`), still-node
handling (``low_motion``) and joint centres of rotation (:func:`joint_positions`).
"""
from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from topopose.errors import InputError
from topopose.match.tree import Tree
from topopose.kinematics.deform import Deformer, densify
from topopose.kinematics.reeb import PERG, perg
from topopose.kinematics.structure import (chains, coherence_rule, intervals, is_coherent, segment_chain,
                        chamfer, velocity_correlation)


@dataclass
class LearnedStructure:
    """The kinematic structure and motion learned from a sequence.

    Attributes
    ----------
    status : ``"ok"`` or ``"no_coherent_interval"`` (then ``model`` is the best partial
        structure — the reduced pERG of the most typical frame — and ``message`` says why).
    message : str
    model : topopose.pose.Model or None
        The reduced tree (end points and junctions as parts) for ``topopose run``.
    full : Tree
        The joint tree: end points, junctions and joints, edge weights = median segment
        lengths; vertex ids are the joint names.
    frames : list of str
    joints : list of dict name -> (3,) array, one per frame (every vertex of ``full``).
    segments : list of (name, name): the edges of ``full`` (rigid segments).
    coherent : list of bool; signatures : list of tuple; intervals : list of (start, stop).
    rule : the coherence rule used (end points, admitted branch-degree tuples).
    initial_frame : int or None
    nodes : (T, n, 3) deformed model node positions; node_edges : (e, 2).
    diagnostics : dict (timings per step in ms per frame, naming, per-interval joints...).
    """

    status: str
    message: str
    model: object
    full: Tree | None
    frames: list
    joints: list
    segments: list
    coherent: list
    signatures: list
    intervals: list
    rule: object
    initial_frame: int | None
    nodes: np.ndarray | None = None
    node_edges: np.ndarray | None = None
    diagnostics: dict = field(default_factory=dict)

    def records(self):
        """One JSON-able record per frame (JSON Lines, like poses)::

            {"frame": "000012", "status": "coherent" | "incoherent",
             "signature": {"end_points": 5, "branch_degrees": [4, 3], "loops": 0},
             "joints": {"head": [x, y, z], "hand_1_j1": [...], ...},
             "segments": [["hand_1", "hand_1_j1", length], ...]}
        """
        for f, name in enumerate(self.frames):
            J = self.joints[f] if f < len(self.joints) else {}
            e, b, loops = self.signatures[f]
            yield {"frame": name, "status": "coherent" if self.coherent[f] else "incoherent",
                   "signature": {"end_points": e, "branch_degrees": list(b), "loops": loops},
                   "joints": {k: [float(x) for x in v] for k, v in J.items()},
                   "segments": [[a, b, float(np.linalg.norm(np.asarray(J[a]) - np.asarray(J[b])))]
                                for a, b in self.segments if a in J and b in J]}

    def write_jsonl(self, path) -> None:
        with open(path, "w") as fh:
            for rec in self.records():
                fh.write(json.dumps(rec) + "\n")

    def full_model(self):
        """The joint tree as a :class:`topopose.pose.Model` (every joint a part)."""
        if self.full is None:
            return None
        from topopose.pose.model import Model

        root = self.model.root if self.model is not None else None
        return Model(name=(self.model.name + "_joints") if self.model is not None else "joints",
                     tree=Tree(list(self.full.edges), vertices=list(self.full.vertices)),
                     root=root, complete=True,
                     description="joint tree learned by topopose learn-model (every joint a part)")


# --------------------------------------------------------------------------- helpers
def _path_length(P, path):
    return float(sum(np.linalg.norm(P[path[i + 1]] - P[path[i]]) for i in range(len(path) - 1)))


def _tree_of(g: PERG) -> PERG:
    """A spanning tree of a pERG (shortest edges first) for partial structures."""
    if g.n_loops() == 0:
        return g
    import networkx as nx

    G = nx.Graph()
    G.add_nodes_from(range(g.n))
    for a, b in g.edges:
        G.add_edge(int(a), int(b), weight=float(np.linalg.norm(g.positions[a] - g.positions[b])))
    T = nx.minimum_spanning_tree(G)
    comp = max(nx.connected_components(T), key=len)
    idx = sorted(comp)
    remap = {v: i for i, v in enumerate(idx)}
    E = np.array([(remap[a], remap[b]) for a, b in T.edges() if a in remap and b in remap], np.int64).reshape(-1, 2)
    return PERG(g.positions[idx], E, g.mu[idx], g.level[idx], dict(g.diagnostics))


def _junction_groups(P, edges, n, merge_dist):
    """Branch nodes joined by a chain shorter than ``merge_dist`` form one junction."""
    deg = np.bincount(edges.ravel(), minlength=n) if len(edges) else np.zeros(n, int)
    branch = [v for v in range(n) if deg[v] >= 3]
    parent = {v: v for v in branch}

    def find(x):
        while parent[x] != x:
            x = parent[x]
        return x

    for ch in chains(n, edges):
        a, b = ch[0], ch[-1]
        if deg[a] >= 3 and deg[b] >= 3 and _path_length(P, ch) < merge_dist:
            parent[find(a)] = find(b)
    groups = {}
    for v in branch:
        groups.setdefault(find(v), []).append(v)
    return deg, list(groups.values())


def _name_parts(keys, key_edges, lengths, heights, up_ok):
    """Name the reduced tree's vertices after a built-in model when isomorphic to it.

    Among the isomorphisms to a built-in model (human, dog, spider), the one that best
    satisfies the model's "above" constraints in the learned motion (``up_ok(a, b)``: the
    fraction of frames with a above b), then best matches its relative lengths, is chosen.
    Otherwise parts are named end_k / junction_k (ordered from top to bottom).
    Returns (names dict key -> name, builtin Model or None).
    """
    import networkx as nx
    from networkx.algorithms.isomorphism import GraphMatcher

    G = nx.Graph()
    G.add_nodes_from(keys)
    for (a, b), L in zip(key_edges, lengths):
        G.add_edge(a, b, length=L)
    try:
        from topopose.pose.model import load_model
    except Exception:  # pose stage absent
        load_model = None
    best = None
    if load_model is not None:
        for name in ("human", "dog", "spider"):
            try:
                m = load_model(name)
            except Exception:
                continue
            if not m.complete:
                continue
            H = nx.Graph()
            H.add_nodes_from(m.tree.vertices)
            for u, v, w in m.tree.edges:
                H.add_edge(u, v, length=w)
            if H.number_of_nodes() != G.number_of_nodes():
                continue
            gm = GraphMatcher(G, H)
            tot_l = sum(lengths) or 1.0
            tot_m = sum(d["length"] for _, _, d in H.edges(data=True)) or 1.0
            for n_iso, iso in enumerate(gm.isomorphisms_iter()):
                if n_iso >= 5000:        # e.g. 8! leg permutations of a spider: enough
                    break
                cons = 0.0
                for c in m.constraints:
                    if c.kind in ("above", "below") and c.axis is None:
                        inv = {v: k for k, v in iso.items()}
                        a, b = inv[c.parts[0]], inv[c.parts[1]]
                        frac = up_ok(a, b)
                        cons += frac if c.kind == "above" else 1 - frac
                lerr = sum(abs(G.edges[a, b]["length"] / tot_l - H.edges[iso[a], iso[b]]["length"] / tot_m)
                           for a, b in G.edges)
                score = (round(cons, 6), -lerr)
                if best is None or score > best[0]:
                    best = (score, dict(iso), m)
    if best is not None:
        return best[1], best[2]
    order = sorted(keys, key=lambda k: -heights[k])
    names, ne, nj = {}, 0, 0
    for k in order:
        if G.degree(k) == 1:
            ne += 1
            names[k] = f"end_{ne}"
        else:
            nj += 1
            names[k] = f"junction_{nj}"
    return names, None


# --------------------------------------------------------------------------- main
@dataclass(frozen=True)
class LearnOptions:
    """Options of :func:`learn_structure` (Mukasa §2); see its parameters."""

    coherence: str = "frequent"
    tau: float = 0.97
    low_motion: float = 0.25
    min_interval: int = 4
    window: int = 3
    merge: float = 0.1
    coarse: int = 16
    fine: int = 64
    n_base: int = 64
    step_size: int = 1
    deform: dict | None = None
    criterion: str = "correlation"
    rigidity: float = 0.002
    smooth: float = 0.0
    place_joints: bool = True


def learn_structure(volumes, frames=None, options: LearnOptions | None = None, *,
                    up=(0.0, 0.0, 1.0), name: str | None = None, source: str = "sequence",
                    progress: bool = False, pergs: list | None = None,
                    **flat) -> LearnedStructure:
    """Learn the kinematic structure and motion from a sequence of volumes (Mukasa §2).

    Parameters
    ----------
    volumes : list of Volume (or of (data, origin, voxel_size) tuples)
    frames : list of frame names (default "000000", ...).
    options : LearnOptions, optional
        The options below (``**flat`` changes them by name, e.g. ``tau=0.9``).
    up : the world up axis (names built-in parts; "above" constraints).
    coherence : rule of §2.2 (see :func:`~.structure.coherence_rule`). With ``"frequent"``,
        when no interval is long enough the rule ``"ends"`` is tried before giving up
        (``diagnostics["coherence_fallback"]``).
    tau : float
        Correlation threshold of the rigid-piece clustering (eq. 5).
    criterion : ``"correlation"`` (eq. 5, the paper) or ``"rigidity"`` (distance
        preservation; see :func:`_affinity`), with ``rigidity`` its noise level × extent.
    smooth : float
        Temporal Gaussian smoothing (frames) of the node trajectories before clustering
        (0: none).
    place_joints : bool
        Place each joint at its estimated centre of rotation (:func:`joint_positions`)
        rather than midway between the two nodes where the chain is cut.
    low_motion : float
        Nodes whose velocity variation (eq. 5's denominator) is below ``low_motion`` × the
        median over the model are "still" (e.g. the trunk of a walker once the mean
        velocity is removed); two still nodes count as perfectly correlated, since their
        correlation is dominated by noise.
    min_interval : int
        Coherent intervals shorter than this are not used for clustering (eq. 5 needs
        several velocity samples).
    window : int
        Frames farther than this from the target are not used as deformation sources.
    merge : float
        Branch points closer than ``merge`` × the subject's extent along the graph form one
        junction (e.g. the 3+3+3 variant of a human's shoulder junction). When the reduced
        tree is isomorphic to no built-in model, 0.2 and 0.3 are tried and kept if one makes
        it so (``diagnostics["junction_merge"]``).
    coarse, fine, n_base, step_size : pERG parameters (:func:`~.reeb.perg`).
    deform : dict
        Keyword arguments of :class:`~.deform.Deformer` (k, dt, steps, sigma); σ defaults
        to (0.06, 0.012) × the subject's extent.
    name, source : the model's name (default: "<built-in>_learned" or "learned") and the
        sequence's name in messages.
    pergs : list of PERG, optional
        Precomputed pERGs of the frames (e.g. to compare settings without recomputing).
    """
    o = replace(options or LearnOptions(), **flat)
    if o.criterion not in ("correlation", "rigidity"):
        raise InputError(f"learn-model: criterion {o.criterion!r} must be 'correlation' or 'rigidity'")
    vols = []
    for v in volumes:
        if hasattr(v, "data"):
            vols.append((np.asarray(v.data, bool), np.asarray(v.origin, float), float(v.voxel_size)))
        else:
            d, o, s = v
            vols.append((np.asarray(d, bool), np.asarray(o, float), float(s)))
    T = len(vols)
    if T == 0:
        raise InputError(f"{source}: no frame to learn from")
    frames = list(frames) if frames is not None else [f"{i:06d}" for i in range(T)]
    if len(frames) != T:
        raise InputError(f"{source}: {len(frames)} frame names for {T} volumes")
    if pergs is not None and len(pergs) != T:
        raise InputError(f"{source}: {len(pergs)} pERGs for {T} volumes")
    up = np.asarray(up, float)
    up = up / np.linalg.norm(up)
    timings = {}
    merge, deform, window = o.merge, o.deform, o.window

    G = _pergs(vols, frames, pergs, o, progress, source, timings)
    extent = float(np.median([g.diagnostics["extent"] for g in G]))

    t0c = time.perf_counter()
    sigs, rule, coh, runs, valid, fallback, status, message, t0, sim = _initial_frame(
        G, frames, o, source)
    timings["coherence"] = 1e3 * (time.perf_counter() - t0c) / T   # with the initial frame
    g0 = _tree_of(G[t0])
    n = g0.n
    E0 = g0.edges

    # 3. deform the initial model over the sequence (§2.3.1, §2.5)
    t0d = time.perf_counter()
    kw = {"sigma": (0.06 * extent, 0.012 * extent)}
    kw.update(deform or {})
    D = Deformer(g0.positions, E0, **kw)
    spacing = float(np.median(np.linalg.norm(g0.positions[E0[:, 0]] - g0.positions[E0[:, 1]], axis=1))) if len(E0) else extent / 20
    Q = np.zeros((T, n, 3))
    Q[t0] = g0.positions
    done = {t0}
    order = sorted(range(T), key=lambda f: (abs(f - t0), f))[1:]
    for f in order:
        src = [s for s in done if abs(s - f) <= window] or [min(done, key=lambda s: abs(s - f))]
        s = max(src, key=lambda s: sim(s, f))
        shift = G[f].positions.mean(0) - G[s].positions.mean(0)
        target = densify(G[f].positions, G[f].edges, 0.5 * spacing)
        dg = G[f].degrees()
        Q[f] = D.fit(Q[s] + shift, target, target_ends=G[f].positions[dg == 1])
        done.add(f)
    timings["deform_fit"] = 1e3 * (time.perf_counter() - t0d) / max(T - 1, 1)   # §2.3.1 + §2.5

    # 4–5. rigid pieces per coherent interval, integrated per branch
    t0k = time.perf_counter()

    st = _structure(g0, E0, n, merge * extent, valid, status, Q, extent, frames, up, o)
    merged = merge
    if st[-1] is None:
        # not (yet) a built-in subject: junctions split in the initial graph (e.g. a spider's
        # 9-limbed cephalothorax) may need a larger merge distance to reveal one
        for mf in (0.2, 0.3):
            if mf > merge:
                st2 = _structure(g0, E0, n, mf * extent, valid, status, Q, extent, frames, up, o)
                if st2[-1] is not None:
                    st, merged = st2, mf
                    break
    (deg, groups, leaves, branch_chains, cuts_per_chain, per_interval, key_pos,
     key_edges, chain_info, seg_len, keys, heights, up_ok, names, builtin) = st
    timings["cluster_integrate"] = 1e3 * (time.perf_counter() - t0k) / T     # §2.3–2.4, joints
    t0f = time.perf_counter()
    full, joints_t, segments, model = _learned_models(keys, names, key_pos, chain_info, key_edges,
                                                      seg_len, builtin, up_ok, T, coh, source,
                                                      name)
    timings["model"] = 1e3 * (time.perf_counter() - t0f) / T
    diag = {"timings_ms_per_frame": timings, "extent": extent, "nodes": n,
            "per_interval": per_interval, "builtin": builtin.name if builtin is not None else None,
            "coherence_fallback": fallback, "junction_merge": merged,
            "valid_intervals": [(frames[a], frames[b - 1]) for a, b in valid]}
    return LearnedStructure(status, message, model, full, frames, joints_t, segments, coh, sigs,
                            runs, rule, t0, Q, E0, diag)


def _affinity(traj, ch, criterion, low_motion, sigma0):
    """Pairwise "same rigid part" affinity of a chain's nodes over an interval.

    ``"correlation"``: eq. 5 (still node pairs count as correlated, see ``low_motion``);
    the chain is then cut with threshold τ. ``"rigidity"`` (an alternative, not in the
    paper): σ0 − std_t |q_i − q_j| (rigid parts keep their nodes' distances; σ0 =
    ``rigidity`` × extent is the tracking noise); cut with threshold 0.
    """
    out = []
    if criterion == "correlation":
        Rm, en = velocity_correlation(traj[:, ch])
        _, en_all = velocity_correlation(traj)
        still = en < low_motion * np.median(en_all)
        Rm = Rm.copy()
        Rm[np.ix_(still, still)] = 1.0
        out.append(Rm)
    if criterion == "rigidity":
        X = traj[:, ch]
        d = np.linalg.norm(X[:, :, None, :] - X[:, None, :, :], axis=3)
        out.append(sigma0 - d.std(0))
    if criterion not in ("correlation", "rigidity"):
        raise InputError(f"learn-model: criterion {criterion!r} must be 'correlation' or 'rigidity'")
    return out[0]


def _line(P):
    """Centroid and unit direction (principal axis) of points P (k, 3)."""
    c = P.mean(0)
    if len(P) < 2:
        return c, None
    _, s, vt = np.linalg.svd(P - c)
    return c, vt[0]


def joint_positions(Q, ch, cuts, start, end, start_junction, end_junction):
    """Per-frame positions of the joints at the cuts of a chain (an addition to §2.3).

    The paper leaves a joint between the two clustered pieces. The nodes of a Reeb graph
    lie on the limbs' axes but the branch nodes sit where the surfaces part (a shoulder's
    is at the armpit, metres from the pivot), so we estimate each joint's centre of rotation:

    - the first joint of a limb from a junction: the nodes of the limb piece beyond it
      turn about a point fixed relative to the junction: a least-squares common-centre
      sphere fit in the junction's translating frame, regularized towards the point of the
      piece's axis nearest the junction (the fit is blind along the rotation axis);
    - joint between two limb pieces: per frame, the point where the two pieces' axes pass
      closest (when they make an angle of more than 10°), else midway between the nodes.

    Falls back to the midpoint of the two cut nodes when an estimate lands farther than the
    adjacent piece's length from it.
    """
    T = Q.shape[0]
    bounds = [0, *cuts, len(ch)]
    out = []
    for k, c in enumerate(cuts):
        prev = ch[bounds[k]:c]
        nxt = ch[c:bounds[k + 2]]
        mid = (Q[:, ch[c - 1]] + Q[:, ch[c]]) / 2
        plen = np.linalg.norm(Q[:, prev[0]] - Q[:, prev[-1]], axis=1).mean()
        nlen = np.linalg.norm(Q[:, nxt[0]] - Q[:, nxt[-1]], axis=1).mean()
        lim = max(plen, nlen, 1e-9)
        first = k == 0 and start_junction and len(nxt) >= 2
        last = k == len(cuts) - 1 and end_junction and len(prev) >= 2
        if first or last:
            J, piece = (start, nxt) if first else (end, prev)
            est = _sphere_centre(Q[:, piece], J)
        else:
            est = mid.copy()
            if len(prev) >= 2 and len(nxt) >= 2:
                for t in range(T):
                    c1, d1 = _line(Q[t, prev])
                    c2, d2 = _line(Q[t, nxt])
                    cosang = abs(float(d1 @ d2))
                    if cosang > np.cos(np.radians(10)):
                        continue
                    # closest points of the two lines
                    w0 = c1 - c2
                    b = float(d1 @ d2)
                    den = 1 - b * b
                    s1 = (b * (d2 @ w0) - (d1 @ w0)) / den
                    s2 = ((d2 @ w0) - b * (d1 @ w0)) / den
                    est[t] = 0.5 * ((c1 + s1 * d1) + (c2 + s2 * d2))
        bad = np.linalg.norm(est - mid, axis=1) > lim
        est[bad] = mid[bad]
        out.append(est)
    return out


def _sphere_centre(X, J, lam: float = 0.05):
    """Centre of rotation of nodes X (T, k, 3) about a point moving with J (T, 3).

    In J's translating frame y = x − J the nodes keep their distance r_i to the centre c:
    |y|² = 2 y·c + (r_i² − |c|²), linear in c and one constant per node; solved by least
    squares with a weak pull (weight ``lam`` per equation) towards the prior c0 = the point of
    the nodes' axis nearest J (averaged over frames). Returns the centre's world positions.
    """
    T, k, _ = X.shape
    Y = X - J[:, None, :]
    # prior: the point of the piece's axis nearest J (the origin in this frame)
    pri = []
    for t in range(T):
        c, d = _line(Y[t])
        pri.append(c - (c @ d) * d if d is not None else c)
    c0 = np.mean(pri, 0)
    rows, rhs = [], []
    for i in range(k):
        for t in range(T):
            r = np.zeros(3 + k)
            r[:3] = 2 * Y[t, i]
            r[3 + i] = 1.0
            rows.append(r)
            rhs.append(Y[t, i] @ Y[t, i])
    A = np.array(rows)
    b = np.array(rhs)
    scale = np.sqrt(len(b))
    reg = np.zeros((3, 3 + k))
    reg[:, :3] = np.eye(3) * lam * scale * 2 * np.abs(Y).mean()
    A = np.vstack([A, reg])
    b = np.concatenate([b, reg[:, :3] @ c0])
    sol = np.linalg.lstsq(A, b, rcond=None)[0]
    return J + sol[:3]


def _clean_cuts(cuts, ch, deg):
    """Drop cuts that would leave a piece made of a lone end point, or of one node inside
    a chain (noise); keep a lone junction node (the junction's own rigid part)."""
    out = []
    k = len(ch)
    for c in cuts:
        if c == 1 and deg[ch[0]] == 1:
            continue
        if c == k - 1 and deg[ch[-1]] == 1:
            continue
        if out and c - out[-1] == 1 and out[-1] != 1:
            continue
        out.append(c)
    return out


# --------------------------------------------------------------------------- metrics
def joint_metrics(detected, truth, height: float) -> tuple:
    """Mukasa eq. 7–9: detection rate and mean nearest-node distance, normalized by height.

    Parameters
    ----------
    detected : dict name -> (3,) or (k, 3) array: the learned structure's points (joints,
        end points, junctions) in one frame.
    truth : dict name -> (3,) or (m, 3) array: the ground-truth joints of that frame.
    height : subject height.

    Returns
    -------
    (R_detection, E_dist): R = S / m, S the number of ground-truth joints m_i whose nearest
    node n_j has m_i as its own nearest joint (eq. 7; eq. 8 writes i_max, the last index —
    we divide by the number of joints m = i_max + 1); E = mean over joints of the distance
    to the nearest node / height (eq. 9).
    """
    N = np.asarray(list(detected.values()) if isinstance(detected, dict) else detected, float).reshape(-1, 3)
    M = np.asarray(list(truth.values()) if isinstance(truth, dict) else truth, float).reshape(-1, 3)
    if len(N) == 0 or len(M) == 0:
        return 0.0, float("nan")
    d = np.linalg.norm(M[:, None, :] - N[None, :, :], axis=2)
    nn_m = d.argmin(1)              # nearest node of each joint
    nn_n = d.argmin(0)              # nearest joint of each node
    S = int(np.sum(nn_n[nn_m] == np.arange(len(M))))
    return S / len(M), float(d.min(1).mean() / height)


def _pergs(vols, frames, pergs, o, progress, source, timings) -> list:
    """Step 1: the pERG of each frame (or the given ones), their mean timings in ``timings``."""
    T = len(vols)
    coarse, fine, n_base, step_size = o.coarse, o.fine, o.n_base, o.step_size
    # 1. pERG per frame
    it = range(T)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="pERG", unit="frame")
    G = []
    tm = {"mesh": 0.0, "geodesic": 0.0, "reeb_perg": 0.0}
    for f in it:
        if pergs is not None:
            g = pergs[f]
        else:
            d, o, s = vols[f]
            if not d.any():
                raise InputError(f"{source}: frame {frames[f]} has an empty volume")
            g = perg(d, o, s, coarse=coarse, fine=fine, n_base=n_base, step_size=step_size)
        for k in tm:
            tm[k] += g.diagnostics["timings_ms"][k]
        G.append(g)
    timings.update({k: v / T for k, v in tm.items()})
    return G


def _initial_frame(G, frames, o, source):
    """Step 2: the coherent intervals (§2.2) and the initial frame (§2.3): ``(sigs, rule, coh,
    runs, valid, fallback, status, message, t0, sim)``, ``sim`` the frames' similarity."""
    T = len(G)
    coherence, min_interval = o.coherence, o.min_interval
    sigs = [g.signature() for g in G]
    rule = coherence_rule(sigs, coherence)
    coh = [is_coherent(s, rule) for s in sigs]
    runs = intervals(coh)
    valid = [(a, b) for a, b in runs if b - a >= max(min_interval, 3)]
    fallback = None
    if not valid and coherence == "frequent":
        # star-like subjects: their junction splits in many ways; accept any loop-free
        # graph with the usual number of end points
        rule2 = coherence_rule(sigs, "ends")
        coh2 = [is_coherent(s, rule2) for s in sigs]
        runs2 = intervals(coh2)
        valid2 = [(a, b) for a, b in runs2 if b - a >= max(min_interval, 3)]
        if valid2:
            fallback = "ends"
            rule, coh, runs, valid = rule2, coh2, runs2, valid2
    pts = [g.positions for g in G]
    cache = {}

    def sim(i, j):
        """−chamfer of two pERGs' node sets (stands in for the AMRG similarity of [11])."""
        if i == j:
            return 0.0
        k = (min(i, j), max(i, j))
        if k not in cache:
            cache[k] = -chamfer(pts[i], pts[j])
        return cache[k]

    def spread(frames_, n=40):
        """At most n frames evenly spread over ``frames_`` (bounds the O(T²) choice)."""
        if len(frames_) <= n:
            return list(frames_)
        return [frames_[i] for i in np.linspace(0, len(frames_) - 1, n).astype(int)]

    status, message = "ok", ""
    cand = [f for a, b in valid for f in range(a, b)]
    if not cand:
        status = "no_coherent_interval"
        if rule is None:
            why = "no frame has a loop-free graph (limbs touch in every frame)"
        elif not any(coh):
            why = "no frame matches the coherence rule"
        else:
            why = (f"coherent frames only in intervals shorter than {max(min_interval, 3)} frames "
                   f"({', '.join(f'{frames[a]}–{frames[b - 1]}' for a, b in runs)})")
        if rule is None:
            rule_txt = "none"
        else:
            degs = "any" if rule[1] is None else sorted(rule[1])
            if degs != "any" and len(degs) > 3:
                degs = f"{degs[:3]} and {len(degs) - 3} more"
            rule_txt = f"{rule[0]} end points, branch degrees {degs}"
        message = (f"{source}: no topologically coherent interval (Mukasa §2.2; rule: {rule_txt}): "
                   f"{why}. Wrote the best partial structure (the reduced graph of the most "
                   f"typical frame) without joints.")
        common = Counter((e, b) for e, b, l in sigs).most_common(1)[0][0]
        pool = [f for f in range(T) if sigs[f][:2] == common] or list(range(T))
        ref = spread(pool)
        t0 = max(spread(pool), key=lambda f: sum(sim(f, j) for j in ref))
    else:
        pool = [f for f in range(T) if coh[f]]
        ref = spread(pool)
        # the initial model has the most frequent signature of the usable frames (the most
        # typical graph), then the highest similarity to all coherent frames (§2.3)
        typical = Counter(sigs[f] for f in cand).most_common(1)[0][0]
        cand = [f for f in cand if sigs[f] == typical]
        t0 = max(spread(cand), key=lambda f: sum(sim(f, j) for j in ref))

    return sigs, rule, coh, runs, valid, fallback, status, message, t0, sim


def _structure(g0, E0, n, merge_dist, valid, status, Q, extent, frames, up, o):
    """Steps 4–6 with branch points closer than ``merge_dist`` merged into junctions."""
    smooth, criterion, low_motion, rigidity, tau, place_joints = (
        o.smooth, o.criterion, o.low_motion, o.rigidity, o.tau, o.place_joints)
    deg, groups = _junction_groups(g0.positions, E0, n, merge_dist)
    group_of = {v: i for i, gr in enumerate(groups) for v in gr}
    leaves = [v for v in range(n) if deg[v] == 1]
    all_chains = chains(n, E0)
    branch_chains = [ch for ch in all_chains
                     if not (ch[0] in group_of and ch[-1] in group_of and group_of[ch[0]] == group_of[ch[-1]])]
    cuts_per_chain = {}
    per_interval = []
    for ci, ch in enumerate(branch_chains):
        best = ([], -1, 0)
        for a, b in (valid if status == "ok" else []):
            traj = Q[a:b]
            if smooth > 0:
                from scipy.ndimage import gaussian_filter1d

                traj = gaussian_filter1d(traj, smooth, axis=0, mode="nearest")
            Rm = _affinity(traj, ch, criterion, low_motion, rigidity * extent)
            cuts = _clean_cuts(segment_chain(Rm, tau if criterion == "correlation" else 0.0), ch, deg)
            per_interval.append({"interval": [frames[a], frames[b - 1]], "chain": ci, "joints": len(cuts)})
            if (len(cuts), b - a) > (len(best[0]), best[2]):
                best = (cuts, a, b - a)
        cuts_per_chain[ci] = best[0]

    # 6. the integrated structure: vertices and their per-frame positions
    key_pos = {}          # key id -> (T, 3)
    for v in leaves:
        key_pos[("end", v)] = Q[:, v]
    for i, gr in enumerate(groups):
        key_pos[("junction", i)] = Q[:, gr].mean(1)

    def key_of(v):
        return ("end", v) if deg[v] == 1 else ("junction", group_of[v])

    key_edges, chain_info = [], []
    seg_len = []
    for ci, ch in enumerate(branch_chains):
        a, b = key_of(ch[0]), key_of(ch[-1])
        cuts = cuts_per_chain[ci]
        jpos = joint_positions(Q, ch, cuts, key_pos[a], key_pos[b],
                               a[0] == "junction", b[0] == "junction") if place_joints else \
            [(Q[:, ch[c - 1]] + Q[:, ch[c]]) / 2 for c in cuts]
        seq = [key_pos[a], *jpos, key_pos[b]]
        lens = [float(np.median(np.linalg.norm(seq[i + 1] - seq[i], axis=1))) for i in range(len(seq) - 1)]
        key_edges.append((a, b))
        chain_info.append((a, b, jpos, lens))
        seg_len.append(sum(lens))
    keys = list(key_pos)
    heights = {k: float(np.median(key_pos[k] @ up)) for k in keys}

    def up_ok(a, b):
        return float(np.mean((key_pos[a] - key_pos[b]) @ up > 0))

    names, builtin = _name_parts(keys, key_edges, seg_len, heights, up_ok)
    return (deg, groups, leaves, branch_chains, cuts_per_chain, per_interval, key_pos,
            key_edges, chain_info, seg_len, keys, heights, up_ok, names, builtin)


def _learned_models(keys, names, key_pos, chain_info, key_edges, seg_len, builtin, up_ok, T,
                    coh, source, name):
    """The full joint tree, the joints' per-frame positions and the reduced model (the
    homeomorphic reduction of the joint tree): ``(full, joints_t, segments, model)``."""
    # full joint tree
    full_edges, joints_t = [], [dict() for _ in range(T)]
    for k in keys:
        for f in range(T):
            joints_t[f][names[k]] = key_pos[k][f]
    for (a, b, jpos, lens) in chain_info:
        na, nb = names[a], names[b]
        if a[0] == "end":          # number the joints from the end point inwards
            stem, order_j = na, list(range(len(jpos)))
            seqn = [na] + [f"{stem}_j{i + 1}" for i in order_j] + [nb]
        elif b[0] == "end":
            stem = nb
            seqn = [na] + [f"{stem}_j{len(jpos) - i}" for i in range(len(jpos))] + [nb]
        else:
            stem = f"{na}_{nb}"
            seqn = [na] + [f"{stem}_j{i + 1}" for i in range(len(jpos))] + [nb]
        for i, p in enumerate(jpos):
            for f in range(T):
                joints_t[f][seqn[i + 1]] = p[f]
        for i in range(len(seqn) - 1):
            full_edges.append((seqn[i], seqn[i + 1], lens[i]))
    full = Tree(full_edges) if full_edges else (Tree([], vertices=[names[keys[0]]]) if len(keys) == 1 else None)
    segments = [(u, v) for u, v, _ in full_edges]

    # the reduced model (homeomorphic reduction of the joint tree)
    from topopose.pose.model import Model

    red_edges = [(names[a], names[b], max(L, 1e-6)) for (a, b), L in zip(key_edges, seg_len)]
    cons = []
    if builtin is not None:
        inv = {v: k for k, v in names.items()}
        for c in builtin.constraints:
            if c.kind in ("above", "below") and all(p in inv for p in c.parts[:2]):
                frac = up_ok(inv[c.parts[0]], inv[c.parts[1]])
                if (frac if c.kind == "above" else 1 - frac) >= 0.95:
                    cons.append(c)
            elif c.kind == "between":
                pass  # chirality is not learned
        root = builtin.root
        mname = name or f"{builtin.name}_learned"
    else:
        jn = [names[k] for k in keys if k[0] == "junction"]
        degs = Counter(p for e in red_edges for p in e[:2])
        root = max(jn, key=lambda p: degs[p]) if jn else None
        mname = name or "learned"
    model = None
    if red_edges:
        desc = (f"learned by topopose learn-model (Mukasa et al.) from {source}: "
                f"{len(full.vertices)} joints, {sum(coh)}/{T} coherent frames")
        model = Model(name=mname, tree=Tree(red_edges, constraints=cons), root=root, complete=True,
                      description=desc)
    return full, joints_t, segments, model


# --------------------------------------------------------------------------- captures
def learn_model(capture, resolution: int = 100, frames=None, *, progress: bool = False,
                **kwargs) -> LearnedStructure:
    """Learn the model tree of a subject from a capture (or a list of volumes).

    Parameters
    ----------
    capture : Capture, path of a capture folder, or list of Volume
    resolution : voxels along the longest side of the capture volume (visual hull).
    frames : frame names or indices to use (default: all).
    kwargs : see :func:`learn_structure`.
    """
    if isinstance(capture, (list, tuple)):
        return learn_structure(capture, frames=frames, progress=progress, **kwargs)
    if isinstance(capture, (str, Path)):
        from topopose.capture import load_capture

        capture = load_capture(capture)
    from topopose.hull import visual_hull

    names = [capture.frame_name(f) for f in (frames if frames is not None else capture.frames)]
    if len(names) < 3:
        raise InputError(f"{capture.path or 'capture'}: learn-model needs a sequence of at least 3 "
                         f"frames, got {len(names)}")
    it = names
    if progress:
        from tqdm import tqdm

        it = tqdm(names, desc="visual hull", unit="frame")
    t = time.perf_counter()
    from topopose.capture import prefetch

    with prefetch(capture, names):           # decoding + silhouettes run ahead in a thread
        vols = [visual_hull(capture, f, resolution=resolution) for f in it]
    hull_ms = 1e3 * (time.perf_counter() - t) / len(names)
    kwargs.setdefault("up", capture.up_vector)
    kwargs.setdefault("source", str(capture.path or "capture"))
    res = learn_structure(vols, frames=names, progress=progress, **kwargs)
    res.diagnostics["timings_ms_per_frame"]["hull"] = hull_ms
    return res


#: coherent intervals shorter than this give learned models whose parts may be mislabelled
#: (6 random frames can give a model that swaps head and hand, yet frames "match")
MIN_COHERENT_FRAMES = 10
