"""Identities over time: numbered parts keep their identity across the frames of a sequence.

Pose initialization solves each frame alone (thesis §12.1), so the tree cannot tell ``hand_1``
from ``hand_2`` (the model's interchangeable groups, :meth:`Model.interchangeable`) and their
numbers may swap from one frame to the next. Thesis §13.3.1: the per-frame result initializes
tracking. Here each group is tracked on its own: every identity predicts its position by a
damped constant velocity from its last two observations, and the matched frame's parts are
assigned to the identities by the Hungarian method (:func:`scipy.optimize.linear_sum_assignment`)
on the distances between predictions and observations.

An assigned observation farther than ``gate`` from its prediction is an outlier; it moves no
track (a wrong velocity from one misplaced part would steer the next assignments). When it is
also inconsistent with the other parts — out of its limb's reach from the part the limb hangs
from (:func:`implausible_reach`: a hand put on a foot), or where a part of another group was
a frame before (:func:`on_other_parts`) — and its track is established, the
per-frame result misplaced it: the part is *held* at its identity's prediction, flagged
(``diagnostics["predicted"]``, its per-frame position in ``diagnostics["misplaced"]``), never
silently. An outlier of an established identity whose frame has a free skeleton leaf (one no
part was matched to, ``diagnostics["free_leaves"]``) within half the gate of its prediction is
*snapped* to the nearest such leaf instead (``diagnostics["snapped"]``): with few cameras the
per-frame result puts a hand on a phantom branch of the hull while the real hand's branch is
left unmatched (the real recording, ``benchmarks/real.py``: hands 0.64 m off in 3 frames;
synthetic 8-camera walks, ``benchmarks/tracking.py``: nothing snapped). A snap corrects a glitch: when the per-frame positions
behind ``max_gap`` + 1 snaps in a row follow a trajectory of their own, the identity is
re-initialized there (the real recording: a raised foot was otherwise kept on a phantom leaf
for 23 frames while the per-frame result had it right). Other outliers re-initialize their
identity only when they are consistently different for ``reinit`` frames (a trajectory of their
own). Tracking is *lost* when no
identity was updated for ``max_gap`` frames; the new segment takes the per-frame numbering, or,
after a gap of at most ``relink`` frames, the numbering that keeps each part on its side of
the part its limb hangs from (positions relative to the torso for the hands; only their
lateral components when the subject travelled across the gap). Frames rejected
only by the confidence gate are observations too (gated the same way); other rejected
frames too when the usable ones are few (:data:`FEW_USABLE`); failed frames are left as they
are.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from topopose.frame.curves import model_arcs
from topopose.frames import sort_poses

PER_PART_DIAGNOSTICS = ("curves", "misplaced", "hand_hints", "detect_parts", "trim", "centred",
                        "centred_trim")
# When fewer than this share of a sequence's frames are usable (matched, or rejected by the
# confidence gate only), the frames the alignment rejected are observations too: a recording whose
# every frame misses T_d (4 cameras) would otherwise never be tracked. Its figures:
# docs/decisions.md.
FEW_USABLE = 0.25


def frame_index(poses) -> np.ndarray:
    """Frame numbers of sorted poses (their position in the list when names are not numbers)."""
    try:
        return np.array([int(p.frame) for p in poses], dtype=float)
    except ValueError:
        return np.arange(len(poses), dtype=float)


def relabel(pose, mapping: dict):
    """A copy of ``pose`` with part names renamed by ``mapping`` (old → new; a permutation or a
    renaming), in ``parts`` and in the per-part diagnostics (e.g. the arc curves)."""
    if not mapping or all(k == v for k, v in mapping.items()):
        return pose
    parts = {mapping.get(k, k): v for k, v in pose.parts.items()}
    diag = dict(pose.diagnostics)
    for key in PER_PART_DIAGNOSTICS:
        d = diag.get(key)
        if isinstance(d, dict):
            diag[key] = {mapping.get(k, k): v for k, v in d.items()}
    for key in ("missing", "predicted", "snapped", "trimmed"):
        if isinstance(diag.get(key), list):
            diag[key] = [mapping.get(k, k) for k in diag[key]]
    return replace(pose, parts=parts, diagnostics=diag)


def gated_only(pose) -> bool:
    """A frame the alignment accepted but the confidence gate rejected
    (:mod:`topopose.frame.confidence`): every clause of its reason is the gate's (none for the
    AHA distance before it, none for the anatomy after it, which the gate's features do not
    decide: :class:`~topopose.frame.confidence.GateOptions` ``max_foot_rise``)."""
    return pose.status == "rejected" and all(
        c.startswith("confidence ") for c in str(pose.error or "").split("; "))


def ungated(poses, threshold=False) -> list:
    """Copies of the poses as with the confidence gate off: the frames only the gate rejected
    (:func:`gated_only`) are ``matched``; the gate judges a frame after its alignment and
    changes nothing else. With ``threshold``, every ``rejected`` frame is (its alignment's
    best guess, kept in ``parts``)."""
    def lifted(p):
        return gated_only(p) or (threshold and p.status == "rejected")

    return [replace(p, status="matched", error=None, diagnostics=dict(p.diagnostics))
            if lifted(p) else replace(p, diagnostics=dict(p.diagnostics)) for p in poses]


def body_scale(poses) -> float:
    """Median extent (bounding-box diagonal of the parts) of the matched frames."""
    ext = []
    for p in poses:
        if p.matched:
            pts = np.array([v for v in p.parts.values() if v is not None], dtype=float)
            if len(pts) > 1:
                ext.append(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))))
    return float(np.median(ext)) if ext else 1.0


def _prediction(last, prev, last_t, prev_t, t, velocity, max_gap):
    """Each identity's constant-velocity prediction at frame number ``t`` (NaN: stale)."""
    pred = last.copy()                        # constant-velocity prediction
    moving = ~np.isnan(prev).any(axis=1) & (last_t > prev_t)
    for a in np.flatnonzero(moving):
        vel = (last[a] - prev[a]) / (last_t[a] - prev_t[a])
        pred[a] = last[a] + velocity * vel * (t - last_t[a])
    pred[t - last_t > max_gap] = np.nan    # stale identity: neutral
    return pred


