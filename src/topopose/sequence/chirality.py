"""Left and right from geometry (the thesis' "A1/A2": a tree cannot tell them apart).

Per frame, from the skeleton curves of the matched arcs (:mod:`.curves`) alone:

1. **Facing** — the subject's forward direction, horizontal (perpendicular to the capture's up
   axis). For a model with ``[facing] feet`` (human): each foot arc ends in the foot, which
   points forward from the ankle (the curve's last fifth, ankle → toe), and bends forward at
   its middle (the knee: offset of the curve's middle from the hip–ankle chord); the planted
   foot is the strongest cue, so the vectors are summed unnormalized (a foot seen end-on or a
   straight knee adds little). For ``[facing] axis = [a, b]`` (dog): from part a to part b.
2. **Sides** — left = up × forward. Each mirror pair (``[[mirror]]`` in the model) is ordered
   by the lateral coordinate of its arcs' proximal quarter (shoulder, hip: steadier than the
   extremities, which cross the body). When only one part of a pair is found (a hand merged
   with the body), that part alone is named: the lateral offset of its proximal quarter from
   its arc's start on the trunk (the chest or crotch junction), doubled to compare with a
   pair's separation. Random poses lose one hand in about a quarter of the matched frames;
   development seeds 21–33 (13 random-pose sequences): 148 of 150 lone hands on their side by
   this offset, the 2 others with a weak facing or a zero offset (unsure).

The frame's signed score is ``(1 - e^{-|f|/f0}) (1 - e^{-|s|/s0})`` with the sign of the
lateral difference ``s``: near 0 when the facing is weak (both feet end-on) or the pair is
side by side along the facing. Over a sequence, a frame whose own score is weak (below
``strong``) takes the sum of the scores of its tracking segment (:mod:`.track`: the identities
are the same), so time only steadies the per-frame decision. A segment whose frames disagree
(coherence ``|Σ score| / Σ |score|`` below ``COH_WEAK``) holds no identity to use — the tracker
joins unrelated poses of a random-pose capture — and its weak frames decide alone
(``benchmarks/tracking.py`` and ``benchmarks/real_motion.py`` measure the sides). A frame
whose confidence stays below ``min_confidence`` keeps the numbered names. A strong frame is
overruled only by at least ``OVERRULE_MIN`` other frames of a segment of coherence
``COHERENT`` whose mean score is strong and opposite (legs crossing on a one-legged balancing
subject turn the hips' order for a frame or two; measured on the Pose2Sim balancing trial,
``benchmarks/real_motion.py``).
"""
from __future__ import annotations

import numpy as np

from topopose.sequence.track import relabel

F0 = 0.05          # facing strength scale (m): a planted foot gives 0.1–0.2
OVERRULE_MIN = 5   # frames of a tracking segment that can overrule a frame's strong decision
COHERENT = 0.8     # a segment's coherence |Σ score| / Σ |score| for overruling a strong frame
COH_WEAK = 0.3     # ... for deciding a weak frame
S0 = 0.05          # lateral separation scale (m): shoulders / hips are 0.3–0.4 apart


def _horizontal(v, up):
    v = np.asarray(v, dtype=float)
    return v - np.dot(v, up) * up


