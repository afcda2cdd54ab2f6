"""A per-frame confidence that says whether to trust a pose (thesis §13.2.2: the AHA distance
alone does not separate right from wrong poses).

For the human model the confidence is **fitted** (:func:`fitted_confidence`): gradient-boosted
shallow regression trees on features of the frame (:func:`frame_features`), times two guards
outside what the calibration frames showed:

    confidence = σ(b + Σ_t v_t(x)) × f_hull × f_size

- the model is ``confidence_model.json`` beside this module (:data:`CONFIDENCE_MODEL`),
  written by ``python benchmarks/confidence.py --fit`` (it fits on calibration seeds and
  reports held-out ones in ``benchmarks/results/confidence.md``). ``"kind": "trees"``: 100
  trees of depth ≤ 3 fitted by scikit-learn's GradientBoostingClassifier (log-loss), stored
  node by node and evaluated here with numpy (:func:`tree_confidence`, equal to scikit-learn's
  ``predict_proba``; scikit-learn is needed to fit, not to run). Otherwise a logistic
  regression (:func:`logistic_confidence`, :func:`fit_logistic`, ``--kind logistic``). All
  features are ratios (lengths over the hull's height H or over tree weights), so the same
  capture at another scale gets the same confidence; ``thickness`` and ``lost`` are guarded
  apart. The features include the matched arcs' shape against the model's (``shape``,
  ``shape_max``), the data tree's weight outside the matched arcs (``spurious_share``), the
  limbs' symmetry (``limb_sym``), the trunk's junctions (``crotch_radius``, ``torso_radius``,
  ``head_torso``, ``hip_flex``, ``crotch_room``, ``head_placed_offset``, ``head_placed_bend``)
  and ``matched_distance`` (the distance without the unmatched leaf parts' deletion cost);
- **camera set-ups**: the calibration captures have 8 cameras (640×480, silhouette noise 1),
  4 cameras (640×480, noise 1) and 4 portrait phone-like cameras (544×960, noise 2);
- **T_d**: with ``"replaces_threshold"`` in the model (and the gate on) a frame rejected for its
  AHA distance alone is decided by the confidence instead;
- a frame is *right* when it is a true positive of the quality classes (every placed part
  within 0.08 × height of its ground truth, at most one part unplaced); the fit also sees, as
  wrong frames, each right frame with the head's and a hand's data vertices exchanged;
- the minimum (:func:`min_confidence_for`) depends on the number of cameras: the smallest whose
  precision of ``matched`` reaches 0.95 in every calibration set-up with that many cameras and
  in every group of it, by out-of-fold confidences;
- **hull**: f_hull = clip((s − s_min) / (0.95 − s_min), 0, 1) where s is the share of the
  hull's voxels in its largest component and ``s_min`` = ``min_share``;
- **size**: r = hull volume / H³; f_size = 1 for r in [0.005, 0.11], 0 below 0.002 or above
  0.13, linear between.

**Per-part trust** (:func:`judge_frame` ``drop_parts``; ``FrameEstimator(part_trust=False)``
off): a frame with every part placed that only the confidence rejects is matched without the
one extremity (:data:`DROP_PARTS`) whose removal (:func:`drop_part_features`) makes the
confidence reach the minimum + ``drop_margin`` (:func:`min_drop_for`); a tie names no part
(:func:`untrusted_part`); the part is unplaced, its guess kept.

**Head doubt** (:func:`head_doubt`, :func:`judge_frame` ``doubt_head``;
``FrameEstimator(head_doubt=False)`` off): when no part's removal explains the doubt and the
alignment left the head unmatched, the frame with its head features (:data:`HEAD_FEATURES`) at
a right frame's typical values (``"typical_head"`` in the model) is scored; reaching
:func:`min_drop_for`, the frame is matched without its head. ``head_doubt="any"`` (opt-in)
also doubts a matched head, which lets through some frames with a spurious limb at the chest.

Other models get the **product** confidence (:func:`frame_confidence`), reported without
gating (give ``FrameEstimator(min_confidence=…)`` to gate them): f_d = 2^(−d / T_d) × f_hull ×
0.5^(unmatched parts) × a fat-hull factor (1 up to r = 0.04, 0 from 0.06).

**Time** (batch runs, :func:`temporal_confidence`): f_t = 2^(−(δ / (0.1 H))²) with δ the median
displacement of the parts since the previous frame (numbered parts paired optimally); frames
whose hull volume departs from the run's median by more than a factor 1.5 get ½; only when
the run is a coherent sequence (median δ / H over consecutive frames ≤ 0.1). They multiply the
product confidence; the fitted confidence only reports them in its factors.

**Not reached**: with 4 cameras no fitted model reaches precision 0.95 for more than a few
right frames: few 4-camera frames are right at all, and the wrong ones score as high. The real
recording's right frames lie outside the synthetic 4-camera right frames' features (a leaning
subject whose alignment puts the torso on another junction; a fatter hull, so the radius
features shrink): ``benchmarks/results/confidence_real_torso.md``. Hence the gate below.

The confidence is reported for every frame. With the gate on (``FrameEstimator(gate=True)``,
``topopose run --confidence-gate on``; the default, :func:`topopose.frame.rules.default_gate`),
``matched`` for the human model is decided by :class:`GateOptions` (:func:`gate_decision`): the
AHA distance within T_d with the silhouettes explained, or above T_d the silhouettes explained
more strictly with the arcs in the model's proportions — three interpretable features chosen
together on several generators (their figures: ``docs/decisions.md``, measured by
``benchmarks/sides.py``). The fitted confidence decides only with
``FrameEstimator(gate_rule=False)`` (with per-part trust and head doubt): ``matched`` then also
needs confidence ≥ ``min_confidence``. Rejected frames keep their best guess. Everything was fitted on synthetic captures only (capsule human and
``body``, the three camera set-ups, walk and random motion, separated / all poses); the real
recording is used to check, never to fit.
"""
from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from topopose.pose.model import part_stem

