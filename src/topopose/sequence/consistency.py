"""Run-relative consistency of a sequence: which frames to trust in a run of one subject
(``matched`` meant to be right in ≥ 95 % of the frames it is given to, on real and synthetic
data alike).

The fitted confidence (:mod:`.confidence`) judges a frame against the calibration captures'
frames in absolute terms; a recording outside them gets low values for its right frames and
its wrong ones alike (the real recording, ``benchmarks/real.py``: every frame 0.01–0.78, the
4-camera minimum 0.91 passes none; it ranks that recording's right frames above its wrong
ones no better than chance: AUC 0.50). A sequence of one subject carries its own reference
(thesis §13.3.1: the per-frame initialization feeds tracking, which relies on the subject
staying the same), so each frame is compared with the run itself and the set-up is
normalized away:

- **time** (:func:`temporal_deviation`): each part against the prediction of its neighbours
  ±d frames (the midpoint of frames i − d and i + d, d = 1…k: exact for a constant
  velocity), numbered parts paired optimally, the smallest over d (a wrong neighbour spoils
  one prediction, not the frame's: with k ≥ 2 the frames next to a wrong one keep their
  agreement), in units of the hull's height; the frame's deviation is its largest part's;
- **rank** (:func:`confidence_rank`): the fitted confidence's rank within the run;
- **support** (:mod:`.support`, ``diagnostics["unexplained"]``, recorded by the estimator
  when the run's consistency is on): the largest share of a camera's silhouette the placed
  model (its matched curves swept by the hull's inscribed balls) leaves unexplained — an arm
  visible in some views whose hand was put elsewhere, which agreement over time cannot see;
- **lengths** (:func:`run_lengths`, :func:`length_ratios`): the subject's own arc lengths, the
  median over the run's frames of each matched model arc's skeleton curve
  (``diagnostics["curves"]``; numbered limbs pooled: both arms, both legs).

:func:`judge_sequence` (applied last by :func:`topopose.sequence.motion.process_sequence`, on
the poses as the run writes them) decides ``matched`` with these in a *coherent* run
(:func:`coherent`: a sequence of one subject; a run of unrelated poses is left as it is). A
frame is *consistent* when its deviation is at most :data:`MAX_DEVIATION`, its rank at least
:data:`MIN_RANK`, its unexplained share at most :data:`MAX_UNEXPLAINED` (and, if given, every
arc within ``max_length_ratio`` of the subject's own) and no part of it was held by the
tracker at its prediction (:func:`held_parts`: placed without the frame's evidence, exactly
where the neighbours predict it, so its agreement proves nothing). Two modes, for the frames
that are matched or that only the confidence gate rejected (:func:`gated`):

- **union** (the run's default, ``topopose run``, :data:`topopose.sequence.motion.CONSISTENCY`):
  a frame the gate matched stays matched (its reasons recorded) unless a part was held; a
  frame the gate alone rejected is matched when consistent;
- **instead of the gate** (``topopose run --consistency``, ``run(consistency=True)``): a
  frame is matched when consistent, else rejected with the reason.

Parts (the best guess) are kept either way, the values in ``diagnostics["consistency"]``. A
frame without a pair of neighbours (the run's first and last) is left as the gate decided
(unless a part was held). ``topopose run --no-consistency``: the gate alone.

**Measured** (``benchmarks/consistency.py``, ``results/consistency.md``; settings chosen on
synthetic walks of the ``body`` subject, development seeds 41–58: the grid's setting with
precision ≥ 0.95 in both 4-camera set-ups and the most right frames passing, the same with
the hands' trim on; never tuned on the real recording). Precision of ``matched`` (frames
passing) as ``run`` writes it (the hands' trim on), the gate alone / ``--consistency`` / the
union (the default): development seeds, 8 cameras 96 % (667) / 98 % (192) / 96 % (668; 95 %
of the right frames), 4 cameras 100 % (12) / 96 % (28) / 97 % (37), phone-like 4 cameras
100 % (1) / 100 % (8) / 100 % (8); held-out seeds 1–4, 8 cameras 97 % (155) / 100 % (56) /
97 % (155), 4 cameras — (0) / 100 % (4) / 100 % (4), phone-like — (0) / 100 % (1) /
100 % (1); the real recording (Pose2Sim's balancing trial, 4 phone cameras,
``benchmarks/real.py``, ``results/real.md``; 75–80 % of the frames right as written), where
the gate passes none and the union is the consistency: ``person`` silhouettes 28 frames at
96 %, ``person+track`` 31 at 94 %, ``person_every = 2`` 19 at 100 %. Parts held at their
prediction, a snapped part, the deviation before the trim: no other frame on the
development seeds (``docs/decisions.md``). The issue's 95 % is reached everywhere but on
``person+track`` (2 wrong of 31: frame 59, a left hand 0.157 m off; frame 80, the right hand
0.20 m). The wrong frames are hands in a phantom volume of the hull in front of the chest,
where Pose2Sim's wrist is right there (``studies/real_hands.py``,
``studies/real_hands.py``: OpenPose sees the hand in 3 views, scores 0.56–0.69, within 4–34
px of Pose2Sim's wrist; the forearm crosses the trunk in cam01 and is hidden behind it in
cam03), inside all 4 silhouettes — no silhouette test can see it. Run-relative arc lengths
(``max_length_ratio`` 1.5) only removed frames on the first development seeds: not used.
The silhouette support costs 2.1 ms a frame (median; of 16 ms) on the synthetic 4-camera
frames, 2.3 ms (of 19) phone-like, 4.0 ms (of 19) with 8 cameras.
"""
from __future__ import annotations

