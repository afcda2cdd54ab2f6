"""The skeleton's motion over a sequence (sequence stage of the kinematic fit): runs of
continuing motion, temporal outliers and their bridging, the bones' spikes (a Hampel filter)
and the Savitzky–Golay window; the tracked body's joints smoothed the same way."""
from __future__ import annotations

import numpy as np

from topopose.sequence.body import joint_positions, snap
from topopose.sequence.gap_filling import _interpolate
from topopose.sequence.skeleton_fit import KinematicTree

SMOOTH = 9          # frames: the default Savitzky–Golay window (order 2) over the runs of
                    # continuing motion (:func:`motion_runs`); 0 / None given to fit_sequence as 0:
                    # off. Per-frame fits jitter (each frame's curves alone) while a body moves
                    # smoothly. Its figures: docs/decisions.md.


SMOOTH_RATE = 25.0  # frames/s SMOOTH was chosen at: at another rate the default window keeps
                    # its duration, 0.36 s (:func:`smooth_window`). Its figures: docs/decisions.md.


def _apart(a, b) -> float:
    """Mean distance between two sets of joints (n_joints, 3)."""
    return float(np.linalg.norm(a - b, axis=1).mean())


def neighbourhood(P, t, tree: KinematicTree, reach, seen) -> tuple:
    """Per frame the fit saw (``seen``): the per-joint median ``M`` of its neighbourhood (the
    seen frames at most ``reach`` frame numbers away, itself included), joints taken from the
    root, and the frame's distance from it (m, mean over the joints); NaN for the other
    frames and for a frame with fewer than 3 seen frames in reach (:func:`motion_runs`)."""
    Q = P - P[:, tree.root:tree.root + 1]
    M = np.full_like(Q, np.nan)
    dist = np.full(len(P), np.nan)
    idx = np.flatnonzero(seen)
    for i in idx:
        near = idx[np.abs(t[idx] - t[i]) <= reach]
        if len(near) >= 3:
            M[i] = np.median(Q[near], axis=0)
            dist[i] = _apart(Q[i], M[i])
    return M, dist


