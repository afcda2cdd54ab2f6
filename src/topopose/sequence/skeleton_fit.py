"""The kinematic skeleton of a model and its fit to one frame (thesis §13.3.1): the kinematic
tree of the model's [[joint]] declarations, the bones' constant lengths over a sequence,
forward kinematics and the least-squares fit of the joints to a frame's skeleton curves."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from topopose.errors import InputError
from topopose.frame.curves import arc_lengths, model_arcs
from topopose.pose.model import part_stem
from topopose.sequence.options import DEFAULT, SkeletonFitOptions

FIT = DEFAULT.skeleton_fit

@dataclass
class KinematicTree:
    """Joint instances of a model: ``names[i]`` (``elbow_1``), ``base[i]`` (``elbow``),
    ``parents[i]`` (index, -1 for the root), ``arc[i]`` = (parent part, child part) of the model
    arc it lies on, ``at[i]`` its relative position along it."""

    names: list
    base: list
    parents: list
    arc: list
    at: list
    offset: list = None            # (along the trunk, outward) per joint, in trunk lengths
    trunk: tuple = ()              # (from part, to part)
    beyond: list = None            # tip joints: past the end part, × the curve length
    limbs: frozenset = frozenset()  # the model's limb parts (``[[mirror]]`` parts)
    width: list = None             # (along the trunk, outward) × hull radius, from the junction
    at_raised: list = None         # at when the arc's end part is past its start along the trunk
    slide: list = None             # the bone from its parent takes the frame's length (slide)
    girdle: list = None            # (pair's joint name, height) or None: one rigid body with it
    extends: list = None           # the body goes on past the joint along its bone

    @property
    def root(self) -> int:
        return self.parents.index(-1)

    def order(self) -> list:
        """Joint indices, parents before children."""
        out, todo = [], [self.root]
        while todo:
            j = todo.pop(0)
            out.append(j)
            todo.extend(c for c, p in enumerate(self.parents) if p == j)
        return out

    def chains(self) -> dict:
        """Model arc (u, v) → joint indices along it in order, with the joint at its start."""
        out = {}
        for j, (u, v) in enumerate(self.arc):
            out.setdefault((u, v), []).append(j)
        for key, js in out.items():
            js.sort(key=lambda j: self.at[j])
            first = js[0]
            p = self.parents[first]
            if p >= 0 and self.at[first] > 0:
                js.insert(0, p)
        return out


def kinematic_tree(model) -> KinematicTree:
    """Expand the model's ``[[joint]]`` declarations over its arcs into one kinematic tree."""
    if not model.joints:
        raise InputError(f"model {model.name!r}: no [[joint]] declared; the full skeleton needs "
                         "joints along the arcs (see topopose.pose.model)")
    names, base, arc, at, offset, beyond, width, raised, slide, girdle, extends = \
        ([] for _ in range(11))
    arcs = model_arcs(model)
    for u, v in arcs:
        for js in model.joints:
            a, b = js.arc
            r = None if js.at_raised is None else float(js.at_raised)
            if a in (u, part_stem(u)) and b in (v, part_stem(v)):
                t = float(js.at)
            elif b in (u, part_stem(u)) and a in (v, part_stem(v)):
                t = 1.0 - float(js.at)
                r = None if r is None else 1.0 - r
            else:
                continue
            suffix = ""
            for decl, part in ((a, u), (b, v), (a, v), (b, u)):
                if decl not in (u, v) and decl == part_stem(part) and part != decl:
                    suffix = "_" + str(part).rpartition("_")[2]
                    break
            names.append(js.name + suffix)
            offset.append(tuple(float(x) for x in js.offset))
            width.append(tuple(float(x) for x in js.width))
            raised.append(r)
            slide.append(bool(js.slide))
            extends.append(bool(js.extends))
            girdle.append(None if js.girdle is None else (str(js.girdle[0]),
                                                          float(js.girdle[1])))
            beyond.append(float(js.beyond) if t == 1.0 else 0.0)
            base.append(js.name)
            arc.append((u, v))
            at.append(t)
    if len(set(names)) != len(names):
        raise InputError(f"model {model.name!r}: two joints share a name ({names})")
    for g in {g for g in girdle if g is not None}:
        if base.count(g[0]) != 2:
            raise InputError(f"model {model.name!r}: field 'girdle' names joint {g[0]!r}, which "
                             f"the arcs make {base.count(g[0])} joints, not a mirror pair of 2")
    anchor = {}
    for j, ((u, v), t) in enumerate(zip(arc, at)):
        if t == 0.0:
            anchor.setdefault(u, j)
        elif t == 1.0:
            anchor.setdefault(v, j)
    parents = [None] * len(names)
    for u, v in arcs:
        js = sorted((j for j in range(len(names)) if arc[j] == (u, v)), key=lambda j: at[j])
        prev = anchor.get(u)
        for j in js:
            if j == prev:
                continue
            if at[j] == 0.0 and anchor.get(u) not in (None, j):
                prev = anchor[u]
                continue
            parents[j] = -1 if prev is None else prev
            prev = j
    for part, j in anchor.items():
        if parents[j] is None:            # an anchor at the start of its arc: link it upwards
            into = [a for a in arcs if a[1] == part]
            up = None
            if into:
                cands = [k for k in range(len(names)) if arc[k] == into[0]]
                if cands:
                    up = max(cands, key=lambda k: at[k])
            parents[j] = -1 if up is None else up
    parents = [-1 if p is None else p for p in parents]
    if sum(p == -1 for p in parents) != 1:
        roots = [names[j] for j, p in enumerate(parents) if p == -1]
        raise InputError(f"model {model.name!r}: the joints form {len(roots)} trees (roots "
                         f"{roots}); put a joint at at = 0 or 1 where arcs meet")
    return KinematicTree(names, base, parents, arc, at, offset,
                         tuple(model.facing.get("trunk", ())), beyond,
                         frozenset(x for parts, _names in model.mirrors for x in parts), width,
                         raised, slide, girdle, extends)