FAT_OK, FAT_MAX = 0.04, 0.06          # the product confidence (models without a fitted one)
FEATURES = ("distance", "thickness", "missing", "lost", "fat", "spurious", "spurious_length",
            "arc_dev", "head_low", "foot_high", "head_radius", "end_radius", "head_bend",
            "head_offset", "head_reach", "trunk", "shape", "shape_max", "spurious_share",
            "limb_sym", "matched_distance", "crotch_radius", "torso_radius", "hip_flex",
            "crotch_room", "head_torso", "head_placed_offset", "head_placed_bend")
MODEL_PATH = Path(__file__).with_name("confidence_model.json")
# the fitted confidence model: trees or logistic (benchmarks/confidence.py --fit rewrites the file)
CONFIDENCE_MODEL = json.loads(MODEL_PATH.read_text())
MIN_CONFIDENCE = float(CONFIDENCE_MODEL["min_confidence"])
# size guard of the fitted confidence, hull volume / H³: 1 inside [SLIM_OK, SIZE_OK], 0 below
# SLIM_MIN or above SIZE_MAX (candidate frames of the calibration captures: right up to 0.104
# — heavy builds —, wrong up to 0.108, judged by the trees' ``fat``; a hull without its legs
# or head is far slimmer). Before the heavy builds: 0.06, 0.08
SLIM_MIN, SLIM_OK, SIZE_OK, SIZE_MAX = 0.002, 0.005, 0.11, 0.13


def min_confidence_for(cameras: int | None, model: dict = None) -> float:
    """The minimum of the fitted confidence for a capture of ``cameras`` cameras: the entry of
    ``model["min_confidence_by_cameras"]`` (default :data:`CONFIDENCE_MODEL`) for the largest
    camera count ≤ ``cameras`` (each chosen for the same precision of ``matched``, 0.95, on its
    calibration set-ups), else ``model["min_confidence"]`` (the strictest)."""
    m = CONFIDENCE_MODEL if model is None else model
    by = {int(k): float(v) for k, v in (m.get("min_confidence_by_cameras") or {}).items()}
    fit = [k for k in by if cameras is not None and k <= int(cameras)]
    return by[max(fit)] if fit else float(m["min_confidence"])


def min_drop_for(min_confidence: float, model: dict = None) -> float:
    """The minimum a frame with one part left unplaced (per-part trust, :func:`judge_frame`)
    must reach: ``min_confidence`` + ``model["drop_margin"]`` (default
    :data:`CONFIDENCE_MODEL`; 0 when absent)."""
    m = CONFIDENCE_MODEL if model is None else model
    return float(min_confidence) + float(m.get("drop_margin", 0.0))


def logistic_confidence(features: dict, model: dict = None) -> float:
    """σ(b + Σ c_i (x_i − mean_i) / scale_i) over ``model["features"]`` (default
    :data:`CONFIDENCE_MODEL`)."""
    m = CONFIDENCE_MODEL if model is None else model
    z = m["intercept"] + sum(c * (float(features[f]) - mu) / sc for f, c, mu, sc
                             in zip(m["features"], m["coef"], m["mean"], m["scale"]))
    return 1.0 / (1.0 + math.exp(-max(min(z, 50.0), -50.0)))


def tree_confidence(features: dict, model: dict = None) -> float:
    """σ(b + Σ_t v_t(x)) over the boosted trees of ``model`` (``"kind": "trees"``): each tree
    (parallel lists ``feature``, ``threshold``, ``left``, ``right``, ``value``; a leaf has
    ``left`` −1) is walked from node 0 to the left while x[feature] ≤ threshold (x as float32,
    as scikit-learn compares), and gives its leaf's value (learning rate included); ``base``:
    b, the log-odds before the first tree."""
    m = CONFIDENCE_MODEL if model is None else model
    x = np.array([float(features[f]) for f in m["features"]], np.float32)
    z = float(m["base"])
    for t in m["trees"]:
        i = 0
        while t["left"][i] >= 0:
            i = t["left"][i] if float(x[t["feature"][i]]) <= t["threshold"][i] else t["right"][i]
        z += t["value"][i]
    return 1.0 / (1.0 + math.exp(-max(min(z, 50.0), -50.0)))


def trees_from_sklearn(gb, features) -> dict:
    """A fitted binary scikit-learn GradientBoostingClassifier ``gb`` (on the columns
    ``features``) as a tree model of :func:`tree_confidence`: per tree its nodes' feature,
    threshold, children and leaf value × learning rate; ``base``: the log-odds before the first
    tree (what ``benchmarks/confidence.py --fit --kind trees`` writes; scikit-learn is not
    needed to evaluate it)."""
    lr = gb.learning_rate
    trees = []
    for est in gb.estimators_[:, 0]:
        t = est.tree_
        leaf = t.children_left < 0
        trees.append({"feature": np.where(leaf, 0, t.feature).tolist(),
                      "threshold": np.where(leaf, 0.0, t.threshold).tolist(),
                      "left": t.children_left.tolist(), "right": t.children_right.tolist(),
                      "value": np.where(leaf, lr * t.value[:, 0, 0], 0.0).tolist()})
    x0 = np.zeros((1, len(features)))
    base = float(gb.decision_function(x0)[0]
                 - sum(lr * e.predict(x0.astype(np.float32))[0] for e in gb.estimators_[:, 0]))
    return {"models": ["human"], "replaces_threshold": True, "kind": "trees",
            "features": list(features), "base": base, "trees": trees}


def model_confidence(features: dict, model: dict = None) -> float:
    """The probability of a right frame by the fitted ``model`` (default
    :data:`CONFIDENCE_MODEL`): :func:`tree_confidence` for ``"kind": "trees"``, else
    :func:`logistic_confidence`."""
    m = CONFIDENCE_MODEL if model is None else model
    return (tree_confidence if m.get("kind") == "trees" else logistic_confidence)(features, m)


