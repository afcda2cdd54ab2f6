"""Joints and frames a frame's curves do not give (sequence stage of the kinematic fit): a joint
held from the last fitted frame, the rest pose of an unseen limb, an unseen arm bent to its
hand hint or moved towards the hull's shoulder, short runs of unfitted frames interpolated."""
from __future__ import annotations

import numpy as np

from topopose.sequence.joint_placement import HULL_GATE
from topopose.sequence.options import DEFAULT, GapOptions
from topopose.sequence.skeleton_fit import KinematicTree, _directions, forward

GAPS = DEFAULT.gaps

# GapOptions.hold_max = 0.15: m, mean move of the seen joints from the last fitted frame.
# GapOptions.hold_frames = 5: the last fitted frame at most this many frames before. Its figures:
# docs/decisions.md.


def _continues(prev, start, dt, gap: GapOptions = GAPS):
    """Whether the last fitted frame ``prev``, ``dt`` frames before, is the same motion:
    ``dt`` at most ``gap.hold_frames`` and the joints seen in both moved (relative to the first
    of them, the root when seen) less than ``gap.hold_max`` on average (unrelated random
    poses: the hands move 0.5–1.5 m)."""
    if prev is None or not 1 <= dt <= gap.hold_frames:
        return False
    ok = np.flatnonzero(~np.isnan(start).any(axis=1))
    if len(ok) == 0:
        return False
    d = (start[ok] - start[ok[0]]) - (prev[ok] - prev[ok[0]])
    return float(np.linalg.norm(d, axis=1).mean()) < gap.hold_max


FOLD = np.radians(130.0)  # an unseen arm's forearm and hand: folded forward and up by this angle
                          # from hanging, and turned ACROSS the body (towards the other side)


ACROSS = np.radians(30.0)  # by this angle about the trunk axis: a hand merged with the body lies
                          # against the trunk's front. Its figures: docs/decisions.md.


def _outward(P, tree, j, ax):
    """Unit vector from the chest to the shoulder of joint j's arm (its arc's first joint),
    across the trunk axis ``ax`` (zero when not defined)."""
    s = j
    while tree.parents[s] >= 0 and tree.arc[tree.parents[s]] == tree.arc[j]:
        s = tree.parents[s]
    c = tree.parents[s]
    if c < 0:
        return np.zeros(3)
    v = P[s] - P[c]
    v = v - np.dot(v, ax) * ax
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.zeros(3)


def rest_fill(start, pose, tree: KinematicTree, L, limbs, held_shoulder=GAPS.held_shoulder
              ) -> np.ndarray:
    """Unseen joints placed in a rest pose (an unseen limb is mostly one merged with the body):
    a joint whose mirror mate hangs from the same parent joint mirrored about the trunk axis
    (a half turn: hips; an arm's shoulder, with a forward known: opposite its mate across
    the trunk axis, raised ``GapOptions.held_shoulder`` from the plane across it), the other bones
    along the trunk axis — down for the limbs (arcs ending at a ``[[mirror]]`` part), up for
    the others (the head) — except an arm's (a limb from the trunk's upper part) bones below
    its first one: folded forward by ``FOLD`` and turned ``ACROSS`` the body (a hand merged
    with the body lies against the trunk's front), forward being the seen lower limbs' tip directions (the toes) across the
    trunk axis, across the direction from the arm's shoulder to the chest; without a forward,
    down."""
    out = start.copy()
    if not tree.trunk:
        return out
    a, b = (pose.parts.get(x) for x in tree.trunk)
    if a is None or b is None or np.isnan(out[tree.root]).any():
        return out
    ax = np.asarray(b, float) - np.asarray(a, float)
    if np.linalg.norm(ax) <= 0:
        return out
    ax /= np.linalg.norm(ax)
    fwd = []                       # forward: the tips of the limbs from the trunk's first part
    for j, p in enumerate(tree.parents):
        if tree.beyond and tree.beyond[j] and tree.arc[j][0] == tree.trunk[0] and \
                not np.isnan(start[j]).any() and not np.isnan(start[p]).any():
            v = start[j] - start[p]
            fwd.append(v - np.dot(v, ax) * ax)
    fwd = np.sum(fwd, axis=0) if fwd else None
    fwd = fwd / np.linalg.norm(fwd) if fwd is not None and np.linalg.norm(fwd) > 0 else None
    for j in tree.order()[1:]:
        if not np.isnan(out[j]).any():
            continue
        p = tree.parents[j]
        mates = [k for k in range(len(tree.names)) if k != j and tree.base[k] == tree.base[j]
                 and tree.parents[k] == p and not np.isnan(start[k]).any()]
        pp = tree.parents[p]
        arm = fwd is not None and tree.arc[j][1] in limbs and tree.arc[j][0] == tree.trunk[1]
        if mates and arm and held_shoulder is not None:
            v = start[mates[0]] - out[p]
            lat = v - np.dot(v, ax) * ax
            lat /= max(np.linalg.norm(lat), 1e-12)
            d = np.sin(held_shoulder) * ax - np.cos(held_shoulder) * lat
        elif mates:
            v = start[mates[0]] - out[p]
            d = 2 * np.dot(v, ax) * ax - v
        elif arm and pp >= 0 and tree.arc[pp] == tree.arc[j]:     # an arm below its elbow
            lat = _outward(out, tree, j, ax)
            d = -np.cos(FOLD) * ax + np.sin(FOLD) * (np.cos(ACROSS) * fwd - np.sin(ACROSS) * lat)
        else:
            d = -ax if tree.arc[j][1] in limbs else ax
        out[j] = out[p] + L[j] * d / max(np.linalg.norm(d), 1e-12)
    return out


