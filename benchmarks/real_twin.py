"""The real recording's synthetic twin: how much of its error is ours, how much the reference's,
and how much the four cameras'.

    python benchmarks/real_twin.py [RECORDING] [--out DIR] [--work DIR] [--frames N]
                                   [--noise 2] [--setups 4,4d,6,8] [--seeds 0,1,2] [--quick]

RECORDING (default ``benchmarks/data/pose2sim_balancing/``, see ``benchmarks/real.py``): its
``Calib.toml`` and ``reference/pose2sim_3d.trc`` are read; its videos are not.

Against Pose2Sim's 3D result the real recording mixes three errors: ours, the reference's own
(triangulated OpenPose keypoints: their noise, and a marker convention that is not the
anatomical joints'), and the four cameras' (a 4-view hull's phantom volume). The twin takes
them apart. The anatomically real ``body`` subject (the MakeHuman rig of
:mod:`topopose.synth.body`) is built to Pose2Sim's bone lengths (:func:`fit_build`) and
posed, frame by frame, to Pose2Sim's markers (:func:`fit_pose`: inverse kinematics over the
capsule human's joint angles and the body's placement, least squares, warm-started from the
previous frame); its silhouettes are rendered exactly through the recording's own four
cameras (the calibration at the ``person`` masks' half size, 544×960; ``--noise`` as
:func:`topopose.synth.capture.add_noise`, over ``--seeds``), and the pipeline runs on them as
``benchmarks/real_motion.py`` runs the recording (:func:`real_motion.run_capture`: 100³, AHA
threshold and confidence gate off, then the motion stage of ``topopose run``). Set-ups
(:data:`SETUPS`): ``4`` the recording's cameras; ``4d`` the same with silhouettes dilated 3 px
(`tracking.py`'s model of MediaPipe's fatter masks); ``6`` and ``8``: two or all four of them also
turned by 45° about the vertical through the subject (the same lenses, distances and
heights; more views of the same motion).

Figures, scored as ``real_motion.py`` scores the recording (:func:`real_motion.score`: the
exported TRC read back, our side names, 14 joints — head, neck, shoulders, elbows, wrists,
hips, knees, ankles; per frame the mean over the joints, median over the frames, cm):

* **the twin's truth against Pose2Sim** (:func:`truth_vs_reference`): what a perfect
  rigid-bone skeleton of the rig's convention scores on the real recording — the inverse
  kinematics' residual, Pose2Sim's own noise and the two conventions' difference;
* **ours against the twin's truth** (its rig points under Pose2Sim's names, :data:`IK_MARKERS`;
  Head = the crown): our error on the recording's poses seen by its cameras, with no
  reference noise, per set-up;
* **ours on the twin against Pose2Sim**, comparable with ``real_motion.py``'s figure on the
  real recording.

Writes ``real_twin.md`` / ``.json`` and ``real_twin.png`` (each set-up's worst frames: our
skeleton beside the truth's and Pose2Sim's, front and side).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
DEFAULT = HERE / "data" / "pose2sim_balancing"

# rig point → Pose2Sim marker, and its weight in the inverse kinematics (tips and the head top
# are surface points of uncertain convention: half weight)
IK_MARKERS = [("Neck_head", "Neck", 1.0), ("crown", "Head", 0.5)] + [
    (f"{S}{bone}_head", f"{c}{m}", 1.0) for S, c in (("Left", "L"), ("Right", "R"))
    for bone, m in (("Arm", "Shoulder"), ("ForeArm", "Elbow"), ("Hand", "Wrist"),
                    ("UpLeg", "Hip"), ("Leg", "Knee"), ("Foot", "Ankle"))] + [
    ("toe_l", "LBigToe", 0.5), ("toe_r", "RBigToe", 0.5)]
# the joint angles the inverse kinematics fits (degrees; the others stay 0)
ANGLES = (["spine_flex", "spine_side", "spine_twist", "neck_flex", "neck_side"]
          + [f"{k}_{s}" for s in "lr" for k in ("sh_flex", "sh_abd", "sh_rot", "elbow",
                                                 "hip_flex", "hip_abd", "hip_rot", "knee",
                                                 "ankle")])
REG = 0.0005        # m per degree: a joint angle's pull towards 0 (the unobservable twists)
# Pose2Sim's 14 joints of real_motion.py: ours → the rig's (twin truth)
P2S_JOINTS = ["Head", "Neck"] + [f"{c}{m}" for c in "LR" for m in
                                 ("Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle")]


def _rig_points(r, A, t, names):
    """World-free (body frame) positions of rig points: bone heads and tip vertices."""
    out = []
    for n in names:
        if n in r.tips:
            vi = r.tips[n]
            b, w = r.skin_bones[vi], r.skin_weights[vi]
            out.append(np.einsum("k,ki->i", w, np.einsum("kij,j->ki", A[b], r.vertices[vi])
                                 + t[b]))
        else:
            i = r.index(n[:-5])
            out.append(A[i] @ r.heads[i] + t[i])
    return np.array(out)


class Poser:
    """The body's rig points for a pose dict, a build and a placement (fast: no skinning of the
    whole mesh; the build's height scale computed once)."""

    def __init__(self, build):
        from topopose.synth import body as sb
        self.sb, self.r, self.build = sb, sb.rig(), build
        self.S = sb._scales(self.r, build)
        self.scale = sb.bone_transforms(None, build)[2]
        self.names = [m[0] for m in IK_MARKERS]

    def points(self, pose, R=np.eye(3), t=np.zeros(3), names=None):
        from topopose.synth.subjects import HUMAN_DEFAULT

        sb, r = self.sb, self.r
        F = sb._frames({**HUMAN_DEFAULT, **pose})
        A = np.stack([F[n] for n in r.names]) @ r.neutral @ self.S
        A, tt = sb._fk(r, A)
        P = _rig_points(r, A * self.scale, tt * self.scale, names or self.names)
        return P @ np.asarray(R).T + t


