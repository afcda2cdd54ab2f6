"""Evidence for an unseen limb from the frame's own hull (thesis §13.3.1: the per-frame result
initializes a kinematic model; the limb the alignment did not find has no skeleton curve).

An arm the alignment did not find mostly lies against the trunk or is fused with it in the
visual hull: the thinning leaves it no branch of its own, but the hull still holds its mass.
The matched skeleton curves, each sample swollen to its inscribed ball (the medial axis
reconstruction of the hull), explain the hull's voxels near them; what they leave unexplained
— the hull's *remainder* — is where an unseen limb can be (plus the trunk's flanks, which its
largest inscribed balls do not reach):

* :func:`hull_remainder` — the per-frame stage (:mod:`.estimate`) records it, sub-sampled, in
  ``diagnostics["arm_evidence"]`` when a limb part is unplaced (nothing else changes);
* :func:`evidence_fill` — the kinematic fit (:mod:`.kinematic_fit`, ``ARM_EVIDENCE``)
  turns an unseen arm's elbow about its shoulder → wrist line (shoulder and wrist as the rest
  pose or the last frame put them, bone lengths constant) to where its two bones pass nearest
  the remainder on its side; with too little remainder in reach the arm is left as it was.
* :func:`hull_shoulders` — the shoulders the trunk's own cross-section below the neck tells
  (its lateral extremes, the column above them), whether an arm is seen or lies on the body;
  the per-frame stage records them in ``diagnostics["hull_shoulders"]``
  (:func:`frame_hull_shoulders`) and the kinematic fit places hanging and unseen arms'
  shoulders there (``SEEN_HULL_SHOULDER``, ``HULL_SHOULDER``).

Development seeds (random 21–28, walks 41–45, gate on; ``benchmarks/tracking.py``'s figures):
with the true shoulder and bone lengths, elbow and wrist bent freely through the remainder
are 9.6 cm off (mean of the two, median over 148 unseen random arms; the arm hanging straight
25.3 cm), but from the fit's own shoulder (9 cm off) the freely bent wrist was worse than the
rest pose's folded one (20.0 against 10.9 cm), and so was a
shoulder searched in a 35° cone too (6.45): hence the elbow alone, on its circle.
"""
from __future__ import annotations

import numpy as np

GROW = 1.3        # a curve sample explains the hull within GROW × its inscribed radius + PAD voxels
PAD = 1.0
STRIDE = 2        # the hull's voxels sub-sampled by this along each axis


def hull_remainder(vol, curves: dict, edt=None, stride: int = STRIDE, grow: float = GROW,
                   pad: float = PAD) -> np.ndarray:
    """(n, 3) world positions of the hull's voxels (every ``stride``-th along each axis) that
    no matched skeleton curve explains: farther from each sample of every curve of ``curves``
    (part → (k, 3) world polyline) than ``grow`` × the sample's inscribed-ball radius + ``pad``
    voxels. ``edt``: :func:`.tips.inscribed_distances` of ``vol.data`` if already computed."""
    from topopose.frame.tips import inscribed_distances

    data = np.asarray(vol.data, bool)
    if edt is None:
        edt = inscribed_distances(data)
    vs, origin = float(vol.voxel_size), np.asarray(vol.origin, float)
    idx = np.argwhere(data[::stride, ::stride, ::stride]) * stride
    if edt is None or not len(idx) or not curves:
        return np.zeros((0, 3))
    dt, lo = edt
    pts = []
    for c in curves.values():             # densified to one voxel between samples
        c = np.asarray(c, float)
        if len(c) < 2:
            pts.append(c)
            continue
        d = np.diff(c, axis=0)
        k = np.maximum(np.ceil(np.linalg.norm(d, axis=1) / vs).astype(int), 1)
        seg = np.repeat(np.arange(len(k)), k)          # k points a segment, at i / k of it
        i = np.arange(len(seg)) - np.repeat(np.cumsum(k) - k, k)
        pts.append(c[:-1][seg] + (i * (1.0 / k)[seg])[:, None] * d[seg])
        pts.append(c[-1:])
    S = np.vstack(pts)
    ijk = np.clip(np.rint((S - origin) / vs).astype(int) - np.asarray(lo) + 1, 0,
                  np.asarray(dt.shape) - 1)
    reach = grow * dt[tuple(ijk.T)] * vs + pad * vs
    from topopose.frame.unseen_kernels import unexplained

    X = origin + idx * vs
    return X[unexplained(X, np.ascontiguousarray(S), np.ascontiguousarray(reach, dtype=float))]