def facing(pose, model, up):
    """Forward direction (unit, horizontal) and its strength (capture units), or (None, 0)."""
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    curves = pose.diagnostics.get("curves") or {}
    f = np.zeros(3)
    for part in model.facing.get("feet", ()):
        c = curves.get(part)
        if c is None:
            continue
        c = np.asarray(c, dtype=float)
        n = len(c)
        k = max(1, int(round(0.2 * (n - 1))))
        f += _horizontal(c[-1] - c[-1 - k], up)                  # ankle → toe
        hip, ankle, mid = c[1], c[-1 - k], c[(n - 1) // 2]
        ax = ankle - hip
        if np.linalg.norm(ax) > 0:
            ax = ax / np.linalg.norm(ax)
            off = (mid - hip) - np.dot(mid - hip, ax) * ax        # the knee's bend
            f += 0.5 * _horizontal(off, up)
    axis = model.facing.get("axis")
    if axis:
        a, b = (pose.parts.get(x) for x in axis)
        if a is not None and b is not None:
            f += _horizontal(np.asarray(b, float) - np.asarray(a, float), up)
    s = float(np.linalg.norm(f))
    return (f / s, s) if s > 1e-9 else (None, 0.0)


def _proximal(pose, part):
    c = (pose.diagnostics.get("curves") or {}).get(part)
    if c is not None:
        c = np.asarray(c, dtype=float)
        return c[int(round(0.25 * (len(c) - 1)))]
    x = pose.parts.get(part)
    return None if x is None else np.asarray(x, dtype=float)


def frame_scores(pose, model, up) -> dict:
    """Signed per-frame score of each mirror pair (index → score in [-1, 1]; > 0: ``parts[0]``
    is on the subject's left)."""
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    f, strength = facing(pose, model, up)
    out = {}
    if f is None:
        return {i: 0.0 for i in range(len(model.mirrors))}
    left = np.cross(up, f)
    for i, (parts, _names) in enumerate(model.mirrors):
        a, b = (_proximal(pose, p) for p in parts)
        if a is None and b is None:
            out[i] = 0.0
            continue
        if a is None or b is None:                 # one part found: its side of the trunk
            x, sign = (a, 1.0) if b is None else (b, -1.0)
            c = (pose.diagnostics.get("curves") or {}).get(parts[0] if b is None else parts[1])
            if c is None:
                out[i] = 0.0
                continue
            s = sign * 2.0 * float(np.dot(x - np.asarray(c[0], dtype=float), left))
        else:
            s = float(np.dot(a - b, left))
        out[i] = float(np.sign(s) * (1 - np.exp(-strength / F0)) * (1 - np.exp(-abs(s) / S0)))
    return out


def side_prefix(name: str, part: str) -> str:
    """``left_`` from mirror name ``left_hand`` and part ``hand_1``; else ``name + "_"``."""
    stem = str(part).rpartition("_")[0] or str(part)
    return name[:-len(stem)] if name.endswith(stem) and len(name) > len(stem) else name + "_"


def joint_renaming(model, mapping: dict, joint_names) -> dict:
    """Joint names renamed with the sides: ``elbow_1`` → ``left_elbow`` when ``hand_1`` →
    ``left_hand`` in ``mapping``."""
    out = {}
    for part, name in mapping.items():
        if part == name:
            continue
        k = str(part).rpartition("_")[2]
        pre = side_prefix(name, part)
        stem = str(part).rpartition("_")[0]
        for j in joint_names:
            base, _, kk = str(j).rpartition("_")
            if kk == k and base and _joint_on(model, base, stem):
                out[j] = pre + base
    return out


def _joint_on(model, base, stem):
    return any(js.name == base and stem in js.arc for js in model.joints)


def assign_sides(poses, model, up, min_confidence=0.3, use_time=True, strong=0.5) -> list:
    """Name the mirror pairs left / right in every matched frame (see the module docstring).

    Parameters
    ----------
    poses : list of Pose (after :func:`.track.track` for the time consistency; curves in their
        diagnostics)
    model : Model with ``mirrors`` and ``facing``
    up : the capture's up vector
    min_confidence : below it a frame keeps the numbered names
    use_time : sum the scores over each tracking segment
    strong : a frame whose own score reaches this keeps its own decision (a tracking segment
        may join unrelated poses: captures of unrelated frames), unless ``OVERRULE_MIN`` other
        frames of its segment have a mean score at least this strong of the other sign

    Returns
    -------
    list of Pose: parts (and joints) renamed; ``diagnostics["chirality"]`` =
    {numbered part: {"name": output name, "confidence": c}} and ``diagnostics["facing"]``.
    """
    if not model.mirrors:
        return list(poses)
    scores = [frame_scores(p, model, up) if p.matched else None for p in poses]
    out = list(poses)
    for i_pair, (parts, names) in enumerate(model.mirrors):
        stem = str(parts[0]).rpartition("_")[0]
        seg_sum, seg_n, seg_abs = {}, {}, {}
        for p, sc in zip(poses, scores):
            if sc is None:
                continue
            seg = (p.diagnostics.get("track") or {}).get(stem) if use_time else None
            key = ("seg", seg) if seg is not None else ("frame", p.frame)
            seg_sum[key] = seg_sum.get(key, 0.0) + sc[i_pair]
            seg_n[key] = seg_n.get(key, 0) + 1
            seg_abs[key] = seg_abs.get(key, 0.0) + abs(sc[i_pair])
        for i, (p, sc) in enumerate(zip(poses, scores)):
            if sc is None:
                continue
            seg = (p.diagnostics.get("track") or {}).get(stem) if use_time else None
            key = ("seg", seg) if seg is not None else ("frame", p.frame)
            own, others = sc[i_pair], seg_n[key] - 1
            mean = (seg_sum[key] - own) / max(others, 1)       # the rest of the segment
            coh = abs(seg_sum[key]) / max(seg_abs[key], 1e-12)
            overruled = (coh >= COHERENT and others >= OVERRULE_MIN and abs(mean) >= strong
                         and mean * own < 0)
            z = seg_sum[key] if overruled or (abs(own) < strong and coh >= COH_WEAK) else own
            conf = float(min(1.0, abs(z)))
            if conf >= min_confidence:
                mapping = ({parts[0]: names[0], parts[1]: names[1]} if z > 0
                           else {parts[0]: names[1], parts[1]: names[0]})
            else:
                mapping = {parts[0]: parts[0], parts[1]: parts[1]}
            q = relabel(out[i], mapping)
            q.joints = {joint_renaming(model, mapping, [j]).get(j, j): v
                        for j, v in q.joints.items()}
            chir = dict(q.diagnostics.get("chirality") or {})
            for a in parts:
                chir[a] = {"name": mapping[a], "confidence": round(conf, 3),
                           "frame_score": round(float(sc[i_pair]), 3)}
            q.diagnostics = {**q.diagnostics, "chirality": chir}
            out[i] = q
    for i, p in enumerate(out):
        if p.matched:
            f, s = facing(poses[i], model, up)
            if f is not None:
                p.diagnostics["facing"] = [round(float(x), 4) for x in f]
    return out


def numbered(pose, model):
    """The pose with mirror names turned back into the model's numbered parts (``left_hand`` →
    ``hand_1``: the order of ``[[mirror]]``, which ground truth follows)."""
    mapping = {n: p for parts, names in model.mirrors for p, n in zip(parts, names)}
    if not any(k in pose.parts for k in mapping):
        return pose
    return relabel(pose, mapping)