def reference_lengths(ref) -> dict:
    """Pose2Sim's bone lengths (m, median over frames, left and right averaged) and widths."""
    def med(a, b):
        return float(np.median(np.linalg.norm(ref[a] - ref[b], axis=1)))

    two = lambda a, b: 0.5 * (med("L" + a, "L" + b) + med("R" + a, "R" + b))  # noqa: E731
    mid = 0.5 * (ref["LHip"] + ref["RHip"])
    return {"upper_arm": two("Shoulder", "Elbow"), "forearm": two("Elbow", "Wrist"),
            "thigh": two("Hip", "Knee"), "shank": two("Knee", "Ankle"),
            "trunk": float(np.median(np.linalg.norm(ref["Neck"] - mid, axis=1))),
            "shoulders": med("LShoulder", "RShoulder"), "hips": med("LHip", "RHip")}


def _rest_lengths(build) -> dict:
    p = Poser(build)
    names = ["LeftArm_head", "LeftForeArm_head", "LeftHand_head", "LeftUpLeg_head",
             "LeftLeg_head", "LeftFoot_head", "Neck_head", "RightArm_head", "RightUpLeg_head"]
    X = dict(zip(names, p.points({}, names=names)))
    d = lambda a, b: float(np.linalg.norm(X[a] - X[b]))  # noqa: E731
    mid = 0.5 * (X["LeftUpLeg_head"] + X["RightUpLeg_head"])
    return {"upper_arm": d("LeftArm_head", "LeftForeArm_head"),
            "forearm": d("LeftForeArm_head", "LeftHand_head"),
            "thigh": d("LeftUpLeg_head", "LeftLeg_head"), "shank": d("LeftLeg_head", "LeftFoot_head"),
            "trunk": float(np.linalg.norm(X["Neck_head"] - mid)),
            "shoulders": d("LeftArm_head", "RightArm_head"),
            "hips": d("LeftUpLeg_head", "RightUpLeg_head")}


def fit_build(ref) -> tuple[dict, dict]:
    """The body's build (height, leg, arm, torso factors; average girths) whose rest bone
    lengths are Pose2Sim's (least squares over upper arm, forearm, thigh, shank, trunk);
    returns (build, {bone: (twin, Pose2Sim)})."""
    from topopose.synth.body import BUILDS

    target = reference_lengths(ref)
    keys = ("upper_arm", "forearm", "thigh", "shank", "trunk")

    def build_of(x):
        return {**BUILDS["average"], "height": x[0], "leg": x[1], "arm": x[2], "torso": x[3]}

    def res(x):
        L = _rest_lengths(build_of(x))
        return [L[k] - target[k] for k in keys]

    sol = least_squares(res, [1.75, 1.0, 1.0, 1.0], bounds=([1.3, 0.8, 0.8, 0.8],
                                                            [2.1, 1.2, 1.2, 1.2]))
    b = build_of(sol.x)
    L = _rest_lengths(b)
    return b, {k: (round(L[k], 3), round(target[k], 3)) for k in target}