def _costs(pred, obs, seen, gate):
    """(k, k) distances of the predictions (rows) to the seen observations (columns); an
    identity never seen costs ``gate``."""
    k = len(obs)
    cost = np.zeros((k, k))
    for a in range(k):
        for j in range(k):
            if seen[j]:
                cost[a, j] = (gate if np.isnan(pred[a]).any()     # never seen: neutral
                              else np.linalg.norm(pred[a] - obs[j]))
    return cost


def _snap_outliers(candidates, obs, outlier, moved, p, pred, cost, streak, reinit, snap, snapped):
    """Each outlier of an established identity moved to the free candidate nearest its
    prediction, within ``snap`` and nearer than the observation (``obs``, ``outlier``,
    ``moved`` and ``snapped`` updated in place)."""
    free = np.asarray(candidates, dtype=float).reshape(-1, 3)
    for j in np.flatnonzero(outlier):
        a = p[j]
        if streak[a] < reinit or np.isnan(pred[a]).any() or not len(free):
            continue
        d = np.linalg.norm(free - pred[a], axis=1)
        m = int(np.argmin(d))
        if d[m] <= snap and d[m] < cost[a, j]:
            obs[j] = snapped[j] = free[m]
            outlier[j], moved[j] = False, True
            free = np.delete(free, m, axis=0)


def _relink(p, rel, rel_anchor, anchor, obs, up, gate):
    """The numbering ``p`` (in place) of a segment after a short gap: the positions relative
    to the anchor assigned to the identities' last ones (only across the anchor's travel and
    the up axis when the anchor travelled)."""
    diff = rel[:, None, :] - (obs - anchor)[None]
    travel = anchor - rel_anchor
    if (up is not None and not np.isnan(up).any() and not np.isnan(travel).any()
            and np.linalg.norm(travel) > 0.25 * gate):
        lat = np.cross(up, travel)
        if np.linalg.norm(lat) > 0:
            diff = diff @ (lat / np.linalg.norm(lat))[:, None]
    cost = np.linalg.norm(diff, axis=2)
    rows, cols = linear_sum_assignment(cost)
    p[cols] = rows


def _fresh_state(k):
    """The state of ``k`` new identities: last and previous positions and frame numbers, the
    outlier runs and the inlier streaks."""
    last, prev = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
    last_t, prev_t = np.full(k, -np.inf), np.full(k, -np.inf)
    return last, prev, last_t, prev_t, [[] for _ in range(k)], np.zeros(k, dtype=int)