def leaf_count(tree) -> int:
    deg = {}
    for e in tree.edges:
        a, b = e[0], e[1]
        deg[a] = deg.get(a, 0) + 1
        deg[b] = deg.get(b, 0) + 1
    return sum(1 for v in deg.values() if v == 1)


def fit_logistic(X, y, l2=1.0, iters=50, weights=None) -> tuple:
    """L2-penalized logistic regression by Newton's method on standardized ``X`` (n, k) and
    labels ``y`` in {0, 1}, rows weighted by ``weights`` (default 1); the intercept is not
    penalized. Returns (coefficients, intercept) (what ``benchmarks/confidence.py --fit``
    writes to :data:`MODEL_PATH`)."""
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    sw = np.ones(len(y)) if weights is None else np.asarray(weights, float)
    Xa = np.hstack([X, np.ones((len(X), 1))])
    w = np.zeros(Xa.shape[1])
    P = l2 * np.eye(Xa.shape[1])
    P[-1, -1] = 0.0
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-np.clip(Xa @ w, -50, 50)))
        g = Xa.T @ (sw * (p - y)) + P @ w
        H = (Xa * (sw * p * (1 - p))[:, None]).T @ Xa + P + 1e-9 * np.eye(len(w))
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-10:
            break
    return w[:-1], float(w[-1])


def _branch_length(adj, leaf) -> float:
    """Length of the branch from ``leaf`` to the first vertex of degree ≠ 2."""
    prev, x, n = None, leaf, 0.0
    while True:
        y, w = next((y, w) for y, w in adj[x] if y != prev)
        n += w if math.isfinite(w) else 0.0
        prev, x = x, y
        if len(adj[x]) != 2:
            return n


def _head_bend_offset(x, t, c, height) -> tuple:
    """(1 − cos of the angle between torso → head and crotch → torso, the head's distance from
    the line crotch → torso / ``height``) for head ``x``, torso ``t``, crotch ``c``; (0, 0)
    when two of them coincide."""
    axis, hv = t - c, x - t
    n, hn = float(np.linalg.norm(axis)), float(np.linalg.norm(hv))
    if n == 0 or hn == 0:
        return 0.0, 0.0
    return (1.0 - float(hv @ axis) / (hn * n),
            float(np.linalg.norm(np.cross(x - c, axis / n))) / height)