def _body_frame(g) -> np.ndarray:
    """Pose2Sim's body frame of one frame: columns forward, left, up (body x, y, z)."""
    up = g["Neck"] - 0.5 * (g["LHip"] + g["RHip"])
    up /= np.linalg.norm(up)
    left = g["LHip"] - g["RHip"] + g["LShoulder"] - g["RShoulder"]
    left -= up * (left @ up)
    left /= np.linalg.norm(left)
    return np.column_stack([np.cross(left, up), left, up])


def fit_pose(poser, g, start=None):
    """Joint angles and placement (R, t) putting the rig's points on one frame's markers ``g``
    (Pose2Sim marker → (3,)); ``start``: the previous frame's solution vector. Returns
    (pose dict, R, t, solution vector, rms residual of the markers in m)."""
    target = np.array([g[m] for _, m, _ in IK_MARKERS])
    w = np.array([x for _, _, x in IK_MARKERS])[:, None]
    if start is None:
        R0 = _body_frame(g)
        hip0 = np.mean(poser.points({}, names=["LeftUpLeg_head", "RightUpLeg_head"]), axis=0)
        t0 = 0.5 * (g["LHip"] + g["RHip"]) - R0 @ hip0
        start = np.concatenate([Rotation.from_matrix(R0).as_rotvec(), t0, np.zeros(len(ANGLES))])

    def unpack(x):
        return (dict(zip(ANGLES, x[6:])), Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6])

    def res(x):
        pose, R, t = unpack(x)
        return np.concatenate([((poser.points(pose, R, t) - target) * w).ravel(), REG * x[6:]])

    sol = least_squares(res, start, x_scale=np.r_[np.ones(6) * 0.1, np.ones(len(ANGLES)) * 10.0],
                        max_nfev=60 * len(start))
    pose, R, t = unpack(sol.x)
    d = np.linalg.norm(poser.points(pose, R, t) - target, axis=1)
    return pose, R, t, sol.x, float(np.sqrt(np.mean(d ** 2)))


def twin_bodies(ref, frames: int):
    """The twin: build fitted to Pose2Sim's bone lengths, each frame posed to its markers.
    Returns (build, {bone: (twin, Pose2Sim)}, posed :class:`MeshBody` list, rms residuals m)."""
    from topopose.synth.body import pose_body

    build, lengths = fit_build(ref)
    poser, x, bodies, rms = Poser(build), None, [], []
    for i in range(frames):
        pose, R, t, x, r = fit_pose(poser, markers_of(ref, i), x)
        bodies.append(pose_body(pose, build).transformed(R, t))
        rms.append(r)
    return build, lengths, bodies, np.array(rms)


def twin_reference(bodies) -> dict:
    """The twin's truth under Pose2Sim's marker names (as :func:`real.read_trc`): marker →
    (frames, 3), the rig points of :data:`IK_MARKERS`."""
    return {m: np.array([b.joints[rp] for b in bodies]) for rp, m, _ in IK_MARKERS}


def twin_cameras(rec: Path, setup: str, centre) -> list:
    """The recording's cameras at the ``person`` masks' half size, and the set-up's turned
    cameras (:data:`SETUPS`): the same ones turned by 45° about the vertical through ``centre``
    (the same lenses, distances and heights)."""
    from topopose.capture.background import scaled_camera
    from topopose.capture.calibration import read_calibration
    from topopose.geometry.camera import Camera

    cams = [scaled_camera(c, 0.5) for c in read_calibration(rec / "Calib.toml")]
    Rz = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    c = np.asarray(centre, float)
    for cam in [cams[k] for k in SETUPS[setup][1]]:
        # the camera carried by Rz about c: x_cam = R (Rzᵀ (x − c) + c) + t
        R = cam.R @ Rz.T
        t = cam.translation + cam.R @ (c - Rz.T @ c)
        cams.append(Camera(cam.name + "_45", cam.size, cam.matrix, cam.distortions,
                           Rotation.from_matrix(R).as_rotvec(), t, cam.fisheye))
    return cams