def _reinit(fresh, p, cand, obs, t, last, last_t, prev, prev_t, streak):
    """The identities of the observations ``fresh`` re-initialized at their consistent run of
    outliers (in place)."""
    for j in fresh:
        a = p[j]
        (t0, x0) = cand[a][-2]
        prev[a], prev_t[a] = x0, t0
        last[a], last_t[a] = obs[j], t
        cand[a].clear()
        streak[a] = 1


def _update(seen, p, obs, t, last, last_t, prev, prev_t, streak, anchor, rel, rel_anchor):
    """Each identity seen at frame number ``t`` moved to its observation (in place); returns
    the positions relative to the anchor ``(rel, rel_anchor)``."""
    k = len(obs)
    for j in np.flatnonzero(seen):
        a = p[j]
        streak[a] = streak[a] + 1 if t - last_t[a] <= 1 else 1
        prev[a], prev_t[a] = last[a], last_t[a]
        last[a], last_t[a] = obs[j], t
        if anchor is not None and not np.isnan(anchor).any():
            if rel is None or len(rel) != k:
                rel = np.full((k, 3), np.nan)
            rel[a] = obs[j] - anchor
            rel_anchor = anchor
    return rel, rel_anchor


def assign_identities(times, observations, gate, max_gap=5, velocity=0.5, misplaced=None,
                      reinit=3, anchors=None, relink=None, up=None, detail=False,
                      candidates=None, snap=None, snap_run=None):
    """Track one interchangeable group.

    Parameters
    ----------
    times : (n,) frame numbers (increasing)
    observations : list of n entries, each None (frame not usable) or an (k, 3) array of the
        group's k positions in the per-frame numbering (NaN rows: part not placed)
    gate : largest distance between a prediction and an observation that updates it (× 1 +
        (dt − 1)/2 after dt frames without update)
    max_gap : an identity without update for more than this many frames is stale (its
        prediction is no longer used); when every identity is stale, tracking is lost
    velocity : weight of the constant-velocity term of the prediction (1: constant velocity,
        0: constant position). The velocity of two noisy per-frame positions is noisy;
        ``benchmarks/tracking.py`` measures the identity switches; crossing hands need some
        velocity.
    misplaced : None or a list of n (k,) bool arrays (or None): observations inconsistent with
        the other parts of their frame (:func:`implausible_reach`, :func:`on_other_parts`).
        An observation beyond the
        gate of its identity's prediction *and* misplaced is *held*: the identity keeps its
        prediction, the observation moves no track and counts for no re-initialization.
    reinit : an identity whose observations lie beyond the gate (not misplaced) for this many
        consecutive observed frames, consistent among themselves (each within the gate of the
        one before), is re-initialized at them; when every identity of the group is
        re-initialized in the same frame, by the per-frame numbering
    anchors : None or (n, 3) positions of the part the group hangs from (NaN: not placed).
        When tracking is lost after a gap of at most ``relink`` frames (default 3 ×
        ``max_gap``), the new segment's numbering is the assignment of the positions relative
        to the anchor against the last ones of the identities (a hand stays on its side of the
        torso across a short gap) instead of the per-frame numbering
    up : None or (n, 3) the subject's up axis per frame (the trunk); with it, when the anchor
        travelled across the gap, only the lateral components (across the travel and the up
        axis) are compared: a foot swings forward and back, it stays on its side
    detail : also return ``held`` and ``predicted`` (and ``snapped`` with ``candidates``)
    candidates : None or a list of n entries, None or (m, 3) positions where a part of the
        group may be instead of where the frame put it (the skeleton's unmatched leaves,
        :func:`topopose.frame.tips.free_leaves`). An outlier of an established identity (beyond the gate, ``reinit``
        inlier updates in a row) moves to the candidate nearest the identity's prediction when
        that one lies within ``snap`` of it and nearer than the observation: the observation
        then counts as an inlier at the candidate (*snapped*), each candidate used once; the
        per-frame observations behind max(``reinit``, ``snap_run`` + 1) snaps in a row that
        are consistent among themselves re-initialize the identity as outliers do
    snap : largest distance between a prediction and a candidate; default ``gate`` / 2
    snap_run : see ``candidates``; default ``max_gap`` (a large number: snaps never give way)

    Returns
    -------
    perm : list of n entries: None, or an int array ``perm[j]`` = identity of observation j
    segment : (n,) int, the tracking segment of each frame (-1 for unusable frames); a new
        segment starts each time tracking is (re-)initialized.
    held : (n, k) bool, observation j of frame i held (only with ``detail``)
    predicted : (n, k, 3) the prediction of identity a in frame i, NaN when none (only with
        ``detail``)
    snapped : (n, k, 3) the candidate observation j of frame i moved to, NaN when none (only
        with ``detail`` and ``candidates``)
    """
    n = len(times)
    perm = [None] * n
    segment = np.full(n, -1, dtype=int)
    kmax = max((len(o) for o in observations if o is not None), default=0)
    held = np.zeros((n, kmax), dtype=bool)
    predicted, snapped = np.full((n, kmax, 3), np.nan), np.full((n, kmax, 3), np.nan)
    snap = 0.5 * gate if snap is None else float(snap)
    snap_run = max_gap if snap_run is None else snap_run
    last = prev = last_t = prev_t = None
    seg = -1
    relink = 3 * max_gap if relink is None else relink
    anchors = None if anchors is None else np.asarray(anchors, dtype=float)
    up = None if up is None else np.asarray(up, dtype=float)
    rel = None                                        # last position of each identity − anchor
    rel_anchor = None                                 # the anchor it was measured from
    for i in range(n):
        obs = observations[i]
        if obs is None:
            continue
        obs = np.array(obs, dtype=float)           # a copy: a snapped observation moves
        k = len(obs)
        seen = ~np.isnan(obs).any(axis=1)
        bad = (np.zeros(k, dtype=bool) if misplaced is None or misplaced[i] is None
               else np.asarray(misplaced[i], dtype=bool))
        lost = last is None or len(last) != k or times[i] - np.max(last_t) > max_gap
        fresh = None
        if not lost:
            pred = _prediction(last, prev, last_t, prev_t, times[i], velocity, max_gap)
            predicted[i, :k] = pred
            cost = _costs(pred, obs, seen, gate)
            rows, cols = linear_sum_assignment(cost)
            p = np.empty(k, dtype=int)
            p[cols] = rows
            # an observation far from its identity's prediction is an outlier: held when it
            # is also inconsistent with the other parts (a misplaced part of the per-frame
            # result), else a candidate for re-initializing its identity
            dt = np.maximum(times[i] - last_t, 1.0)       # the gate widens over gaps
            outlier = np.array([seen[j] and cost[p[j], j] > gate * (1 + 0.5 * (dt[p[j]] - 1))
                                for j in range(k)])
            orig, moved = obs.copy(), np.zeros(k, dtype=bool)
            if candidates is not None and candidates[i] is not None and len(candidates[i]):
                # an outlier of an established track moves to the free skeleton leaf nearest
                # its prediction (the frame put the part on another branch: a phantom one)
                _snap_outliers(candidates[i], obs, outlier, moved, p, pred, cost, streak, reinit,
                               snap, snapped[i])
            # only an established track (``reinit`` inlier updates in a row) holds a part: the
            # prediction of a track that follows unrelated poses means nothing
            held[i, :k] = outlier & bad & (streak[p] >= reinit)
            moved &= ~bad                             # a misplaced observation counts for nothing
            bad = held[i, :k]
            fresh = []
            for j in np.flatnonzero((outlier & ~bad) | moved):
                a = p[j]
                c = cand[a]
                if c and (times[i] - c[-1][0] > max_gap or
                          np.linalg.norm(orig[j] - c[-1][1]) > gate * (times[i] - c[-1][0])):
                    c.clear()                         # not consistent with the previous ones
                c.append((times[i], orig[j]))
                # snapped: the per-frame result's own trajectory wins after snap_run frames (a
                # snap corrects a glitch, it must not keep a track on a phantom leaf)
                if len(c) >= (max(reinit, snap_run + 1) if moved[j] else reinit):
                    fresh.append(j)
                    if moved[j]:
                        obs[j], snapped[i, j] = orig[j], np.nan
                        outlier[j], moved[j] = True, False
            for j in np.flatnonzero(seen & ~outlier & ~moved):
                cand[p[j]].clear()
            streak[p[outlier & ~bad]] = 0
            if len(fresh) == k:                       # the whole group: per-frame numbering
                lost = True
            seen = seen & ~outlier
        if lost:                                      # (re-)initialize: per-frame numbering
            p = np.arange(k)
            if (anchors is not None and rel is not None and len(rel) == k and fresh is None
                    and not np.isnan(anchors[i]).any() and seen.all()
                    and not np.isnan(rel).any() and times[i] - np.max(last_t) <= relink):
                _relink(p, rel, rel_anchor, anchors[i], obs, None if up is None else up[i], gate)
            seg += 1
            last, prev, last_t, prev_t, cand, streak = _fresh_state(k)
            held[i] = False
            fresh = None
        elif fresh:                                   # some identities re-initialized
            seg += 1
            _reinit(fresh, p, cand, obs, times[i], last, last_t, prev, prev_t, streak)
        perm[i] = p
        segment[i] = seg
        rel, rel_anchor = _update(seen, p, obs, times[i], last, last_t, prev, prev_t, streak,
                                  None if anchors is None else anchors[i], rel, rel_anchor)
    if detail:
        return ((perm, segment, held, predicted) if candidates is None
                else (perm, segment, held, predicted, snapped))
    return perm, segment


