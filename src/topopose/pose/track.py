"""Identities over time: numbered parts keep their identity across the frames of a sequence.

Pose initialization solves each frame alone (thesis §12.1), so the tree cannot tell ``hand_1``
from ``hand_2`` (the model's interchangeable groups, :meth:`Model.interchangeable`) and their
numbers may swap from one frame to the next. Thesis §13.3.1: the per-frame result initializes
tracking. Here each group is tracked on its own: every identity predicts its position by a
damped constant velocity from its last two observations, and the matched frame's parts are assigned to
the identities by the Hungarian method (:func:`scipy.optimize.linear_sum_assignment`) on the
distances between predictions and observations. Tracking is *lost* — and re-initialized by the
per-frame numbering, starting a new segment — when the gap since the last matched frame exceeds
``max_gap`` frames. An assigned observation farther than ``gate`` from its prediction is an
outlier (a part the per-frame result misplaced): it is named by the assignment but does not
move its track, which coasts on its prediction (a wrong velocity from one misplaced part would
otherwise steer the next assignments). Frames rejected only by the confidence gate are
observations too (gated the same way); other rejected and failed frames are left as they are.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment

PER_PART_DIAGNOSTICS = ("curves",)


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
    miss = diag.get("missing")
    if isinstance(miss, list):
        diag["missing"] = [mapping.get(k, k) for k in miss]
    return replace(pose, parts=parts, diagnostics=diag)


def gated_only(pose) -> bool:
    """A frame the alignment accepted but the confidence gate rejected
    (:mod:`topopose.pose.confidence`)."""
    return pose.status == "rejected" and str(pose.error or "").startswith("confidence ")


def body_scale(poses) -> float:
    """Median extent (bounding-box diagonal of the parts) of the matched frames."""
    ext = []
    for p in poses:
        if p.matched:
            pts = np.array([v for v in p.parts.values() if v is not None], dtype=float)
            if len(pts) > 1:
                ext.append(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))))
    return float(np.median(ext)) if ext else 1.0


def assign_identities(times, observations, gate, max_gap=5, velocity=0.5):
    """Track one interchangeable group.

    Parameters
    ----------
    times : (n,) frame numbers (increasing)
    observations : list of n entries, each None (frame not usable) or an (k, 3) array of the
        group's k positions in the per-frame numbering (NaN rows: part not placed)
    gate : largest distance between a prediction and an observation that updates it
    max_gap : tracking is lost after more than this many frames without observation
    velocity : weight of the constant-velocity term of the prediction (1: constant velocity,
        0: constant position). The velocity of two noisy per-frame positions is noisy;
        ``benchmarks/tracking.py`` walks (400 frames, identity switches on frames with both
        parts right, gate 0.25): 1.0 → 5, 0.5 → 0, 0.0 → 0; crossing hands need some velocity.

    Returns
    -------
    perm : list of n entries: None, or an int array ``perm[j]`` = identity of observation j
    segment : (n,) int, the tracking segment of each frame (-1 for unusable frames); a new
        segment starts each time tracking is (re-)initialized.
    """
    n = len(times)
    perm = [None] * n
    segment = np.full(n, -1, dtype=int)
    last = prev = last_t = prev_t = None
    seg = -1
    for i in range(n):
        obs = observations[i]
        if obs is None:
            continue
        obs = np.asarray(obs, dtype=float)
        k = len(obs)
        seen = ~np.isnan(obs).any(axis=1)
        lost = last is None or len(last) != k or times[i] - np.max(last_t) > max_gap
        if not lost:
            pred = last.copy()                        # constant-velocity prediction
            pred[times[i] - last_t > max_gap] = np.nan    # stale identity: neutral
            moving = ~np.isnan(prev).any(axis=1) & (last_t > prev_t)
            for a in np.flatnonzero(moving):
                vel = (last[a] - prev[a]) / (last_t[a] - prev_t[a])
                pred[a] = last[a] + velocity * vel * (times[i] - last_t[a])
            cost = np.zeros((k, k))
            for a in range(k):
                for j in range(k):
                    if seen[j]:
                        cost[a, j] = (gate if np.isnan(pred[a]).any()     # never seen: neutral
                                      else np.linalg.norm(pred[a] - obs[j]))
            rows, cols = linear_sum_assignment(cost)
            p = np.empty(k, dtype=int)
            p[cols] = rows
            # an observation far from its identity's prediction is an outlier (a misplaced part
            # of the per-frame result): it keeps the name the assignment gives, but does not
            # move the track; the track coasts until max_gap, then tracking is lost
            dt = np.maximum(times[i] - last_t, 1.0)       # the gate widens over gaps
            outlier = np.array([seen[j] and cost[p[j], j] > gate * (1 + 0.5 * (dt[p[j]] - 1))
                                for j in range(k)])
            seen = seen & ~outlier
        if lost:                                      # (re-)initialize: per-frame numbering
            p = np.arange(k)
            seg += 1
            last, prev = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
            last_t, prev_t = np.full(k, -np.inf), np.full(k, -np.inf)
        perm[i] = p
        segment[i] = seg
        for j in np.flatnonzero(seen):
            a = p[j]
            prev[a], prev_t[a] = last[a], last_t[a]
            last[a], last_t[a] = obs[j], times[i]
    return perm, segment


def track(poses, model, max_gap=5, gate=None, velocity=0.5, use_rejected=True) -> list:
    """Give the numbered parts of a sequence stable identities (see the module docstring).

    Parameters
    ----------
    poses : list of Pose
    model : Model (its :meth:`~Model.interchangeable` groups are tracked)
    max_gap : frames without a matched observation after which tracking is lost
    gate : distance above which an assigned observation is an outlier (× 1 + (dt − 1)/2 after
        dt frames without update); default 0.25 × the median extent of the subject
        (:func:`body_scale`), 45 cm for a standing adult
    velocity : see :func:`assign_identities`
    use_rejected : frames only the confidence gate rejected (:func:`gated_only`) are
        observations too: the gate rejects many right frames, whose gaps would otherwise lose
        the tracks (``benchmarks/tracking.py``, walks: identity switches on matched frames per
        500 frames 13.8 → 2.5); frames the alignment itself rejected are not (with them: worse)

    Returns
    -------
    list of Pose, sorted by frame: parts renamed to their track identity;
    ``diagnostics["track"]`` = {group stem: segment number} on the tracked frames.
    """
    poses = sorted(poses, key=lambda p: p.frame)
    if gate is None:
        gate = 0.25 * body_scale(poses)
    times = frame_index(poses)
    out = list(poses)
    for group in model.interchangeable():
        obs = []
        for p in poses:
            if not (p.matched or (use_rejected and gated_only(p))):
                obs.append(None)
                continue
            obs.append(np.array([np.full(3, np.nan) if p.parts.get(g) is None
                                 else np.asarray(p.parts[g], float) for g in group]))
        perm, seg = assign_identities(times, obs, gate, max_gap, velocity)
        stem = str(group[0]).rpartition("_")[0]
        for i, p in enumerate(perm):
            if p is None:
                continue
            q = relabel(out[i], {group[j]: group[p[j]] for j in range(len(group))})
            q.diagnostics = {**q.diagnostics,
                             "track": {**q.diagnostics.get("track", {}), stem: int(seg[i])}}
            out[i] = q
    return out