# set-up → (silhouette dilation px, the recording's cameras also turned by 45°, title); the
# recording's azimuths are −53°, 15°, 145°, −159°: "6" adds 60° and −114°
SETUPS = {"4": (0, (), "the recording's 4 cameras"),
          "4d": (3, (), "the recording's 4 cameras, silhouettes dilated 3 px (`tracking.py`'s "
                        "4pd, its model of the real masks' fatter hull)"),
          "6": (0, (1, 3), "the 4 cameras and 2 of them turned by 45°"),
          "8": (0, (0, 1, 2, 3), "the 4 cameras and the same 4 turned by 45°")}


def twin_capture(bodies, cams, noise: int, dilate: int, fps: float, seed: int = 0):
    """The in-memory capture of the twin's exact silhouettes (:func:`~topopose.capture.
    synth_body.MeshBody.render`), ``noise`` as :func:`~topopose.synth.capture.add_noise`
    (its random state from ``seed``), dilated by ``dilate`` px."""
    import cv2

    from topopose.capture.capture import Capture
    from topopose.synth.capture import add_noise
    from topopose.synth.geometry import ray_table

    tables = [ray_table(c) for c in cams]
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate + 1,) * 2) if dilate else None
    names, masks = [f"{i:06d}" for i in range(len(bodies))], {}
    for fi, (name, body) in enumerate(zip(names, bodies)):
        ms = []
        for ci, (cam, tab) in enumerate(zip(cams, tables)):
            m = body.render(cam, tab)
            if noise:
                m = add_noise(m, noise, np.random.default_rng([seed, fi, ci, 7]))
            if ker is not None:
                m = cv2.dilate(m.astype(np.uint8), ker) > 0
            ms.append(m)
        masks[name] = ms
    return Capture(cams, names, None, "+z", "m", float(fps), None, {}, masks)


def mask_overlap(rec: Path, bodies, cams, frames=(0, 20, 50, 80, 95)) -> dict | None:
    """How alike the twin's silhouettes and the real ones are: per frame of ``frames``, the
    intersection over union of the twin's exact silhouette (no noise) and MediaPipe's
    ``person`` mask of the same camera (area-averaged to the half size), one per camera;
    None without MediaPipe."""
    import importlib.util

    import cv2

    from real import person_capture

    if importlib.util.find_spec("mediapipe") is None or not (rec / "videos").is_dir():
        return None
    frames = [f for f in frames if f < len(bodies)]
    twin = twin_capture([bodies[f] for f in frames], cams, noise=0, dilate=0, fps=1.0)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = person_capture(rec, Path(tmp) / "capture", ["scale = 0.5"])
        out = {}
        for k, f in enumerate(frames):
            row = []
            for ci, real in enumerate(cap.silhouettes(cap.frames[f])):
                m = twin.masks[twin.frames[k]][ci]
                r = cv2.resize(np.asarray(real, np.float32), m.shape[::-1],
                               interpolation=cv2.INTER_AREA) > 0.5
                row.append(round(float((m & r).sum() / max((m | r).sum(), 1)), 2))
            out[int(f)] = row
    return out


def markers_of(ref: dict, i: int) -> dict:
    """Frame i of a marker dict as exported markers (our TRC names are Pose2Sim's)."""
    return {k: v[i] for k, v in ref.items()}


def truth_vs_reference(twin: dict, ref: dict, n: int) -> dict:
    """The twin's truth scored as a skeleton against Pose2Sim (``real_motion.joint_errors``):
    what a perfect skeleton of the rig's convention scores on the recording."""
    from real_motion import joint_errors, mpjpe

    return mpjpe([joint_errors(markers_of(twin, i), ref, i) for i in range(n)])