def frame_features(vol, n_vox, data, model, up, distance, threshold, missing, al=None,
                   thickness_cost=0.0, radii=None, missing_cost=0.0, parts=None) -> dict:
    """What one frame's stages know about how far to trust it, as numbers (the inputs of the
    logistic confidence, :data:`FEATURES`).

    - ``distance``: AHA length distance / T_d (3 when infinite); ``matched_distance``: the
      same without what the unmatched leaf parts cost (``missing_cost``,
      :func:`topopose.frame.estimate.missing_cost`): a missing limb of §13.2.2 (an arm lying on
      the body has no branch) is a right frame, and its deleted arm alone costs the alignment
      its model weight (0.18 of the human's), more than half of T_d;
    - ``thickness``: the thickness arc cost paid by the matched arcs (a hand placed on a thick
      branch, a head on a thin one; :func:`topopose.frame.estimate.thickness_arc_cost`);
    - ``missing``: parts left unmatched;
    - ``lost``: share of the hull's voxels outside its largest component;
    - ``fat``: hull volume / H³ (H: hull extent along the up axis);
    - ``spurious``: data leaves that no part maps to; ``spurious_length``: the longest of
      their branches (share of the tree's total weight);
    - ``arc_dev``: the largest |log(data length / model length)| of the matched arcs (both
      relative to their tree's total);
    - ``head_low``: 1 − the head's height above the hull's bottom / H (0: at the top);
      ``foot_high``: the higher foot's height / H (0: on the floor);
    - ``head_bend``: 1 − cos of the angle between torso → head and crotch → torso (0: the
      head continues the trunk); ``head_offset``: the head's distance from the trunk's line /
      H; ``head_reach``: |head − torso| / H; ``trunk``: |torso − crotch| / H;
    - ``shape``: Σ |data share − model share| over the matched arcs, each arc's length as a
      share of the *matched* arcs' total (unmatched branches do not shorten it); ``shape_max``:
      the largest |log(data share / model share)|; ``spurious_share``: the data tree's weight
      outside the matched arcs; ``limb_sym``: the larger |log| of the two arms' and of the two
      legs' length ratio;
    - ``head_radius``, ``end_radius``: the hull's inscribed-ball radius at the head and the
      largest at a hand or foot, relative to the hull's largest (``radii``: per data vertex,
      :func:`topopose.frame.estimate.vertex_radii`; absent: 0); ``crotch_radius``,
      ``torso_radius``: the same at the crotch and the torso (junctions in the trunk's mass,
      not on a limb); ``head_torso``: head radius / torso radius (0 without a torso radius);
    - ``hip_flex``: 1 + the mean over the feet of the cosine of the angle between crotch →
      torso and crotch → foot (0: legs straight below the trunk, 1: at a right angle, as
      sitting);
      ``crotch_room``: the hull's depth straight below the crotch / H (at most 0.2; the gap
      between the legs is right beneath a standing crotch, flexed hips put thigh there:
      :func:`topopose.frame.anatomy.room_below`);
    - ``head_placed_offset``, ``head_placed_bend``: ``head_offset`` and ``head_bend`` of the
      *placed* parts (``parts``: the pose's positions — the head from the hull, the trunk moved
      back onto the spine), where the features above see the alignment's data vertices only (a
      head the alignment left unmatched has none: 0 there).
    """
    vd = vol.diagnostics or {}
    share = float(vd.get("largest_share", 1.0))
    up = np.asarray(up, float)
    ax = int(np.argmax(np.abs(up)))
    sign = 1.0 if up[ax] >= 0 else -1.0
    bb = vd.get("bbox")
    if bb:
        lo_i, hi_i = bb[0][ax], bb[1][ax]
    else:
        occ = np.flatnonzero(vol.data.any(axis=tuple(i for i in range(3) if i != ax)))
        lo_i, hi_i = (int(occ[0]), int(occ[-1])) if occ.size else (0, 0)
    vs = float(vol.voxel_size)
    height = (hi_i - lo_i + 1) * vs
    z0 = vol.origin[ax] + (lo_i if sign > 0 else hi_i) * vs
    inf = distance is None or not math.isfinite(distance)
    f = {"distance": 3.0 if inf else min(float(distance) / threshold, 3.0),
         "matched_distance": 3.0 if inf else min(max(float(distance) - float(missing_cost), 0.0)
                                                 / threshold, 3.0),
         "thickness": min(float(thickness_cost or 0.0), 5.0),
         "missing": float(missing), "lost": 1.0 - share,
         "fat": n_vox * vs ** 3 / height ** 3 if height > 0 else 0.0,
         "spurious": 0.0, "spurious_length": 0.0, "arc_dev": 0.0,
         "head_low": 0.0, "foot_high": 0.0, "head_radius": 0.0, "end_radius": 0.0,
         "head_bend": 0.0, "head_offset": 0.0, "head_reach": 0.0, "trunk": 0.0,
         "shape": 2.0, "shape_max": 3.0, "spurious_share": 1.0, "limb_sym": 0.0,
         "crotch_radius": 0.0, "torso_radius": 0.0, "hip_flex": 0.0, "crotch_room": 0.0,
         "head_torso": 0.0, "head_placed_offset": 0.0, "head_placed_bend": 0.0}
    if al is None:
        return f
    mapping = al.mapping or {}
    adj = data.adjacency()
    used = {v for v in mapping.values() if v is not None}
    spur = [_branch_length(adj, v) for v, n in adj.items() if len(n) == 1 and v not in used]
    f["spurious"] = float(len(spur))
    padj = model.tree.adjacency()
    ptot = model.tree.total_weight() or 1.0
    dtot = data.total_weight() or 1.0
    f["spurious_length"] = max(spur, default=0.0) / dtot
    # each matched arc as (part at its lower end, model length, data length)
    arcs = []
    for ppath, dpath in (al.pairs or []):
        pl = sum(w for a, b in zip(ppath[:-1], ppath[1:]) for y, w in padj.get(a, ()) if y == b)
        dl = sum(w for a, b in zip(dpath[:-1], dpath[1:]) for y, w in adj.get(a, ()) if y == b)
        if pl > 0 and dl > 0 and math.isfinite(pl) and math.isfinite(dl):
            arcs.append((part_stem(ppath[-1]), pl, dl))
    f["arc_dev"] = max((abs(math.log((dl / dtot) / (pl / ptot))) for _, pl, dl in arcs),
                       default=0.0)
    # the same relative to the matched total only: unmatched (spurious, e.g. phantom-volume)
    # branches inflate the data tree's total and shorten every arc in ``arc_dev`` and the
    # distance with few cameras, not here
    pm, dm = sum(a[1] for a in arcs), sum(a[2] for a in arcs)
    if arcs:
        f["shape"] = sum(abs(dl / dm - pl / pm) for _, pl, dl in arcs)
        f["shape_max"] = max(abs(math.log((dl / dm) / (pl / pm))) for _, pl, dl in arcs)
        f["spurious_share"] = max(0.0, 1.0 - dm / dtot)
        sym = [abs(math.log(ls[0] / ls[1])) for k in ("hand", "foot")
               for ls in [[dl for s, _, dl in arcs if s == k]] if len(ls) == 2]
        f["limb_sym"] = max(sym, default=0.0)
    pos = {p: data.positions.get(v) for p, v in mapping.items() if v is not None}
    def h(p):
        return sign * (float(np.asarray(pos[p])[ax]) - z0) / height if height > 0 else 0.0
    heads = [p for p in pos if part_stem(p) == "head" and pos[p] is not None]
    feet = [p for p in pos if part_stem(p) == "foot" and pos[p] is not None]
    if heads:
        f["head_low"] = 1.0 - max(h(p) for p in heads)
    if feet:
        f["foot_high"] = max(h(p) for p in feet)
    trunk = [np.asarray(pos[p], float) for p in ("torso", "crotch") if pos.get(p) is not None]
    if len(trunk) == 2 and heads and height > 0:
        t, c = trunk
        x = np.asarray(pos[heads[0]], float)
        f["trunk"] = float(np.linalg.norm(t - c)) / height
        f["head_reach"] = float(np.linalg.norm(x - t)) / height
        f["head_bend"], f["head_offset"] = _head_bend_offset(x, t, c, height)
    if radii:
        r = {p: radii.get(v, 0.0) for p, v in mapping.items() if v is not None}
        f["head_radius"] = max((r[p] for p in r if part_stem(p) == "head"), default=0.0)
        f["end_radius"] = max((r[p] for p in r if part_stem(p) in ("hand", "foot")), default=0.0)
        f["crotch_radius"], f["torso_radius"] = r.get("crotch", 0.0), r.get("torso", 0.0)
        if f["torso_radius"] > 0:
            f["head_torso"] = f["head_radius"] / f["torso_radius"]
    if len(trunk) == 2 and feet:
        t, c = trunk
        legs = [np.asarray(pos[p], float) - c for p in feet]
        legs = [v / np.linalg.norm(v) for v in legs if np.linalg.norm(v) > 0]
        n = float(np.linalg.norm(t - c))
        if legs and n > 0:
            f["hip_flex"] = 1.0 + float(np.mean(legs, axis=0) @ (t - c)) / n
    pp = [None if parts is None or parts.get(p) is None else np.asarray(parts[p], float)
          for p in ("head", "torso", "crotch")]
    if all(x is not None for x in pp) and height > 0:
        f["head_placed_bend"], f["head_placed_offset"] = _head_bend_offset(*pp, height)
    if pos.get("crotch") is not None and height > 0:
        from topopose.frame.anatomy import room_below
        f["crotch_room"] = room_below(vol, pos["crotch"], sign * np.eye(3)[ax],
                                      0.2 * height) / height
    return {k: round(float(v), 5) for k, v in f.items()}