TIP_DIRECTION = 0.1      # the tip direction: along the curve's last 10 % (see _along)


def _along(curve, t, beyond=0.0):
    """The point at relative arc length ``t`` of a curve; with ``beyond`` (t = 1), past its end
    by ``beyond`` × its length along its last direction (the chord of its last
    ``TIP_DIRECTION``): thinning stops a skeleton branch short of the limb's tip."""
    c = np.asarray(curve, dtype=float)
    s = arc_lengths(c)
    if s[-1] <= 0:
        return c[0]
    x = t * s[-1]
    out = np.array([np.interp(x, s, c[:, k]) for k in range(3)])
    if beyond:
        d = _end_direction(c, s)
        if d is not None:
            out = out + beyond * s[-1] * d
    return out


def _end_direction(c, s):
    """The unit direction of curve ``c`` (cumulative lengths ``s``) at its end: the chord of
    its last :data:`TIP_DIRECTION` of length; None when that is a point."""
    back = np.array([np.interp((1 - TIP_DIRECTION) * s[-1], s, c[:, k]) for k in range(3)])
    d = c[-1] - back
    n = float(np.linalg.norm(d))
    return d / n if n > 0 else None


def _beside(tree, j) -> bool:
    """Whether joint ``j`` lies beside its curve (an ``offset`` or a ``width``)."""
    return any(tree.offset[j]) or bool(tree.width and any(tree.width[j]))