# GapOptions.hints = True: an unseen arm bent to reach its hand hint's end (:func:`hint_fill`)
HINT_END = "wrist"  # the hint's end taken as the wrist ("wrist") or the elbow's direction
                    # ("elbow": the upper arm towards it, the forearm as it was). Its figures:
                    # docs/decisions.md.


SHOULDER_BLEND = 0.5  # the fraction of the way to the hull's shoulder an unseen arm moves


def shoulder_fill(start, pose, tree: KinematicTree, unseen) -> np.ndarray:
    """``start`` with each unseen arm (an arc from the trunk's upper part to a limb part, all
    its joints ``unseen``) moved whole, its shoulder :data:`SHOULDER_BLEND` of the way to the
    nearer of the frame's two shoulders from the hull (``diagnostics["hull_shoulders"]``: the
    lateral extremes of the trunk's cross-section below the neck,
    :func:`topopose.frame.unseen.hull_shoulders`) when that lies within :data:`HULL_GATE`. The
    fit then keeps the chest → shoulder bone's length, taking its direction."""
    H = pose.diagnostics.get("hull_shoulders")
    out = start.copy()
    if H is None or not tree.trunk:
        return out
    H = np.asarray(H, float).reshape(-1, 3)
    for (u, v), js in tree.chains().items():
        arm = js[1:]
        if u != tree.trunk[1] or v not in tree.limbs or not arm or not unseen[arm].all() \
                or np.isnan(out[arm]).any():
            continue
        h = H[int(np.argmin(np.linalg.norm(H - out[arm[0]], axis=1)))]
        if np.linalg.norm(h - out[arm[0]]) > HULL_GATE:
            continue
        h = out[arm[0]] + SHOULDER_BLEND * (h - out[arm[0]])
        out[arm] += h - out[arm[0]]
    return out


def hint_fill(start, pose, tree: KinematicTree, L, unseen) -> np.ndarray:
    """``start`` with each unseen arm that has a hand hint (``diagnostics["hand_hints"]``:
    the curve of the branch of a hand the per-frame stage left unplaced — an arm branch
    ending at the elbow (``short_arm``), a hand on the trunk's core (``hand_on_trunk``) or an
    untrusted hand — from the chest junction to the branch end) bent at the hint. With
    :data:`HINT_END` ``"wrist"`` (default; the end lies near the wrist, not the elbow): the
    shoulder kept (as ``start`` has it), the elbow and wrist by the law of cosines so that the
    wrist is at the hint's end (on the line towards it, the arm straight, when out of reach),
    bent in the plane of ``start``'s elbow (the rest pose's hanging upper arm or the last
    frame's); with ``"elbow"``: the elbow a bone length from the shoulder towards the end.
    The joints below keep ``start``'s bone directions. Only arcs whose joints are all
    ``unseen`` (bool per joint: not placed by the frame)."""
    hints = pose.diagnostics.get("hand_hints") or {}
    out = start.copy()
    for (u, v), js in tree.chains().items():
        c = hints.get(v)
        arm = js[1:]
        if c is None or len(arm) < 2 or np.isnan(out[arm[0]]).any():
            continue
        end = np.asarray(c, float)[-1]
        d = end - out[arm[0]]
        if np.linalg.norm(d) <= 0 or np.isnan(out[arm]).any() or not unseen[arm].all():
            continue
        if HINT_END == "elbow" or len(arm) < 3:
            e = out[arm[0]] + L[arm[1]] * d / np.linalg.norm(d)
            out[arm[1:]] += e - out[arm[1]]
            continue
        # the end as the wrist: two bones (law of cosines), bent as ``start`` bends them
        a, b, r = L[arm[1]], L[arm[2]], float(np.linalg.norm(d))
        t = d / r
        n = out[arm[1]] - out[arm[0]]
        n = n - np.dot(n, t) * t
        n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-9 else np.zeros(3)
        ca = np.clip((a * a + r * r - b * b) / (2 * a * r), -1.0, 1.0) if r < a + b else 1.0
        e = out[arm[0]] + a * (ca * t + np.sqrt(1 - ca * ca) * n)
        w = end - e
        w = e + b * w / max(np.linalg.norm(w), 1e-12)
        out[arm[3:]] += w - out[arm[2]]
        out[arm[1]], out[arm[2]] = e, w
    return out


def _interpolate(P, t, L, tree: KinematicTree, a, b) -> None:
    """Frames ``a + 1 … b - 1`` of ``P`` (in place) interpolated between frames ``a`` and ``b``
    by their frame numbers ``t``: the root position and the bone directions linearly
    (normalized), the bone lengths ``L`` (per frame) too."""
    Da, Db = _directions(P[a], tree), _directions(P[b], tree)
    for k in range(a + 1, b):
        s = (t[k] - t[a]) / (t[b] - t[a])
        root = (1 - s) * P[a, tree.root] + s * P[b, tree.root]
        P[k] = forward(root, (1 - s) * Da + s * Db, (1 - s) * L[a] + s * L[b], tree)