def one_setup(setup, bodies, twin, ref, rec, noise, fps, centre, work: Path, seed=0) -> dict:
    """Render, run (as real_motion.py), score against the twin's truth and against Pose2Sim."""
    from real_motion import run_capture, score

    dilate = SETUPS[setup][0]
    cams = twin_cameras(rec, setup, centre)
    t0 = time.perf_counter()
    cap = twin_capture(bodies, cams, noise, dilate, fps, seed)
    t_render = time.perf_counter() - t0
    work.mkdir(parents=True, exist_ok=True)
    raw, motion, cap, model, trc, secs = run_capture(cap, work)
    vs_truth, markers, right = score(raw, motion.poses, trc, twin, model)
    vs_p2s, _m, right_p2s = score(raw, motion.poses, trc, ref, model)
    fat = [p.diagnostics["hull_litres"] / p.diagnostics["height"] ** 3 for p in raw
           if p.diagnostics.get("height")]
    return {"setup": setup, "seed": seed, "cameras": len(cams), "dilate_px": dilate, "noise": noise,
            "render_s": round(t_render, 2), **secs,
            "hull_fatness": round(float(np.median(fat)), 2) if fat else None,
            "vs_truth": vs_truth, "vs_pose2sim": vs_p2s,
            "right_vs_truth": right, "right_vs_pose2sim": right_p2s,
            "_markers": markers, "_poses": motion.poses}


def worst_picture(path, rows, twin, ref, k=4):
    """Per set-up, the ``k`` frames with the largest error against the twin's truth: ours
    (red) beside the twin's truth (black) and Pose2Sim (blue), front and side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bones = [("Head", "Neck"), ("Neck", "LShoulder"), ("Neck", "RShoulder"),
             ("LShoulder", "LElbow"), ("LElbow", "LWrist"), ("RShoulder", "RElbow"),
             ("RElbow", "RWrist"), ("Neck", "LHip"), ("Neck", "RHip"), ("LHip", "RHip"),
             ("LHip", "LKnee"), ("LKnee", "LAnkle"), ("RHip", "RKnee"), ("RKnee", "RAnkle")]
    fig, axes = plt.subplots(len(rows), 2 * k, figsize=(2.2 * 2 * k, 3.6 * len(rows)),
                             squeeze=False)
    for r, row in enumerate(rows):
        per = row["vs_truth"]["all"]["mpjpe_named"]["per_frame"]
        order = np.argsort(per)[::-1][:k]
        for j, i in enumerate(order):
            fwd = _body_frame(markers_of(ref, i))
            for v, (ax, h) in enumerate(((axes[r, 2 * j], 1), (axes[r, 2 * j + 1], 0))):
                for pts, col in ((markers_of(twin, i), "k"), (markers_of(ref, i), "tab:blue"),
                                 (row["_markers"][i], "tab:red")):
                    for a, b in bones:
                        pa, pb = pts.get(a), pts.get(b)
                        if pa is None or pb is None or np.isnan(pa).any() or np.isnan(pb).any():
                            continue
                        P = np.array([pa, pb]) @ fwd
                        ax.plot(P[:, h], P[:, 2], color=col, lw=1.2)
                ax.set_aspect("equal")
                ax.set_xticks([])
                ax.set_yticks([])
                ax.set_title(f"{row['setup']}: frame {i}, {100 * per[i]:.0f} cm"
                             + (" (side)" if h == 0 else ""), fontsize=7)
    fig.suptitle("The twin's worst frames: ours (red), the twin's truth (black), Pose2Sim "
                 "(blue); front and side views in Pose2Sim's body frame", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _cm(x):
    return "–" if x is None else f"{100 * x:.1f}"


def _over_seeds(rows, key, label) -> list:
    """Each seed's MPJPE (m) of ``rows`` (one set-up) against ``key`` on frames ``label``."""
    return [r[key][label]["mpjpe_named"]["mpjpe"] for r in rows]


def _spread(v) -> str:
    v = [x for x in v if x is not None]
    return "–" if not v else f"**{_cm(float(np.mean(v)))}** ({_cm(min(v))}–{_cm(max(v))})"


