"""The thesis' applications (§13.3): hull segmentation, pose detection, pose clustering.

1. Segmentation by flooding (§13.3.1.1): synthetic humans — the anatomically real ``body``
   (MakeHuman mesh) and the capsule ``human`` — (random poses, limbs kept 3 voxels apart at
   100³ — 7.5 cm —, silhouette noise 1), pipeline at 100³; voxel accuracy of the label volume
   against ground truth (body: each hull voxel's nearest mesh vertex's dominant skinning bone;
   human: the nearest primitive's link; grouped into the model's arcs; numbered limbs paired
   optimally) on the frames the quality study calls *good*,
   for the plain flooding (the thesis'), the part-weighted flooding, the radius-weighted
   flooding, radius-weighted + the kinematic model's bones with limbs from their first joint,
   the same with limb starts (arm 45 % down the upper arm, banded floods, bone weight 0.8) and
   the default (arm 35 %, bone weight 0.7), on the held-out seeds and
   on the development seeds the parameters were chosen on; time of the
   flooding call alone and of the whole segment step, beside the peer
   ``skimage.segmentation.watershed`` (constant image, markers, mask: the same multi-source
   flooding) on the same inputs, and how often both agree.
2. Pose detection (§13.3.2.1): synthetic sequences whose poses are drawn to contain the named
   poses (hands up, one hand up, arms spread, inverted bodies) among random ones; each named
   pose evaluated on the pipeline's matched frames and on the ground truth of the same frames
   (the truth: the points corresponding to the pipeline's, :func:`pipeline_points`; beside it
   the alternative correspondence and gt.json's own parts); precision
   and recall, with the class balance, on all matched frames, on the *good* ones (the
   per-frame matcher's errors apart) and on good frames whose truth is stable under 3 cm, and
   with the undecided band; the wrong decisions by cause; the truth on gt.json's own parts.
3. Pose clustering (§13.3.2.2): K known base poses (:data:`BASE_POSES`: standing, hands up, arms
   spread, kick, squat, star), frames = a base pose with joint angles jittered by ±5° at a random
   place and heading; (a) the pipeline's matched frames, (b) the gt parts jittered
   by 2 cm; adjusted Rand index against the base-pose labels and the number of clusters found by
   the largest-gap rule and by the silhouette rule.

   Peers on the same frames: the head from the hull along the body's axis off (acrobatic:
   ``head_axis=False``), and every description evaluated on the pose's parts alone (the
   crotch dropped below the legs' junction, ``pose/anatomy.py`` CROTCH_DROP: *dropped crotch*) beside
   the points the detection uses (``topopose.apps.detect.description_parts``: the junction).

Writes benchmarks/results/applications.{md,json} and applications_*.png (``--detection-only``:
only part 2, to applications_detection.{md,json}; ``--dev``: part 2 on the development seeds,
capsule human 3–4 and body 1–2, to applications_detection_dev.{md,json}).
Usage: python benchmarks/applications.py [--quick] [--detection-only] [--dev]
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _machine import machine  # noqa: E402
from topopose.sequence.consistency import MAX_UNEXPLAINED  # noqa: E402

RES = 100
MARGIN = 0.075            # 3 voxels of the human grid at 100³ (benchmarks/quality.py)


# ----------------------------------------------------------------------------- pose samplers
def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _raise(p, s, rng):
    p.update({f"sh_flex_{s}": _u(rng, 155, 180), f"sh_abd_{s}": _u(rng, 0, 25),
              f"elbow_{s}": _u(rng, 0, 30)})


def _lower(p, s, rng):
    p.update({f"sh_flex_{s}": _u(rng, -30, 60), f"sh_abd_{s}": _u(rng, 0, 50),
              f"elbow_{s}": _u(rng, 0, 60)})


def detection_sampler(kind):
    """A human pose sampler mixing named poses with random ones (tagged ``_k``)."""
    from topopose.synth.subjects import human_random

    def sample(rng):
        p = human_random(rng)
        r = rng.random()
        if kind == "acrobatic":
            if r < 0.5:
                p.update(pelvis_pitch=_u(rng, 160, 200), pelvis_roll=_u(rng, -15, 15))
                p["_k"] = "inverted"
            else:
                p["_k"] = "random"
            return p
        if r < 0.25:
            _raise(p, "l", rng)
            _raise(p, "r", rng)
            p["_k"] = "hands-up"
        elif r < 0.45:
            s, o = ("l", "r") if rng.random() < 0.5 else ("r", "l")
            _raise(p, s, rng)
            _lower(p, o, rng)
            p["_k"] = "one-hand-up"
        elif r < 0.65:
            for s in "lr":
                p.update({f"sh_flex_{s}": _u(rng, -10, 10), f"sh_abd_{s}": _u(rng, 80, 100),
                          f"elbow_{s}": _u(rng, 0, 15), f"sh_rot_{s}": _u(rng, -20, 20)})
            p["_k"] = "spread"
        else:
            p["_k"] = "random"
        return p
    return sample


#: the tags of :func:`body_detection_sampler` (gt.json records a pose's angles as floats: the
#: tag is its index here)
BODY_TAGS = ("hands-up", "one-hand-up", "spread", "random")


def body_detection_sampler():
    """A ``body`` pose sampler mixing the named poses with its own random ones
    (:func:`~topopose.synth.body.body_random`), tagged ``_k`` (index into
    :data:`BODY_TAGS`): both hands up (arms abducted 145–175°, a V above the head: raised
    forward as the capsule human's they touch the head and fail the limb separation),
    one hand up and the other down, arms spread (abducted 80–100°), random. The draw's
    shares (0.12, 0.30, 0.03, 0.55) offset how often each kind passes the limb separation
    (arms spread nearly always, random poses seldom), so that the sequences hold the four
    kinds in about equal numbers."""
    from topopose.synth.body import body_random

    def up(p, s, rng):
        p.update({f"sh_flex_{s}": _u(rng, -10, 30), f"sh_abd_{s}": _u(rng, 145, 175),
                  f"elbow_{s}": _u(rng, 0, 20), f"sh_rot_{s}": _u(rng, -20, 20)})

    def sample(rng):
        p = body_random(rng)
        r = rng.random()
        if r < 0.12:
            up(p, "l", rng)
            up(p, "r", rng)
            k = 0
        elif r < 0.42:
            s, o = ("l", "r") if rng.random() < 0.5 else ("r", "l")
            up(p, s, rng)
            p.update({f"sh_flex_{o}": _u(rng, -15, 40), f"sh_abd_{o}": _u(rng, 20, 60),
                      f"elbow_{o}": _u(rng, 0, 40)})
            k = 1
        elif r < 0.45:
            for s in "lr":
                p.update({f"sh_flex_{s}": _u(rng, -10, 10), f"sh_abd_{s}": _u(rng, 80, 100),
                          f"elbow_{s}": _u(rng, 0, 15), f"sh_rot_{s}": _u(rng, -20, 20)})
            k = 2
        else:
            k = 3
        p["_k"] = float(k)
        return p
    return sample


@contextlib.contextmanager
def body_poses(sample):
    """Let ``synthetic_capture(subject="body")`` draw its random poses from ``sample``."""
    from topopose.synth import subjects as SS
    old = SS.RANDOM["body"]
    SS.RANDOM["body"] = sample
    try:
        yield
    finally:
        SS.RANDOM["body"] = old


#: K known poses (joint angles, degrees; the rest 0): distinct configurations of the limbs
BASE_POSES = [
    {"sh_abd_l": 35, "sh_abd_r": 35, "elbow_l": 10, "elbow_r": 10},                  # standing
    {"sh_flex_l": 170, "sh_flex_r": 170, "sh_abd_l": 10, "sh_abd_r": 10},           # hands up
    {"sh_abd_l": 90, "sh_abd_r": 90},                                               # arms spread
    {"sh_flex_l": 90, "sh_abd_r": 35, "hip_flex_r": 90, "knee_r": 10},              # kick, arm forward
    {"spine_flex": 20, "sh_flex_l": 80, "sh_flex_r": 80, "hip_flex_l": 70, "hip_flex_r": 70,
     "knee_l": 100, "knee_r": 100, "sh_abd_l": 30, "sh_abd_r": 30},                 # squat, arms forward
    {"sh_flex_l": 150, "sh_abd_l": 40, "sh_abd_r": 60, "hip_abd_l": 35, "hip_abd_r": 35},  # star
]
for _b in BASE_POSES:                   # legs apart: limbs 3 voxels apart in the hull
    _b.setdefault("hip_abd_l", 14)
    _b.setdefault("hip_abd_r", 14)


def cluster_sampler(K, jitter=5.0):
    """Frames from the first K :data:`BASE_POSES`: every angle jittered by ±``jitter``°."""
    from topopose.synth.subjects import HUMAN_DEFAULT

    base = [{**HUMAN_DEFAULT, **b} for b in BASE_POSES[:K]]

    def sample(rng):
        k = int(rng.integers(K))
        p = {a: v + _u(rng, -jitter, jitter) for a, v in base[k].items()}
        p["_k"] = k
        return p
    return sample


@contextlib.contextmanager
def human_poses(sample):
    """Let ``synthetic_capture(subject="human")`` draw its random poses from ``sample`` and
    remember each body's tag (``body.extra["k"]``)."""
    from topopose.synth import subjects as SS
    old_r, old_b = SS.RANDOM["human"], SS.BUILD["human"]

    def build(pose, thickness=1.0):
        body = old_b(pose, thickness)
        body.extra["k"] = pose.get("_k")
        return body

    SS.RANDOM["human"], SS.BUILD["human"] = sample, build
    try:
        yield
    finally:
        SS.RANDOM["human"], SS.BUILD["human"] = old_r, old_b


def capture(sample, frames, seed, noise=1):
    from topopose.synth.capture import synthetic_capture

    with human_poses(sample):
        return synthetic_capture("human", frames=frames, seed=seed, noise=noise, separated=True,
                                 margin=MARGIN)


# ----------------------------------------------------------------------------- 1. segmentation
#: the labellings compared (keyword arguments of tp.segment from the frame's pose and model);
#: the last is tp.segment's default given the pose and the model
SEG_METHODS = {
    "none": lambda pose, model: {"weighting": "none"},
    "part": lambda pose, model: {"weighting": "part"},
    "radius": lambda pose, model: {"weighting": "radius"},
    "first_joint": lambda pose, model: {"weighting": "radius", "pose": pose, "model": model,
                                        "limb_start": {}, "band": np.inf, "bone_weight": 0.8},
    "start145": lambda pose, model: {"weighting": "radius", "pose": pose, "model": model,
                                     "limb_start": {"head": 0.5, "hand": 1.45, "foot": 1.0},
                                     "bone_weight": 0.8},
    "default": lambda pose, model: {"weighting": "radius", "pose": pose, "model": model},
}
SEG_LABELS = {"none": "plain flooding (thesis)", "part": "part-weighted, BFS steps",
              "radius": "radius-weighted, chamfer steps",
              "first_joint": "radius + bones, limbs from their first joint",
              "start145": "radius + bones, arm 45 % down the upper arm, bone weight 0.8",
              "default": "radius + bones, arm 35 % down the upper arm, bone weight 0.7 (default)"}
def girdle_bone_arc(bone):
    """The other grouping of the ``body`` rig's girdle bones: the clavicle (``*Shoulder``, neck
    base → shoulder joint) and ``*HipJoint`` (hip centre → hip joint) lie on the model's
    torso→hand and crotch→foot arcs, so they go to the limbs."""
    from topopose.synth.labels import body_bone_arc

    k = "1" if bone.startswith("L") else "2"
    if bone.endswith("Shoulder"):
        return f"torso-hand_{k}"
    if bone.endswith("HipJoint"):
        return f"crotch-foot_{k}"
    return body_bone_arc(bone)


def error_figure(path, vol, lab, m, truth, names, up, title):
    """Truth, segmentation and errors of one frame: the hull's voxels seen from the front
    (nearest voxel along the body's depth axis) and from the side."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from topopose.apps.segment import label_colours
    from topopose.viz.view import _up_rotation

    cols = label_colours(len(names)).astype(float) / 255
    ijk = np.argwhere(truth > 0)
    w = vol.world(ijk) @ _up_rotation(up).T
    t, p = truth[tuple(ijk.T)], m[lab[tuple(ijk.T)]]
    xy = w[:, :2] - w[:, :2].mean(0)                  # body's width axis: largest horizontal spread
    _, vec = np.linalg.eigh(xy.T @ xy)
    across, depth_ax = xy @ vec[:, 1], xy @ vec[:, 0]
    fig, axs = plt.subplots(2, 3, figsize=(10, 9), dpi=70)
    for r, (hor, dep) in enumerate(((across, depth_ax), (depth_ax, across))):
        order = np.argsort(dep)                        # farthest first, nearest drawn last
        for c, (title_c, colour) in enumerate((("truth", cols[t]), ("segmentation", cols[p]),
                                               ("errors (red)", np.where((p != t)[:, None],
                                                                         [[0.85, 0.1, 0.1]],
                                                                         [[0.8, 0.8, 0.8]])))):
            ax = axs[r, c]
            ax.scatter(hor[order], w[order, 2], c=colour[order], s=16, marker="s", lw=0)
            ax.set_aspect("equal")
            ax.set_title(f"{title_c} ({'front' if r == 0 else 'side'})", fontsize=9)
            ax.axis("off")
    for i, n in enumerate(names):
        axs[0, 0].plot([], [], "s", color=cols[i + 1], label=n)
    axs[0, 0].legend(fontsize=6, loc="lower left")
    fig.suptitle(f"{title}: accuracy {np.mean(p == t):.3f}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def bench_segmentation(n_frames, seeds, log, subject="human", figure=None):
    from skimage.segmentation import watershed

    from topopose.synth.subjects import human_random
    from topopose.frame.estimate import FrameEstimator
    from topopose.batch.quality import evaluate
    from topopose.apps.segment import (_box, arc_names, flood_labels, renumbered_accuracy,
                                       segment, skeleton_labels)
    from topopose.synth.labels import synthetic_truth

    rows = []
    for seed in seeds:
        if subject == "body":
            from topopose.synth.capture import synthetic_capture

            cap = synthetic_capture("body", frames=n_frames, seed=seed, noise=1, separated=True,
                                    margin=MARGIN)
        else:
            cap = capture(lambda rng: human_random(rng), n_frames, seed)
        est = FrameEstimator(cap, "human", RES)
        names = arc_names(est.model)
        dets, poses = [], []
        for f in cap.frames:
            pose, det = est.estimate(f, detail=True)
            poses.append(pose)
            dets.append(det)
        ev = evaluate(cap.gt, poses, est.model)
        quality = {fs.frame: fs.quality for fs in ev.frames}
        for fi, (pose, det) in enumerate(zip(poses, dets)):
            if pose.status != "matched":
                continue
            vol = det.volume
            truth = synthetic_truth(vol, cap.options["bodies"][fi], names)
            row = {"subject": subject, "seed": seed, "frame": pose.frame,
                   "quality": quality.get(pose.frame),
                   "hull_voxels": int(vol.data.sum()),
                   **detection_row(pose, cap.gt["frames"][pose.frame], cap.up)}
            seeds_grid, _ = skeleton_labels(det.skeleton, det.alignment, det.data, names)
            bbox = vol.diagnostics.get("bbox")
            sel = truth > 0
            for key, kw in SEG_METHODS.items():
                lab, _ = segment(vol, det.skeleton, det.alignment, det.data, names=names,
                                 **kw(pose, est.model))
                row[f"acc_{key}"], m = renumbered_accuracy(lab, truth, names, return_mapping=True)
                # each true part's voxels labelled right
                row[f"part_correct_{key}"] = {n: int(np.sum((truth[sel] == i + 1) & (m[lab[sel]] == i + 1)))
                                              for i, n in enumerate(names)}
            row["part_voxels"] = {n: int(np.sum(truth[sel] == i + 1)) for i, n in enumerate(names)}
            if subject == "body":        # the other grouping of the girdle bones
                alt = synthetic_truth(vol, cap.options["bodies"][fi], names, bone_arc=girdle_bone_arc)
                row["acc_default_girdles_in_limbs"] = renumbered_accuracy(lab, alt, names)
                if figure and row["quality"] == "good":
                    error_figure(figure, vol, lab, m, truth, names, cap.up_vector,
                                 f"body seed {seed} frame {pose.frame}")
                    figure = None
            # timings: best of 5 (shared machine)
            t_seg, t_prev, t_rad, t_old, t_flood, t_ws = [], [], [], [], [], []
            for _ in range(5):
                t0 = time.perf_counter()
                segment(vol, det.skeleton, det.alignment, det.data, names=names, pose=pose,
                        model=est.model)
                t_seg.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                segment(vol, det.skeleton, det.alignment, det.data, names=names,
                        **SEG_METHODS["first_joint"](pose, est.model))
                t_prev.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                segment(vol, det.skeleton, det.alignment, det.data, names=names)
                t_rad.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                segment(vol, det.skeleton, det.alignment, det.data, names=names, weighting="part")
                t_old.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                plain = flood_labels(vol.data, seeds_grid, 26, "none", bbox=bbox)
                t_flood.append(time.perf_counter() - t0)
                box = _box(vol.data, bbox)
                t0 = time.perf_counter()
                m = vol.data[box]
                ws = watershed(np.zeros(m.shape, np.uint8), markers=seeds_grid[box], mask=m,
                               connectivity=3)
                t_ws.append(time.perf_counter() - t0)
            row.update(segment_ms=min(t_seg) * 1e3, segment_first_joint_ms=min(t_prev) * 1e3,
                       segment_radius_ms=min(t_rad) * 1e3,
                       segment_part_ms=min(t_old) * 1e3, flood_ms=min(t_flood) * 1e3,
                       watershed_ms=min(t_ws) * 1e3,
                       agree_watershed=float(np.mean(ws[m] == plain[box][m])))
            rows.append(row)
        log(f"segmentation {subject} seed {seed}: {sum(r['seed'] == seed for r in rows)} matched frames")
    return rows


# ----------------------------------------------------------------------------- 2. detection
STABLE_SIGMA = 0.03        # m
STABLE_TRIALS = 20
#: undecided bands tried (m): a relation is undecided when moving one of its parts this far flips it
DETECT_MARGINS = (0.0, 0.05, 0.08)
#: limits on the unexplained silhouette share (pose/support.py) compared on the development
#: seeds; the reported rule is pose/consistency.py MAX_UNEXPLAINED (``run --support``)
SUPPORT_LIMITS = (0.04, 0.06, 0.08, 0.10, 0.12)


def supported(row, limit):
    """Whether ``run --support`` keeps a matched frame (``judge_support``: no value, kept)."""
    u = row.get("unexplained")
    return u is None or u <= limit


#: the ``body`` subject's rig points nearest to what the pipeline outputs for each part (median
#: distance pipeline − point on 90 matched body frames, seeds 1–4 and 11: head `Head_tail` 4.1 cm
#: against gt.json's head 8.3; hand `*Hand_tail` 3.3 against 7.2; torso `Spine1_head` 6.3
#: against 10.1; crotch `Hips_head` 4.4 against 5.7; on 73 good frames of the detection sampler,
#: seeds 1–2: foot `*Foot_tail` 5.5 against 8.0): the head is the crown, where the hull's
#: highest thick point leaves the hull (pose/tips.py head_from_hull), the hand the hand bone's
#: end (mid-hand), the foot the foot bone's end (the ball of the foot, mid-foot), the torso
#: junction mid-chest, the crotch the pelvis' top (the legs' junction the detection compares,
#: ``detect.description_parts``, on 80 frames of the detection sampler, seeds 1–2: `Hips_head`
#: 3.9 cm median, +2.1 cm along up, against `Hips_tail` 5.4 and the dropped crotch 5.2)
BODY_PART_JOINTS = {"head": "Head_tail", "torso": "Spine1_head", "crotch": "Hips_head",
                    "hand_1": "LeftHand_tail", "hand_2": "RightHand_tail",
                    "foot_1": "LeftFoot_tail", "foot_2": "RightFoot_tail"}
#: the capsule human's pelvis centre above its hip line (synth_subjects.human_build: the pelvis
#: ellipsoid's centre 2 cm above the root, the crotch 2 cm below it), m
PELVIS_CENTRE = 0.04
#: peers (points the descriptions could compare instead, measured on the same frames):
#: the capsule human's crown above gt.json's head (its centre), 7.8 cm, and gt.json's hand
#: beyond the skeleton's branch end along the branch, 7.0 cm (pipeline_points' docstring,
#: development seeds 3–4): the pipeline's head and hands moved onto gt.json's points
HEAD_CENTRE_DROP, HAND_REACH = 0.078, 0.070


def peer_points(pose, parts):
    """The peers' points from a pose's :func:`description_parts` ``parts`` and its
    skeleton curves: ``crotch_curve`` — the crotch at the legs' junction of the skeleton curves
    (the crotch arc's end, where the legs' curves start) instead of ``detect_parts``;
    ``gt_points`` — the head moved :data:`HEAD_CENTRE_DROP` from the crown towards the torso
    and each hand :data:`HAND_REACH` on along its branch's end direction (the last 4 of the
    curve's samples), gt.json's head centre and hand (scored against gt.json's parts)."""
    curves = pose.diagnostics.get("curves") or {}
    unit = lambda v: np.asarray(v, float) / max(np.linalg.norm(v), 1e-9)  # noqa: E731
    cc = dict(parts)
    if parts.get("crotch") is not None and "crotch" in curves:
        cc["crotch"] = np.asarray(curves["crotch"][-1], float)
    gp = dict(parts)
    if parts.get("head") is not None and parts.get("torso") is not None:
        h = np.asarray(parts["head"], float)
        gp["head"] = h - HEAD_CENTRE_DROP * unit(h - np.asarray(parts["torso"], float))
    for k in ("hand_1", "hand_2"):
        c = curves.get(k)
        if parts.get(k) is not None and c is not None and len(c) >= 4:
            gp[k] = np.asarray(parts[k], float) + HAND_REACH * unit(np.subtract(c[-1], c[-4]))
    return cc, gp


#: the alternative correspondence (``pipeline_points(frame, former=True)``), reported beside: hands and
#: feet gt.json's axis ends, the crotch its hip line, the body's feet gt.json's
FORMER_JOINTS = {k: v for k, v in BODY_PART_JOINTS.items() if not k.startswith("foot")}


def pipeline_points(frame, former=False):
    """The ground-truth points that correspond to what the pipeline outputs for each part, from a
    gt.json frame: ``body`` (rig joints recorded): :data:`BODY_PART_JOINTS`; capsule human: the
    head is the crown (the end of gt.json's head segment; pipeline − crown 2.3 cm median on 37
    upright frames, against 7.8 cm to gt.json's head 8 cm below it), the torso the middle of
    the torso segment (neck base → chest: 4.8 against 11.5 cm), the hands and feet the middle
    of their last bone (mid-hand, mid-foot, as the body's: the skeleton's branch ends 7 cm
    short of gt.json's axis end, along the bone — pipeline − gt.json along the hand −7.0 cm,
    sd 3.7, across it 1.3 cm median; foot −7.2 cm; 564 good frames, seeds 3–4), the crotch
    the pelvis' centre :data:`PELVIS_CENTRE` up the body axis from gt.json's hip line (where
    the legs' and the trunk's branches meet: pipeline − gt.json +3.6 cm up the body, sd 4.4).
    ``former``: the alternative correspondence (:data:`FORMER_JOINTS`)."""
    gt, joints, seg = frame["parts"], frame.get("joints") or {}, frame.get("segments") or {}
    table = FORMER_JOINTS if former else BODY_PART_JOINTS
    if all(j in joints for j in BODY_PART_JOINTS.values()):
        return {**gt, **{k: joints[j] for k, j in table.items()}}
    out = dict(gt)
    if "head" in seg:
        out["head"] = seg["head"][1]
    for k in ("torso",) if former else ("torso", "hand_1", "hand_2", "foot_1", "foot_2"):
        if k in seg:
            out[k] = list(np.mean(np.asarray(seg[k], float), axis=0))
    if "crotch" in seg and gt.get("crotch") is not None and not former:
        s = np.asarray(seg["crotch"], float)
        axis = (s[1] - s[0]) / np.linalg.norm(s[1] - s[0])
        out["crotch"] = list(np.asarray(gt["crotch"], float) + PELVIS_CENTRE * axis)
    return out


def detection_row(pose, frame, up, rng=None):
    """Each named pose's detected value (per margin) and truth on one frame: ``truth`` on the gt
    points corresponding to the pipeline's parts (:func:`pipeline_points`), ``truth_former`` on
    the alternative correspondence, ``truth_gt`` on gt.json's parts; whether the truth is stable
    (:func:`stable_truth`), and each part's offset estimate − corresponding point (numbered
    parts paired optimally)."""
    from topopose.apps.detect import description_parts, detect, evaluate, load_library, up_frame

    gt, former = pipeline_points(frame), pipeline_points(frame, former=True)
    # the points the descriptions compare (the crotch: the legs' junction before the drop of
    # pose/anatomy.py, which the correspondence was measured on)
    parts = description_parts(pose)
    crotch_curve, gt_points = peer_points(pose, parts)
    rng = rng if rng is not None else np.random.default_rng(0)
    library, aliases = load_library()
    est = {k: np.asarray(v, float) for k, v in parts.items() if v is not None}
    for a, b in (("hand_1", "hand_2"), ("foot_1", "foot_2")):
        if a in est and b in est and (np.linalg.norm(est[a] - gt[b]) + np.linalg.norm(est[b] - gt[a])
                                      < np.linalg.norm(est[a] - gt[a]) + np.linalg.norm(est[b] - gt[b])):
            est[a], est[b] = est[b], est[a]
    det = {}
    for n, p in library.items():
        t = evaluate(p.expr, gt, up, aliases)
        det[n] = {"truth": t, "stable": t is not None and stable_truth(p.expr, gt, up, aliases, t, rng),
                  "truth_gt": evaluate(p.expr, frame["parts"], up, aliases),
                  "truth_former": evaluate(p.expr, former, up, aliases),
                  # before: the pose's parts alone (the crotch dropped below the junction)
                  "parts": evaluate(p.expr, pose.parts, up, aliases),
                  "crotch_curve": evaluate(p.expr, crotch_curve, up, aliases),
                  "gt_points": evaluate(p.expr, gt_points, up, aliases),
                  **{f"m{m:g}": detect([pose], p.expr, up=up, aliases=aliases, margin=m)[0]["value"]
                     for m in DETECT_MARGINS}}
        v = det[n]["m0"]
        if v is not None and t is not None and v != t:
            # the parts whose pipeline point, replaced by its corresponding truth point alone,
            # makes the decision right (hands and feet paired as below)
            det[n]["blame"] = [k for k in est if gt.get(k) is not None and evaluate(
                p.expr, {**est, k: np.asarray(gt[k], float)}, up, aliases) == t]
    z = up_frame(up)[2]
    off = {k: [float((v - np.asarray(gt[k])) @ z), float(np.linalg.norm(v - np.asarray(gt[k])))]
           for k, v in est.items() if gt.get(k) is not None}
    if pose.parts.get("crotch") is not None and gt.get("crotch") is not None:
        d = np.asarray(pose.parts["crotch"], float) - np.asarray(gt["crotch"], float)
        off["crotch-dropped"] = [float(d @ z), float(np.linalg.norm(d))]
    return {"detect": det, "part_offsets": off}


def detection_counts(rows, name, margin=0.0, keep=None, truth="truth", value=None):
    """TP/FP/FN/TN, undecided (margin) and missing (a part unmatched) over frames' detection rows
    (``keep(row, detect_entry)``: the frames counted; ``truth``: the truth's key; ``value``:
    the detected value's key, default the margin's)."""
    c = {"tp": 0, "fp": 0, "fn": 0, "tn": 0, "undecided": 0, "missing": 0, "truth_true": 0}
    for r in rows:
        d = r["detect"][name]
        if keep is not None and not keep(r, d):
            continue
        t, v = d[truth], d[value or f"m{margin:g}"]
        c["truth_true"] += bool(t)
        if d["m0"] is None:
            c["missing"] += 1
        elif v is None:
            c["undecided"] += 1
        else:
            c[("tp" if t else "fp") if v else ("fn" if t else "tn")] += 1
    c["precision"] = c["tp"] / (c["tp"] + c["fp"]) if c["tp"] + c["fp"] else None
    c["recall"] = c["tp"] / (c["tp"] + c["fn"]) if c["tp"] + c["fn"] else None
    return c


def error_causes(rows, name):
    """The wrong decisions (margin 0) by cause: the frame's pose is not *good* (the per-frame
    matcher), the truth is borderline (not stable under 3 cm), or neither."""
    out = {"not_good": 0, "borderline": 0, "stable_good": 0}
    for r in rows:
        d = r["detect"][name]
        if d["m0"] is None or d["m0"] == d["truth"]:
            continue
        out["not_good" if r.get("quality") != "good" else
            "borderline" if not d["stable"] else "stable_good"] += 1
    return out


def error_blame(rows, name):
    """The wrong decisions (margin 0) by the part whose pipeline point alone, replaced by its
    corresponding truth point, makes the decision right (``"none"``: no single part; several
    parts counted each), and that part's offset pipeline − truth along the capture's up axis:
    mean and median (one gross mismatch — a hand on a foot's branch, a model flipped end for
    end, offsets of 0.6–1.5 m — moves the mean of a few decisions by tens of cm;
    ``studies/detection_inverted_dev.py``)."""
    out = {}
    for r in rows:
        d = r["detect"][name]
        if "blame" not in d:
            continue
        for k in d["blame"] or ["none"]:
            b = out.setdefault(k.split("_")[0], {"n": 0, "dz": []})
            b["n"] += 1
            if k in r["part_offsets"]:
                b["dz"].append(r["part_offsets"][k][0])
    return {k: {"n": v["n"], "dz_mean": _mean(v["dz"]) if v["dz"] else None,
                "dz_median": float(np.median(v["dz"])) if v["dz"] else None}
            for k, v in out.items()}


def stable_truth(expr, parts, up, aliases, value, rng):
    """Whether the truth keeps its value when every gt part moves by N(0, 3 cm) (20 draws):
    a frame near a decision boundary (a hand at head height) is not *stable* — a few cm of
    difference between the pipeline's part and gt.json's flips it."""
    from topopose.apps.detect import evaluate

    for _ in range(STABLE_TRIALS):
        q = {k: None if v is None else np.asarray(v) + rng.normal(0, STABLE_SIGMA, 3)
             for k, v in parts.items()}
        if evaluate(expr, q, up, aliases) != value:
            return False
    return True


def _detection_rows(cap, est, rng, tags=None):
    """Detection rows of a capture's matched frames, with the quality class and the tag."""
    from topopose.batch.quality import evaluate as quality_of

    poses = [est.estimate(f) for f in cap.frames]
    quality = {fs.frame: fs.quality for fs in quality_of(cap.gt, poses, est.model).frames}
    rows = []
    for fi, p in enumerate(poses):
        body = cap.options["bodies"][fi]
        tag = getattr(body, "extra", {}).get("k")
        if tag is None and "_k" in (getattr(body, "pose", None) or {}):
            tag = BODY_TAGS[int(body.pose["_k"])]
        if tags is not None:
            tags[tag] = tags.get(tag, 0) + 1
        if p.status == "matched":
            rows.append({**detection_row(p, cap.gt["frames"][p.frame], cap.up, rng),
                         "quality": quality.get(p.frame), "tag": tag,
                         "unexplained": p.diagnostics.get("unexplained")})
    return rows, len(poses)


def bench_detection(n_frames, seeds, log):
    from topopose.frame.estimate import FrameEstimator

    out = {}
    # "acrobatic no-tip-anchor": the peer of the head tip prolonged from the torso
    # (pose/tips.py TIP_ANCHOR), the head along its branch's own end direction, 1.5 radii;
    # "acrobatic no-head-axis": the peer of the head from the hull along the body's axis
    # (pose/tips.py HEAD_AXIS), the head tip prolonged from the torso
    for kind, constraints, opts in (("upright", True, {}), ("acrobatic", False, {}),
                                    ("acrobatic no-head-axis", False, {"head_axis": False}),
                                    ("acrobatic no-tip-anchor", False, {"tip_anchor": False,
                                                                        "head_axis": False})):
        tags, frames, rows = {}, 0, []
        rng = np.random.default_rng(0)
        for seed in seeds:
            cap = capture(detection_sampler(kind.split()[0]), n_frames, seed)
            est = FrameEstimator(cap, "human", RES, constraints=constraints, support=True,
                                 **opts)
            r, n = _detection_rows(cap, est, rng, tags)
            rows += r
            frames += n
        out[kind] = {"frames": frames, "matched": len(rows), "constraints": constraints,
                     "tags": tags, "rows": rows}
        log(f"detection {kind}: {len(rows)}/{frames} matched")
    return out


def bench_body_detection(n_frames, seeds, log, **opts):
    """The named poses on the ``body`` subject (random builds), sequences drawn to contain them
    (:func:`body_detection_sampler`); ``opts``: FrameEstimator options."""
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    rows, frames, tags = [], 0, {}
    rng = np.random.default_rng(0)
    for seed in seeds:
        with body_poses(body_detection_sampler()):
            cap = synthetic_capture("body", frames=n_frames, seed=seed, noise=1, separated=True,
                                    margin=MARGIN)
        est = FrameEstimator(cap, "human", RES, support=True, **opts)
        r, n = _detection_rows(cap, est, rng, tags)
        rows += r
        frames += n
        log(f"detection body seed {seed}: {len(rows)}/{frames} matched so far")
    return {"frames": frames, "matched": len(rows), "tags": tags, "rows": rows}


# ----------------------------------------------------------------------------- 3. clustering
def bench_clustering(K, n_frames, seeds, log, figure=None):
    from topopose.apps.cluster import adjusted_rand_index, cluster_figure, cluster_poses
    from topopose.frame.estimate import FrameEstimator
    from topopose.pose.pose import Pose

    rows = []
    for seed in seeds:
        cap = capture(cluster_sampler(K), n_frames, seed)
        truth = [b.extra["k"] for b in cap.options["bodies"]]
        est = FrameEstimator(cap, "human", RES)
        poses = [est.estimate(f) for f in cap.frames]
        m = [i for i, p in enumerate(poses) if p.status == "matched"]
        rng = np.random.default_rng(seed)
        gt_poses = [Pose(f, "matched", 0.0, {k: np.asarray(v) + rng.normal(0, 0.02, 3)
                                             for k, v in cap.gt["frames"][f]["parts"].items()})
                    for f in cap.frames]
        for source, ps, idx in (("pipeline", poses, m), ("gt+2cm", gt_poses, list(range(len(poses))))):
            for auto in ("gap", "silhouette"):
                t0 = time.perf_counter()
                res = cluster_poses(ps, auto=auto)
                ms = (time.perf_counter() - t0) * 1e3
                lab = [res.labels[i] for i in idx]
                rows.append({"seed": seed, "source": source, "auto": auto, "frames": len(idx),
                             "K_true": len({truth[i] for i in idx}), "K_found": res.k,
                             "ari": adjusted_rand_index(lab, [truth[i] for i in idx]),
                             "ms": ms})
                if figure and source == "pipeline" and auto == "silhouette" and seed == seeds[0]:
                    cluster_figure(ps, res, figure)
        log(f"clustering seed {seed}: {len(m)}/{len(poses)} matched")
    return rows


# ----------------------------------------------------------------------------- report
def _mean(x):
    x = [v for v in x if v is not None]
    return float(np.mean(x)) if x else float("nan")


def segmentation_figure(path):
    """One segmented frame of the body subject (the README picture)."""
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator
    from topopose.apps.segment import segmentation_figure as fig

    cap = synthetic_capture("body", frames=3, seed=5, noise=1, separated=True, margin=MARGIN)
    est = FrameEstimator(cap, "human", RES)
    for f in cap.frames:
        pose, det = est.estimate(f, detail=True)
        if pose.status == "matched":
            fig(path, cap, f, est.model, det, up=cap.up_vector, pose=pose)
            return


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--detection-only", action="store_true",
                    help="only the pose detection (2.), written to applications_detection.{md,json}")
    ap.add_argument("--dev", action="store_true",
                    help="only the pose detection on the development seeds (capsule human 3–4, "
                         "body 1–2), to applications_detection_dev.{md,json}")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    a.detection_only = a.detection_only or a.dev
    suffix = (("_quick" if a.quick else "") + ("_detection" if a.detection_only else "")
              + ("_dev" if a.dev else ""))
    log = lambda s: print(s, flush=True)  # noqa: E731
    t0 = time.time()
    # warm the kernels (compilation is not what is measured)
    bench_segmentation(2, [99], lambda s: None)
    if a.detection_only:
        seg, clu = [], []
        # held out: capsule human seeds 1–2, body 5–7; development: 3–4 and 1–2
        hs, bs = ([3, 4], [1, 2]) if a.dev else ([1, 2], [5, 6, 7])
        det = bench_detection(30 if a.quick else 100, hs[:1] if a.quick else hs, log)
        bdet = bench_body_detection(10 if a.quick else 40, bs[-1:] if a.quick else bs, log)
    elif a.quick:
        seg = bench_segmentation(8, [2], log) + bench_segmentation(
            6, [2], log, "body", out / f"applications_segmentation_errors{suffix}.png")
        det = bench_detection(30, [1], log)
        bdet = bench_body_detection(10, [2], log)
        clu = bench_clustering(4, 30, [1], log, out / f"applications_clusters{suffix}.png")
    else:
        seg = bench_segmentation(25, [2, 3], log) + bench_segmentation(
            20, [2, 3, 4], log, "body", out / f"applications_segmentation_errors{suffix}.png")
        # the development seeds (the segmentation's parameters were chosen on them)
        for r in bench_segmentation(20, [1, 11], log, "body"):
            seg.append({**r, "subject": "body-dev"})
        det = bench_detection(100, [1, 2], log)
        bdet = bench_body_detection(40, [5, 6, 7], log)
        clu = bench_clustering(5, 60, [1, 2, 3], log, out / f"applications_clusters{suffix}.png")
    if not a.detection_only:
        segmentation_figure(out / f"applications_segmentation{suffix}.png")
    mach = machine(resolution=RES, wall_s=round(time.time() - t0, 1))
    f3 = lambda x: "–" if x is None else f"{x:.3f}"  # noqa: E731
    pr = lambda c: f"{f3(c['precision'])} / {f3(c['recall'])}"  # noqa: E731

    # ---- summaries (the JSON keeps these, not the per-frame rows)
    seg_summary = {}
    for subject in ("body", "body-dev", "human"):
        sr = [r for r in seg if r["subject"] == subject]
        for cls, rs in (("good", [r for r in sr if r["quality"] == "good"]), ("all matched", sr)):
            if rs:
                seg_summary[f"{subject} {cls}"] = {
                    "frames": len(rs), **{k: {"mean": _mean([r[f"acc_{k}"] for r in rs]),
                                              "min": float(min(r[f"acc_{k}"] for r in rs))}
                                          for k in SEG_METHODS}}
    bg = [r for r in seg if r["subject"] == "body" and r["quality"] == "good"]
    part_recall = {k: {n: sum(r[f"part_correct_{k}"][n] for r in bg)
                       / max(1, sum(r["part_voxels"][n] for r in bg)) for n in bg[0]["part_voxels"]}
                   for k in SEG_METHODS} if bg else {}
    speed = {k: float(np.median([r[k] for r in seg])) for k in
             ("segment_ms", "segment_first_joint_ms", "segment_radius_ms", "segment_part_ms",
              "flood_ms", "watershed_ms", "hull_voxels")} if seg else {}
    if seg:
        speed["ratio_watershed_over_flood"] = float(np.median([r["watershed_ms"] / r["flood_ms"] for r in seg]))
        speed["agree_watershed"] = _mean([r["agree_watershed"] for r in seg])
    sets = [(f"human {k}", d["rows"]) for k, d in det.items()] + [
        ("body", bdet["rows"])]
    pose_names = list(sets[0][1][0]["detect"]) if sets and sets[0][1] else []
    margin_counts = {label: {n: {f"{m:g}": detection_counts(rows, n, m) for m in DETECT_MARGINS}
                             for n in pose_names} for label, rows in sets}
    good = lambda r, d: r.get("quality") == "good"  # noqa: E731
    views = {"all": None, "good": good, "good_stable": lambda r, d: good(r, d) and d["stable"],
             "stable": lambda r, d: d["stable"]}
    det_summary = {label: {n: {**{v: detection_counts(rows, n, keep=k) for v, k in views.items()},
                               "causes": error_causes(rows, n),
                               "truth_gt": detection_counts(rows, n, truth="truth_gt"),
                               "truth_former": detection_counts(rows, n, truth="truth_former"),
                               "before": detection_counts(rows, n, value="parts"),
                               "crotch_curve": detection_counts(rows, n, value="crotch_curve"),
                               "gt_points": detection_counts(rows, n, truth="truth_gt",
                                                             value="gt_points"),
                               "blame": error_blame(rows, n),
                               "support": {f"{x:g}": detection_counts(
                                   rows, n, keep=lambda r, d, x=x: supported(r, x))
                                   for x in SUPPORT_LIMITS + (MAX_UNEXPLAINED,)}}
                           for n in pose_names} for label, rows in sets}
    support_cover = {label: {f"{x:g}": sum(supported(r, x) for r in rows)
                             for x in SUPPORT_LIMITS + (MAX_UNEXPLAINED,)}
                     for label, rows in sets}
    # the acrobatic set's wrong decisions by the generator's tag (inverted vs upright)
    blame_split = [(f"{label}, {t} frames", [r for r in rows if (r["tag"] == "inverted") == (t == "inverted")])
                   for label, rows in sets if label == "human acrobatic" for t in ("upright", "inverted")]
    offsets = {}
    body_rows = bdet["rows"] + [r for r in seg if r["subject"] == "body"]
    human_sets = [(f"human {k}", d["rows"]) for k, d in det.items() if k != "acrobatic"]
    if "acrobatic" in det:         # no coordinate constraints: the head is the extremity tip
        rows = det["acrobatic"]["rows"]
        human_sets += [("human acrobatic, upright frames", [r for r in rows if r["tag"] != "inverted"]),
                       ("human acrobatic, inverted frames", [r for r in rows if r["tag"] == "inverted"])]
    for label, rows in human_sets + [("body", body_rows)]:
        by = {}
        for r in rows:
            for k, (dz, dd) in r["part_offsets"].items():
                by.setdefault(k.split("_")[0], []).append((dz, dd))
        offsets[label] = {k: {"frames": len(v), "dz_mean": float(np.mean(np.asarray(v)[:, 0])),
                              "dz_sd": float(np.std(np.asarray(v)[:, 0])),
                              "dist_median": float(np.median(np.asarray(v)[:, 1])),
                              "dist_p90": float(np.percentile(np.asarray(v)[:, 1], 90))}
                          for k, v in by.items()}
    (out / f"applications{suffix}.json").write_text(json.dumps(
        {"machine": mach, "segmentation": {"accuracy": seg_summary, "body_good_part_recall": part_recall,
                                           "speed_median": speed},
         "detection": {k: {kk: v for kk, v in d.items() if kk != "rows"} for k, d in det.items()},
         "detection_body": {k: v for k, v in bdet.items() if k != "rows"},
         "detection_summary": det_summary, "detection_support_kept": support_cover,
         "max_unexplained": MAX_UNEXPLAINED,
         "detection_blame_by_tag": {label: {n: error_blame(rows, n) for n in pose_names}
                                    for label, rows in blame_split}, "detection_margins": margin_counts,
         "part_offsets": offsets, "clustering": clu}, indent=1))

    L = [f"# Applications (thesis §13.3){' — quick run' if a.quick else ''}", "",
         f"Machine: {mach['cpu']}, {mach['cores']} cores, load {mach['load_average']}, "
         f"{mach['date']}; Python {mach['python']}, NumPy {mach['numpy']}, Numba {mach['numba']}. "
         f"Wall time {mach['wall_s']} s. Produced by `benchmarks/applications.py{' --quick' if a.quick else ''}`.",
         "", "## 1. Hull segmentation by flooding (§13.3.1.1)", "",
         f"Synthetic humans (random poses, limbs ≥ 7.5 cm apart, silhouette noise 1, 8 cameras), "
         f"pipeline at {RES}³ with the `human` model. `body`: the anatomically real MakeHuman "
         "mesh, seeds 2–4 (held out: the delays, the bone weight and the limb starts were "
         "chosen on seeds 1 and 11, *body-dev* below); truth: "
         "the dominant skinning bone of the nearest posed mesh vertex, grouped into the model's "
         "arcs (`topopose.synth.labels.body_bone_arc`). `human`: the capsule subject (seeds 2–3); "
         "truth: the nearest primitive's link. Numbered limbs paired optimally. *Good*: the "
         "quality study's class (every part right). Labellings, all from the same skeleton "
         "labels: *plain* — the thesis' flooding (breadth first, 26-adjacency); *part* — the "
         "part-weighted flooding (each part starts late by 1.5 × how much thinner it is than the "
         "thickest, in BFS steps); *radius* — the same with chamfer step lengths (3, 4, 5 for "
         "face, edge, corner steps ≈ 1, √2, √3) and radii, delay 1.25; *radius + bones* — given the frame's "
         "pose, each part's own flood mixed (1 − w / w) with the distance to its bones, the "
         "model's joints placed on the skeleton curves: with limbs from their first joint (w = 0.8) a limb "
         "begins at its first joint (shoulder, hip, neck) and each part's flood covers the whole "
         "hull; with limb starts (w = 0.8) and in the default (w = 0.7, "
         "`topopose.apps.segment.LIMB_START`) the head begins half-way "
         "from the chest to the neck joint, the arm 45 % or 35 % (default) down the "
         "upper arm, the leg at the "
         "hip, and each part's flood runs only where its bones are within 3 voxels of the "
         "nearest bone (`BAND`), all parts in one kernel. The default's arm start and bone "
         "weight were re-chosen on the development seeds (38 good frames, a plateau: hand start "
         "1–1.35 × weight 0.6–0.8 all within 0.896–0.900; a start per frame from the inscribed "
         "radius along the arm's branch, 0.895–0.900: see `bone_segments`' docstring).", "",
         "| subject | frames | " + " | ".join(SEG_LABELS[k] for k in SEG_METHODS) + " |",
         "|---|---|" + "---|" * len(SEG_METHODS)]
    for key, d in seg_summary.items():
        subject, cls = key.split(" ", 1)
        L.append(f"| {subject} | {cls} ({d['frames']}) | " + " | ".join(
            f"mean {d[k]['mean']:.3f}, min {d[k]['min']:.3f}" for k in SEG_METHODS) + " |")
    if bg:
        names = list(bg[0]["part_voxels"])
        L += ["", "Where the body's errors are (good frames): share of each true part's voxels "
              "labelled right (recall), and the part's share of all voxels.", "",
              "| labelling | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        L += [f"| {SEG_LABELS[k]} | " + " | ".join(f"{part_recall[k][n]:.3f}" for n in names) + " |"
              for k in SEG_METHODS]
        L += ["| share of voxels | " + " | ".join(
            f"{sum(r['part_voxels'][n] for r in bg) / sum(sum(r['part_voxels'].values()) for r in bg):.1%}"
            for n in names) + " |", "",
              "Truth grouping: the clavicle and hip-joint bones in the trunk (above); in the "
              f"limbs (they lie on the model's torso→hand and crotch→foot arcs): default mean "
              f"{_mean([r['acc_default_girdles_in_limbs'] for r in bg]):.3f} on the same good "
              "frames. Picture (default labelling): `applications_segmentation_errors.png`."]
    if seg:
        L += ["", "Speed per frame (both subjects; median over frames of the best of 5 runs; hull "
              f"{int(speed['hull_voxels'])} voxels median):", "",
              "| step | ms |", "|---|---|",
              f"| whole segment step, default (`tp.segment` with pose and model: skeleton labels, "
              f"bones, each part's flood on its band, one kernel) | {speed['segment_ms']:.2f} |",
              f"| whole segment step, limbs from their first joint (each part's "
              f"flood over the whole hull) | {speed['segment_first_joint_ms']:.2f} |",
              f"| whole segment step, radius-weighted without bones (no pose given) | "
              f"{speed['segment_radius_ms']:.2f} |",
              f"| whole segment step, part-weighted | {speed['segment_part_ms']:.2f} |",
              f"| flooding call alone (`flood_labels`, plain, 26-adjacency) | {speed['flood_ms']:.2f} |",
              f"| peer: `skimage.segmentation.watershed` (constant image, markers, mask) | "
              f"{speed['watershed_ms']:.2f} |",
              f"| ratio peer / ours (plain flooding) | {speed['ratio_watershed_over_flood']:.1f} |", "",
              f"Voxels on which the peer and our plain flooding agree: mean "
              f"{speed['agree_watershed']:.4f} (they differ only on ties).", ""]
    L += ["## 2. Specific pose detection (§13.3.2.1)", ""]
    if a.dev:
        L += ["**Development seeds** (`--dev`): capsule human seeds 3–4, body seeds 1–2 (what "
              "the text below calls held out is the default run's; these are the seeds the "
              "choices were made on).", ""]
    L += [
          "Truth = the same description evaluated on the ground-truth points that correspond to "
          "what the pipeline outputs for each part (`pipeline_points`: the pipeline's head is the "
          "crown, placed from the hull by `pose/tips.py` `head_from_hull`; body: head → rig point "
          "`Head_tail` (crown), hands → `*Hand_tail` (mid-hand), feet → `*Foot_tail` "
          "(mid-foot), torso → `Spine1_head` (mid-chest), crotch → `Hips_head`; capsule human: "
          "head → the crown (end of gt.json's head segment), torso → the middle of its torso "
          "segment, hands and feet → the middle of their last bone (mid-hand, mid-foot: the "
          "skeleton's branch ends 7 cm short of gt.json's axis end, along the bone), crotch → "
          "the pelvis' centre, 4 cm up the body axis from gt.json's hip line; offsets pipeline − "
          "point below; the hand, foot and crotch correspondences were measured on the "
          "development seeds 3–4 (capsule human) and 1–2 (body), not on the seeds reported). "
          "*human upright / acrobatic*: "
          "capsule human, sequences drawn to contain the named poses (generator tags below), 2 "
          "seeds × 100 frames. *body*: the MakeHuman subject (random builds), sequences drawn "
          "to contain the named poses (`body_detection_sampler`: hands up in a V, one hand up, "
          "arms spread, the body's own random poses; tags below), seeds 5–7 × 40 frames "
          "(held out: the correspondences were measured on the segmentation's seeds 1–4 and 11, "
          "the sampler set on seeds 1–2). "
          "Counted on matched frames whose value is decided (*missing*: a part the description "
          "needs is unmatched, left out). *Good*: the quality study's class (every part within "
          "tolerance), so the detector's own quality is visible apart from the per-frame "
          "matcher's misplaced parts. *Stable*: the truth keeps its value when every gt part "
          "moves by N(0, 3 cm) (20 draws); the others sit at a decision boundary (a hand at head "
          "height). Wrong decisions by cause: the frame is not good (matcher) / good but the "
          "truth is borderline / good and stable. The headline is *P / R, all* (margin 0, "
          "every decided matched frame); *P / R, stable truth* scores the borderline frames "
          "apart (as PASCAL VOC leaves its *difficult* objects out), an extra view, not the "
          "figure; *P / R, alternative truth*: all frames against the alternative correspondence "
          "(hands and feet gt.json's axis ends, the crotch its hip line, the body's feet "
          "gt.json's).", ""]
    for kind, d in det.items():
        L.append(f"*human {kind}* ({'model constraints on' if d['constraints'] else 'no coordinate constraints (--no-constraints)'}): "
                 f"{d['matched']} matched of {d['frames']} frames; generator tags {d['tags']}.")
    L.append(f"*body*: {bdet['matched']} matched of {bdet['frames']} frames; generator tags "
             f"{bdet.get('tags')}.")
    L.append("Peers (same frames): *human acrobatic no-head-axis* — the head not placed from the "
             "hull along the body's axis (`FrameEstimator(head_axis=False)`, "
             "`pose/tips.py` `HEAD_AXIS`, on by default without coordinate constraints); "
             "*dropped crotch* (column): the descriptions on the pose's parts alone, whose crotch "
             "`pose/anatomy.py` `CROTCH_DROP` drops 0.35 × the hull's radius below the legs' "
             "junction (for the matching quality of flexed hips) — 4 cm below the pelvis' "
             "centre on the development seeds, out of the hands' R_b ball in wide-spread arms; "
             "*junction*: the points `topopose.apps.detect.description_parts` gives, the junction "
             "before the drop (recorded in `diagnostics[\"detect_parts\"]`), the point the "
             "pelvis correspondence was measured on.")
    L += ["", "| subject | pose | truth true / matched | missing | precision / recall, all | "
          "good frames | P / R, good | good, stable frames | P / R, good and stable | "
          "wrong: not good / borderline / stable | stable-truth frames | P / R, stable truth "
          "(extra) | P / R, alternative truth | P / R, all: dropped crotch ← junction |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, rows in sets:
        for n in pose_names:
            c = det_summary[label][n]
            ng = sum(c["good"][k] for k in ("tp", "fp", "fn", "tn"))
            ns = sum(c["good_stable"][k] for k in ("tp", "fp", "fn", "tn"))
            e = c["causes"]
            L.append(f"| {label} | {n} | {c['all']['truth_true']} / {len(rows)} | "
                     f"{c['all']['missing']} | {pr(c['all'])} | {ng} | {pr(c['good'])} | {ns} | "
                     f"{pr(c['good_stable'])} | {e['not_good']} / {e['borderline']} / {e['stable_good']} | "
                     f"{sum(c['stable'][k] for k in ('tp', 'fp', 'fn', 'tn'))} | {pr(c['stable'])} | "
                     f"{pr(c['truth_former'])} | {pr(c['before'])} ← {pr(c['all'])} |")
    lim = f"{MAX_UNEXPLAINED:g}"
    L += ["", f"**On the frames the silhouette support accepts** (`topopose run --support`, "
          f"`run(support_test=True)`, `pose/consistency.py` `judge_support`): a matched frame is "
          f"kept when the share of a camera's silhouette the placed model leaves unexplained "
          f"(`pose/support.py`, the largest over the cameras) is at most {lim} "
          f"(`MAX_UNEXPLAINED`, chosen on the synthetic 4-camera walks' development seeds 41–58 "
          f"of `benchmarks/consistency.py`, not on these sequences), on top of the estimator's "
          f"default confidence gate (on; off without coordinate constraints, *human acrobatic*). "
          f"Kept: frames "
          f"the rule keeps of the matched frames (coverage). The other limits are a sweep "
          f"(P / R, kept) — a limit is chosen from it on the development seeds (`--dev`) only.", "",
          "| subject | pose | P / R, all matched | kept / matched | P / R, support ≤ " + lim
          + " | " + " | ".join(f"≤ {x:g}: kept, P / R" for x in SUPPORT_LIMITS) + " |",
          "|---|---|---|---|---|" + "---|" * len(SUPPORT_LIMITS)]
    for label, rows in sets:
        for n in pose_names:
            c = det_summary[label][n]
            L.append(f"| {label} | {n} | {pr(c['all'])} | {support_cover[label][lim]} / "
                     f"{len(rows)} | {pr(c['support'][lim])} | " + " | ".join(
                         f"{support_cover[label][f'{x:g}']}, {pr(c['support'][f'{x:g}'])}"
                         for x in SUPPORT_LIMITS) + " |")
    L += ["", "Which point makes each wrong decision (margin 0, all matched frames): the part "
          "whose pipeline point alone, replaced by its corresponding truth point, makes the "
          "decision right (*none*: no single part does; a decision two parts can each fix "
          "counts for both), with that part's mean offset pipeline − truth along the up axis "
          "over those decisions, mean / median (one gross mismatch, a hand on a foot's branch "
          "or a model flipped end for end, moves the mean by tens of cm). *human acrobatic* is "
          "also split by the generator's tag (*inverted* / the *upright* random frames). Offset "
          "row *crotch-dropped* below: the pose's own crotch (dropped) against the "
          "same truth point.", "",
          "| subject | pose | wrong decisions by part (n, vertical offset m: mean / median) |",
          "|---|---|---|"]
    for label, rows in sets + blame_split:
        for n in pose_names:
            b = det_summary[label][n]["blame"] if label in det_summary else error_blame(rows, n)
            if b:
                L.append(f"| {label} | {n} | " + ", ".join(
                    f"{k} {v['n']}" + ("" if v["dz_mean"] is None else
                                       f" ({v['dz_mean']:+.3f} / {v['dz_median']:+.3f})")
                    for k, v in sorted(b.items(), key=lambda kv: -kv[1]["n"])) + " |")
    L += ["", "*Definitions.* gt.json's head is the crown minus the head's radius (the head's "
          "centre), its hands the fingertips minus the hand's radius, its torso the neck base, "
          "its crotch the hip centre: not the points the pipeline outputs. The truth on gt.json's "
          "parts instead gives, on all matched frames (P / R): " + "; ".join(
              f"{label} {n} {pr(det_summary[label][n]['truth_gt'])}" for label, _ in sets
              for n in pose_names if det_summary[label][n]["truth_gt"]["truth_true"]) + "."]
    L += ["", "**Other points, measured.** P / R, all matched frames. *Crotch at the "
          "curves' junction*: the crotch the legs' skeleton curves start from (the crotch arc's "
          "end) instead of `detect_parts`' junction, truth as above. *gt.json's points*: the "
          "truth on gt.json's parts (head centre, fingertips minus the hand's radius, neck base, "
          "hip centre), the pipeline's head moved "
          f"{HEAD_CENTRE_DROP * 100:.1f} cm from the crown towards the torso and each hand "
          f"{HAND_REACH * 100:.1f} cm on along its branch (`peer_points`; the capsule human's "
          "offsets, development seeds), torso and crotch as now; beside it the same truth on "
          "the points as now.", "",
          "| subject | pose | P / R, now | crotch at the curves' junction | gt.json's truth, "
          "points moved onto gt.json's | gt.json's truth, points as now |", "|---|---|---|---|---|---|"]
    for label, _rows in sets:
        for n in pose_names:
            c = det_summary[label][n]
            if c["all"]["truth_true"] or c["truth_gt"]["truth_true"]:
                L.append(f"| {label} | {n} | {pr(c['all'])} | {pr(c['crotch_curve'])} | "
                         f"{pr(c['gt_points'])} | {pr(c['truth_gt'])} |")
    L += ["", "**Undecided band.** `detect(..., margin=m)` (CLI `--margin`) leaves a relation "
          "undecided (null) when moving one of its parts by m along one axis flips it (Kleene "
          "logic for and/or/not). Truth: the description on the corresponding points, no band; undecided "
          "and missing frames are left out of precision and recall, their share is given.", "",
          "| subject | pose | margin (m) | decided / matched | undecided | missing | TP | FP | FN | "
          "precision | recall |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, rows in sets:
        for n, per_margin in margin_counts[label].items():
            for m in DETECT_MARGINS:
                c = per_margin[f"{m:g}"]
                dec = c["tp"] + c["fp"] + c["fn"] + c["tn"]
                L.append(f"| {label} | {n} | {m:g} | {dec} / {len(rows)} | "
                         f"{c['undecided'] / max(1, len(rows)):.0%} | "
                         f"{c['missing'] / max(1, len(rows)):.0%} | {c['tp']} | {c['fp']} | "
                         f"{c['fn']} | {f3(c['precision'])} | {f3(c['recall'])} |")
    L += ["", f"Where the pipeline puts a part vs the corresponding ground-truth point (matched frames; up: the capture's up "
          "axis — in inverted frames + is towards the feet; hands and feet paired optimally): "
          "the expressions compare these points. *human acrobatic* runs without coordinate "
          "constraints, so without the head from the hull along up (`head_from_hull`): its head "
          "comes from the hull along the body's own axis crotch → torso (`head_along_axis`, "
          "`HEAD_AXIS`: the thick point farthest along it, prolonged from the torso to the "
          "hull's border); *human acrobatic no-head-axis* is its peer, the head branch's "
          "extremity tip (`extremity_tips`), prolonged from the torso's data vertex through "
          "the branch end to the hull's border, at most 3 inscribed radii (`TIP_ANCHOR`); "
          "*human acrobatic no-tip-anchor* the tip along the branch's own end direction, at "
          "most 1.5 radii (`FrameEstimator(tip_anchor=False, head_axis=False)`).", "",
          "| subject | part | frames | vertical offset mean (m) | sd | distance median (m) | p90 |",
          "|---|---|---|---|---|---|---|"]
    for label, by in offsets.items():
        for k, v in by.items():
            L.append(f"| {label} | {k} | {v['frames']} | {v['dz_mean']:+.3f} | {v['dz_sd']:.3f} | "
                     f"{v['dist_median']:.3f} | {v['dist_p90']:.3f} |")
    L += ["", "## 3. Pose clustering (§13.3.2.2)", "",
          f"K known base poses ({', '.join(['standing', 'hands up', 'arms spread', 'kick', 'squat', 'star'][:5])}), each frame a base pose with every joint angle jittered by ±5°, random "
          "place and heading. Similarity: Jaccard of the R_b relation sets, best over the "
          "renumberings of hands and feet; average linkage.", "",
          "| source | auto rule | runs | frames | ARI mean (min) | K found − K true |", "|---|---|---|---|---|---|"]
    for source in ("pipeline", "gt+2cm"):
        for auto in ("gap", "silhouette"):
            rs = [r for r in clu if r["source"] == source and r["auto"] == auto]
            if rs:
                L.append(f"| {source} | {auto} | {len(rs)} | {int(np.mean([r['frames'] for r in rs]))} | "
                         f"{_mean([r['ari'] for r in rs]):.3f} ({min(r['ari'] for r in rs):.3f}) | "
                         + ", ".join(f"{r['K_found'] - r['K_true']:+d}" for r in rs) + " |")
    (out / f"applications{suffix}.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
