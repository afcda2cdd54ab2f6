"""Anatomical placement of the body-axis parts: the spine lies behind the skeleton.

A curve skeleton runs through the middle of each cross-section of the hull (thesis §4.3), so
the junctions where the limbs meet (torso, crotch) and the head's branch lie on the body's
*medial* axis. A real body's joints do not: the spine runs along the back, the hip joints and
the pelvis behind the belly, so the rig's joints — the ground truth of the ``body`` subject,
and the markers of a motion-capture suit — lie a few centimetres behind the medial axis.
Measured on ``body`` (training seeds 41, 42, 5 builds, 200 matched frames, 100³, noise 1;
``studies/diagnose_body.py``): the torso, the crotch and the head sit 0.027, 0.028 and
0.016 × height *in front of* their ground-truth segments (medians; 0.32, 0.34 and 0.17 × the
hull's largest inscribed-ball radius), the largest offset of any part; most misplaced frames
have a single torso, crotch or head just beyond the tolerance.

The body's *front* is not known to a tree, but the feet tell it: a foot's skeleton branch
ends in the toes, so its end direction, projected on the ground plane, points forward (over
the same frames: median cosine with the true front 0.975, within 45° in 91 %, backwards in
1 %). :func:`front_direction` averages both feet; :func:`spine_shift` moves the parts back
by their share of the hull's largest radius (the chest's: girth, not height, sets the
offset).

The shift is measured by ``benchmarks/quality.py --only body`` (its *no-spine* rows; the
figure that chose it: docs/decisions.md). The capsule human's ground truth lies on its
capsules' axis: there the shift only adds 1.5–2.5 cm to the torso and crotch errors.
"""
from __future__ import annotations

import numpy as np

from topopose.frame.tips import end_direction

# Backward shift of each body-axis part, × the hull's largest inscribed-ball radius (the
# medians of the training frames above); model name → {part: share}. See FrameEstimator.
SPINE_SHIFT = {"human": {"torso": 0.32, "crotch": 0.34, "head": 0.17}}
# The torso put back on the trunk line when the alignment slid it down to the crotch
# (:func:`torso_on_trunk`): model name → (part, lower end, upper end, min_fraction, fraction). An
# arm lying along the trunk leaves the hull at the hip, and its junction there — or the contracted
# torso–crotch arc — takes the torso, 0.1–0.3 × height below the chest. Its figures:
# docs/decisions.md.
TORSO_ON_TRUNK = {"human": ("torso", "crotch", "head", 0.35, 0.6)}
# The torso drawn towards its place on the trunk line (:func:`trunk_blend`): model name → (part,
# lower end, upper end, fraction, weight). Arms folded on the chest or hanging against it add volume
# in front of and beside the trunk, and the shoulder junction of the skeleton moves with it: the
# torso near misses of the all-pose frames lie 0.05 × height in front of the chest and 0.02–0.03
# sideways and down (studies/diagnose_body.py). The trunk line crotch → head (the head from the
# hull's crown) does not see the arms, but alone it is a coarser estimate (the chest at 0.53–0.71 of
# it, see TORSO_ON_TRUNK): half way between the two. Its figures: docs/decisions.md.
TRUNK_BLEND = {"human": ("torso", "crotch", "head", 0.6, 0.5)}
# The crotch lowered and moved further back when the spine shift applies (:func:`crotch_drop`):
# model name → (part, down share, extra back share) × the hull's largest inscribed radius. The legs'
# junction of the skeleton lies in the thick mass of pelvis and thighs; when the hips are flexed
# (crouching, sitting, one knee up; the trunk bent forward) that mass fills the angle between belly
# and thighs and the junction rises and comes forward: the crotch near misses of
# ``studies/diagnose_body.py`` (gate off, separated) lie +0.05–0.10 × height above and +0.03–0.08 in
# front of the pelvis segment. Its figures: docs/decisions.md.
CROTCH_DROP = {"human": ("crotch", 0.35, 0.10, 0.5)}
# A hand on the trunk left unplaced (:func:`hand_on_trunk`): model name → (hands, core, reach). A
# forearm folded onto the chest or the belly fuses with the trunk in the hull; the arm's skeleton
# branch then ends at the elbow or runs on along the forearm inside the trunk's surface, and the
# hand placed at its end lies at the elbow or the shoulder — on a branch of ordinary length, which
# SHORT_ARM does not see. Such an end lies next to the trunk's thick core (the hull's voxels whose
# inscribed radius is ≥ ``core`` × the largest), a free hand away from it. The hand nearest the
# core, closer than ``reach`` × the hull's largest radius, is left unplaced when every other part is
# placed (a *missing limb*, right by §13.2.2). Its figures: docs/decisions.md.
HAND_ON_TRUNK = {"human": (("hand_1", "hand_2"), 0.6, 1.3)}