def bone_lengths(init: np.ndarray, tree: KinematicTree, quantile=None,
                 fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """Length of each bone (child joint index): the ``quantile`` (default
    ``SkeletonFitOptions.quantile``) % of its lengths over the frames, mirror bones pooled. The joints
    at fixed relative arc lengths shorten a bone when its curve is cut short (the junction of
    a raised arm, a bent limb's curve cutting the corner): the median upper arm was 10 % short
    on walks, 20–25 % on random poses (development seeds). A ``slide`` bone (the neck's) takes
    ``SkeletonFitOptions.slide_quantile``, a bone from the root to a joint beside the curve (a shoulder's)
    ``SkeletonFitOptions.shoulder_quantile``: neither has a corner to make up for; the bones along a limb
    named in ``SkeletonFitOptions.limb_quantile`` (the legs') take its percentile."""
    limb = fit.limb_quantile if quantile is None else {}     # a quantile given: every bone's
    quantile = fit.quantile if quantile is None else quantile
    L = np.full(len(tree.names), np.nan)
    pooled = {}
    for j, p in enumerate(tree.parents):
        if p < 0:
            continue
        d = np.linalg.norm(init[:, j] - init[:, p], axis=1)
        pooled.setdefault((tree.base[j], tree.base[p]), []).extend(d[~np.isnan(d)])
    for j, p in enumerate(tree.parents):
        if p >= 0:
            v = pooled[(tree.base[j], tree.base[p])]
            q = (fit.slide_quantile if tree.slide and tree.slide[j] and fit.slide_quantile
                 else quantile)
            if fit.shoulder_quantile and p == tree.root and _beside(tree, j):
                q = fit.shoulder_quantile            # from the junction to a joint beside it
            if tree.arc[p] == tree.arc[j] and part_stem(tree.arc[j][1]) in limb:
                q = limb[part_stem(tree.arc[j][1])]   # along a limb ending at that part
            L[j] = float(np.percentile(v, q)) if v else np.nan
    return L


def frame_lengths(target, L, tree: KinematicTree, slide=None,
                  fit: SkeletonFitOptions = FIT) -> np.ndarray:
    """The frame's bone lengths: ``L``, except the bones of the joints declared ``slide``
    (when ``slide``, default ``SkeletonFitOptions.slide``): the distance of the joint's initial placement
    ``target`` from its parent's, when both are placed."""
    slide = fit.slide if slide is None else slide
    out = L.copy()
    if not slide or not tree.slide:
        return out
    for j, p in enumerate(tree.parents):
        if tree.slide[j] and p >= 0 and not np.isnan(target[[j, p]]).any():
            out[j] = float(np.linalg.norm(target[j] - target[p]))
    return out


def forward(root, dirs, L, tree: KinematicTree, order=None) -> np.ndarray:
    """Joint positions from the root position and one direction per bone (normalized here)."""
    order = tree.order() if order is None else order
    P = np.zeros((len(tree.names), 3))
    P[tree.root] = root
    for j in order[1:]:
        d = dirs[j]
        P[j] = P[tree.parents[j]] + L[j] * d / max(np.linalg.norm(d), 1e-12)
    return P


def _seg_dist(q, A, B):
    """Distance of points q (m, 3) to the nearest of segments A→B (k, 3)."""
    return _seg_nearest(q, A, B)[0]


def _seg_nearest(q, A, B):
    """Distance of points q (m, 3) to the nearest of segments A→B (k, 3), that segment's
    index and the parameter (0 at A, 1 at B) of the nearest point on it."""
    ab = B - A
    t = np.einsum("mkc,kc->mk", q[:, None, :] - A[None], ab) / np.maximum(
        np.einsum("kc,kc->k", ab, ab), 1e-12)
    t = np.clip(t, 0.0, 1.0)
    proj = A[None] + t[..., None] * ab[None]
    d = np.linalg.norm(q[:, None, :] - proj, axis=2)
    s = d.argmin(axis=1)
    rows = np.arange(len(q))
    return d[rows, s], s, t[rows, s]


def chain_joints(x, p0, L):
    """The joints ``Q_b = p0 + sum_{j <= b} L_j u_j`` of one arc chain for the bone directions
    ``x`` (flattened (m, 3)), with the unit directions ``u`` and their norms ``|d_j|``."""
    d = x.reshape(-1, 3)
    nd = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    u = d / nd[:, None]
    return p0 + np.cumsum(L[:, None] * u, axis=0), u, nd


def chain_residuals(x, p0, L, target, weight, curve=None, curve_weight=1.0, jac=False):
    """Residuals of one arc chain (:func:`fit_frame`) and, with ``jac``, their Jacobian.

    The chain's joints are ``Q_b = p0 + sum_{j <= b} L_j d_j / |d_j|`` for the bone
    directions ``x = (d_0, ..., d_{m-1})`` (m, 3 flattened). Residuals: each joint's weighted
    offset from its target (``weight`` (m, 1), 0 for a joint without one), the gauge
    ``0.1 (|d_j| - 1)``, and, with a curve (k, 3), every sample's distance to the nearest
    segment of the polyline ``p0, Q_0 … Q_{m-1}`` × ``curve_weight / sqrt(k)``.

    The Jacobian is exact where the nearest segment does not change (the envelope of the
    distance to a segment: its derivative moves the segment's two ends by (1 - t) and t);
    ``dQ_b / dd_j = L_j (I - u_j u_j^T) / |d_j|`` for j <= b, ``u_j = d_j / |d_j|``.

    Returns
    -------
    r : (3m + m [+ k],) residuals; with ``jac``, (r, J) with J of shape (len(r), 3m)
    """
    Q, u, nd = chain_joints(x, p0, L)
    m = len(u)
    r = [((Q - target) * weight).ravel(), 0.1 * (nd - 1.0)]
    if curve is not None:
        A = np.vstack([p0, Q])
        dist, seg, t = _seg_nearest(curve, A[:-1], A[1:])
        k = curve_weight / np.sqrt(len(curve))
        r.append(k * dist)
    r = np.concatenate(r)
    if not jac:
        return r
    # G[j] = L_j (I - u_j u_j^T) / |d_j|: the move of every joint from bone j on per unit of d_j
    G = L[:, None, None] * (np.eye(3)[None] - u[:, :, None] * u[:, None, :]) / nd[:, None, None]
    J = np.zeros((len(r), 3 * m))
    for b in range(m):
        for j in range(b + 1):
            J[3 * b:3 * b + 3, 3 * j:3 * j + 3] = weight[b, 0] * G[j]
        J[3 * m + b, 3 * b:3 * b + 3] = 0.1 * u[b]
    if curve is not None:
        P = A[seg] + t[:, None] * (A[seg + 1] - A[seg])
        nrm = np.where(dist[:, None] > 1e-12, (P - curve) / np.maximum(dist, 1e-12)[:, None], 0.0)
        rows = 4 * m + np.arange(len(curve))
        for j in range(m):
            # segment s runs from A_s (moved by the bones j < s) to A_{s+1} (by the bones j <= s)
            f = np.where(j < seg, 1.0, np.where(j == seg, t, 0.0))
            J[rows, 3 * j:3 * j + 3] = k * f[:, None] * (nrm @ G[j])
    return r, J


ROOT_STEPS = 1      # root refinements (development seeds 21–33 random poses, MPJPE median of
                    # the fit; each step costs one more fit). Its figures: docs/decisions.md.


def fit_frame(target, curves, L, tree: KinematicTree, start=None, inner_weight=1.0,
              curve_weight=1.0, root_steps=None, root=None):
    """Fit the kinematic tree to one frame (see the module docstring), one arc chain at a time
    from the root down: each chain's first joint is fixed by the chains above it, its bone
    directions are fitted (a dozen unknowns per :func:`least_squares`). Then ``root_steps``
    times: the root moved by the mean offset of the other joints from their targets, and the
    chains fitted again (alternating minimization over the root's position: the root, the
    chest junction, is the frame's least steady point).

    Returns (positions (n, 3), rms of the curve distances) or (None, None) without targets.
    """
    root_steps = ROOT_STEPS if root_steps is None else root_steps
    ok = ~np.isnan(target).any(axis=1)
    if not ok[tree.root] or ok.sum() < 2:
        return None, None
    init = target if start is None else np.where(np.isnan(start), target, start)
    n = len(tree.names)
    P = np.full((n, 3), np.nan)
    P[tree.root] = target[tree.root] if root is None else root
    w = np.where(np.array([t in (0.0, 1.0) or _beside(tree, j) for j, t in enumerate(tree.at)]),
                 1.0, inner_weight)
    rms = []
    for (u, v), js in tree.chains().items():
        if np.isnan(P[js[0]]).any():
            continue
        bones = js[1:]
        c = curves.get(v)
        c = None if c is None else np.asarray(c, float)
        tgt = target[bones]
        has = ~np.isnan(tgt).any(axis=1)
        if c is None and not has.any():
            if start is not None:      # nothing seen on this arc: the start's directions (held)
                d = np.diff(np.vstack([start[js[0]], start[bones]]), axis=0)
                d /= np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
                P[bones] = P[js[0]] + np.cumsum(L[bones][:, None] * d, axis=0)
            continue
        x0 = []
        prev = P[js[0]]
        for j in bones:
            d = init[j] - prev if not np.isnan(init[j]).any() else np.array([0.0, 0.0, -1.0])
            d = d / max(np.linalg.norm(d), 1e-9)
            x0.append(d)
            prev = prev + L[j] * d
        x0 = np.concatenate(x0)
        Lb = L[bones]
        wb = (w[bones] * has)[:, None]
        tgt0 = np.nan_to_num(tgt)
        p0 = P[js[0]]

        args = (p0, Lb, tgt0, wb, c, curve_weight)
        sol = least_squares(chain_residuals, x0, jac=lambda x, *a: chain_residuals(
            x, *a, jac=True)[1], args=args, method="lm", max_nfev=200)
        Q = chain_joints(sol.x, p0, Lb)[0]
        P[bones] = Q
        if c is not None:
            A = np.vstack([p0, Q])
            rms.append(float(np.sqrt(np.mean(_seg_dist(c, A[:-1], A[1:]) ** 2))))
    if np.isnan(P).any():
        return None, None
    if root_steps > 0:
        seen = ok.copy()
        seen[tree.root] = False
        return fit_frame(target, curves, L, tree, start, inner_weight, curve_weight,
                         root_steps - 1, P[tree.root] + np.mean(target[seen] - P[seen], axis=0))
    return P, float(np.mean(rms)) if rms else None


def _directions(P, tree):
    D = np.zeros_like(P)
    for j, p in enumerate(tree.parents):
        if p >= 0:
            d = P[j] - P[p]
            D[j] = d / max(np.linalg.norm(d), 1e-12)
    return D