def implausible_reach(poses, model, group, low=0.6, high=1.25, q=5.0):
    """Which of a group's parts lie where their limb cannot reach, per pose.

    The *reach* of a part is its distance to the part its model arc hangs from
    (:func:`~topopose.frame.curves.model_arcs`: the torso for a hand, the crotch for a foot). Over
    the usable poses of the sequence the reach of the group's parts spans [P_q, P_100−q]
    (percentiles); a reach below ``low`` × P_q or above ``high`` × P_100−q is implausible: a
    hand put on a foot (reach of a leg from the torso), a foot put on a hand. Parts whose
    parent is not placed are not judged.

    Returns a list (one per pose) of (k,) bool arrays, None for poses without usable parts.
    """
    parent = {v: u for u, v in model_arcs(model)}
    reach = np.full((len(poses), len(group)), np.nan)
    for i, p in enumerate(poses):
        for j, g in enumerate(group):
            x, r = p.parts.get(g), p.parts.get(parent.get(g))
            if x is not None and r is not None:
                reach[i, j] = np.linalg.norm(np.asarray(x, float) - np.asarray(r, float))
    ok = reach[~np.isnan(reach)]
    if len(ok) < 5:
        return [None] * len(poses)
    lo, hi = low * np.percentile(ok, q), high * np.percentile(ok, 100 - q)
    with np.errstate(invalid="ignore"):
        bad = (reach < lo) | (reach > hi)
    return list(bad)