def _seg_dist(X, A, B):
    """Distances of points X (n, 3) to segments A→B (m, 3): (m, n)."""
    d = B - A
    dd = np.maximum((d * d).sum(axis=1), 1e-12)
    t = np.clip(((X[None, :, :] - A[:, None, :]) * d[:, None, :]).sum(axis=2) / dd[:, None], 0, 1)
    q = A[:, None, :] + t[..., None] * d[:, None, :]
    return np.linalg.norm(X[None, :, :] - q, axis=2)


INNER = 0.4         # remainder points nearer the shoulder than this × the upper arm: its own mass
MIN_POINTS = 4      # fewer remainder points within the arm's reach: no evidence (rest pose kept)
CAP = 0.17          # a remainder point's distance to the arm counted up to CAP × the arm's length
PRIOR = 0.1         # weight of the elbow's distance to the rest pose's (over the arm's length,
                    # × the cap) against the points' mean capped distance


def _elbow_towards(s, w, a, b, e):
    """The elbow of a two-bone limb (lengths ``a``, ``b``) from ``s`` to ``w`` nearest ``e``
    (on the line towards ``w`` when out of reach)."""
    d = w - s
    r = float(np.linalg.norm(d))
    if r <= 1e-9:
        return e
    t = d / r
    ca = np.clip((a * a + r * r - b * b) / (2 * a * r), -1.0, 1.0)
    n = (e - s) - np.dot(e - s, t) * t
    nn = np.linalg.norm(n)
    n = n / nn if nn > 1e-9 else np.zeros(3)
    return s + a * (ca * t + np.sqrt(1 - ca * ca) * n)


ANGLES = 72         # elbow positions tried on the circle about the shoulder → wrist line