# the parts a frame may be matched without (a *missing limb* of §13.2.2, still right) when the
# confidence doubts the whole frame: :func:`drop_part_features`, :func:`judge_frame`
DROP_PARTS = ("head", "hand_1", "hand_2", "foot_1", "foot_2")


def untrusted_part(confidences: dict, minimum: float):
    """The part whose removal explains a frame's doubt: of ``confidences`` (part → confidence
    of the frame without it), the one scoring highest, if it reaches ``minimum`` and no other
    part scores as high (a tie — both hands' removal alike — names no one part: None)."""
    ranked = sorted(confidences.items(), key=lambda kv: -kv[1])
    if not ranked or ranked[0][1] < minimum or (len(ranked) > 1 and ranked[1][1] >= ranked[0][1]):
        return None
    return ranked[0][0]


# the features that judge the alignment's head alone (its height, bend, offset and reach against the
# alignment's trunk, its thickness against the torso's): the head's doubt, :func:`head_doubt`. Its
# figures: docs/decisions.md.
HEAD_FEATURES = ("head_low", "head_bend", "head_offset", "head_reach", "head_torso")


def head_doubt(features: dict, share: float, min_share: float = 0.8, model: dict = None):
    """:func:`fitted_confidence` of a frame whose head looked as a right frame's usually does:
    ``features`` with :data:`HEAD_FEATURES` at ``model["typical_head"]`` (the medians of the
    calibration's right frames, written by ``benchmarks/confidence.py --fit``; default
    :data:`CONFIDENCE_MODEL`). None when the model has none. When this reaches the minimum
    while the frame does not, the doubt lies in the head alone (per-part trust,
    :func:`judge_frame` ``doubt_head``)."""
    m = CONFIDENCE_MODEL if model is None else model
    typical = m.get("typical_head")
    if not typical:
        return None
    return fitted_confidence({**features, **typical}, share, min_share, m)


def drop_part_features(vol, n_vox, data, model, up, distance, threshold, missing, al,
                       thickness_cost, radii, missing_cost, parts, part) -> dict:
    """:func:`frame_features` of the frame with ``part`` left unplaced: its data vertex and
    matched arc taken out of the alignment ``al`` (the branch it had counts as spurious), one
    more part missing, ``parts[part]`` None; the distance as it is (per-part trust,
    :func:`judge_frame`)."""
    from types import SimpleNamespace

    m = {**(al.mapping or {}), part: None}
    pairs = [(pp, dp) for pp, dp in (al.pairs or []) if pp[-1] != part]
    return frame_features(vol, n_vox, data, model, up, distance, threshold, missing + 1,
                          SimpleNamespace(mapping=m, pairs=pairs), thickness_cost, radii,
                          missing_cost, {**(parts or {}), part: None})


def frame_confidence(distance, threshold, share, missing, min_share=0.8, fatness=None) -> dict:
    """Factors and product (see the module docstring) of one frame, without the time term.
    ``fatness``: hull volume / H³ (None: not known)."""
    fd = 0.0 if distance is None or not math.isfinite(distance) else 2.0 ** (-distance / threshold)
    fh = float(np.clip((share - min_share) / max(0.95 - min_share, 1e-9), 0.0, 1.0))
    fm = 0.5 ** max(0, int(missing))
    fv = 1.0 if fatness is None else float(np.clip((FAT_MAX - fatness) / (FAT_MAX - FAT_OK), 0, 1))
    return {"alignment": round(fd, 4), "hull": round(fh, 4), "placement": round(fm, 4),
            "fat": round(fv, 4), "confidence": round(fd * fh * fm * fv, 4)}


def fitted_confidence(features: dict, share: float, min_share: float = 0.8,
                      model: dict = None) -> dict:
    """Factors and product of the fitted confidence (module docstring): the logistic
    :func:`logistic_confidence` times the guards ``hull`` (split hull, as
    :func:`frame_confidence`) and ``size`` (hull volume / H³ outside what the calibration
    frames showed)."""
    fl = model_confidence(features, model)
    fh = float(np.clip((share - min_share) / max(0.95 - min_share, 1e-9), 0.0, 1.0))
    r = float(features["fat"])
    fs = float(np.clip(min((r - SLIM_MIN) / (SLIM_OK - SLIM_MIN), (SIZE_MAX - r) / (SIZE_MAX - SIZE_OK)),
                       0.0, 1.0))
    return {"fitted": round(fl, 4), "hull": round(fh, 4), "size": round(fs, 4),
            "confidence": round(fl * fh * fs, 4)}


def replaces_threshold(model: dict = None) -> bool:
    """Whether the fitted confidence ``model`` (default :data:`CONFIDENCE_MODEL`) decides
    ``matched`` in place of the threshold T_d on the AHA distance (``"replaces_threshold"``)."""
    return bool((CONFIDENCE_MODEL if model is None else model).get("replaces_threshold", False))


def distance_only(error) -> bool:
    """Whether a frame's rejection ``error`` is the AHA distance above T_d (and nothing else)."""
    return bool(error) and str(error).startswith("AHA distance") and "inf" not in str(error)


def passes_gate(status, error, confidence, min_confidence) -> bool:
    """Whether a frame judged *without* the gate (its ``status``, ``error``, ``confidence``) is
    ``matched`` with it, as :func:`judge_frame` decides at the model's own T_d: confidence ≥
    ``min_confidence`` and matched, or rejected for its AHA distance alone when the confidence
    replaces T_d (:func:`replaces_threshold`)."""
    if confidence is None or confidence < min_confidence:
        return False
    return status == "matched" or (replaces_threshold() and distance_only(error))


@dataclass(frozen=True)
class Gate:
    """How :func:`judge_frame` judges a frame: ``min_share`` of the hull in its largest
    component, ``min_confidence`` (None: no gate), per-part trust (``drop_parts``, e.g.
    :data:`DROP_PARTS`; empty: off) and the head doubt (``doubt_head``)."""

    min_share: float = 0.8
    min_confidence: float | None = MIN_CONFIDENCE
    drop_parts: tuple = ()
    doubt_head: object = False