import itertools

import numpy as np

from topopose.frame.curves import model_arcs

#: the largest part deviation from the neighbours' prediction (× hull height) of a consistent
#: frame, with :data:`NEIGHBOURS`; chosen on synthetic 4-camera walks (module docstring)
MAX_DEVIATION = 0.06
#: neighbours on each side of a frame (2: the pairs i ± 1 and i ± 2)
NEIGHBOURS = 2
#: the lowest rank of the fitted confidence within the run of a consistent frame
MIN_RANK = 0.0
#: the largest share of a camera's silhouette the placed model may leave unexplained
#: (``diagnostics["unexplained"]``, :mod:`.support`; frames without it are not judged by it)
MAX_UNEXPLAINED = 0.08


def part_group(part: str, groups=None) -> str:
    """``hand_1`` → ``hand``: the numbered parts of one group share a length (both arms) and
    are paired over time; ``groups`` (name → group) names others (``left_hand`` → ``hand``,
    :func:`mirror_groups`)."""
    if groups and part in groups:
        return groups[part]
    head, _, tail = part.rpartition("_")
    return head if tail.isdigit() and head else part


def mirror_groups(model) -> dict:
    """The side names of the model's mirror pairs → their numbered parts' group
    (``left_hand`` → ``hand``), for poses after :func:`.chirality.assign_sides`."""
    return {n: part_group(p) for parts, names in model.mirrors for p, n in zip(parts, names)}


def curve_length(curve) -> float:
    """Length of a polyline ``(n, 3)``."""
    c = np.asarray(curve, float)
    return float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum()) if len(c) > 1 else 0.0


def arc_lengths(pose, model) -> dict:
    """Child part → length of its arc's skeleton curve (``diagnostics["curves"]``), for the
    arcs whose both ends are placed (the model's numbered part names, also for a pose with
    side names)."""
    side = {p: n for parts, names in model.mirrors for p, n in zip(parts, names)}
    curves = pose.diagnostics.get("curves") or {}
    out = {}
    for u, v in model_arcs(model):
        u, key = (x if x in pose.parts else side.get(x, x) for x in (u, v))
        if key in curves and pose.parts.get(u) is not None and pose.parts.get(key) is not None:
            out[v] = curve_length(curves[key])
    return out


def run_lengths(poses, model) -> dict:
    """Group → the subject's own arc length: the median over the run's processed frames of
    the arc lengths (:func:`arc_lengths`) of that group's parts (numbered parts pooled)."""
    pooled = {}
    for p in poses:
        if p.status == "failed":
            continue
        for part, length in arc_lengths(p, model).items():
            pooled.setdefault(part_group(part), []).append(length)
    return {g: float(np.median(v)) for g, v in pooled.items() if v}


def length_ratios(pose, model, lengths) -> dict:
    """Part → its arc length over the subject's own (:func:`run_lengths`)."""
    return {part: x / lengths[part_group(part)] for part, x in arc_lengths(pose, model).items()
            if lengths.get(part_group(part))}


