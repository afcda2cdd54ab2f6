"""Left and right from geometry (the thesis' "A1/A2": a tree cannot tell them apart).

Per frame, from the skeleton curves of the matched arcs (:mod:`.curves`) alone:

1. **The subject's up** — along the model's ``[facing] trunk`` (human: crotch → torso,
   :func:`body_up`): a subject lying down, crouching or leaning has its own up; the capture's
   up when the trunk is not placed.
2. **Facing** — the subject's forward direction, perpendicular to its up. For a model with
   ``[facing] feet`` (human): each foot arc ends in the foot, which points forward *across its
   shin* (the curve's last fifth, ankle → toe, without its component along knee → ankle: a
   kneeling subject's foot lies along the shin and points back), and bends forward at its
   middle (the knee: offset of the curve's middle from the hip–ankle chord). The cues are
   summed unnormalized (a foot seen end-on or a straight knee adds little); their
   *agreement* ``|Σ cue| / Σ |cue|`` is 1 when they all point the same way. For ``[facing]
   axis = [a, b]`` (dog): from part a to part b.
3. **Sides** — left = up × forward. Each mirror pair (``[[mirror]]`` in the model) is ordered
   by the lateral coordinate of its arcs' proximal quarter (shoulder, hip: steadier than the
   extremities, which cross the body). When only one part of a pair is found (a hand merged
   with the body), that part alone is named: the lateral offset of its proximal quarter from
   its arc's start on the trunk (the chest or crotch junction), doubled to compare with a
   pair's separation.

The frame's signed score is ``a (1 - e^{-|f|/f0}) (1 - e^{-|s|/s0})`` with the sign of the
lateral difference ``s``, ``a`` the cues' agreement and f0, s0 shares of the subject's height
(:class:`SideOptions`): near 0 when the facing is weak (both feet end-on), its cues disagree
(the feet of a kneeling subject against its knees) or the pair is side by side along the
facing; 0 when the cues' agreement is below ``min_agree``. A pair is named when its confidence
reaches ``margin``; otherwise it keeps the numbered names and
``diagnostics["chirality"][part]["why"]`` says why (facing weak, cues disagreeing,
the pair not apart, a disagreeing tracking segment). The margin is the smallest whose claims
are right in ≥ 98 % of the development generators' frames (``benchmarks/sides.py``, which
reports them per build and pose family against held-out ones and the Pose2Sim recording's
L/R markers).

Over a sequence, a frame whose own score is weak (below ``strong``) takes the sum of the scores
of its tracking segment (:mod:`.track`: the identities are the same), so time only steadies the
per-frame decision. A segment whose frames disagree (coherence ``|Σ score| / Σ |score|`` below
``coherence_weak``) holds no identity to use — the tracker joins unrelated poses of a
random-pose capture — and its weak frames decide alone (on the Pose2Sim balancing trial,
``benchmarks/real_motion.py``, a coherence above 0.7 leaves one long segment unsure: 0.3). A
strong frame is overruled only by at least ``overrule_min`` other frames of a segment of
coherence ``coherent`` whose mean score is strong and opposite (legs crossing on a one-legged
balancing subject turn the hips' order for a frame or two; measured on the Pose2Sim balancing
trial).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from topopose.sequence.track import relabel


@dataclass(frozen=True)
class SideOptions:
    """How sure a frame must be before it names sides (module docstring; the reason of each
    default: ``docs/decisions.md``, measured by ``benchmarks/sides.py``).

    Parameters
    ----------
    margin : a pair is named left / right when its confidence reaches this, else it keeps the
        numbered names (``diagnostics["chirality"][part]["why"]`` says why)
    facing_scale, separation_scale : f0, s0 of the score, as shares of the subject's height
        (the hull's extent; a planted foot gives 0.05–0.1, shoulders and hips are 0.15–0.2 apart)
    body_axis : the subject's own up, along the model's ``[facing] trunk`` (crotch → torso),
        instead of the capture's (a subject lying down, crouching or leaning)
    min_agree : below this agreement of the facing cues (``|Σ cue| / Σ |cue|``, 0.5: the cues
        for the facing outweigh those against it threefold) the frame names no side (a
        crouching subject's thighs on its belly bend its leg arcs every way)
    strong, overrule_min, coherent, coherence_weak : the time rule (module docstring)
    """

    margin: float = 0.3
    facing_scale: float = 0.03
    separation_scale: float = 0.03
    body_axis: bool = True
    min_agree: float = 0.5
    strong: float = 0.5
    overrule_min: int = 5
    coherent: float = 0.8
    coherence_weak: float = 0.3


#: the defaults (``assign_sides(options=...)``)
SIDES = SideOptions()


def _horizontal(v, up):
    v = np.asarray(v, dtype=float)
    return v - np.dot(v, up) * up


def _unit(v):
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else None


def body_up(pose, model, up, options: SideOptions = SIDES):
    """The subject's up: along the model's ``[facing] trunk = [from, to]`` (human: crotch →
    torso) when ``options.body_axis`` and both parts are placed, else the capture's ``up``."""
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    trunk = model.facing.get("trunk")
    if options.body_axis and trunk:
        c, t = (pose.parts.get(x) for x in trunk)
        if t is not None and c is not None:
            u = _unit(np.asarray(t, float) - np.asarray(c, float))
            if u is not None:
                return u
    return up


def subject_height(pose, up) -> float:
    """The subject's extent along ``up``: the frame's hull height when it recorded one, else that
    of its parts and skeleton curves."""
    h = pose.diagnostics.get("height")
    if h:
        return float(h)
    pts = [np.asarray(x, float).reshape(-1, 3) for x in pose.parts.values() if x is not None]
    pts += [np.asarray(c, float).reshape(-1, 3)
            for c in (pose.diagnostics.get("curves") or {}).values() if c is not None]
    if not pts:
        return 1.0
    z = np.concatenate(pts) @ np.asarray(up, float)
    return max(float(z.max() - z.min()), 1e-9)


def facing_cues(pose, model, up) -> list:
    """The facing cues of one frame (vectors perpendicular to ``up``, capture units): per foot
    arc of ``[facing] feet``, the foot's direction across its shin (ankle → toe without its
    component along knee → ankle: a kneeling subject's foot lies along the shin, pointing
    back) and half the knee's bend (the curve's middle off the hip–ankle chord); for
    ``[facing] axis = [a, b]``, a → b."""
    curves = pose.diagnostics.get("curves") or {}
    cues = []
    for part in model.facing.get("feet", ()):
        c = curves.get(part)
        if c is None:
            continue
        c = np.asarray(c, dtype=float)
        n = len(c)
        k = max(1, int(round(0.2 * (n - 1))))
        hip, ankle, knee = c[1], c[-1 - k], c[(n - 1) // 2]
        toe = c[-1] - ankle
        shin = _unit(ankle - knee)
        if shin is not None:
            toe = toe - np.dot(toe, shin) * shin
        cues.append(_horizontal(toe, up))
        ax = _unit(ankle - hip)
        if ax is not None:
            off = (knee - hip) - np.dot(knee - hip, ax) * ax        # the knee's bend
            cues.append(0.5 * _horizontal(off, up))
    axis = model.facing.get("axis")
    if axis:
        a, b = (pose.parts.get(x) for x in axis)
        if a is not None and b is not None:
            cues.append(_horizontal(np.asarray(b, float) - np.asarray(a, float), up))
    return cues


def facing(pose, model, up, options: SideOptions = SIDES):
    """Forward direction (unit, perpendicular to the subject's up, :func:`body_up`), its strength
    (capture units) and the cues' agreement ``|Σ cue| / Σ |cue|`` (1: every cue points the same
    way), or (None, 0, 0)."""
    u = body_up(pose, model, up, options)
    cues = facing_cues(pose, model, u)
    f = np.sum(cues, axis=0) if cues else np.zeros(3)
    s = float(np.linalg.norm(f))
    if s <= 1e-9:
        return None, 0.0, 0.0
    return f / s, s, s / sum(float(np.linalg.norm(c)) for c in cues)


def _proximal(pose, part):
    c = (pose.diagnostics.get("curves") or {}).get(part)
    if c is not None:
        c = np.asarray(c, dtype=float)
        return c[int(round(0.25 * (len(c) - 1)))]
    x = pose.parts.get(part)
    return None if x is None else np.asarray(x, dtype=float)


def frame_evidence(pose, model, up, options: SideOptions = SIDES) -> dict:
    """Per mirror pair (index): (signed score in [-1, 1], why) — > 0: ``parts[0]`` is on the
    subject's left; ``why`` names what weakens the score (None when nothing does)."""
    u = body_up(pose, model, up, options)
    H = subject_height(pose, u)
    f, strength, agree = facing(pose, model, up, options)
    if f is None:
        return {i: (0.0, "facing weak: no foot direction nor knee bend")
                for i in range(len(model.mirrors))}
    if agree < options.min_agree:
        return {i: (0.0, f"facing cues disagree (agreement {agree:.2f}, at least "
                         f"{options.min_agree:g})") for i in range(len(model.mirrors))}
    ff = (1 - np.exp(-strength / (options.facing_scale * H))) * agree
    left = np.cross(u, f)
    out = {}
    for i, (parts, _names) in enumerate(model.mirrors):
        a, b = (_proximal(pose, p) for p in parts)
        if a is None and b is None:
            out[i] = (0.0, "neither part found")
            continue
        if a is None or b is None:                 # one part found: its side of the trunk
            x, sign = (a, 1.0) if b is None else (b, -1.0)
            c = (pose.diagnostics.get("curves") or {}).get(parts[0] if b is None else parts[1])
            if c is None:
                out[i] = (0.0, "one part found, without its arc")
                continue
            s = sign * 2.0 * float(np.dot(x - np.asarray(c[0], dtype=float), left))
        else:
            s = float(np.dot(a - b, left))
        fs = 1 - np.exp(-abs(s) / (options.separation_scale * H))
        why = None
        if min(ff, fs) < 1 - np.exp(-1):
            why = (f"facing weak (strength {strength / H:.3f} of the height, cues agree "
                   f"{agree:.2f})" if ff <= fs else
                   f"the pair is not apart across the facing ({abs(s) / H:.3f} of the height)")
        out[i] = (float(np.sign(s) * ff * fs), why)
    return out


def frame_scores(pose, model, up, options: SideOptions = SIDES) -> dict:
    """Signed per-frame score of each mirror pair (index → score in [-1, 1]; > 0: ``parts[0]``
    is on the subject's left): :func:`frame_evidence` without the reasons."""
    return {i: s for i, (s, _why) in frame_evidence(pose, model, up, options).items()}


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


def assign_sides(poses, model, up, min_confidence=None, use_time=True, strong=None,
                 options: SideOptions = SIDES) -> list:
    """Name the mirror pairs left / right in every matched frame (see the module docstring).

    Parameters
    ----------
    poses : list of Pose (after :func:`.track.track` for the time consistency; curves in their
        diagnostics)
    model : Model with ``mirrors`` and ``facing``
    up : the capture's up vector
    min_confidence : below it a frame keeps the numbered names (default ``options.margin``)
    use_time : sum the scores over each tracking segment
    strong : a frame whose own score reaches this keeps its own decision (a tracking segment
        may join unrelated poses: captures of unrelated frames), unless ``overrule_min`` other
        frames of its segment have a mean score at least this strong of the other sign
        (default ``options.strong``)
    options : :class:`SideOptions`

    Returns
    -------
    list of Pose: parts (and joints) renamed; ``diagnostics["chirality"]`` =
    {numbered part: {"name": output name, "confidence": c, "frame_score": s}, with ``"why"``
    when the numbered name is kept} and ``diagnostics["facing"]``.
    """
    if not model.mirrors:
        return list(poses)
    o = options
    margin = o.margin if min_confidence is None else float(min_confidence)
    strong = o.strong if strong is None else float(strong)
    evidence = [frame_evidence(p, model, up, o) if p.matched else None for p in poses]
    out = list(poses)
    for i_pair, (parts, names) in enumerate(model.mirrors):
        stem = str(parts[0]).rpartition("_")[0]
        seg_sum, seg_n, seg_abs = {}, {}, {}
        keys = []
        for p, ev in zip(poses, evidence):
            seg = (p.diagnostics.get("track") or {}).get(stem) if use_time else None
            key = ("seg", seg) if seg is not None else ("frame", p.frame)
            keys.append(key)
            if ev is None:
                continue
            seg_sum[key] = seg_sum.get(key, 0.0) + ev[i_pair][0]
            seg_n[key] = seg_n.get(key, 0) + 1
            seg_abs[key] = seg_abs.get(key, 0.0) + abs(ev[i_pair][0])
        for i, (p, ev, key) in enumerate(zip(poses, evidence, keys)):
            if ev is None:
                continue
            own, why = ev[i_pair]
            others = seg_n[key] - 1
            mean = (seg_sum[key] - own) / max(others, 1)       # the rest of the segment
            coh = abs(seg_sum[key]) / max(seg_abs[key], 1e-12)
            overruled = (coh >= o.coherent and others >= o.overrule_min and abs(mean) >= strong
                         and mean * own < 0)
            timed = overruled or (abs(own) < strong and coh >= o.coherence_weak)
            z = seg_sum[key] if timed else own
            conf = float(min(1.0, abs(z)))
            if conf >= margin:
                mapping = ({parts[0]: names[0], parts[1]: names[1]} if z > 0
                           else {parts[0]: names[1], parts[1]: names[0]})
            else:
                mapping = {parts[0]: parts[0], parts[1]: parts[1]}
                if timed and others:
                    why = (f"its tracking segment's frames disagree (coherence {coh:.2f})"
                           if abs(own) >= margin else f"{why}; so is its tracking segment's")
                why = f"confidence {conf:.2f} below {margin:g}: {why or 'weak evidence'}"
            q = relabel(out[i], mapping)
            q.joints = {joint_renaming(model, mapping, [j]).get(j, j): v
                        for j, v in q.joints.items()}
            chir = dict(q.diagnostics.get("chirality") or {})
            for a in parts:
                chir[a] = {"name": mapping[a], "confidence": round(conf, 3),
                           "frame_score": round(float(own), 3)}
                if mapping[a] == a:
                    chir[a]["why"] = why
            q.diagnostics = {**q.diagnostics, "chirality": chir}
            out[i] = q
    for i, p in enumerate(out):
        if p.matched:
            f, _s, _agree = facing(poses[i], model, up, o)
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