def elbow_on_circle(s, w, a, b, X, rest, cap=np.inf, n=ANGLES, prior=PRIOR):
    """The elbow of a two-bone limb from ``s`` to ``w`` (bone lengths ``a``, ``b``: the
    elbow on a circle about the line s → w; on the line towards ``w`` when out of reach)
    whose two segments pass nearest the points ``X``: the mean over the points of their
    distance to the segments, capped at ``cap``, plus ``prior`` × ``cap`` × the elbow's
    distance to ``rest`` over ``a + b`` (a tie-breaker), over ``n`` angles."""
    d = w - s
    r = float(np.linalg.norm(d))
    if r <= 1e-9 or r >= a + b:
        return _elbow_towards(s, w, a, b, rest)
    t = d / r
    ca = np.clip((a * a + r * r - b * b) / (2 * a * r), -1.0, 1.0)
    c, rho = s + a * ca * t, a * np.sqrt(1 - ca * ca)
    u = np.cross(t, [1.0, 0.0, 0.0] if abs(t[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(t, u)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    E = c + rho * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
    du = _seg_dist(X, np.repeat(s[None], n, 0), E)
    dw = _seg_dist(X, E, np.repeat(w[None], n, 0))
    cost = np.minimum(np.minimum(du, dw), cap).mean(axis=1)
    cost = cost + prior * (cap if np.isfinite(cap) else 1.0) \
        * np.linalg.norm(E - rest, axis=1) / (a + b)
    return E[int(np.argmin(cost))]


def evidence_fill(start, pose, tree, L, unseen, limbs, reach: float = 1.15,
                  min_points: int = MIN_POINTS) -> np.ndarray:
    """``start`` with the elbow of each unseen arm (an arc from the trunk's upper part to a
    limb part, all of its joints ``unseen``, at least shoulder, elbow, wrist) turned towards
    the frame's hull remainder (``diagnostics["arm_evidence"]``, :func:`hull_remainder`) on
    its side: the points within ``reach`` × the arm's length of its shoulder, beyond
    :data:`INNER` × the upper arm (the shoulder's own mass) and nearer to it than to the other
    arm's shoulder (when placed); :func:`elbow_on_circle`, ``start``'s elbow as the
    tie-breaking rest. Shoulder, wrist and the joints below stay. Fewer than ``min_points``
    points: the arm as ``start`` has it."""
    X = pose.diagnostics.get("arm_evidence")
    out = start.copy()
    if X is None or not tree.trunk:
        return out
    X = np.asarray(X, float).reshape(-1, 3)
    chains = {k: js for k, js in tree.chains().items() if k[0] == tree.trunk[1] and k[1] in limbs}
    shoulders = {k: js[1] for k, js in chains.items() if len(js) >= 4}
    for (u, v), js in chains.items():
        arm = js[1:]
        if len(arm) < 3 or np.isnan(out[arm]).any() or not unseen[arm].all():
            continue
        s, a, b = out[arm[0]], L[arm[1]], L[arm[2]]
        d = np.linalg.norm(X - s, axis=1)
        near = (d <= reach * (a + b)) & (d >= INNER * a)
        for k, o in shoulders.items():
            if k != (u, v) and not np.isnan(out[o]).any():
                near &= d < np.linalg.norm(X - out[o], axis=1)
        if near.sum() < min_points:
            continue
        out[arm[1]] = elbow_on_circle(s, out[arm[2]], a, b, X[near], out[arm[1]],
                                      cap=CAP * (a + b))
    return out


# The shoulders from the trunk's own cross-section (hull radii, r: the hull's largest inscribed
# radius): the hull's voxels in a slab SLAB ± SLAB_HALF above the chest junction along the
# trunk axis, on each side of the plane through the trunk axis and the front; the side's
# lateral extreme (its deltoid or the upper arm against it) minus LATERAL is the shoulder's
# lateral position, the median front-back position of the slab's voxels within FRONT_BAND of
# that extreme minus FRONT its front-back position, and the top of the hull's column above
# (LATERAL_BAND inside the extreme, within COLUMN of that front-back position, below TOP)
# minus DROP its height. Development seeds 21–28 random and 41–45 walks, gate on, 181 unseen
# arms, against the fit's chest (medians): the true shoulder is 5.4 cm below the column top
# (interquartile 3.5 cm), 6.0 cm inside the extreme (2.7 cm); the rest pose's shoulder was
# 8.2 cm off, this estimate 3.6 cm.
SLAB, SLAB_HALF = 0.42, 0.28
LATERAL, FRONT_BAND, FRONT = 0.42, 0.56, 0.08
LATERAL_BAND, COLUMN, TOP, DROP = (0.2, 0.7), 0.42, 2.4, 0.375


def hull_shoulders(vol, junction, axis, front, radius):
    """(2, 3) world positions of the shoulders the hull's cross-section below the neck tells
    (see :data:`SLAB`): on the side of ``+lateral`` then ``-lateral``, ``lateral`` = axis ×
    front (``junction``: the skeleton curves' chest junction; ``axis``: the trunk's direction
    up; ``front``: the body's front; ``radius``: the hull's largest inscribed radius). None
    when a side's slab is empty."""
    ax = np.asarray(axis, float)
    ax = ax / np.linalg.norm(ax)
    f = np.asarray(front, float)
    f = f - np.dot(f, ax) * ax
    if np.linalg.norm(f) <= 0 or not radius or radius <= 0:
        return None
    f /= np.linalg.norm(f)
    lat = np.cross(ax, f)
    M = np.stack([ax, f, lat])
    from topopose.frame.tips import hull_box, skeleton_voxels

    data = np.asarray(vol.data, bool)       # its voxels in index order, read within its box
    box = hull_box(vol)
    idx = np.argwhere(data) if box is None else skeleton_voxels(data, box)
    X = np.asarray(vol.origin, float) + idx * float(vol.voxel_size)
    Y = (X - np.asarray(junction, float)) @ M.T
    r = float(radius)
    out = []
    for sg in (1.0, -1.0):
        m = (np.abs(Y[:, 0] - SLAB * r) <= SLAB_HALF * r) & (Y[:, 2] * sg > 0)
        if not m.any():
            return None
        lv = Y[m, 2] * sg
        e = lv.max()
        fb = float(np.median(Y[m][lv > e - FRONT_BAND * r, 1])) - FRONT * r
        col = ((Y[:, 2] * sg > e - LATERAL_BAND[1] * r) & (Y[:, 2] * sg < e - LATERAL_BAND[0] * r)
               & (np.abs(Y[:, 1] - fb) < COLUMN * r) & (Y[:, 0] < TOP * r))
        a = (Y[col, 0].max() if col.any() else SLAB * r + SLAB_HALF * r) - DROP * r
        out.append(np.asarray(junction, float) + M.T @ np.array([a, fb, sg * (e - LATERAL * r)]))
    return np.array(out)


def frame_hull_shoulders(vol, curves: dict, parts: dict, model, spine_shift):
    """:func:`hull_shoulders` of a frame: the junction is the start of the skeleton curves from
    the model's upper trunk part (``[facing] trunk``, e.g. crotch → torso: the trunk axis), the
    front and the hull radius are the spine shift's (:mod:`.anatomy`: −radius × front). None
    when one of them is missing."""
    from topopose.frame.curves import model_arcs

    trunk = tuple(model.facing.get("trunk", ()))
    if len(trunk) != 2 or spine_shift is None:
        return None
    a, b = (parts.get(x) for x in trunk)
    starts = [curves[v] for u, v in model_arcs(model) if u == trunk[1] and v in curves]
    if a is None or b is None or not starts:
        return None
    axis = np.asarray(b, float) - np.asarray(a, float)
    s = np.asarray(spine_shift, float)
    if np.linalg.norm(axis) <= 0 or np.linalg.norm(s) <= 0:
        return None
    return hull_shoulders(vol, np.asarray(starts[0], float)[0], axis, -s, float(np.linalg.norm(s)))