def report(doc) -> str:
    from _machine import machine_line

    J = ("Head", "Neck", "shoulder", "elbow", "wrist", "hip", "knee", "ankle")
    tv = doc["truth_vs_pose2sim"]
    by = {}
    for r in doc["setups"]:
        by.setdefault(r["setup"], []).append(r)
    out = ["# The real recording's synthetic twin", "",
           machine_line(doc["machine"]) + " Written by `benchmarks/real_twin.py`.", "",
           "The anatomically real `body`, built to Pose2Sim's bone lengths (twin / Pose2Sim, "
           "m: " + ", ".join(f"{k} {a} / {b}" for k, (a, b) in doc["lengths"].items())
           + f") and posed to Pose2Sim's markers frame by frame (inverse kinematics; rms "
           f"residual over the {len(IK_MARKERS)} markers {_cm(doc['ik_rms_median'])} cm median, "
           f"{_cm(doc['ik_rms_p90'])} cm p90); {doc['frames']} frames at {doc['fps']:g} "
           f"frames/s, silhouettes rendered exactly through the cameras at 544×960 (noise "
           f"{doc['noise']}, seeds {', '.join(map(str, doc['seeds']))}), the pipeline as "
           "`real_motion.py` (100³, gates off, then the motion stage of `topopose run`). "
           "MPJPE: median over frames of the per-frame mean over the 14 joints (Head = the "
           "crown), cm; *right* frames: the per-frame head, hands and feet within 0.15 m of "
           "the truth (of Pose2Sim for the columns against it).", "",
           ("The twin's silhouettes against MediaPipe's real `person` masks (intersection "
            "over union per camera, no noise): " + "; ".join(
                f"frame {f}: " + ", ".join(map(str, v)) for f, v in doc["mask_iou"].items())
            + "." if doc.get("mask_iou") else "MediaPipe not installed: the twin's silhouettes "
            "were not compared with the real masks."), "",
           "## A perfect skeleton of the rig's convention against Pose2Sim", "",
           f"The twin's truth against Pose2Sim: MPJPE **{_cm(tv['mpjpe'])} cm** (p90 "
           f"{_cm(tv['mpjpe_p90'])}): what a rigid-bone, symmetric skeleton of the rig's joint "
           "convention, placed perfectly, scores on this reference (Pose2Sim's own bones vary "
           "by its noise, `real_motion.md`).", "",
           "| joint | " + " | ".join(J) + " |", "|---" * (len(J) + 1) + "|",
           "| twin truth vs Pose2Sim | " + " | ".join(_cm(tv["per_joint"].get(j)) for j in J)
           + " |", "",
           "## Ours on the twin, by the number of views", "",
           "Mean over the seeds (range), cm:", "",
           "| set-up | ours vs twin truth, all frames | right frames | ours vs Pose2Sim, all "
           f"frames | right frames | right frames (of {doc['frames']}) |",
           "|---|---|---|---|---|---|"]
    for s, rs in by.items():
        out.append(f"| {s}: {SETUPS[s][2]} | {_spread(_over_seeds(rs, 'vs_truth', 'all'))} | "
                   f"{_spread(_over_seeds(rs, 'vs_truth', 'right'))} | "
                   f"{_spread(_over_seeds(rs, 'vs_pose2sim', 'all'))} | "
                   f"{_spread(_over_seeds(rs, 'vs_pose2sim', 'right'))} | "
                   + ", ".join(str(r["vs_truth"]["right_frames"]) for r in rs) + " |")
    if doc.get("real"):
        out += ["", "The real recording (`real_motion.json`, the same pipeline on MediaPipe's "
                    f"masks): against Pose2Sim all frames {_cm(doc['real']['all'])} cm, right "
                    f"frames {_cm(doc['real']['right'])} cm."]
    out += ["", "Each run:", "",
            "| set-up | seed | hull fatness | p90 vs truth | PA-MPJPE vs truth | chirality vs "
            "truth | identity switches (tracked) |", "|---|---|---|---|---|---|---|"]
    for r in doc["setups"]:
        a = r["vs_truth"]["all"]
        ch = a["chirality"]
        out.append(f"| {r['setup']} | {r['seed']} | {r['hull_fatness']} | "
                   f"{_cm(a['mpjpe_named']['mpjpe_p90'])} | {_cm(a['pa_mpjpe']['median'])} | "
                   f"{ch['right']}/{sum(ch.values())} | {a['switches_tracked']} |")
    out += ["", "Per joint, all frames, the first seed (cm):", "",
            "| set-up | against | " + " | ".join(J) + " |", "|---" * (len(J) + 2) + "|"]
    for s, rs in by.items():
        for key, label in (("vs_truth", "twin truth"), ("vs_pose2sim", "Pose2Sim")):
            pj = rs[0][key]["all"]["mpjpe_named"]["per_joint"]
            out.append(f"| {s} | {label} | " + " | ".join(_cm(pj.get(j)) for j in J) + " |")
    out += ["", "Times, the first seed (s): " + "; ".join(
        f"{s}: render {rs[0]['render_s']}, per frame {rs[0]['per_frame_run_s']}, motion "
        f"{rs[0]['motion_stage_s']}" for s, rs in by.items())
        + f"; inverse kinematics {doc['ik_s']}.",
            "", f"Picture: `{doc['picture']}` (each set-up's worst frames against the truth, "
                "the first seed)."]
    return "\n".join(out) + "\n"