def motion_runs(P, t, tree: KinematicTree, win, max_move=None, seen=None, near=None) -> list:
    """Runs ``(a, b)`` (frames ``a`` … ``b - 1``) of at least ``win`` fitted frames with
    consecutive frame numbers ``t`` along which the motion continues. Each frame the fit saw
    (``seen``, default every fitted frame; not one interpolated between two others) is
    compared with its neighbourhood: the per-joint median, joints taken from the root, of the
    seen frames at most ``win // 2`` frame numbers away (itself included). A frame at least
    ``max_move`` (m, mean over the joints; None: no check) from its neighbourhood, or with
    fewer than 3 seen frames in it, is an *outlier*: it belongs to no run (a single wrong
    frame among right ones). Between two successive seen frames that are not outliers, a run
    breaks where both the frames and their neighbourhoods lie ``max_move`` apart (the motion
    jumped and stayed; the frames interpolated between them belong to none). Unrelated poses
    (a random-pose capture) make no run: each frame is far from its neighbours' median, or
    the frames and the medians jump.
    Per-frame jitter does not break a run, as it did when each frame was compared with the
    one before (the real recording's 4-camera fits: 27 of 100 frames smoothed, now 59; see
    ``SmoothingOptions.move``).

    Parameters
    ----------
    P : (n_frames, n_joints, 3) joints (NaN: frame not fitted)
    t : (n_frames,) frame numbers
    win : the least run length (frames); ``win // 2`` the neighbourhood's reach
    max_move : the largest mean distance of a frame's joints from its neighbourhood's, and
        between two successive neighbourhoods (m)
    seen : (n_frames,) bool, the frames the fit saw (None: every fitted frame)
    near : ``(M, dist)`` of :func:`neighbourhood` for these frames and ``win // 2``, if
        already computed

    Returns
    -------
    list of (a, b) index pairs.
    """
    n_f = len(P)
    t = np.asarray(t)
    ok = ~np.isnan(P).reshape(n_f, -1).any(axis=1)
    seen = ok if seen is None else ok & np.asarray(seen, bool)
    outlier = np.zeros(n_f, dtype=bool)
    M = Q = None
    if max_move is not None:
        Q = P - P[:, tree.root:tree.root + 1]
        M, dist = near if near is not None else neighbourhood(P, t, tree, win // 2, seen)
        outlier = seen & ~(dist < max_move)         # NaN: too few neighbours to judge
    runs, start, last = [], None, None

    def close(end):
        if start is not None and end - start >= win:
            runs.append((start, end))

    for i in range(n_f):
        if not ok[i] or outlier[i] or (start is not None and t[i] - t[i - 1] != 1):
            close(i)
            start, last = None, None
            if not ok[i] or outlier[i]:
                continue
        if start is None:
            start, last = i, (i if seen[i] else None)
            continue
        if not seen[i]:
            continue
        if M is not None and last is not None and _apart(Q[i], Q[last]) >= max_move \
                and _apart(M[i], M[last]) >= max_move:
            close(last + 1)
            start = i
        last = i
    close(n_f)
    return runs


def despike(D, half, k, floor):
    """A Hampel filter on bone directions: each frame's direction of each bone more than
    ``max(med + k × MAD, floor)`` degrees from the median direction of its window (the frames
    at most ``half`` away, itself included; ``med``, ``MAD``: the median and the scaled median
    absolute deviation of the window's angles to it) is replaced by that median direction.

    Parameters
    ----------
    D : (n_frames, n_joints, 3) unit bone directions (:func:`_directions`; the root's zero)
    half : the window's half-width (frames)
    k, floor : the threshold's MAD factor and its least value (degrees)

    Returns
    -------
    (D with the spikes replaced, (n_frames, n_joints) bool: the bones replaced)

    Examples
    --------
    >>> D = np.tile([0.0, 0.0, -1.0], (7, 1, 1))
    >>> D[3, 0] = [1.0, 0.0, 0.0]                  # one frame's bone swung out 90 degrees
    >>> out, bad = despike(D, 3, 3.0, 15.0)
    >>> bad[:, 0].tolist(), out[3, 0].tolist()
    ([False, False, False, True, False, False, False], [0.0, 0.0, -1.0])
    """
    n = len(D)
    out = D.copy()
    bad = np.zeros(D.shape[:2], dtype=bool)
    for i in range(n):
        W = D[max(0, i - half):i + half + 1]
        m = np.median(W, axis=0)
        norm = np.linalg.norm(m, axis=1)
        m = m / np.maximum(norm, 1e-12)[:, None]
        ang = np.degrees(np.arccos(np.clip(np.einsum("wjk,jk->wj", W, m), -1.0, 1.0)))
        med = np.median(ang, axis=0)
        mad = 1.4826 * np.median(np.abs(ang - med), axis=0)
        a_i = np.degrees(np.arccos(np.clip(np.einsum("jk,jk->j", D[i], m), -1.0, 1.0)))
        bad[i] = (a_i > np.maximum(med + k * mad, floor)) & (norm > 1e-9)
        out[i, bad[i]] = m[bad[i]]
    return out, bad


def smooth_window(fps=None) -> int:
    """The default smoothing window (frames) at ``fps`` frames/s: the odd number of frames
    nearest :data:`SMOOTH` / :data:`SMOOTH_RATE` seconds (at least 3); :data:`SMOOTH` itself
    when the rate is unknown, :data:`SMOOTH` is off or :data:`SMOOTH_RATE` is None (the
    window in frames at any rate).

    Examples
    --------
    >>> smooth_window(25), smooth_window(60), smooth_window(None), smooth_window(10)
    (9, 21, 9, 3)
    """
    if not SMOOTH or not fps or not SMOOTH_RATE:
        return SMOOTH or 0
    return odd_window(SMOOTH / SMOOTH_RATE, fps)


def odd_window(seconds, fps) -> int:
    """The odd number of frames nearest ``seconds`` at ``fps`` frames/s, at least 3 (0: no
    time, no window).

    Examples
    --------
    >>> odd_window(0.36, 25), odd_window(0.36, 60), odd_window(0.0, 25)
    (9, 21, 0)
    """
    if not seconds:
        return 0
    return max(3, 2 * int(round((seconds * float(fps) - 1) / 2)) + 1)


def bridge_outliers(P, t, tree: KinematicTree, L, dist, max_gap, max_move, M=None, reach=None):
    """``P`` with short stretches of *outlier* frames (a skeleton ``max_move`` or more from its
    neighbours' median, :func:`neighbourhood`) replaced by the interpolation of the frames
    either side (root position and bone directions, as the gap filling): gap filling of
    short rejected stretches, for frames the per-frame stage matched but the motion around
    them rejects. A stretch is bridged when

    * it has at most ``max_gap`` frames, consecutive frame numbers to the two frames either
      side, and those two were judged and are not outliers;
    * the two are of one motion: less than ``max_move`` apart (mean over the joints, from the
      root), or their neighbourhoods' medians ``M`` are (a 4-camera fit jitters; as
      :func:`motion_runs`);
    * its pose does not recur: no other judged frame within ``reach`` frame numbers lies less
      than ``max_move`` from one of its frames (two poses taken in turn are the capture's);
    * most judged frames within ``reach`` of it (itself included) are not outliers: a wrong
      frame among right ones. In a capture of unrelated poses most frames are outliers, and
      the few near their neighbours' median are typical poses, not one motion.

    Parameters
    ----------
    P : (n_frames, n_joints, 3) joints (NaN: frame not fitted)
    t : (n_frames,) frame numbers
    L : (n_frames, n_joints) bone lengths per frame
    dist : (n_frames,) each frame's distance from its neighbours' median (m; NaN: not
        judged: not fitted, interpolated, or too few neighbours)
    max_gap : longest stretch bridged (frames)
    max_move : m, the outliers' distance and the ends' largest one
    M : (n_frames, n_joints, 3) the neighbourhood medians (:func:`neighbourhood`), or None
    reach : frames around a stretch looked at (None: ``max_gap``)

    Returns
    -------
    P : a copy, bridged; bridged : (n_frames,) bool

    Examples
    --------
    A chain whose middle frame jumped away (the root stays, the bones point elsewhere):

    >>> from topopose.pose.model import load_model
    >>> tree = kinematic_tree(load_model("human"))
    >>> rng = np.random.default_rng(0)
    >>> P = np.stack([np.cumsum(rng.normal(0, 0.1, (len(tree.names), 3)), 0)] * 3)
    >>> P[1] += rng.normal(0, 0.5, P[1].shape)
    >>> L = np.ones((3, len(tree.names)))
    >>> Q, done = bridge_outliers(P, np.arange(3), tree, L, np.array([0, 1, 0]), 5, 0.15)
    >>> done.tolist(), bool(np.allclose(Q[1] - Q[1, tree.root], forward(
    ...     np.zeros(3), _directions(P[0], tree), L[0], tree)))
    ([False, True, False], True)
    """
    P = np.array(P, dtype=float, copy=True)
    t = np.asarray(t)
    dist = np.asarray(dist, float)
    outlier, end = dist >= max_move, dist < max_move          # NaN: neither
    judged = np.flatnonzero(np.isfinite(dist))
    reach = max_gap if reach is None else reach
    Q = P - P[:, tree.root:tree.root + 1]
    done = np.zeros(len(P), dtype=bool)

    def bridgeable(i, j):
        a, b = i - 1, j + 1
        if a < 0 or b >= len(P) or not (end[a] and end[b]) or j - i + 1 > max_gap \
                or t[i] - t[a] != 1 or t[b] - t[j] != 1:
            return False
        if _apart(Q[a], Q[b]) >= max_move and (M is None or _apart(M[a], M[b]) >= max_move):
            return False
        around = judged[(t[judged] >= t[i] - reach) & (t[judged] <= t[j] + reach)]
        if 2 * np.count_nonzero(outlier[around]) >= len(around):
            return False
        others = around[(around < i) | (around > j)]
        return not any(_apart(Q[k], Q[m]) < max_move for m in range(i, j + 1) for k in others
                       if abs(t[k] - t[m]) <= reach)

    i = 0
    while i < len(P):
        if not outlier[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(P) and outlier[j + 1] and t[j + 1] - t[j] == 1:
            j += 1
        if bridgeable(i, j):
            _interpolate(P, t, L, tree, i - 1, j + 1)
            done[i:j + 1] = True
        i = j + 1
    return P, done


def bridged_parts(poses, t, bridged, i) -> tuple:
    """The parts of bridged frame ``i`` (:func:`bridge_outliers`): each part placed in both
    frames either side of its stretch interpolated between them by frame number, the others
    as the frame had them; returns (parts, the names interpolated)."""
    a, b = i - 1, i + 1
    while bridged[a]:
        a -= 1
    while bridged[b]:
        b += 1
    s = (t[i] - t[a]) / (t[b] - t[a])
    pa, pb = poses[a].parts, poses[b].parts
    done = sorted(k for k in pa if pa[k] is not None and pb.get(k) is not None)
    parts = dict(poses[i].parts)
    for k in done:
        parts[k] = (1 - s) * np.asarray(pa[k], float) + s * np.asarray(pb[k], float)
    return parts, done


def smooth_track(body, joints, segment, window) -> np.ndarray:
    """The tracked joints smoothed in time, each run of consecutive frames that follow from
    one initialization (the same ``segment``) apart: a Savitzky–Golay filter of order 2 over
    ``window`` frames (an odd number; a shorter run: its own length, odd, at least 3), each
    frame then put back on the body's bone lengths (:func:`~.body.snap`): the tracker's motion
    (:func:`.tracker.track_sequence`).

    Parameters
    ----------
    body : CapsuleBody
    joints : ndarray (F, J, 3), NaN rows where no frame was fitted
    segment : ndarray (F,) int, :attr:`.tracker.Track.segment`
    window : int, frames

    Returns
    -------
    ndarray (F, J, 3)
    """
    from scipy.signal import savgol_filter

    joints = np.asarray(joints, float)
    out = joints.copy()
    ok = ~np.isnan(joints).any(axis=(1, 2))
    i, F = 0, len(joints)
    while i < F:
        j = i + 1
        while j < F and ok[i] and ok[j] and segment[j] == segment[i]:
            j += 1
        w = min(int(window), j - i - (j - i + 1) % 2)
        if ok[i] and w >= 3:
            S = savgol_filter(joints[i:j], w, 2, axis=0)
            out[i:j] = [joint_positions(body, *snap(body, x)) for x in S]
        i = j
    return out