def on_other_parts(poses, usable, group, others, radius):
    """Which of a group's parts lie within ``radius`` of one of the parts ``others`` as the
    previous usable pose placed it (a hand put where a foot was a frame before), per pose;
    None for poses that are not usable or have no usable predecessor."""
    out, before = [], None
    for p, u in zip(poses, usable):
        if not u:
            out.append(None)
            continue
        if before is None:
            out.append(None)
        else:
            there = np.array([np.asarray(before.parts[k], float) for k in others
                              if before.parts.get(k) is not None]).reshape(-1, 3)
            out.append(np.array([p.parts.get(g) is not None and len(there) > 0 and
                                 bool(np.min(np.linalg.norm(there - np.asarray(p.parts[g], float),
                                                            axis=1)) < radius)
                                 for g in group]))
        before = p
    return out


def track(poses, model, max_gap=5, gate=None, velocity=0.5, use_rejected=True, reinit=3,
          few=FEW_USABLE, snap=True, snap_run=None) -> list:
    """Give the numbered parts of a sequence stable identities (see the module docstring).

    Parameters
    ----------
    poses : list of Pose
    model : Model (its :meth:`~Model.interchangeable` groups are tracked)
    max_gap : frames without a matched observation after which tracking is lost
    gate : distance above which an assigned observation is an outlier (× 1 + (dt − 1)/2 after
        dt frames without update); default 0.25 × the median extent of the subject
        (:func:`body_scale`), 45 cm for a standing adult
    velocity, reinit : see :func:`assign_identities`
    snap : move outliers to the frame's free skeleton leaves (``diagnostics["free_leaves"]``,
        :func:`topopose.frame.tips.free_leaves`) as :func:`assign_identities` does with ``candidates``
    snap_run : see :func:`assign_identities`
    use_rejected : frames only the confidence gate rejected (:func:`gated_only`) are
        observations too: the gate rejects many right frames, whose gaps would otherwise lose
        the tracks (``benchmarks/tracking.py``, identity switches); frames the alignment itself
        rejected are not (with them: worse),
        unless fewer than ``few`` of the frames are usable (:data:`FEW_USABLE`; 0: never)

    Returns
    -------
    list of Pose, sorted by frame: parts renamed to their track identity;
    ``diagnostics["track"]`` = {group stem: segment number} on the tracked frames. A *held*
    part (beyond the gate of its prediction and inconsistent with the other parts: the
    per-frame result misplaced it) is never followed: it is
    placed at its identity's prediction (None when there is none), listed in
    ``diagnostics["predicted"]``, its per-frame position kept in ``diagnostics["misplaced"]``
    and its skeleton curve dropped (the kinematic fit then bridges the frame, flagged
    ``interpolated``). A *snapped* part is placed at its free leaf, listed in
    ``diagnostics["snapped"]``, its per-frame position in ``diagnostics["misplaced"]``, its
    curve dropped.
    """
    poses = sort_poses(poses)
    if gate is None:
        gate = 0.25 * body_scale(poses)
    times = frame_index(poses)
    out = list(poses)
    usable = [p.matched or (use_rejected and gated_only(p)) for p in poses]
    if use_rejected and sum(usable) < few * len(poses):     # nearly every frame misses T_d
        usable = [u or p.status == "rejected" for u, p in zip(usable, poses)]
    parent = {v: u for u, v in model_arcs(model)}
    groups = model.interchangeable()
    up = None
    trunk = tuple(model.facing.get("trunk", ()))
    if len(trunk) == 2:                               # the subject's up axis per frame
        up = np.array([np.asarray(p.parts[trunk[1]], float) - np.asarray(p.parts[trunk[0]], float)
                       if p.parts.get(trunk[0]) is not None and p.parts.get(trunk[1]) is not None
                       else np.full(3, np.nan) for p in poses])
    for group in groups:
        obs = []
        for p, u in zip(poses, usable):
            obs.append(None if not u else
                       np.array([np.full(3, np.nan) if p.parts.get(g) is None
                                 else np.asarray(p.parts[g], float) for g in group]))
        bad = implausible_reach([p if u else replace(p, parts={}) for p, u in zip(poses, usable)],
                                model, group)
        near = on_other_parts(poses, usable, group,
                              [g for other in groups if other != group for g in other], 0.5 * gate)
        bad = [n if b is None else (b if n is None else b | n) for b, n in zip(bad, near)]
        hang = parent.get(group[0])
        anchors = np.array([np.asarray(p.parts[hang], float) if u and p.parts.get(hang) is not None
                            else np.full(3, np.nan) for p, u in zip(poses, usable)])
        cands = ([None if not u else p.diagnostics.get("free_leaves")
                  for p, u in zip(poses, usable)] if snap else None)
        perm, seg, held, pred, *moved = assign_identities(
            times, obs, gate, max_gap, velocity, misplaced=bad, reinit=reinit, anchors=anchors,
            up=up, detail=True, candidates=cands, snap_run=snap_run)
        stem = str(group[0]).rpartition("_")[0]
        for i, p in enumerate(perm):
            if p is None:
                continue
            q = relabel(out[i], {group[j]: group[p[j]] for j in range(len(group))})
            diag = {**q.diagnostics, "track": {**q.diagnostics.get("track", {}), stem: int(seg[i])}}
            moved_i = (np.zeros(len(group), bool) if not moved
                       else ~np.isnan(moved[0][i, :len(group)]).any(axis=1))
            if held[i].any() or moved_i.any():
                parts = dict(q.parts)
                curves = dict(diag.get("curves") or {})
                mis = dict(diag.get("misplaced") or {})
                prd = list(diag.get("predicted") or [])
                for j in np.flatnonzero(held[i, :len(group)]):
                    name = group[p[j]]
                    x = pred[i, p[j]]
                    mis[name] = [round(float(c), 5) for c in parts[name]]
                    parts[name] = None if np.isnan(x).any() else x.copy()
                    curves.pop(name, None)
                    prd.append(name)
                snp = list(diag.get("snapped") or [])
                for j in np.flatnonzero(moved_i):
                    name = group[p[j]]
                    mis[name] = [round(float(c), 5) for c in parts[name]]
                    parts[name] = moved[0][i, j].copy()
                    curves.pop(name, None)
                    snp.append(name)
                diag.update(misplaced=mis)
                if prd:
                    diag["predicted"] = sorted(prd)
                if snp:
                    diag["snapped"] = sorted(snp)
                if "curves" in diag:
                    diag["curves"] = curves
                q = replace(q, parts=parts)
            q.diagnostics = diag
            out[i] = q
    return out