def main(argv=None):
    from _machine import machine, results_dir, write_results
    from real import open_recording

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(DEFAULT))
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--work", default=None, help="folder for the runs (default: a temp dir)")
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--noise", type=int, default=2)
    ap.add_argument("--setups", default="4,4d,6,8", help=f"of {', '.join(SETUPS)}")
    ap.add_argument("--seeds", default="0,1,2", help="the silhouette noise's seeds")
    ap.add_argument("--quick", action="store_true",
                    help="20 frames, set-ups 4 and 8, one seed (a check, not the figures)")
    a = ap.parse_args(argv)
    if a.quick:
        a.frames, a.setups, a.seeds = 20, "4,8", "0"
    opened = open_recording(a.recording)
    if opened is None:
        return 2
    rec, ref = opened
    setups = [s for s in a.setups.split(",") if s]
    seeds = [int(x) for x in a.seeds.split(",") if x]
    bad = [s for s in setups if s not in SETUPS]
    if bad:
        ap.error(f"--setups: unknown {bad} (known: {', '.join(SETUPS)})")
    n = min(a.frames, len(ref["Neck"]))
    ref = {k: v[:n] for k, v in ref.items()}
    fps = float(Path(rec / "reference" / "pose2sim_3d.trc").read_text().splitlines()[2]
                .split("\t")[0])
    hips = 0.5 * (ref["LHip"] + ref["RHip"]).mean(axis=0)
    centre = np.array([hips[0], hips[1], 0.0])   # the 45° turn's vertical axis
    t0 = time.perf_counter()
    build, lengths, bodies, rms = twin_bodies(ref, n)
    t_ik = time.perf_counter() - t0
    twin = twin_reference(bodies)
    overlap = mask_overlap(rec, bodies, twin_cameras(rec, "4", centre))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(a.work or tmp)
        for s, seed in ((s, seed) for s in setups for seed in seeds):
            rows.append(one_setup(s, bodies, twin, ref, rec, a.noise, fps, centre,
                                  work / f"{s}_{seed}", seed))
            r = rows[-1]
            print(f"set-up {s}, seed {seed}: vs truth "
                  f"{_cm(r['vs_truth']['all']['mpjpe_named']['mpjpe'])} cm, vs Pose2Sim "
                  f"{_cm(r['vs_pose2sim']['all']['mpjpe_named']['mpjpe'])} cm", flush=True)
    worst_picture(out / "real_twin.png", [r for r in rows if r["seed"] == seeds[0]], twin, ref)
    real = None
    rj = results_dir() / "real_motion.json"
    if rj.exists():
        import json

        s = json.loads(rj.read_text())["scores"]
        real = {k: s[k]["mpjpe_named"]["mpjpe"] for k in ("all", "right")}
    doc = {"recording": str(rec), "machine": machine(resolution=100), "frames": n,
           "noise": a.noise, "seeds": seeds, "fps": fps, "build": {k: float(v) for k, v in build.items()},
           "lengths": lengths, "ik_rms_median": float(np.median(rms)),
           "ik_rms_p90": float(np.percentile(rms, 90)), "ik_s": round(t_ik, 1),
           "truth_vs_pose2sim": truth_vs_reference(twin, ref, n), "real": real,
           "mask_iou": overlap,
           "setups": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows],
           "picture": "real_twin.png"}
    write_results(out / "real_twin", doc, report)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
