"""Motion on every frame: the subject's capsule body tracked through the sequence
(:mod:`topopose.sequence`) against the sequence stage before it, in the same run.

    python benchmarks/tracking.py --tracker [--real DIR] [--child-rope DIR] [--frames 40]
                                            [--dev] [--setups 8,4p] [--out DIR] [--work DIR]
                                            [--follow NAME=VALUE ...] [--set NAME=VALUE ...]
                                            [--rng-seeds 3]

Every sequence runs twice as ``topopose run`` runs it: with the tracker (the default,
:class:`~topopose.sequence.follow.FollowOptions`, or those defaults with the ``--follow``
settings, e.g. ``extends=False``, ``trunk_sides=None``, ``track.prior=0.1``, and the ``--set``
sequence options, e.g. ``hints=False``: results written as ``tracking_tracker_variant``) and
without it (``follow=FollowOptions(enabled=False)``: the sequence stage as it was, the peer).

* **synthetic** ``body`` sequences (100³; ``8``: 8 cameras 640×480 noise 1; ``4p``: 4 portrait
  phones in facing pairs, noise 2, AHA threshold and gate off as ``tracking.py --setup 4p``;
  ``--defaults``: both on, as ``topopose run`` with no flag, results ``tracking_tracker_defaults``):
  walk, random-smooth and the motions whose limbs touch the body (``hang``, ``hips``, ``fold``,
  ``jump``, ``crouch``: :data:`topopose.synth.body.TOUCHING`). Held-out seeds
  (:data:`SEEDS`; ``--dev``: :data:`DEV_SEEDS`, where the constants were chosen). Per sequence:
  the frames with a skeleton, the MPJPE (neck, shoulders, elbows, wrists, hips, knees, ankles
  against the rig joints, mirror pairs paired optimally, ``tracking.joint_errors``) over the
  frames with a skeleton (those ``matched`` or ``tracked``, whose joints the exports hold;
  median and mean of the per-frame mean), the statuses, the tracker's fit (:func:`fit_spread`:
  the median silhouette IoU of a sequence, its lowest frame's share of it).
* **the real recording** (``--real``, Pose2Sim's balancing trial) by the README's own route:
  ``person`` silhouettes, the Qualisys calibration imported (``Calib.qca.txt``), ``size_policy
  = "pad"``, no other flag; the exported TRC scored as ``real_motion.py`` scores it (14 joints
  against Pose2Sim's, side names kept): frames with all 14, MPJPE median / p90, left and right
  swapped per joint pair (the named pair farther from Pose2Sim's than the swapped one).
* **child_rope** (``--child-rope``, 10 cameras, P matrices, no 3D reference; read by path: a
  capture folder of links is built in the work folder, frames sorted numerically): frames with
  a skeleton, the silhouette IoU of the fitted body per camera (median over frames) beside
  the hull's own (:func:`hull_silhouette_iou`, every 10th frame: how far the masks agree with
  each other, which a body inside the hull does not pass by much), pictures
  of 6 frames (3 with a wrist within :data:`TOUCH` of the trunk) with the body drawn over the
  masks (written to the work folder, not to ``--out``: the recording has no licence to copy).
* **sampling seeds** (``--rng-seeds N``): the tracker draws each frame's hull points and
  silhouette rays at random (``FollowOptions.seed``), and a track's choices between fits
  follow small differences in them; the tracker arm runs again with seeds 1..N-1 on the
  synthetic sequences and the real recording, each seed's figures reported and averaged.
* **speed**: the tracker's stages per frame (``timings_ms``: ``track_hull`` reading the
  hull the frame loop kept, ``track_data`` surface points and silhouette rays, ``track_fit``
  the Gauss–Newton fits, ``track_quality`` the silhouette IoU), the mean over the synthetic
  8-camera sequences.
"""
from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np

MOTIONS = ("walk", "random-smooth", "hang", "hips", "fold", "jump", "crouch")
BUILDS = ("average", "lean", "heavy", "random", "child", "average", "random")
SEEDS = {m: 81 + k for k, m in enumerate(MOTIONS)}           # held out
DEV_SEEDS = {m: 61 + k for k, m in enumerate(MOTIONS)}       # the constants chosen here
TOUCH = 0.12    # m: a wrist this near the trunk's axis (chest → pelvis) touches the body


def _numbered(name):
    if name.startswith("left_"):
        return name[5:] + "_1"
    if name.startswith("right_"):
        return name[6:] + "_2"
    return name


def fit_spread(poses) -> dict | None:
    """The silhouette fits of the frames the tracker followed (``matched``, ``tracked``,
    ``lost``): their median, and the lowest as a share of it (how far a frame falls below its
    own run, :func:`topopose.sequence.follow.lost_frames`)."""
    f = [p.fit for p in poses if p.fit is not None and p.status in ("matched", "tracked", "lost")]
    if not f:
        return None
    med = float(np.median(f))
    return {"median": round(med, 4), "lowest_share": round(min(f) / med, 4) if med else None}