def _pairing(xa: list, xb: list) -> list:
    """Index pairs (i, j) of ``xa`` and ``xb`` (positions or None) minimizing the summed
    distance over the pairs both placed (every permutation: groups are small)."""
    n = len(xa)
    best, best_cost = [], None
    for perm in itertools.permutations(range(n)):
        pairs = [(i, j) for i, j in zip(range(n), perm)
                 if xa[i] is not None and xb[j] is not None]
        cost = sum(float(np.linalg.norm(np.subtract(xa[i], xb[j]))) for i, j in pairs)
        if best_cost is None or len(pairs) > len(best) or (len(pairs) == len(best)
                                                          and cost < best_cost):
            best, best_cost = pairs, cost
    return best


def _groups(parts, groups=None) -> dict:
    out = {}
    for p in parts:
        out.setdefault(part_group(p, groups), []).append(p)
    return out


def temporal_deviation(poses, k: int = NEIGHBOURS, index=None, groups=None) -> list:
    """Per pose, part → distance to its neighbours' nearest prediction over the hull's height
    (parts no neighbour pair predicts are left out). See the module docstring.

    Parameters
    ----------
    poses : list of Pose, sorted by frame
    k : neighbours on each side
    index : frame numbers of ``poses`` (default: their order)
    groups : see :func:`part_group`
    """
    idx = list(range(len(poses))) if index is None else [int(i) for i in index]
    at = {i: p for i, p in zip(idx, poses) if p.status != "failed"}
    out = []
    for i, p in zip(idx, poses):
        H = p.diagnostics.get("height")
        dev = {}
        if p.status == "failed" or not H:
            out.append(dev)
            continue
        per = {}
        for d in range(1, k + 1):
            a, b = at.get(i - d), at.get(i + d)
            if a is None or b is None:
                continue
            for names in _groups(p.parts, groups).values():
                xa = [a.parts.get(n) for n in names]
                xb = [b.parts.get(n) for n in names]
                pred = [None] * len(names)
                for u, v in _pairing(xa, xb):
                    pred[u] = 0.5 * (np.asarray(xa[u], float) + np.asarray(xb[v], float))
                x = [p.parts.get(n) for n in names]
                for u, v in _pairing(x, pred):
                    per.setdefault(names[u], []).append(
                        float(np.linalg.norm(np.subtract(x[u], pred[v]))) / H)
        out.append({n: float(np.min(v)) for n, v in per.items()})
    return out


def confidence_rank(poses) -> list:
    """Per pose, the share of the run's processed frames whose confidence is below its own
    (None for a frame without one)."""
    c = np.array([p.diagnostics.get("confidence", np.nan) if p.status != "failed" else np.nan
                  for p in poses], float)
    ok = np.isfinite(c)
    out = []
    for x in c:
        out.append(None if not np.isfinite(x) else float(np.mean(c[ok] < x)))
    return out


def coherent(poses, index=None) -> bool:
    """Whether ``poses`` (sorted by frame; ``index``: their frame indices, default 0…n−1) are a
    sequence of one subject (:func:`.confidence.coherent_run`); failed frames are left out."""
    from topopose.frame.confidence import coherent_run

    idx = list(range(len(poses))) if index is None else [int(i) for i in index]
    return coherent_run({i: p for i, p in zip(idx, poses) if p.status != "failed"})


def gated(pose) -> bool:
    """Matched, or rejected by the confidence gate alone (its reason's last clause is the
    confidence's: a frame rejected for its AHA distance that the fitted confidence decides,
    ``confidence.judge_frame``, too) — the frames :func:`judge_sequence` decides."""
    if pose.status == "matched":
        return True
    return pose.status == "rejected" and str(pose.error or "").split("; ")[-1].startswith(
        "confidence ")


def held_parts(pose) -> list:
    """The parts the tracker held at their identity's prediction in this frame
    (``diagnostics["predicted"]``, :func:`.track.track_identities`): placed without the frame's
    evidence, so their agreement with the neighbours' prediction proves nothing."""
    return [q for q in (pose.diagnostics.get("predicted") or []) if q in pose.parts]


