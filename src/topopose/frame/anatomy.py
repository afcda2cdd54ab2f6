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
# (:func:`torso_on_trunk`): model name → (part, lower end, upper end, min_fraction, fraction).
# An arm lying along the trunk leaves the hull at the hip, and its junction there — or the
# contracted torso–crotch arc — takes the torso, 0.1–0.3 × height below the chest. Measured on
# ``body`` (training seeds 41, 42, 5 builds × 12 frames, 100³, noise 1, gate off; the crotch
# and the head as placed — spine shift, head from the hull): the chest's ground truth lies at
# 0.59–0.60 of crotch → head (median; 5–95 %: 0.53–0.71); the torso of the alignment is right
# (within 0.08 × height) in 116 of 119 separated and 100 of 118 all-pose frames, and lies below
# 0.35 of crotch → head in 9 and 24 of them (right in 7 and 9); put at 0.6 there: 117 and 115
# right (at 0.6 in every frame: 117 and 116). Tried and dropped: the confidence's features
# computed with the torso so placed (figures "features as placed" below). Same training frames
# with the gate (TP rate / FP per match,
# separated; all poses): off 0.883 / 0.036; 0.650 / 0.071 → on (default) 0.892 / 0.027; 0.658
# / 0.060 → on, features as placed 0.892 / 0.036; 0.683 / 0.057. Held-out seeds 21, 22
# (``benchmarks/quality.py``, quality_body.md, *no-trunk* rows): with the gate the same figures
# either way (0.85 / 0.010; 0.60 / 0.053: the mended frames were already rejected or the gate
# rejects them; features as placed 0.86 / 0.019; 0.60 / 0.065, not kept); over all frames,
# whatever the status, all poses misplaced 26 → 24. It helps the training frames and costs the
# held-out ones nothing: kept on.
TORSO_ON_TRUNK = {"human": ("torso", "crotch", "head", 0.35, 0.6)}
# The torso drawn towards its place on the trunk line (:func:`trunk_blend`): model name →
# (part, lower end, upper end, fraction, weight). Arms folded on the chest or hanging against
# it add volume in front of and beside the trunk, and the shoulder junction of the skeleton
# moves with it: the torso near misses of the all-pose frames lie 0.05 × height in front of
# the chest and 0.02–0.03 sideways and down (studies/diagnose_body.py). The trunk line crotch →
# head (the head from the hull's crown) does not see the arms, but alone it is a coarser
# estimate (the chest at 0.53–0.71 of it, see TORSO_ON_TRUNK): half way between the two. Dev
# seeds 41, 42 (5 builds × 12 frames, 100³, noise 1, gate off; TP rate / FP per match), weight
# 0 / 0.25 / 0.5 / 0.75 / 1: all poses 0.800 / 0.086, 0.808 / 0.076 (0.25–0.75), 0.800 / 0.086;
# separated 0.908 / 0.052 → 0.917 / 0.043 (0.25–1). Torso beyond 0.08 × height among the all-pose
# frames with torso, crotch and head placed: 3 → 1 at 0.5 (median error 0.33 → 0.38 × the
# tolerance). Tried and dropped: the torso moved further back than the spine shift (0.1 / 0.2 /
# 0.3 × the hull's radius: wrong torsos 3 → 3 / 4 / 6), projected onto the trunk line at its
# own height (3 → 3, median error 0.61 × the tolerance). Held out (``benchmarks/quality.py``,
# quality_body.md, "no-trunk-blend" rows; gate off): all poses 0.77 / 0.080 → 0.79 / 0.050
# (misplaced 21 → 18), separated 0.93 / 0.067 either way.
TRUNK_BLEND = {"human": ("torso", "crotch", "head", 0.6, 0.5)}
# The crotch lowered and moved further back when the spine shift applies (:func:`crotch_drop`):
# model name → (part, down share, extra back share) × the hull's largest inscribed radius. The
# legs' junction of the skeleton lies in the thick mass of pelvis and thighs; when the hips are
# flexed (crouching, sitting, one knee up; the trunk bent forward) that mass fills the angle
# between belly and thighs and the junction rises and comes forward: the crotch near misses of
# ``studies/diagnose_body.py`` (gate off, separated) lie +0.05–0.10 × height above and
# +0.03–0.08 in front of the pelvis segment. No per-frame cue of the tree separated those frames
# (thigh descent, trunk–thigh angle: the failing frames sit among right ones), but the pelvis
# segment is 0.11 × height long above and below the hip centre, so a constant drop costs the
# right frames little. Dev seeds 41, 42, 43 (5 builds × 12 frames, gate off, matched frames;
# crotch beyond 0.08 × height): separated 3 → 1, all poses 4 → 4 (grid over down 0–0.6, back
# −0.1–0.2; 0.3–0.4 down with 0.1 back best). Held-out seeds 21, 22 (``benchmarks/quality.py
# --only body``, quality_body.md, *crotch-drop* rows; TP rate / FP per match, off → on): gate
# off, separated 0.93 / 0.067 → 0.96 / 0.034 (misplaced 9 → 5 of 120, past the 0.95 target),
# all poses 0.73 / 0.111 → 0.72 / 0.121 (misplaced 24 → 25); gate on, separated 0.85 / 0.010
# either way, all poses 0.60 / 0.053 → 0.58 / 0.079; 50³ separated 0.53 / 0.232 → 0.51 / 0.256;
# the crotch's median error 2.9 → 3.7 cm (separated). Dev seeds 41, 42 through the same study
# (gate on; off): separated 0.892 / 0.027 → 0.892 / 0.027; 0.908 / 0.052 → 0.917 / 0.043,
# all poses 0.658 / 0.060 → 0.650 / 0.071; 0.800 / 0.086 → 0.783 / 0.105 (misplaced 16 → 18;
# part of it the torso's trunk line drawn from the lowered crotch: dropped after
# :func:`torso_on_trunk` instead, 16 → 17). It loses all-pose frames, dev and held out.
# The frame it lost (dev seeds 41–43, all poses, lean 42 frame 4: a legs-apart stance whose
# junction already sat at the crotch, 0.07 × height *below* the hip centre) has the hull's
# gap between the legs right beneath the crotch: 0.26 × the radius, where the near misses it
# mends have 1.0–2.4 (clean frames: 5–95 % 0.8–1.7). Hence the fourth entry, the *floor*: the
# drop stops ``floor`` × radius above the hull's lower border straight beneath the crotch
# (:func:`room_below`). Dev seeds 41, 42, 43 (5 builds × 12 frames, gate off, every frame whose
# other parts are right; crotch beyond 0.08 × height, no drop → drop → drop with floor 0.5):
# separated 4 → 1 → 1, all poses 4 → 4 → 3 (floor 0.3–0.9 alike; a drop growing with the room,
# k × (room − d0), d0 0.8–1.1, k 0.25–1: separated 1–2, all poses 3, not kept). Held out
# (quality_body.md, *no-crotch-drop* and *crotch-drop-no-floor* rows, gate off; TP rate / FP
# per match, none → drop without → with the floor): separated 0.93 / 0.067 → 0.96 / 0.034 →
# 0.96 / 0.034, all poses 0.79 / 0.050 → 0.78 / 0.060 → 0.79 / 0.050 (before SHORT_ARM and
# TRUNK_BLEND: 0.73 / 0.111 → 0.72 / 0.121 → 0.73 / 0.111): on by default.
# A smaller down share, 0.1, tried and not kept: before the drop the legs' junction
# already lies at what the pose descriptions need of a crotch — the pelvis (capsule human: its
# centre, −0.5 cm along up, sd 2.5, dev seed 3; ``body``: ``Hips_head``, +0.5 cm, sd 3.3, dev
# seed 1) —, and 0.35 × radius puts it 4.1 cm (capsule) and 2.0 cm (body) below, out of the
# hands' ball in wide-spread arms (benchmarks/applications.py). Detection dev (wide-spread arms
# P / R, 0.35 → 0.1): capsule human seeds 3–4 0.989 / 0.877 → 0.990 / 0.914, body seeds 1–2
# 0.950 / 0.905 → 0.953 / 0.976. Dev seeds 41, 42 (``benchmarks/quality.py``'s body study, gate
# on; TP rate / FP per match, down 0.35 → 0.2 → 0.1 → none): separated 0.950 / 0.034 → 0.958 /
# 0.025 → 0.958 / 0.025 → 0.933 / 0.043, all poses 0.817 / 0.049 → 0.817 / 0.039 → 0.817 /
# 0.030 → 0.817 / 0.030. But held out (seeds 21, 22, ``quality.py --only body``, 0.35 → 0.1):
# separated 0.98 / 0.017 → 0.96 / 0.034 (misplaced 2 → 4 of 120; 150³ 0 → 1), all poses 0.78 /
# 0.021 either way — flexed hips (the frame of tests/test_pose_anatomy.py) need the whole drop,
# and no per-frame cue told them from the capsule's (hip flexion in the sagittal plane: 5–95 %
# alike). The peer *crotch-drop-0.1* (quality_body.md) keeps the trade measured. The pose
# descriptions (§13.3.2.1) compare the junction before the drop instead, which the estimate
# records in ``diagnostics["detect_parts"]`` (:func:`topopose.apps.detect.description_parts`;
# applications.md): the parts, and so the quality figures, are unchanged.
CROTCH_DROP = {"human": ("crotch", 0.35, 0.10, 0.5)}
# A hand on the trunk left unplaced (:func:`hand_on_trunk`): model name → (hands, core, reach).
# A forearm folded onto the chest or the belly fuses with the trunk in the hull; the arm's
# skeleton branch then ends at the elbow or runs on along the forearm inside the trunk's
# surface, and the hand placed at its end lies at the elbow or the shoulder — on a branch of
# ordinary length, which SHORT_ARM does not see. Such an end lies next to the trunk's thick
# core (the hull's voxels whose inscribed radius is ≥ ``core`` × the largest), a free hand
# away from it. The hand nearest the core, closer than ``reach`` × the hull's largest radius,
# is left unplaced when every other part is placed (a *missing limb*, right by §13.2.2).
# ``body`` dev seeds 41, 42, 43 (5 builds × 12 frames, 100³, noise 1, gate off; placed hands
# of the run's frames, distance to the core ÷ largest radius, core 0.6): all poses, the wrong
# hands 0.70–1.33 (14 of 17; 3 more at 2.7–3.1, on another limb), the right ones 1 % / 5 % /
# median 0.97 / 1.43 / 3.07; separated right hands 1 % 1.43. TP rate / FP per match, off →
# reach 1.0 / 1.2 / 1.3 / 1.5 / 1.7: all poses 0.833 / 0.062 → 0.844 / 0.050, 0.850 / 0.044,
# 0.856 / 0.037 (1.3–1.7; right hands dropped 5, 8, 14 frames at 1.3, 1.5, 1.7); separated
# 0.922 / 0.051 → 0.928 / 0.046 (1.3–1.5) (offline on the run's frames). Held out
# (``benchmarks/quality.py``, quality_body.md, *no-hand-trunk* rows; gate off): all poses 0.79 /
# 0.050 → 0.81 / 0.030 (misplaced 18 → 14 of 120), separated 0.97 / 0.025 → 0.97 / 0.017;
# gate on (main's refit with per-part trust) 0.74 / 0.022 and 0.95 / 0.009 either way. Capsule
# human (quality.md): TP rates unchanged, a few right hands become "missing limb".
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