def _arms(tracker, rng_seeds):
    """The runs compared: the peer (no tracker), the tracker arm, and the tracker arm drawing
    its hull points and silhouette rays with each sampling seed 1..``rng_seeds``-1
    (``FollowOptions.seed``)."""
    from dataclasses import replace

    from topopose.sequence.follow import FollowOptions

    return [("peer", FollowOptions(enabled=False)), ("tracker", tracker)] + \
        [(f"seed {k}", replace(tracker or FollowOptions(), seed=k)) for k in range(1, rng_seeds)]


def synthetic_sequence(work, motion, seed, build, frames, setup, model, tracker=None, flat=None,
                       defaults=False, rng_seeds=1):
    """One synthetic sequence with and without the tracker (``flat``: sequence options of the
    tracker arm; ``defaults``: the gate and the AHA threshold on with any set-up; the tracker
    run again with each sampling seed below ``rng_seeds``: ``tracker_seeds``): rows of
    figures."""
    from tracking import MPJPE_JOINTS, joint_errors, make_sequence

    from topopose.capture import load_capture
    from topopose.batch import run

    d = make_sequence(work, motion, seed, build, frames, setup)
    cap = load_capture(d)
    loose = {} if setup == "8" or defaults else {"threshold": 1e9, "gate": False}
    out = {"motion": motion, "seed": seed, "build": build, "setup": setup, "frames": frames}
    for key, follow in _arms(tracker, rng_seeds):
        t0 = time.perf_counter()
        extra = (flat or {}) if key != "peer" else {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = run(cap, model=model, resolution=100, progress=False, follow=follow, **loose,
                      **extra)
        errs, drawn = [], []
        for p in res.poses:
            if not p.joints or p.status not in ("matched", "tracked"):   # as exported
                continue
            names = [_numbered(k) for k in p.joints]
            gtj = cap.gt["frames"][p.frame]["joints"]
            e = joint_errors(names, np.array(list(p.joints.values())), gtj)
            v = [x for k, xs in e.items() if k in MPJPE_JOINTS for x in xs]
            if v:
                errs.append(float(np.mean(v)))
                drawn.append(_figure(p, names, gtj, errs[-1], motion, seed, setup))
        figures = {"skeleton": len(errs),
                   "mpjpe_median": float(np.median(errs)) if errs else None,
                   "mpjpe_mean": float(np.mean(errs)) if errs else None}
        if key.startswith("seed"):
            out.setdefault("tracker_seeds", []).append(figures)
            continue
        st = {}
        for p in res.poses:
            st[p.status] = st.get(p.status, 0) + 1
        timing = {k: float(np.mean([p.timings_ms.get(k, 0.0) for p in res.poses]))
                  for k in ("track_hull", "track_data", "track_fit", "track_quality")}
        out[key] = {**figures, "per_frame": [round(x, 4) for x in errs], "statuses": st,
                    "fit": fit_spread(res.poses), "seconds": round(time.perf_counter() - t0, 2),
                    "timings_ms": timing,
                    "worst": sorted(drawn, key=lambda f: -f["mpjpe"])[:3]}
    return out


#: the bones drawn (joint base names; sided joints as ``_1`` / ``_2``) and the rig's joint of
#: each base name (``tracking.RIG``; the pelvis the middle of the hips)
STICKS = (("skull", "neck"), ("neck", "shoulder"), ("shoulder", "elbow"), ("elbow", "wrist"),
          ("neck", "pelvis"), ("pelvis", "hip"), ("hip", "knee"), ("knee", "ankle"))


def _figure(pose, names, gtj, err, motion, seed, setup) -> dict:
    """A frame's stick figures, ours and the ground truth's: base name (``elbow_1``) → xyz."""
    from tracking import RIG

    ours = {n: [round(float(x), 4) for x in v] for n, v in zip(names, pose.joints.values())}
    truth = {}
    for base, rig in RIG.items():
        if base == "pelvis":
            truth[base] = list(0.5 * (np.asarray(gtj[rig[0]]) + np.asarray(gtj[rig[1]])))
        elif len(rig) == 1:
            truth[base] = list(gtj[rig[0]])
        else:
            truth[base + "_1"], truth[base + "_2"] = list(gtj[rig[0]]), list(gtj[rig[1]])
    return {"motion": motion, "seed": seed, "setup": setup, "frame": pose.frame,
            "status": pose.status, "mpjpe": round(err, 4), "ours": ours,
            "truth": {k: [round(float(x), 4) for x in v] for k, v in truth.items()}}


def worst_synthetic_picture(path, rows, k=8) -> list:
    """The ``k`` tracked frames with the largest MPJPE over the synthetic sequences ``rows``:
    stick figures, the ground truth (thick grey) and ours (red: side 1, blue: side 2, black:
    the trunk), seen along the two horizontal axes. Returns (sequence, frame, MPJPE m)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    picks = sorted((f for r in rows for f in r["tracker"].get("worst") or []),
                   key=lambda f: -f["mpjpe"])[:k]
    if not picks:
        return []
    fig, axes = plt.subplots(2, len(picks), figsize=(2.3 * len(picks), 6.5), squeeze=False)
    for c, f in enumerate(picks):
        for r, horiz in enumerate((0, 1)):
            ax = axes[r, c]
            for fig_joints, style in ((f["truth"], dict(color="0.7", lw=4)), (f["ours"], None)):
                for a, b in STICKS:
                    for side in ("_1", "_2"):
                        pa = fig_joints.get(a) or fig_joints.get(a + side)
                        pb = fig_joints.get(b) or fig_joints.get(b + side)
                        if pa is None or pb is None:
                            continue
                        col = "k" if b in ("neck", "pelvis") else ("tab:red" if side == "_1"
                                                                   else "tab:blue")
                        ax.plot([pa[horiz], pb[horiz]], [pa[2], pb[2]],
                                **(style or dict(color=col, lw=1.2)))
            ax.set_aspect("equal")
            ax.axis("off")
            if r == 0:
                ax.set_title(f"{f['setup']} {f['motion']} {f['seed']}\nframe {f['frame']} "
                             f"({f['status']}): {100 * f['mpjpe']:.0f} cm", fontsize=6.5)
    fig.suptitle("The synthetic tracked frames with the largest MPJPE: ground truth (thick "
                 "grey) and ours (red: side 1, blue: side 2, black: trunk); top: seen along y, "
                 "bottom: along x", fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return [(f"{f['setup']} {f['motion']} {f['seed']}", f["frame"], f["mpjpe"]) for f in picks]


# --------------------------------------------------------------------------- the real recording
def readme_capture(rec: Path, out: Path):
    """The README's "Your own recording" capture folder over the recording (videos linked)."""
    from topopose.capture.calib_import import import_calibration, write_calibration

    out.mkdir(parents=True, exist_ok=True)
    if not (out / "videos").exists():
        (out / "videos").symlink_to((rec / "videos").resolve())
    (out / "capture.toml").write_text('[capture]\nup = "+z"\nsize_policy = "pad"\n\n'
                                      '[silhouettes]\nmethod = "person"\n')
    write_calibration(import_calibration([rec / "Calib.qca.txt"], "qualisys"),
                      out / "calibration.toml")


def score_real(poses, cap, ref, work, tag, model, picture=None):
    """MPJPE, left/right swaps and statuses of a run's poses against Pose2Sim's 3D result;
    ``picture``: a PNG of the frames with the largest MPJPE (ours against Pose2Sim's)."""
    from real_motion import OURS, PAIRED, joint_errors, mpjpe, worst_picture

    from topopose.pose.export import OPENSIM_LABELS, marker_names, read_trc, write_trc

    trc = Path(work) / f"{tag}.trc"
    write_trc(trc, poses, marker_names(poses, model.parts), fps=cap.fps or 25.0, units=cap.units,
              up=cap.up, labels=OPENSIM_LABELS)
    names, _t, a = read_trc(trc)
    errs, swaps, pairs, full, markers = [], 0, 0, 0, []
    for i in range(len(poses)):
        w = a[i][:, [2, 0, 1]]                          # TRC (X, Y, Z) = world (y, z, x)
        mk = {nm: w[k] for k, nm in enumerate(names)}
        markers.append(mk)
        e = joint_errors(mk, ref, i)
        full += sum(len(v) if isinstance(v, list) else 1 for v in e.values()) >= 14
        if e:
            errs.append(e)
        for stem in PAIRED:
            L, R = ref[f"L{OURS[stem]}"][i], ref[f"R{OURS[stem]}"][i]
            x, y = mk.get(f"L{OURS[stem]}"), mk.get(f"R{OURS[stem]}")
            if x is None or y is None or np.isnan(x).any() or np.isnan(y).any():
                continue
            pairs += 1
            swaps += (np.linalg.norm(x - L) + np.linalg.norm(y - R)
                      > np.linalg.norm(x - R) + np.linalg.norm(y - L))
    r = mpjpe(errs)
    worst = (worst_picture(picture, markers, ref, [False] * len(poses), poses)
             if picture is not None else None)
    st = {}
    for p in poses:
        st[p.status] = st.get(p.status, 0) + 1
    return {"frames": len(poses), "skeleton_14": int(full), "mpjpe_median": r["mpjpe"],
            "mpjpe_p90": r["mpjpe_p90"], "per_joint": r["per_joint"], "swaps": int(swaps),
            "pairs": int(pairs), "statuses": st,
            "worst": None if worst is None else {"file": Path(picture).name, "frames": worst},
            "fit": fit_spread(poses)}


def real_recording(path, work, model, tracker=None, out=None, flat=None, rng_seeds=1):
    from real import person_recording

    import topopose as tp
    from topopose.batch import run

    opened = person_recording(path)
    if isinstance(opened, int):
        return None
    rec, ref = opened
    cdir = Path(work) / "real_capture"
    readme_capture(rec, cdir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = tp.load_capture(cdir)
        out_dir, out = out, {}
        for key, follow in _arms(tracker, rng_seeds):
            t0 = time.perf_counter()
            res = run(cap, model=model, progress=False, follow=follow,
                      **((flat or {}) if key != "peer" else {}))
            pic = out_dir / "tracking_tracker_real_worst.png" if (
                key == "tracker" and out_dir is not None) else None
            r = score_real(res.poses, cap, ref, work, key.replace(" ", "_"), model, pic)
            if key.startswith("seed"):
                out.setdefault("tracker_seeds", []).append(
                    {k: r[k] for k in ("skeleton_14", "mpjpe_median", "mpjpe_p90", "swaps")})
                continue
            out[key] = r
            out[key]["seconds"] = round(time.perf_counter() - t0, 1)
            out[key]["timings_ms"] = {k: float(np.mean([p.timings_ms.get(k, 0.0)
                                                        for p in res.poses]))
                                      for k in ("track_hull", "track_data", "track_fit",
                                                "track_quality")}
    return out


# --------------------------------------------------------------------------- child_rope
def child_rope_capture(src: Path, out: Path, frames=None) -> Path:
    """A capture folder over child_rope by path (links, nothing copied): cameras from their
    projection matrices (``camXX/cam_par.txt``: name, then P row-major; K R t by
    ``cv2.decomposeProjectionMatrix``), silhouettes ``camXX/N.png`` linked as zero-padded
    frame names (numeric order)."""
    import cv2

    from topopose.capture.calib_import import write_calibration
    from topopose.geometry.camera import Camera

    out.mkdir(parents=True, exist_ok=True)
    cams = []
    for cdir in sorted(p for p in src.iterdir() if p.is_dir() and (p / "cam_par.txt").exists()):
        words = (cdir / "cam_par.txt").read_text().split()
        P = np.array([float(x) for x in words[-12:]]).reshape(3, 4)
        K, R, c = cv2.decomposeProjectionMatrix(P)[:3]
        K = K / K[2, 2]
        t = -R @ (c[:3, 0] / c[3, 0])
        h, w = cv2.imread(str(next(cdir.glob("*.png"))), cv2.IMREAD_GRAYSCALE).shape
        cams.append(Camera(cdir.name, (w, h), K, np.zeros(4), cv2.Rodrigues(R)[0].ravel(), t))
        nums = sorted(int(f.stem) for f in cdir.glob("*.png") if f.stem.isdigit())
        if frames is not None:
            nums = nums[:frames]
        d = out / "silhouettes" / cdir.name
        d.mkdir(parents=True, exist_ok=True)
        for n in nums:
            link = d / f"{n:06d}.png"
            if not link.exists():
                link.symlink_to((cdir / f"{n}.png").resolve())
    write_calibration(cams, out / "calibration.toml")
    (out / "capture.toml").write_text('[capture]\nup = "+z"\nunits = "m"\nfps = 25.0\n')
    return out


def hull_silhouette_iou(volume, views) -> list:
    """The visual hull's own silhouette IoU per camera, measured as the tracker's ``fit``
    (``views``: :class:`~topopose.sequence.kept.CroppedViews`, the silhouettes it reads):
    each surface voxel drawn as 4³ points over its cube, the inner voxels as their centres."""
    from scipy import ndimage

    q = np.array([-0.375, -0.125, 0.125, 0.375])
    off = np.stack(np.meshgrid(q, q, q, indexing="ij"), -1).reshape(-1, 3)
    surface = np.argwhere(volume.data & ~ndimage.binary_erosion(volume.data))
    X = np.concatenate([(volume.world(surface)[:, None] + off * volume.voxel_size)
                        .reshape(-1, 3), volume.world(np.argwhere(volume.data))])
    out = []
    for cam, (y0, x0, m), (h, w) in zip(views.cameras, views.crops, views.shapes):
        uv = np.rint(cam.project(X)).astype(np.int64)
        ok = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        img = np.zeros((h, w), bool)
        img[uv[ok, 1], uv[ok, 0]] = True
        both = np.count_nonzero(img[y0:y0 + m.shape[0], x0:x0 + m.shape[1]] & m)
        union = np.count_nonzero(img) + np.count_nonzero(m) - both
        out.append(both / union if union else np.nan)
    return out


def hull_iou(cap, model, frames) -> list:
    """:func:`hull_silhouette_iou` per camera, median over ``frames``, the hulls carved as
    ``run`` carves them."""
    from topopose.frame.estimate import FrameEstimator
    from topopose.sequence.follow import estimator_views
    from topopose.sequence.kept import CroppedViews

    est = FrameEstimator(cap, model, 100, None, None)
    rows = [hull_silhouette_iou(est.hull(f), CroppedViews.scaled(*estimator_views(est, f)))
            for f in frames]
    return [round(float(x), 3) for x in np.nanmedian(np.array(rows, float), axis=0)]


def child_rope(path, work, model, frames=None, peer=True, pictures=None, tracker=None,
               flat=None):
    import topopose as tp
    from topopose.batch import run
    from topopose.sequence.follow import FollowOptions

    src = Path(path)
    if not (src / "cam00").exists():
        print(f"child_rope: {src} absent; skipped")
        return None
    cap = tp.load_capture(child_rope_capture(src, Path(work) / "child_rope_capture", frames))
    out = {"frames": len(cap.frames), "cameras": len(cap.cameras)}
    keys = (("peer", FollowOptions(enabled=False)),) if peer else ()
    for key, follow in keys + (("tracker", tracker),):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = run(cap, model=model, progress=False, follow=follow,
                      **((flat or {}) if key == "tracker" else {}))
        st = {}
        for p in res.poses:
            st[p.status] = st.get(p.status, 0) + 1
        full = sum(len(p.joints) >= 20 and p.status in ("matched", "tracked") for p in res.poses)
        ious = np.array([p.diagnostics.get("fit_cameras") or [np.nan] * len(cap.cameras)
                         for p in res.poses], dtype=float)
        out[key] = {"skeleton": int(full), "statuses": st, "fit": fit_spread(res.poses),
                    "iou_per_camera_median": [None if np.isnan(x) else round(float(x), 3)
                                              for x in np.nanmedian(ious, axis=0)]
                    if np.isfinite(ious).any() else None,
                    "seconds": round(time.perf_counter() - t0, 1),
                    "timings_ms": {k: float(np.mean([p.timings_ms.get(k, 0.0)
                                                     for p in res.poses]))
                                   for k in ("track_hull", "track_data", "track_fit",
                                             "track_quality")}}
        if key == "tracker":
            out[key]["iou_native_per_camera_median"] = native_iou(cap, res.poses, model,
                                                                  cap.frames[::10])
            if pictures is not None:
                out["pictures"] = child_pictures(cap, res.poses, model, pictures)
    out["hull_iou_per_camera_median"] = hull_iou(cap, model, cap.frames[::10])
    return out


def _touching(p) -> bool:
    j = p.joints
    need = ("chest", "pelvis", "left_wrist", "right_wrist")
    if not all(k in j for k in need):
        return False
    a, b = np.asarray(j["chest"]), np.asarray(j["pelvis"])
    ab = b - a
    for w in ("left_wrist", "right_wrist"):
        x = np.asarray(j[w])
        t = np.clip((x - a) @ ab / (ab @ ab), 0, 1)
        if np.linalg.norm(x - (a + t * ab)) < TOUCH:
            return True
    return False


def tracked_body(poses, model):
    """The tracked body as ``poses`` record it (``diagnostics["track_body"]``: radii, extra
    capsules) and a function giving a pose's joints (J, 3) in the body's order."""
    from topopose.sequence.body import CapsuleBody
    from topopose.sequence.kinematic_fit import kinematic_tree

    tree = kinematic_tree(model)
    names = list(tree.names)
    info = next((p.diagnostics["track_body"] for p in poses
                 if p.diagnostics.get("track_body")), None)
    radii = np.array([np.nan if x is None else x for x in info["radii"]], float) \
        if info else np.full(len(names), 0.05)
    extra = (info or {}).get("extra")
    body = CapsuleBody(tuple(names), np.array(tree.parents), np.full(len(names), 1.0), radii,
                       tuple(tree.order()),
                       ends=None if extra is None else np.array(extra["ends"], float),
                       extra_radii=None if extra is None else np.array(extra["radii"], float))

    def joints(p):
        return np.array([p.joints.get(n, p.joints.get(_side(n), np.full(3, np.nan)))
                         for n in names], float)
    return body, joints


def native_iou(cap, poses, model, frames) -> list:
    """The tracked body's silhouette IoU per camera at the images' own resolution (the
    tracker judges its fits at :data:`~topopose.sequence.silhouette.MAX_SIDE`), median over
    the tracked frames among ``frames``."""
    from topopose.sequence.silhouette import silhouette_iou

    body, joints = tracked_body(poses, model)
    by_frame = {p.frame: p for p in poses if p.status in ("matched", "tracked") and p.joints}
    rows = [silhouette_iou(body, joints(by_frame[f]), cap.cameras, cap.silhouettes(f))
            for f in frames if f in by_frame]
    return [round(float(x), 3) for x in np.nanmedian(np.array(rows, float), axis=0)] \
        if rows else None


def child_pictures(cap, poses, model, out_dir, n_touch=3, n_other=3):
    """Pictures of 6 tracked frames (``n_touch`` with a wrist at the trunk): per frame, 3
    cameras' masks (grey) with the fitted body's silhouette outlined (red)."""
    import cv2
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from topopose.sequence.silhouette import body_masks, scaled_views

    good = [i for i, p in enumerate(poses) if p.status in ("matched", "tracked") and p.joints]
    touch = [i for i in good if _touching(poses[i])]
    other = [i for i in good if i not in touch]
    pick = ([touch[k] for k in np.linspace(0, len(touch) - 1, min(n_touch, len(touch)))
             .round().astype(int)] if touch else [])
    pick += [other[k] for k in np.linspace(0, len(other) - 1, min(n_other, len(other)))
             .round().astype(int)] if other else []
    files = []
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    body, pose_joints = tracked_body(poses, model)
    for i in pick:
        p = poses[i]
        P = pose_joints(p)
        cams, sils = scaled_views(cap.cameras, cap.silhouettes(p.frame), 400)
        sel = list(range(0, len(cams), max(1, len(cams) // 3)))[:3]
        drawn = body_masks(body, P, [cams[c] for c in sel], [sils[c].shape for c in sel])
        fig, axes = plt.subplots(1, len(sel), figsize=(3 * len(sel), 4))
        for ax, c, d in zip(np.atleast_1d(axes), sel, drawn):
            ys, xs = np.nonzero(sils[c] | d)
            if len(ys):                               # the subject, with a margin
                m = 15
                y0, y1 = max(ys.min() - m, 0), ys.max() + m
                x0, x1 = max(xs.min() - m, 0), xs.max() + m
                sils[c], d = sils[c][y0:y1, x0:x1], d[y0:y1, x0:x1]
            img = np.dstack([sils[c] * 0.6] * 3)
            edge = d ^ (cv2.erode(d.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
            img[d & ~edge] = img[d & ~edge] * 0.7 + np.array([0.3, 0.0, 0.0])
            img[edge] = (1.0, 0.1, 0.1)
            ax.imshow(np.clip(img, 0, 1))
            ax.set_axis_off()
            ax.set_title(f"frame {p.frame} {cams[c].name}  IoU "
                         f"{(p.diagnostics.get('fit_cameras') or [None] * len(cams))[c]}",
                         fontsize=8)
        fig.suptitle(f"{p.status}{' — a wrist at the trunk' if i in touch else ''}", fontsize=9)
        fig.tight_layout()
        f = out_dir / f"tracking_child_rope_{p.frame}.png"
        fig.savefig(f, dpi=80)
        plt.close(fig)
        files.append({"frame": p.frame, "touching": i in touch, "file": str(f)})
    return files


def _side(n):
    base, _, k = n.rpartition("_")
    return {"1": "left_", "2": "right_"}.get(k, "") + base if k in ("1", "2") else n


# --------------------------------------------------------------------------- the report
def _cm(x):
    return "–" if x is None else f"{100 * x:.1f}"


def _fit_line(fit) -> str:
    if not fit:
        return "The tracker's fit: none"
    return (f"The tracker's fit (silhouette IoU): median {fit['median']:.2f}, the lowest frame "
            f"at {fit['lowest_share']:.2f} of it")


def report(doc) -> str:
    m = doc["machine"]
    lines = ["# Motion on every frame: the tracked capsule body against the sequence stage", "",
             f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
             "Peer: the same run without the tracker (`follow=FollowOptions(enabled=False)`)."
             + (f" Tracker settings: {', '.join(doc['follow'])}." if doc.get("follow") else "")
             + (f" The tracker arm's sequence options: {', '.join(doc['set'])}."
                if doc.get("set") else "")
             + (" Set-up 4p" if doc.get("defaults") else " Set-up 4p with the AHA threshold and "
                "the gate off, 8") + " with `run`'s defaults.",
             ""]
    syn = doc.get("synthetic") or []
    if syn:
        lines += ["## Synthetic `body` sequences" + (" (development seeds)" if doc.get("dev")
                                                     else " (held-out seeds)"), "",
                  "| set-up | motion | seed | build | frames | skeleton: peer → tracker | "
                  "MPJPE median cm: peer → tracker | MPJPE mean cm: peer → tracker | tracker "
                  "statuses |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in syn:
            a, b = r["peer"], r["tracker"]
            lines.append(f"| {r['setup']} | {r['motion']} | {r['seed']} | {r['build']} | "
                         f"{r['frames']} | {a['skeleton']} → {b['skeleton']} | "
                         f"{_cm(a['mpjpe_median'])} → {_cm(b['mpjpe_median'])} | "
                         f"{_cm(a['mpjpe_mean'])} → {_cm(b['mpjpe_mean'])} | "
                         f"{', '.join(f'{k} {v}' for k, v in sorted(b['statuses'].items()))} |")
        lines.append("")
        for st in sorted({r["setup"] for r in syn}):
            rows = [r for r in syn if r["setup"] == st]
            for key in ("peer", "tracker"):
                pf = [x for r in rows for x in r[key]["per_frame"]]
                n = sum(r["frames"] for r in rows)
                lines.append(f"- set-up {st}, {key}: a skeleton on {len(pf)} of {n} frames "
                             f"({100 * len(pf) / max(n, 1):.1f} %), MPJPE over those frames "
                             f"mean {_cm(float(np.mean(pf)) if pf else None)} cm, median "
                             f"{_cm(float(np.median(pf)) if pf else None)} cm")
        for st in sorted({r["setup"] for r in syn}):
            rows = [r for r in syn if r["setup"] == st and r.get("tracker_seeds")]
            if rows:
                k = len(rows[0]["tracker_seeds"]) + 1
                means = [float(np.mean([r["tracker"]["mpjpe_mean"] for r in rows]))]
                means += [float(np.mean([r["tracker_seeds"][s]["mpjpe_mean"] for r in rows]))
                          for s in range(k - 1)]
                lines.append(f"- set-up {st}, tracker, sampling seeds 0–{k - 1} "
                             "(`FollowOptions.seed`: the hull points and silhouette rays drawn): "
                             "MPJPE mean of the sequences' means " +
                             " / ".join(_cm(x) for x in means) +
                             f" cm, over the seeds {_cm(float(np.mean(means)))} cm")
        for st in sorted({r["setup"] for r in syn}):
            fits = [r["tracker"].get("fit") for r in syn if r["setup"] == st]
            fits = [f for f in fits if f]
            if fits:
                lines.append(f"- set-up {st}, the tracker's fit (silhouette IoU): median over a "
                             f"sequence {min(f['median'] for f in fits):.2f}–"
                             f"{max(f['median'] for f in fits):.2f}; the lowest frame at "
                             f"{min(f['lowest_share'] for f in fits):.2f} of its sequence's "
                             "median (`lost` below `FollowOptions.min_fit` of it)")
        t = [r["tracker"]["timings_ms"] for r in syn if r["setup"] == "8"]
        if t:
            lines += ["", "Tracker cost a frame (8 cameras, 100³, mean over the sequences, ms): "
                      + ", ".join(f"{k[6:]} {np.mean([x[k] for x in t]):.1f}" for k in t[0])
                      + " (hull: the frame loop's kept hull read; fit: the Gauss–Newton fits, both directions and "
                      "the confident frames' starts)"]
        for st, picks in (doc.get("synthetic_worst") or {}).items():
            if picks:
                lines += ["", f"The tracked frames with the largest MPJPE, set-up {st} "
                          f"(`tracking_tracker_worst_{st}.png`): " + ", ".join(
                              f"{seq} frame {fr} ({100 * e:.0f} cm)" for seq, fr, e in picks)
                          + "."]
        lines.append("")
    real = doc.get("real")
    if real:
        lines += ["## The real recording (README route, no flags)", "",
                  "| | frames with 14 joints | MPJPE median / p90 cm | L/R swapped pairs | "
                  "statuses | fit (IoU) median |", "| --- | --- | --- | --- | --- | --- |"]
        for key in ("peer", "tracker"):
            r = real[key]
            lines.append(f"| {key} | {r['skeleton_14']} / {r['frames']} | {_cm(r['mpjpe_median'])}"
                         f" / {_cm(r['mpjpe_p90'])} | {r['swaps']} / {r['pairs']} | "
                         f"{', '.join(f'{k} {v}' for k, v in sorted(r['statuses'].items()))} | "
                         f"{'–' if r['fit'] is None else round(r['fit']['median'], 3)} |")
        if real.get("tracker_seeds"):
            runs = [real["tracker"]] + real["tracker_seeds"]
            lines += ["", f"The tracker with sampling seeds 0–{len(runs) - 1}: MPJPE median / "
                      "p90 " + ", ".join(f"{_cm(r['mpjpe_median'])} / {_cm(r['mpjpe_p90'])}"
                                  for r in runs) + " cm; over the seeds "
                      f"{_cm(float(np.mean([r['mpjpe_median'] for r in runs])))} / "
                      f"{_cm(float(np.mean([r['mpjpe_p90'] for r in runs])))} cm; L/R swaps "
                      + ", ".join(str(r["swaps"]) for r in runs)]
        w = real["tracker"].get("worst")
        if w:
            lines += ["", f"The tracker's frames with the largest MPJPE, ours against Pose2Sim's "
                      f"(`{w['file']}`): " + ", ".join(f"{f} ({100 * e:.0f} cm)"
                                                      for f, e in w["frames"]) + "."]
        lines += ["", "Per joint (tracker, cm): " + ", ".join(
            f"{k} {100 * v:.1f}" for k, v in real["tracker"]["per_joint"].items()),
            _fit_line(real["tracker"].get("fit")),
            "Tracker cost a frame (ms): " + ", ".join(
                f"{k[6:]} {v:.1f}" for k, v in real["tracker"]["timings_ms"].items()), ""]
    ch = doc.get("child_rope")
    if ch:
        lines += ["## child_rope (10 cameras, no 3D reference)", ""]
        for key in ("peer", "tracker"):
            if key in ch:
                r = ch[key]
                lines.append(f"- {key}: a skeleton on {r['skeleton']} of {ch['frames']} frames "
                             f"({100 * r['skeleton'] / ch['frames']:.1f} %); statuses "
                             f"{r['statuses']}; silhouette IoU per camera (median over frames) "
                             f"{r['iou_per_camera_median']}")
        if ch.get("tracker", {}).get("iou_native_per_camera_median"):
            lines.append("- the tracker's silhouette IoU per camera at the images' own "
                         "resolution (median over every 10th frame; above: the longest side "
                         "scaled to 320 pixels, as the tracker judges its fits): "
                         f"{ch['tracker']['iou_native_per_camera_median']}")
        if ch.get("tracker", {}).get("fit"):
            lines.append("- " + _fit_line(ch["tracker"]["fit"]))
        if ch.get("hull_iou_per_camera_median"):
            lines.append("- the hull's own silhouette IoU per camera (median over every 10th "
                         "frame; how far the masks agree with each other): "
                         f"{ch['hull_iou_per_camera_median']}")
        for f in ch.get("pictures") or []:
            lines.append(f"  - frame {f['frame']}: `{Path(f['file']).name}` in the work folder "
                         "(the recording's masks stay out of the repository)"
                         + (", a wrist at the trunk" if f["touching"] else ""))
        lines.append("")
    return "\n".join(lines)


def follow_options(settings):
    """The tracker arm's :class:`~topopose.sequence.follow.FollowOptions` from ``NAME=VALUE``
    settings (``extends=False``, ``track.prior=0.1``; values as Python literals); None: the
    defaults."""
    import ast
    from dataclasses import replace

    from topopose.sequence.follow import FollowOptions

    if not settings:
        return None
    top, track = {}, {}
    for kv in settings:
        name, _, value = kv.partition("=")
        (track if name.startswith("track.") else top)[name.removeprefix("track.")] = \
            ast.literal_eval(value)
    opts = replace(FollowOptions(), **top)
    return replace(opts, track=replace(opts.track, **track))


def main(a, model):
    from _machine import machine

    work = Path(a.work) if a.work else Path(__import__("tempfile").mkdtemp(prefix="tp_tracker_"))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = DEV_SEEDS if a.dev else SEEDS
    motions = [m for m in MOTIONS if not a.motions or m in a.motions.split(",")]
    from _machine import sequence_settings

    tracker = follow_options(a.follow)
    flat = sequence_settings(a.set)
    variant = bool(a.follow or flat)
    doc = {"dev": a.dev, "synthetic": [], "follow": a.follow or [], "set": a.set or [],
           "defaults": a.defaults}
    for st in a.setups.split(",") if a.setups else ():
        for k, mo in enumerate(motions):
            r = synthetic_sequence(work, mo, seeds[mo], BUILDS[MOTIONS.index(mo)], a.frames,
                                   st, model, tracker, flat, a.defaults, a.rng_seeds)
            doc["synthetic"].append(r)
            print(json.dumps({k: v for k, v in r.items() if k not in ("peer", "tracker")}
                             | {x: {kk: r[x][kk] for kk in ("skeleton", "mpjpe_median",
                                                            "mpjpe_mean")}
                                for x in ("peer", "tracker")}), flush=True)
    if doc["synthetic"] and not (a.dev or variant or a.defaults):
        doc["synthetic_worst"] = {
            st: worst_synthetic_picture(out / f"tracking_tracker_worst_{st}.png",
                                        [r for r in doc["synthetic"] if r["setup"] == st])
            for st in a.setups.split(",")}
    if a.real:
        doc["real"] = real_recording(a.real, work, model, tracker,
                                     None if a.dev or variant else out, flat, a.rng_seeds)
        print(json.dumps(doc["real"], default=str)[:600], flush=True)
    if a.child_rope:
        # the pictures show the recording's masks, which stay out of the repository: the work
        # folder holds them
        doc["child_rope"] = child_rope(a.child_rope, work, model, a.child_frames,
                                       peer=not a.no_child_peer,
                                       pictures=work / "child_rope_pictures", tracker=tracker,
                                       flat=flat)
        print(json.dumps(doc["child_rope"], default=str)[:600], flush=True)
    doc["machine"] = machine(resolution=100)
    name = "tracking_tracker" + ("_dev" if a.dev else "") + ("_variant" if variant else "") + \
        ("_defaults" if a.defaults else "")
    (out / f"{name}.json").write_text(json.dumps(doc, indent=1, default=str))
    (out / f"{name}.md").write_text(report(doc))
    print(report(doc))