def judge_sequence(poses, model, index=None, max_deviation=MAX_DEVIATION,
                   neighbours=NEIGHBOURS, min_rank=MIN_RANK, max_length_ratio=None,
                   groups=None, max_unexplained=MAX_UNEXPLAINED, union=False) -> bool:
    """Decide ``matched`` by the run's own consistency, in place (module docstring).

    Parameters
    ----------
    poses : list of Pose, sorted by frame
    model : Model
    index : frame numbers of ``poses`` (default: their order)
    max_deviation, neighbours, min_rank : see :data:`MAX_DEVIATION`, :data:`NEIGHBOURS`,
        :data:`MIN_RANK`
    max_length_ratio : float, optional
        Also require every matched arc within this factor of the subject's own length
        (numbered part names).
    groups : see :func:`part_group` (poses with side names: :func:`mirror_groups`)
    max_unexplained : float, optional
        Also require ``diagnostics["unexplained"]`` (:mod:`.support`) at most this, in the
        frames that have it.
    union : bool
        False (``run --consistency``): the consistency replaces the confidence gate — a
        matched frame found inconsistent is rejected. True (the run's default): the union of
        the gate and the consistency — a matched frame stays matched (its reasons recorded)
        unless a part of it was held at its prediction (:func:`held_parts`); a frame the gate
        alone rejected is matched when consistent.

    Returns
    -------
    bool
        Whether the run was coherent (False: nothing was changed).
    """
    if not coherent(poses, index):
        return False
    dev = temporal_deviation(poses, neighbours, index, groups)
    rank = confidence_rank(poses)
    lengths = run_lengths(poses, model) if max_length_ratio else None
    for p, d, r in zip(poses, dev, rank):
        if p.status == "failed":
            continue
        worst = max(d, key=d.get) if d else None
        info = {"deviation": None if worst is None else round(d[worst], 4), "part": worst,
                "rank": None if r is None else round(r, 3)}
        reasons = []
        held = held_parts(p)
        if held:                           # no evidence: not matched, whatever else says
            reasons.append(f"{', '.join(held)} held at the tracked prediction (no evidence "
                           f"in this frame)")
        ends = worst is None               # no neighbours (the run's ends): only a held part
        if not ends:                       # counts, else the gate decides
            if d[worst] > max_deviation:
                reasons.append(f"{worst} {d[worst]:.2f} × height from its neighbours' "
                               f"prediction (above {max_deviation:g})")
            if r is not None and r < min_rank:
                reasons.append(f"confidence ranks {r:.2f} in the run (below {min_rank:g})")
            u = p.diagnostics.get("unexplained")
            if u is not None:
                info["unexplained"] = u
            if max_unexplained is not None and u is not None and u > max_unexplained:
                reasons.append(f"{u:.2f} of a silhouette unexplained by the placed model "
                               f"(above {max_unexplained:g})")
            if lengths is not None:
                ratios = length_ratios(p, model, lengths)
                info["length_ratios"] = {k: round(v, 3) for k, v in ratios.items()}
                off = [k for k, v in ratios.items()
                       if not 1 / max_length_ratio <= v <= max_length_ratio]
                if off:
                    reasons.append(f"arc length of {', '.join(off)} off the subject's own")
        if reasons:
            info["reasons"] = reasons
        p.diagnostics["consistency"] = info
        if not gated(p):
            continue
        if reasons:
            if p.status == "matched" and (not union or held):
                p.status = "rejected"
                p.error = "inconsistent with the run: " + "; ".join(reasons)
        elif p.status == "rejected" and not ends:
            info["gate"] = p.error        # what the absolute gate said
            p.status, p.error = "matched", None
    return True


def judge_support(poses, max_unexplained=MAX_UNEXPLAINED, gate=True) -> int:
    """Per-frame silhouette support test, in place (``topopose run --support``,
    :func:`topopose.batch.run.run` ``support_test=True``): for runs of unrelated poses too,
    where the temporal part of :func:`judge_sequence` does not apply.

    A matched frame whose ``diagnostics["unexplained"]`` (:mod:`.support`) is above
    ``max_unexplained`` (default :data:`MAX_UNEXPLAINED`, chosen on the synthetic development
    seeds, module docstring) is rejected with the reason; its parts are kept. A frame without
    the value (no matched curve) is left as it is.

    Parameters
    ----------
    poses : iterable of Pose
    max_unexplained : float
    gate : bool
        True: the test comes on top of the confidence gate (only matched frames are judged).
        False: it replaces the gate — a frame the confidence gate alone rejected
        (:func:`gated`) is matched when its unexplained share is within the limit.

    Returns
    -------
    int
        The number of frames whose status changed.
    """
    changed = 0
    for p in poses:
        u = p.diagnostics.get("unexplained")
        if u is None or not gated(p):
            continue
        if u > max_unexplained:
            if p.status == "matched":
                p.status = "rejected"
                p.error = (f"silhouette support: {u:.2f} of a silhouette unexplained by the "
                           f"placed model (above {max_unexplained:g})")
                changed += 1
        elif not gate and p.status == "rejected":
            p.diagnostics["support_gate"] = p.error      # what the absolute gate said
            p.status, p.error = "matched", None
            changed += 1
    return changed