def front_direction(vol, skeleton, data, mapping: dict, feet, up, reach: float = 4.0,
                    min_agreement: float = 1.0, voxels=None):
    """The body's forward direction on the ground plane, from its feet, or None.

    Each foot matched to a data leaf gives the end direction of its skeleton branch
    (:func:`topopose.frame.tips.end_direction`, the skeleton points within ``reach`` voxels),
    projected on the plane normal to ``up`` and made unit; the result is their mean, made
    unit, when its length is at least ``min_agreement`` (two feet within 120° of each other:
    1.0; one foot: 1.0 as well) — None otherwise (no foot, feet pointing apart, a foot
    pointing straight up or down). ``voxels``: :func:`topopose.frame.tips.skeleton_voxels` of
    ``skeleton`` if already computed."""
    vs = float(vol.voxel_size)
    pts = (np.argwhere(skeleton) if voxels is None else voxels) * vs + np.asarray(vol.origin, float)
    up = np.asarray(up, float)
    up = up / np.linalg.norm(up)
    acc, n = np.zeros(3), 0
    for p in feet:
        v = mapping.get(p)
        if v is None or data.degree(v) != 1 or data.positions.get(v) is None:
            continue
        d = end_direction(pts, np.asarray(data.positions[v], float), reach * vs)
        if d is None:
            continue
        h = d - (d @ up) * up
        nh = float(np.linalg.norm(h))
        if nh < 0.2:               # a foot pointing up or down says nothing of the front
            continue
        acc += h / nh
        n += 1
    length = float(np.linalg.norm(acc))
    if n == 0 or length < min_agreement:
        return None
    return acc / length


def hull_radius(vol, edt=None) -> float:
    """The hull's largest inscribed-ball radius in world units (exact Euclidean distance
    transform on the hull's bounding box; ``edt``: :func:`.tips.inscribed_distances` of
    ``vol.data`` if already computed)."""
    from topopose.frame.tips import inscribed_distances

    edt = inscribed_distances(vol.data) if edt is None else edt
    return 0.0 if edt is None else float(edt[0].max()) * float(vol.voxel_size)


def spine_shift(parts: dict, front, radius: float, shares: dict) -> dict:
    """``parts`` with every part of ``shares`` moved back (against ``front``) by its share
    × ``radius``; parts without a position, or all of them when ``front`` is None, unchanged."""
    if front is None or radius <= 0:
        return dict(parts)
    out = dict(parts)
    for p, s in shares.items():
        if out.get(p) is not None:
            out[p] = np.asarray(out[p], float) - s * radius * np.asarray(front, float)
    return out


def torso_on_trunk(parts: dict, rule) -> tuple:
    """``parts`` with ``rule``'s part (the torso) moved to ``fraction`` of the way lower end →
    upper end (crotch → head) when it lies below ``min_fraction`` of it (its projection on that
    line), and whether it moved. ``rule``: ``(part, lower, upper, min_fraction, fraction)``,
    e.g. :data:`TORSO_ON_TRUNK`; nothing moves when one of the three is unplaced or the two
    ends coincide."""
    part, lo, hi, min_fraction, fraction = rule
    pts = [parts.get(p) for p in (part, lo, hi)]
    if any(x is None for x in pts):
        return parts, False
    x, a, b = (np.asarray(p, float) for p in pts)
    u = b - a
    n2 = float(u @ u)
    if n2 == 0 or float((x - a) @ u) / n2 >= min_fraction:
        return parts, False
    out = dict(parts)
    out[part] = a + fraction * u
    return out, True