@dataclass(frozen=True)
class Aligned:
    """What the alignment of a frame tells :func:`judge_frame`: ``al`` (its mapping and
    matched arcs give the features), ``thickness_cost`` (the part of its distance paid to the
    thickness term), ``missing_cost``, ``parts`` (the placed positions: features
    ``head_placed_*``), ``reach`` and ``radius_map`` (its ``radii``, if already computed) of
    :func:`topopose.frame.thickness.vertex_radii`."""

    al: object = None
    thickness_cost: float = 0.0
    missing_cost: float = 0.0
    parts: dict | None = None
    reach: int = 0
    radius_map: object = None


@dataclass(frozen=True)
class GateOptions:
    """The gate that decides ``matched`` (:func:`gate_decision`): a frame the alignment placed
    is matched when the placed model explains its silhouettes (``diagnostics["unexplained"]``,
    :mod:`.support`: at most ``max_unexplained`` of a camera's silhouette left over) and either
    its AHA distance is within ``max_distance`` × T_d (the thesis' test) or, above it, the
    silhouettes are explained more strictly (``far_unexplained``) with the arcs in the model's
    proportions (``confidence_features["shape"]`` at most ``far_shape``: an arc stretched onto
    a phantom branch or shrunk onto a stump is out of proportion). With 4 cameras the phantom
    volume's branches put nearly every frame above T_d, right or wrong; the silhouettes and the
    arcs' proportions do not depend on the camera count. Chosen together on the development
    generators of ``benchmarks/sides.py`` (builds, pose families, 4 and 8 cameras; the mean over
    generators of the share of their right frames matched, under precision of ``matched`` ≥
    0.98 in each camera set-up), checked on held-out generators and the real recordings there.

    **A foot on the wrong kind of branch** (``max_foot_rise``, :func:`foot_rise`): whatever the
    three features say, a frame is rejected when a foot's end lies higher above the subject's
    lowest skeleton point than ``max_foot_rise`` × its leg's skeleton arc — a foot can rise no
    higher than its hip without a kick above it, while the foot the alignment puts on a hanging
    or raised arm (the legs together leave the data tree one leg branch, and the model's second
    foot takes an arm's) ends near the crotch's height on a short arc. The reason's last clause
    names the anatomy, not the confidence gate: the run's consistency
    (:func:`topopose.sequence.consistency.judge_sequence`), which matches a frame the gate alone
    rejected when its neighbours agree, leaves it rejected — a foot on an arm agrees with its
    neighbours frame after frame. Chosen on the development generators of
    ``benchmarks/confidence.py --foot-rule`` (the lowest tenth above every right frame the
    alignment placed there).

    Parameters
    ----------
    max_distance : the AHA distance over T_d within which a frame needs only ``max_unexplained``
    max_unexplained : the largest unexplained silhouette share of a matched frame
    far_unexplained, far_shape : above ``max_distance``, the largest unexplained share and
        arc-proportion error of a matched frame
    max_foot_rise : the largest :func:`foot_rise` of a matched frame (None: not checked)
    models : the models it decides for (thresholds measured on the human); other models keep
        the product confidence's minimum (:func:`judge_frame`)
    """

    max_distance: float = 0.8
    max_unexplained: float = 0.2
    far_unexplained: float = 0.12
    far_shape: float = 0.1
    max_foot_rise: float | None = 0.8
    models: tuple = ("human",)


#: the default gate (``FrameEstimator(gate_rule=...)``; False there: the fitted confidence)
GATE = GateOptions()


def foot_rise(curves: dict, up) -> tuple:
    """How high a foot is for its leg: over the feet's skeleton curves (``curves``:
    ``diagnostics["curves"]``, part → (n, 3) points from the crotch's junction to the foot,
    :mod:`.curves`), the largest height of a foot's end above the lowest point of all the
    curves (the subject's ground side along ``up``), over that foot's curve length.

    Standing feet give 0, a knee raised in front or a leg lifted sideways up to ~0.7, a foot
    at its hip's height ~1 (the arc starts at the crotch's junction, below the hips).

    Returns
    -------
    (part, ratio), or (None, None) without a foot's curve.
    """
    u = np.asarray(up, float)
    u = u / np.linalg.norm(u)
    pts = {p: np.asarray(c, float).reshape(-1, 3) for p, c in (curves or {}).items()}
    pts = {p: c for p, c in pts.items() if len(c)}
    if not pts:
        return None, None
    low = min(float((c @ u).min()) for c in pts.values())
    best = (None, None)
    for p, c in pts.items():
        if part_stem(p) != "foot" or len(c) < 2:
            continue
        length = float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum())
        if length > 0:
            r = (float(c[-1] @ u) - low) / length
            if best[1] is None or r > best[1]:
                best = (p, r)
    return best


def gate_decision(status, error, diag, options: GateOptions = GATE, unplaced=0,
                  max_missing=1, up=None) -> tuple:
    """``(status, error)`` of a frame after the gate (:class:`GateOptions`). Only a frame the
    alignment placed is decided — matched, or rejected for its AHA distance alone
    (:func:`distance_only`); a failed frame, a split hull or unmatched parts stay as they are.
    ``diag``: the frame's diagnostics with ``confidence_features`` (:func:`frame_features`)
    and, when measured, ``unexplained`` (not measured: the distance alone decides);
    ``unplaced``: its parts without a position, at most ``max_missing`` in a matched frame (the
    thesis' missing limb; a frame above T_d is not otherwise told its unmatched parts); ``up``:
    the capture's up vector (None: ``max_foot_rise`` is not checked). A rejected frame's reason
    begins with its AHA distance reason, if any, then ``confidence gate: ...``, then, when a
    foot is too high for its leg, ``anatomy: ...`` (which the run's consistency does not
    override, :class:`GateOptions`)."""
    if not (status == "matched" or (status == "rejected" and distance_only(error))):
        return status, error
    status, error = _gate_features(status, error, diag, options, unplaced, max_missing)
    if options.max_foot_rise is None or up is None:
        return status, error
    part, rise = foot_rise(diag.get("curves"), up)
    if rise is None or rise <= options.max_foot_rise:
        return status, error
    why = (f"anatomy: {part} {rise:.2f} of its leg's length above the subject's lowest point "
           f"(at most {options.max_foot_rise:g}: a foot on an arm's branch)")
    return "rejected", (f"{error}; {why}" if error else why)


