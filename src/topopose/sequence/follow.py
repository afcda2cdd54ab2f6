"""The tracker on a run's poses: every joint on every frame (:mod:`.tracker`).

:func:`follow` reads the sequence stage's result (the matched frames' fitted skeletons, their
left and right) and the frames' hulls, learns the subject's capsule body (:mod:`.body`),
tracks it through the sequence and writes every frame's joints, its ``fit`` (the quality) and
its status: ``matched`` (the alignment confident and the fit agreeing with it), ``tracked``,
``lost``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from topopose.sequence.kept import KeptFrame
from topopose.sequence.tracker import TrackOptions, frame_data, track_sequence


@dataclass(frozen=True)
class FollowOptions:
    """Options of the tracking stage of a run (``run(..., follow=FollowOptions(...))``).

    Attributes
    ----------
    enabled : track the body through the sequence (default on)
    body_frames : at most this many confident frames (evenly spread) learn the body's radii
    radius_scales : the factors of the radii tried on the same frames' silhouettes, the best
        silhouette IoU kept (:func:`~topopose.sequence.silhouette.radius_scale`; one: none)
    calibrate : rounds refining the bone lengths on those frames' hulls, all frames and
        mirrored bones jointly (:func:`~topopose.sequence.tracker.calibrate`; 0: the
        kinematic fit's lengths)
    silhouette_fit : the frame's ``fit`` is the silhouette IoU of the projected body, mean
        over the cameras (``diagnostics["fit_cameras"]`` per camera,
        :func:`~topopose.sequence.silhouette.silhouette_iou`); else (or without silhouettes)
        the voxel agreement (:func:`~topopose.sequence.tracker.agreement`); the track
        chooses between a frame's fits by it
    trunk_sides : (upper, lower) reach of the capsules down the trunk's sides
        (:func:`~topopose.sequence.body.trunk_sides`), or None: none
    extends : a capsule on past each joint the model marks ``extends`` (the human's skull and
        ankles: the top of the head, the heels) as far as the hull goes on
        (:func:`~topopose.sequence.body.reach_beyond`)
    part_reach : the parts no joint places (the head, past the skull) where the confident
        frames' alignments put them along the last bone (:func:`part_reach`); else the bone
        extended as far as the joint's place on its arc says
    min_fit : a frame the track does not match is ``lost`` when its ``fit`` is below this
        share of the median ``fit`` of the frames the track fitted, else ``tracked``: the
        silhouette IoU a right fit reaches is the set-up's (the cameras, the images' size, the
        segmentation, the subject's size in the images), so a frame is judged against the
        same run's frames (:func:`lost_frames`)
    unconfirmed : when the ``matched`` frames give the track no start, start it from the
        alignments the confidence gate alone rejected
        (:func:`~topopose.sequence.track.gated_only`), else from every rejected one: their
        frames are ``tracked`` or ``lost``, never ``matched``, and
        ``diagnostics["follow"]["confirmed"]`` is false (:func:`topopose.batch.run.run`)
    seed : the seed of the random sampling of each frame's hull points and silhouette rays
    track : the tracker's settings (:class:`~topopose.sequence.tracker.TrackOptions`)
    """

    enabled: bool = True
    body_frames: int = 12
    calibrate: int = 2
    radius_scales: tuple = (1.0,)
    silhouette_fit: bool = True
    trunk_sides: tuple | None = (0.6, 1.0)
    extends: bool = True
    part_reach: bool = True
    min_fit: float = 0.75
    unconfirmed: bool = True
    seed: int = 0
    track: TrackOptions = field(default_factory=TrackOptions)


SIDES = "left_", "right_"


def _limb_groups(model, tree):
    """Per mirror pair of the model: the (part_1 joint, part_2 joint) index pairs along its
    two limbs, and the joint renaming that names part_1's side left."""
    from topopose.sequence.chirality import joint_renaming

    groups, rename = [], {}
    for parts, names in model.mirrors:
        on = [[j for j, arc in enumerate(tree.arc) if parts[k] in arc] for k in (0, 1)]
        base = [{tree.base[j]: j for j in js} for js in on]
        pairs = [(base[0][b], base[1][b]) for b in base[0] if b in base[1]]
        if pairs:
            groups.append(pairs)
            rename.update(joint_renaming(model, dict(zip(parts, names)), tree.names))
    return groups, rename


def _canonical(pose, tree, groups, rename):
    """The pose's joints as an array in the tree's order (part_1's limb = left when sided)
    and, per group, whether its joints carry side names."""
    index = {n: j for j, n in enumerate(tree.names)}
    index.update({v: index[k] for k, v in rename.items()})
    P = np.full((len(tree.names), 3), np.nan)
    for k, v in (pose.joints or {}).items():
        if k in index:
            P[index[k]] = v
    sided = [any(str(k).startswith(SIDES) and index.get(k) in {i for pr in g for i in pr}
                 for k in pose.joints) for g in groups]
    return P, np.array(sided, dtype=bool)


def body_parts(tree, P, reach=None) -> dict:
    """The model's parts placed by the skeleton ``P`` (J, 3): a part at an arc's end takes the
    joint declared there (``at`` 0 or 1: chest → torso, pelvis → crotch, fingertip → hand), or
    lies on along the arc's last bone past its joint (skull → head): by ``reach[part]`` (m,
    :func:`part_reach`), else as far as the joint's place on the arc extends the bone."""
    out = {}
    for j, (u, v) in enumerate(tree.arc):
        if tree.at[j] == 0.0:
            out.setdefault(u, P[j])
        elif tree.at[j] == 1.0:
            out[v] = P[j]
    for j, p, v in _extended(tree):
        d = P[j] - P[p]
        if reach and v in reach and np.isfinite(reach[v]):
            out[v] = P[j] + reach[v] * d / max(float(np.linalg.norm(d)), 1e-12)
        else:
            at_p = tree.at[p] if tree.arc[p] == tree.arc[j] else 0.0
            out[v] = P[j] + (1.0 - tree.at[j]) / (tree.at[j] - at_p) * d
    return {k: np.asarray(x, float).copy() for k, x in out.items()}


def _extended(tree) -> list:
    """The parts no joint places, at an arc's end: (the arc's last joint, its parent, the
    part)."""
    ends = {v for j, (u, v) in enumerate(tree.arc) if tree.at[j] == 1.0} | \
        {u for j, (u, v) in enumerate(tree.arc) if tree.at[j] == 0.0}
    out = []
    for j, (u, v) in enumerate(tree.arc):
        last = max((k for k in range(len(tree.arc)) if tree.arc[k] == (u, v)),
                   key=lambda k: tree.at[k])
        if v in ends or j != last:
            continue
        p = tree.parents[j]
        at_p = tree.at[p] if p >= 0 and tree.arc[p] == (u, v) else 0.0
        if p >= 0 and tree.at[j] > at_p:
            out.append((j, p, v))
    return out


def part_reach(tree, poses, align) -> dict:
    """How far each part no joint places (:func:`_extended`: the head past the skull) lies
    past its arc's last joint along that joint's bone where the alignment placed both: the
    median over the confident frames (``align`` (F, J, 3), NaN elsewhere) of the alignment's
    part (the head's top, where the hull ends) projected on the bone. The
    tracker's frames then put the part where the confident frames have it, a constant of the
    subject's body like its bone lengths."""
    out = {}
    for j, p, v in _extended(tree):
        r = []
        for i, pose in enumerate(poses):
            x = (pose.parts or {}).get(v)
            if x is None or np.isnan(align[i, [j, p]]).any():
                continue
            d = align[i, j] - align[i, p]
            r.append(float(np.dot(np.asarray(x, float) - align[i, j], d))
                     / max(float(np.linalg.norm(d)), 1e-12))
        if r:
            out[v] = float(np.median(r))
    return out


def follow(poses, model, tree, lengths, hull, options: FollowOptions | None = None,
           fps=None, starts=None) -> list:
    """Track the subject's body through a run's poses (sorted by frame).

    Parameters
    ----------
    poses : list of Pose, after the sequence stage (:func:`topopose.sequence.motion.process_sequence`)
    model : Model
    tree : KinematicTree, lengths : ndarray
        The kinematic fit's tree and bone lengths (``Motion.tree``, ``Motion.lengths``).
    hull : callable frame name → KeptFrame, Volume or (Volume, (cameras, silhouettes))
        The frame's visual hull (as the per-frame estimator carved it), with the silhouettes
        it was carved from (for the silhouette term and the silhouette IoU); a
        :class:`~topopose.sequence.kept.KeptFrame` holds both as the tracker reads them.
        Called once per frame.
    options : FollowOptions
    fps : the capture's frame rate (the track's smoothing window, ``TrackOptions.smooth``)
    starts : sequence of bool, optional
        The frames whose alignments start and guide the track (default: the ``matched``
        ones); only a ``matched`` frame can stay ``matched``.

    Returns
    -------
    list of Pose: every frame the tracker fitted with ``joints`` (left / right names where the
    confident frames of its track decided them), ``fit`` and status ``matched`` / ``tracked``
    / ``lost``; ``diagnostics["follow"]`` holds the frame the track started from (``from``),
    whether that frame is ``matched`` (``confirmed``), whether it re-initialized there and
    the frame's status before (``before``: ``matched``, ``rejected`` or ``failed``),
    ``diagnostics["track_body"]`` the body's radii and bone lengths (per joint, the bone
    into it) and its extra capsules (``extra``: their ends' weights of the joints and their
    radii). A frame the per-frame stage rejected or failed keeps its reason (``error``);
    frames with no hull keep their pose.
    """
    from topopose.sequence.body import learn_body

    opts = options or FollowOptions()
    poses = list(poses)
    if not poses or tree is None or lengths is None:
        return poses
    if np.isnan(np.asarray(lengths)[[j for j, p in enumerate(tree.parents) if p >= 0]]).any():
        return poses
    groups, rename = _limb_groups(model, tree)
    F, J = len(poses), len(tree.names)
    align = np.full((F, J, 3), np.nan)
    sided = np.zeros((F, len(groups)), dtype=bool)
    starts = [p.matched for p in poses] if starts is None else list(starts)
    for i, p in enumerate(poses):
        if starts[i] and p.joints and not p.diagnostics.get("interpolated"):
            P, s = _canonical(p, tree, groups, rename)
            if not np.isnan(P).any():
                align[i], sided[i] = P, s
    conf = np.flatnonzero(~np.isnan(align).any(axis=(1, 2)))
    if not len(conf):
        return poses
    timings = {"hull": 0.0, "data": 0.0, "quality": 0.0}
    kept = {}

    def record(i):
        """Frame i's KeptFrame (None: it failed to load), asked of ``hull`` once."""
        if i not in kept:
            t0 = time.process_time()
            try:
                v = hull(poses[i].frame)
                kept[i] = v if isinstance(v, KeptFrame) else \
                    KeptFrame.keep(*(v if isinstance(v, tuple) else (v, None)))
            except Exception:          # a frame that failed to load: no fit
                kept[i] = None
            timings["hull"] += time.process_time() - t0
        return kept[i]

    def volume(i):
        """(Volume, (cameras, silhouettes) scaled, or None), or (None, None)."""
        r = record(i)
        return (None, None) if r is None else r.read()

    pick = conf[np.linspace(0, len(conf) - 1, min(opts.body_frames, len(conf))).round()
                .astype(int)]
    picked = [(volume(i), align[i]) for i in pick]
    learn = [(v[0], P) for v, P in picked if v[0] is not None]
    if not learn:
        return poses
    body = learn_body(tree, lengths, learn, learn[0][0].voxel_size, sides=opts.trunk_sides,
                      extends=opts.extends)
    rng = np.random.default_rng(opts.seed)
    views = [(v[1], P) for v, P in picked if v[1] is not None]
    if views and len(opts.radius_scales) > 1:
        from topopose.sequence.silhouette import radius_scale
        body = radius_scale(body, views, opts.radius_scales)
    if opts.calibrate:
        from topopose.sequence.tracker import calibrate
        body = calibrate(body, [(frame_data(v, opts.track.points, rng), P) for v, P in learn],
                         opts.track, rounds=opts.calibrate)

    def data_of(i):
        r = record(i)
        if r is None:
            return None
        t0 = time.process_time()
        views = None if r.views is None else (r.views.cameras, r.views.crops)
        d = frame_data(r.hull, opts.track.points, rng, views, opts.track.n_rays)
        timings["data"] += time.process_time() - t0
        return d

    from topopose.sequence.silhouette import silhouette_iou
    from topopose.sequence.tracker import agreement

    last = {}                   # each frame's last silhouette IoU per camera, and its pose

    def cameras_fit(i, P):
        """Frame i's silhouette IoU per camera of the body at ``P``, or None (no
        silhouettes, or ``silhouette_fit`` off)."""
        r = record(i)
        if r is None or r.views is None or not opts.silhouette_fit:
            return None
        if i not in last or not np.array_equal(last[i][0], P):
            t0 = time.process_time()
            last[i] = (np.array(P), silhouette_iou(body, P, r.views.cameras, r.views.crops,
                                                   r.views.shapes))
            timings["quality"] += time.process_time() - t0
        return last[i][1] if np.isfinite(last[i][1]).any() else None

    def quality(i, d, P):
        """The fit's quality the track chooses by: the frame's ``fit``."""
        iou = cameras_fit(i, P)
        return agreement(body, d, P) if iou is None else float(np.nanmean(iou))

    t0, before = time.process_time(), sum(timings.values())
    tr = track_sequence(body, data_of, align, opts.track, groups=groups, fps=fps,
                        quality=quality)
    fit_s = time.process_time() - t0 - (sum(timings.values()) - before)
    if tr is None:
        return poses
    votes = inherit_votes(tr.segment, tr.joints, _segment_votes(tr, align, sided, len(groups)),
                          groups)
    reach = part_reach(tree, poses, align) if opts.part_reach else None

    radii = {"radii": [None if not np.isfinite(x) else round(float(x), 4) for x in body.radii],
             "lengths": [None if not np.isfinite(x) else round(float(x), 4)
                         for x in body.lengths]}
    if body.n_extra:            # the extra capsules: their ends' joint weights and radii
        radii["extra"] = {"ends": np.round(body.ends, 4).tolist(),
                          "radii": [round(float(x), 4) for x in body.extra_radii]}
    ious = {}                   # each fitted frame's silhouette IoU per camera
    for i in np.flatnonzero(np.array([bool(s) for s in tr.status])):
        iou = cameras_fit(i, tr.joints[i])
        if iou is not None:
            ious[i] = iou
    fits = {i: float(np.nanmean(iou)) for i, iou in ious.items()} or \
        {int(i): float(tr.quality[i]) for i in np.flatnonzero(np.isfinite(tr.quality))}
    lost = lost_frames(fits, opts.min_fit)
    out = []
    for i, p in enumerate(poses):
        if not tr.status[i]:
            out.append(p)
            continue
        names, side = _side_names(model, tree, groups, rename,
                                  [votes.get((int(tr.segment[i]), g), 0) for g in range(len(groups))])
        joints = {n: tr.joints[i, j].copy() for j, n in enumerate(names)}
        parts = p.parts
        if tr.status[i] != "matched" or not p.matched:        # the body's own parts
            parts = {side.get(k, k): v
                     for k, v in body_parts(tree, tr.joints[i], reach).items()}
        start = poses[int(tr.segment[i])]
        diag = {**p.diagnostics, "follow": {"from": start.frame, "confirmed": start.matched,
                                            "reinitialized": bool(i in tr.reinitialized),
                                            "before": p.status},
                "track_body": radii}
        status, fit, diag_fit = tr.status[i], float(tr.quality[i]), {}
        if status == "matched" and not p.matched:      # a start the gate rejected
            status = "tracked"
        if i in ious:
            fit = fits[i]
            diag_fit = {"fit_cameras": [None if not np.isfinite(x) else round(float(x), 4)
                                        for x in ious[i]]}
        if status != "matched":
            status = "lost" if i in lost else "tracked"
        out.append(replace(p, status=status, joints=joints, parts=parts, fit=round(fit, 4),
                           diagnostics={**diag, **diag_fit},
                           timings_ms=p.timings_ms))
    per_frame = {k: round(1e3 * v / max(F, 1), 3) for k, v in timings.items()}
    per_frame["fit"] = round(1e3 * fit_s / max(F, 1), 3)
    for q in out:       # the stage's mean CPU time (this process) a frame, on every frame
        q.timings_ms = {**q.timings_ms, **{f"track_{k}": v for k, v in per_frame.items()}}
    return out


def lost_frames(fits, share) -> set:
    """The frames whose fit is below ``share`` of the median fit: ``fits`` maps a frame to
    its fit (the silhouette IoU of the fitted body, mean over the cameras,
    :func:`~topopose.sequence.silhouette.silhouette_iou`; or its voxel agreement,
    :func:`~topopose.sequence.tracker.agreement`).

    Examples
    --------
    >>> sorted(lost_frames({0: 0.62, 1: 0.6, 2: 0.3, 3: 0.58}, 0.75))
    [2]
    """
    if not fits:
        return set()
    floor = share * float(np.median(list(fits.values())))
    return {i for i, f in fits.items() if f < floor}


def _segment_votes(tr, align, sided, n_groups) -> dict:
    """Left / right of each track segment: ``(segment, group) → vote``, the sum over its
    confident, sided frames of +1 (as aligned) or -1 (swapped by the tracker)."""
    votes = {}
    for i in range(len(align)):
        s = tr.segment[i]
        if s < 0 or np.isnan(align[i]).any():
            continue
        for g in range(n_groups):
            if sided[i, g]:
                votes[(s, g)] = votes.get((s, g), 0) + (-1 if tr.swapped[i, g] else 1)
    return votes


def inherit_votes(segment, joints, votes, groups) -> dict:
    """Left / right carried into the track segments none of whose confident frames named a
    mirror group: from a frame next to one of another segment that did, each limb taking the
    side of the limb nearer to it there (summed over the group's joints).

    Parameters
    ----------
    segment : ndarray (F,) of int, each frame's segment (-1: none)
    joints : ndarray (F, J, 3)
    votes : dict, ``(segment, group) → vote`` (:func:`_segment_votes`; 0 or absent: undecided)
    groups : list of lists of joint index pairs (limb 1, limb 2)

    Returns
    -------
    dict, the votes with the undecided ones that a neighbouring frame decides

    Examples
    --------
    >>> J = np.array([[[0., 0, 0], [1, 0, 0]], [[1.1, 0, 0], [0.1, 0, 0]]])  # limbs crossed
    >>> inherit_votes(np.array([0, 1]), J, {(0, 0): 2}, [[(0, 1)]])
    {(0, 0): 2, (1, 0): -1}
    """
    votes = dict(votes)
    F = len(segment)
    changed = True
    while changed:
        changed = False
        for i in range(F):
            for g, pairs in enumerate(groups):
                s = int(segment[i])
                if s < 0 or votes.get((s, g)):
                    continue
                for k in (i - 1, i + 1):
                    t = int(segment[k]) if 0 <= k < F else -1
                    v = votes.get((t, g), 0) if t >= 0 and t != s else 0
                    if not v:
                        continue
                    a = [x for x, _ in pairs]
                    b = [y for _, y in pairs]
                    same = np.linalg.norm(joints[i, a] - joints[k, a], axis=1).sum() + \
                        np.linalg.norm(joints[i, b] - joints[k, b], axis=1).sum()
                    cross = np.linalg.norm(joints[i, a] - joints[k, b], axis=1).sum() + \
                        np.linalg.norm(joints[i, b] - joints[k, a], axis=1).sum()
                    if np.isfinite(same) and np.isfinite(cross):
                        votes[(s, g)] = int(np.sign(v)) * (1 if same <= cross else -1)
                        changed = True
                        break
    return votes


def _side_names(model, tree, groups, rename, votes) -> tuple:
    """The joints' names of a frame and its parts' renaming (numbered → left / right) by the
    votes of its segment, one per mirror group (0: undecided, numbered names kept)."""
    names = list(tree.names)
    side = {}
    for g, pairs in enumerate(groups):
        v = votes[g]
        if v:
            mp, mn = model.mirrors[g]
            side.update(zip(mp, mn if v > 0 else mn[::-1]))
        for a, b in pairs:
            if v > 0:
                names[a], names[b] = rename[tree.names[a]], rename[tree.names[b]]
            elif v < 0:
                names[a], names[b] = rename[tree.names[b]], rename[tree.names[a]]
    return names, side


def follow_run(poses, motion, model, cap, resolution, threshold, estimator=None,
               options: FollowOptions | None = None, kept=None, starts=None) -> list:
    """The tracking stage of :func:`topopose.batch.run.run`: :func:`follow` on a run's poses
    when the sequence stage fitted a skeleton. ``kept``: ``{frame: KeptFrame}`` of the frames
    the run's estimator computed (:class:`~topopose.sequence.kept.KeptFrame`); any other
    frame's hull is carved again as that estimator carves it (``estimator``: its
    :class:`~topopose.frame.options.EstimatorOptions`); ``starts``: as :func:`follow`'s."""
    opts = options or FollowOptions()
    if not opts.enabled or motion is None or motion.tree is None or len(poses) < 3:
        return poses
    tree, lengths = motion.tree, motion.lengths
    if any(p.matched and not p.joints for p in poses):
        poses, tree, lengths = refit(poses, model, cap.up_vector, cap.fps)
    kept = kept or {}
    est = []

    def hull(frame):
        if frame in kept:
            return kept[frame]
        if not est:
            from topopose.frame.estimate import FrameEstimator
            est.append(FrameEstimator(cap, model, resolution, threshold, estimator))
        vol = est[0].hull(frame)
        return vol, estimator_views(est[0], frame)

    return follow(poses, model, tree, lengths, hull, opts, cap.fps, starts)


def estimator_views(est, frame) -> tuple:
    """The cameras and silhouettes the estimator ``est`` carved ``frame``'s hull from (after
    ``est.hull(frame)``): those it compares its result with, else the capture's."""
    views = getattr(est, "_silhouettes", None)
    return views if views is not None else (est.cap.cameras, est.cap.silhouettes(frame))


def refit(poses, model, up, fps=None):
    """The kinematic fit and the sides again on the frames ``matched`` now (the run's
    consistency decides ``matched`` after them, and may add frames): returns (poses, tree,
    lengths)."""
    from topopose.sequence.chirality import assign_sides, numbered
    from topopose.sequence.kinematic_fit import fit_sequence

    fitted, tree, lengths = fit_sequence([numbered(p, model) for p in poses], model, fps=fps)
    if model.mirrors and model.facing:
        fitted = assign_sides(fitted, model, up)
    return fitted, tree, lengths