def trunk_blend(parts: dict, rule) -> dict:
    """``parts`` with ``rule``'s part (the torso) moved ``weight`` of the way from where it is
    to ``fraction`` of the way lower end → upper end (crotch → head). ``rule``: ``(part,
    lower, upper, fraction, weight)``, e.g. :data:`TRUNK_BLEND`; unchanged when one of the
    three is unplaced."""
    part, lo, hi, fraction, weight = rule
    pts = [parts.get(p) for p in (part, lo, hi)]
    if any(x is None for x in pts):
        return dict(parts)
    x, a, b = (np.asarray(p, float) for p in pts)
    out = dict(parts)
    out[part] = (1.0 - weight) * x + weight * (a + fraction * (b - a))
    return out


def room_below(vol, x, up, limit: float) -> float:
    """Distance from ``x`` straight down (against ``up``) to the first voxel outside the hull
    ``vol`` (its grid, half-voxel steps), at most ``limit`` (world units)."""
    vs = float(vol.voxel_size)
    o = np.asarray(vol.origin, float)
    step = -0.5 * vs * np.asarray(up, float) / np.linalg.norm(up)
    shape = np.asarray(vol.data.shape)
    x = np.asarray(x, float)
    for k in range(1, int(np.ceil(limit / (0.5 * vs))) + 1):
        q = np.round((x + k * step - o) / vs).astype(int)
        if np.any(q < 0) or np.any(q >= shape) or not vol.data[tuple(q)]:
            return min(k * 0.5 * vs, limit)
    return float(limit)


def crotch_drop(parts: dict, up, front, radius: float, rule, vol=None) -> dict:
    """``parts`` with ``rule``'s part moved down (along ``up``) by its down share and back
    (against ``front``) by its extra back share, × ``radius``. ``rule``: ``(part, down,
    back[, floor])``, e.g. :data:`CROTCH_DROP`; with ``floor`` and the hull ``vol`` the drop
    stops ``floor`` × ``radius`` above the hull's border beneath the part (:func:`room_below`:
    the gap between the legs). Unchanged when the part is unplaced, ``front`` is None or
    ``radius`` ≤ 0."""
    part, down, back = rule[:3]
    if parts.get(part) is None or front is None or radius <= 0:
        return dict(parts)
    up = np.asarray(up, float) / np.linalg.norm(up)
    x = np.asarray(parts[part], float)
    drop = down * radius
    if len(rule) > 3 and vol is not None:
        floor = rule[3] * radius
        drop = min(drop, max(0.0, room_below(vol, x, up, drop + floor) - floor))
    out = dict(parts)
    out[part] = x - drop * up - back * radius * np.asarray(front, float)
    return out


def hand_on_trunk(parts: dict, rule, vol, edt) -> str | None:
    """The hand of ``rule`` (:data:`HAND_ON_TRUNK`: ``(hands, core, reach)``) nearest the
    trunk's core — the hull's voxels whose inscribed radius is at least ``core`` × the largest
    — when it lies closer to it than ``reach`` × that largest radius; else None (also without
    a placed hand or a distance transform). ``edt``: :func:`.tips.inscribed_distances` of
    ``vol.data``. A folded forearm fused with the trunk ends the arm's branch there."""
    hands, core, reach = rule
    if edt is None:
        return None
    dt, lo = edt
    rmax = float(dt.max())
    if rmax <= 0:
        return None
    ijk = np.argwhere(dt >= core * rmax) - 1 + np.asarray(lo)      # grid voxels of the core
    best = None
    for p in hands:
        x = parts.get(p)
        if x is None:
            continue
        v = (np.asarray(x, float) - np.asarray(vol.origin, float)) / float(vol.voxel_size)
        d = float(np.sqrt(((ijk - v) ** 2).sum(axis=1).min()))
        if d < reach * rmax and (best is None or d < best[0]):
            best = (d, p)
    return None if best is None else best[1]