def _gate_features(status, error, diag, o: GateOptions, unplaced, max_missing) -> tuple:
    """:func:`gate_decision` by the AHA distance, the unexplained silhouette and the arcs'
    proportions."""
    f = diag.get("confidence_features") or {}
    d, shape, u = f.get("distance", math.inf), f.get("shape", math.inf), diag.get("unexplained")
    if unplaced > max_missing:
        why = f"{unplaced} parts without a position (at most {max_missing})"
    elif u is not None and u > o.max_unexplained:
        why = f"silhouette unexplained {u:.2f} (at most {o.max_unexplained:g})"
    elif d <= o.max_distance:
        return "matched", None
    elif u is None:
        why = f"AHA distance {d:.2f} T_d, no silhouette support measured"
    elif u <= o.far_unexplained and shape <= o.far_shape:
        return "matched", None
    else:
        why = (f"AHA distance {d:.2f} T_d above {o.max_distance:g} with the silhouette "
               f"unexplained {u:.2f} (at most {o.far_unexplained:g}) or the arc proportions off "
               f"by {shape:.2f} (at most {o.far_shape:g})")
    why = "confidence gate: " + why
    return "rejected", (f"{error}; {why}" if status == "rejected" and error else why)


def judge_frame(vol, n_vox, data, model, up, distance, threshold, missing, status, error,
                gate: Gate | None = None, units="m", aligned: Aligned | None = None) -> tuple:
    """Status, reason and diagnostics of one frame from what the stages know.

    A ``matched`` frame becomes ``rejected`` when the hull's largest component holds less than
    ``min_share`` of its voxels (the dropped components are named with their sizes and shares),
    or when its confidence is below ``min_confidence`` (None: no gate; both of ``gate``,
    :class:`Gate`). The confidence is the fitted one (:func:`fitted_confidence`) for the
    models of :data:`CONFIDENCE_MODEL`, else the product (:func:`frame_confidence`), from the
    features of the hull, the data tree and what the alignment tells (``aligned``,
    :class:`Aligned`).

    **Per-part trust** (``drop_parts``, e.g. :data:`DROP_PARTS`; empty: off): a frame with every
    part placed that only the fitted confidence rejects is matched without one part when the
    frame with that part unplaced (:func:`drop_part_features`, the part of ``drop_parts``
    whose removal scores highest) reaches :func:`min_drop_for` — a right *missing limb* frame
    (§13.2.2) rather than a rejected one. The part is named in ``untrusted`` (the caller
    unplaces it and keeps its guess), its confidence is the reported one, the whole frame's in
    ``confidence_all_parts``.

    **Head doubt** (``doubt_head``, with per-part trust): when no part's removal
    explains the doubt but the frame with a typical head (:func:`head_doubt`) reaches
    :func:`min_drop_for`, the head is the untrusted part — True: only a head the alignment
    left unmatched (placed from the hull alone); ``"any"``: any head (a right frame with the
    alignment's torso on a shoulder junction, but also one on a spurious limb's junction).
    The head's removal alone does not do this: a frame without a head, which the fit saw
    rarely right, scores lower still.

    Returns
    -------
    (status, error, diagnostics) with ``hull_litres``, ``largest_share``,
    ``components_dropped`` (the five largest), ``data_leaves``, ``height`` (hull extent along
    the up axis), ``confidence``, ``confidence_factors`` and ``confidence_features``.
    """
    from topopose.capture.options import UNITS

    g, a = gate or Gate(), aligned or Aligned()
    min_share, min_confidence, drop_parts, doubt_head = (g.min_share, g.min_confidence,
                                                         g.drop_parts, g.doubt_head)
    al, thickness_cost, missing_cost, parts, reach, radius_map = (
        a.al, a.thickness_cost, a.missing_cost, a.parts, a.reach, a.radius_map)
    vd = vol.diagnostics or {}
    share = float(vd.get("largest_share", 1.0))
    dropped = vd.get("components_dropped") or []
    leaves = leaf_count(data)
    ax = int(np.argmax(np.abs(up)))
    bb = vd.get("bbox")
    height = None if not bb else float((bb[1][ax] - bb[0][ax] + 1) * vol.voxel_size)
    radii = None
    if al is not None:
        from types import SimpleNamespace

        from topopose.frame.thickness import vertex_radii
        mapped = [v for v in (al.mapping or {}).values() if v is not None]
        radii = vertex_radii(vol, SimpleNamespace(vertices=mapped, positions=data.positions), reach,
                             radius_map)
    feats = frame_features(vol, n_vox, data, model, up, distance, threshold, missing, al,
                           thickness_cost, radii, missing_cost, parts)
    fitted = model.name in CONFIDENCE_MODEL.get("models", ())
    if fitted:
        conf = fitted_confidence(feats, share, min_share)
    else:
        conf = frame_confidence(distance, threshold, share, missing, min_share,
                                feats["fat"] if model.name == "human" else None)
    if (fitted and min_confidence is not None and status == "rejected" and replaces_threshold()
            and distance_only(error) and threshold == model.threshold):
        # the fitted confidence has the distance among its features: it decides instead of the
        # model's own T_d (a T_d the caller chose stands); with 4 cameras the phantom branches'
        # deletion cost alone exceeds T_d (kept in the reason if the confidence rejects it too)
        status, error, above_td = "matched", None, error
    else:
        above_td = None
    if status == "matched" and share < min_share:
        status = "rejected"
        total = n_vox + sum(dropped)
        error = (f"hull split: the largest component holds {100 * share:.0f} % of the {total} "
                 f"hull voxels; dropped: "
                 + ", ".join(f"{d} ({100 * d / total:.0f} %)" for d in dropped[:3])
                 + (f" and {len(dropped) - 3} smaller" if len(dropped) > 3 else ""))
    elif status == "matched" and min_confidence is not None and conf["confidence"] < min_confidence:
        status = "rejected"
        error = f"confidence {conf['confidence']:.2f} below {min_confidence:g}"
        if above_td:           # not a frame only the gate rejected (track.gated_only)
            error = f"{above_td}; {error}"
    untrusted = None
    if (fitted and drop_parts and status == "rejected" and " below " in str(error)
            and str(error).split("; ")[-1].startswith("confidence")
            and parts and all(x is not None for x in parts.values())):
        # per-part trust: the frame without the one part that explains the doubt
        cps = {part: fitted_confidence(drop_part_features(
                   vol, n_vox, data, model, up, distance, threshold, missing, al,
                   thickness_cost, radii, missing_cost, parts, part), share, min_share)
               for part in drop_parts if parts.get(part) is not None}
        untrusted = untrusted_part({p: c["confidence"] for p, c in cps.items()},
                                   min_drop_for(min_confidence))
        mapped = (getattr(al, "mapping", None) or {}).get("head") is not None
        if (untrusted is None and doubt_head and "head" in cps
                and (doubt_head == "any" or not mapped)):
            typical = head_doubt(feats, share, min_share)
            if typical is not None and typical["confidence"] >= min_drop_for(min_confidence):
                untrusted, cps["head"] = "head", typical
        if untrusted is not None:
            status, error = "matched", None
            conf = {**cps[untrusted], "all_parts": conf["confidence"]}
    metre = UNITS.get(units, 1.0)
    diag = {"hull_litres": round(n_vox * (vol.voxel_size * metre) ** 3 * 1000.0, 2),
            "largest_share": round(share, 4), "components_dropped": dropped[:5],
            "data_leaves": leaves, "height": height,
            "confidence": conf.pop("confidence"), "confidence_factors": conf,
            "confidence_features": feats}
    if untrusted:
        diag["untrusted"] = untrusted
        diag["confidence_all_parts"] = conf.pop("all_parts")
    return status, error, diag


def _group(part: str) -> str:
    head, _, tail = part.rpartition("_")
    return head if tail.isdigit() and head else part


def part_displacement(a: dict, b: dict) -> float | None:
    """Median distance between the parts of two poses, numbered parts (``hand_1``, ``hand_2``)
    paired optimally within their group."""
    groups = {}
    for p in a:
        groups.setdefault(_group(p), []).append(p)
    ds = []
    for g, ps in groups.items():
        xa = [a.get(p) for p in ps]
        xb = [b.get(p) for p in ps]
        best = None
        for perm in itertools.permutations(range(len(ps))):
            d = [float(np.linalg.norm(np.asarray(xa[i]) - np.asarray(xb[j])))
                 for i, j in zip(range(len(ps)), perm) if xa[i] is not None and xb[j] is not None]
            if d and (best is None or sum(d) < sum(best)):
                best = d
            if len(ps) > 4:
                break
        if best:
            ds.extend(best)
    return float(np.median(ds)) if ds else None


#: a run is a coherent sequence of one subject when the median displacement of its parts
#: between consecutive frames is at most this × the hull height (:func:`coherent_run`)
COHERENT_STEP = 0.1


def coherent_run(by_index) -> bool:
    """Whether the poses ``by_index`` (frame index → pose) are a sequence of one subject: the
    median over consecutive frames of the parts' median displacement
    (:func:`part_displacement`, numbered parts paired) over the hull height is at most
    :data:`COHERENT_STEP`; unrelated poses (a per-frame run of random poses) are not."""
    steps = []
    for i, p in by_index.items():
        prev, H = by_index.get(i - 1), p.diagnostics.get("height")
        if prev is not None and H:
            d = part_displacement(p.parts, prev.parts)
            if d is not None:
                steps.append(d / H)
    return bool(steps) and float(np.median(steps)) <= COHERENT_STEP


def temporal_confidence(poses, frame_index, gate=True, min_confidence=MIN_CONFIDENCE) -> None:
    """Multiply the time factors into each pose's confidence, in place (module docstring), and
    re-decide ``matched`` when ``gate``. ``frame_index``: frame name → index in the capture."""
    done = [p for p in poses if p.status != "failed" and "confidence" in p.diagnostics]
    vols = [p.diagnostics.get("hull_voxels") for p in done if p.diagnostics.get("hull_voxels")]
    vmed = float(np.median(vols)) if vols else None
    by_idx = {frame_index[p.frame]: p for p in done if p.frame in frame_index}
    coherent = coherent_run(by_idx)
    for i, p in sorted(by_idx.items()):
        diag = p.diagnostics
        if "time" in diag.get("confidence_factors", {}):
            continue                       # a resumed frame: already done
        ft = 1.0
        prev = by_idx.get(i - 1)
        H = diag.get("height")
        if coherent and prev is not None and H:
            d = part_displacement(p.parts, prev.parts)
            if d is not None:
                ft = 2.0 ** (-(d / (0.1 * H)) ** 2)
        fv = 1.0
        v = diag.get("hull_voxels")
        if coherent and vmed and v and not (vmed / 1.5 <= v <= vmed * 1.5):
            fv = 0.5
        diag["confidence_factors"]["time"] = round(ft, 4) if coherent else None
        diag["confidence_factors"]["volume"] = fv if coherent else None
        if "fitted" in diag["confidence_factors"]:
            continue                       # the fitted confidence: the time factors are told only
        diag["confidence"] = round(diag["confidence"] * ft * fv, 4)
        if gate and p.status == "matched" and diag["confidence"] < min_confidence:
            p.status = "rejected"
            p.error = f"confidence {diag['confidence']:.2f} below {min_confidence:g}"
