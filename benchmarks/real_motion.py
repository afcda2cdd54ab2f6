"""From poses to motion on the real recording (Pose2Sim's balancing trial) against Pose2Sim's 3D
result: the full skeleton's per-joint error, left and right, identities over time.

    python benchmarks/real_motion.py [RECORDING] [--raw RAW.jsonl] [--out DIR] [--spread R,...] [--quick]

RECORDING (default ``benchmarks/data/pose2sim_balancing/``, see ``benchmarks/real.py``): 4 videos,
``Calib.toml`` and ``reference/pose2sim_3d.trc`` (TRC axes (X, Y, Z) = world (y, z, x)).

Silhouettes ``[silhouettes] method = "person"``, ``scale = 0.5`` (MediaPipe's pose network's
segmentation mask; needs ``mediapipe``: without it this script says so and measures nothing).
The per-frame result runs once (100³, as ``topopose run --no-track --no-sides --no-skeleton``)
with the AHA threshold and the confidence gate OFF: with 4 phone cameras the AHA distance of
this recording is 0.3–0.9, above the human model's T_d = 0.4 on almost every frame, so the
gated run matches (almost) nothing; the figures are those of the per-frame *best guesses*, and
the frames the AHA distance would have kept are counted beside them (the confidence gate's
decision is ``benchmarks/real.py``'s: with the threshold off the confidence's distance feature,
the distance / T_d, is not the run's). The motion stage then runs as
``topopose run`` runs it (:func:`topopose.sequence.motion.process_sequence`: track, skeleton,
sides, the defaults), the TRC is exported as ``run --trc`` writes it and read back, and:

* **MPJPE** per joint, median over frames, of the exported markers against Pose2Sim's: head
  (our ``head`` part, the head's tip) → ``Head``, ``neck`` → ``Neck``, shoulders, elbows, wrists,
  hips, knees, ankles → ``L…``/``R…``; the per-frame mean over these 14 joints, median over
  frames. Twice: with our side names (a wrong side costs; a frame whose sides are unsure keeps
  numbered joints, paired optimally) and with every mirror pair paired optimally (the error
  of the skeleton alone).
* **toes** (not in the MPJPE): our ``left_toe`` / ``right_toe`` against Pose2Sim's
  ``LBigToe`` / ``RBigToe``, paired optimally, median over frames × feet (the big toe's tip is
  not quite our toe, the foot's tip; the figure follows the toe's placement, e.g.
  :func:`~topopose.sequence.kinematic_fit.tip_targets`).
* **PA-MPJPE** (:func:`procrustes_mpjpe`): the same 14 joints after a per-frame rigid
  alignment to Pose2Sim's — how much of the error is the skeleton's shape, not its place.
* **chirality**: per frame and mirror pair (hands, feet), right when ``left_X`` + ``right_X``
  are nearer Pose2Sim's L/R segments (hand: wrist → 0.1 m beyond it, foot: ankle → big toe)
  than the swapped pair; wrong; or unsure (numbered names kept).
* **identity switches** of the numbered parts (``hand_1``/``hand_2``, ``foot_1``/``foot_2``):
  consecutive frames in which a numbered part changes the Pose2Sim side it is nearest to; the
  per-frame numbering (raw) against the tracked one (``diagnostics["chirality"]`` names the
  tracked part behind each side name).

* **the reference itself**: Pose2Sim's bone lengths, left and right, and their spread over
  the frames (:func:`reference_spread`: a rigid bone varies by the reference's own noise), and
  where its markers and ours lie against the visual hull (:func:`markers_in_hull`);
* **the grid's placement alone** (:func:`grid_spread`, ``--spread``): the whole benchmark
  again at resolutions 96, 98, 102, 104 (voxel size and lattice moved, the subject not);
* **peers**: the motion stage again from the same per-frame poses with a default switched
  off (:data:`PEERS`, :func:`peer_scores`).

Every figure on all 100 frames and on the *right* frames (per-frame result: head, both hands,
both feet within 0.15 m of Pose2Sim, as ``benchmarks/real.py``). Writes ``real_motion.md``,
``real_motion.json`` and ``real_motion.png`` (our joints against Pose2Sim's over time).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
DEFAULT = HERE / "data" / "pose2sim_balancing"
SILHOUETTES = 'scale = 0.5\n'
# our marker (exported TRC, OPENSIM_LABELS) → Pose2Sim marker; paired joints by their stem
SINGLE = ("Head", "Neck")          # our head part (its tip) and neck joint, as exported
PAIRED = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")
OURS = {"shoulder": "Shoulder", "elbow": "Elbow", "wrist": "Wrist", "hip": "Hip",
        "knee": "Knee", "ankle": "Ankle"}
PAIRS = (("hand", "hand_1", "hand_2"), ("foot", "foot_1", "foot_2"))


def pose2sim_segments(ref: dict, i: int) -> dict:
    """Pose2Sim's hand and foot segments of frame i: (kind, "L"/"R") → (a, b)."""
    from real import HAND_EXT

    g = {k: v[i] for k, v in ref.items()}
    out = {}
    for s in "LR":
        w, e = g[f"{s}Wrist"], g[f"{s}Elbow"]
        out[("hand", s)] = (w, w + HAND_EXT * (w - e) / max(np.linalg.norm(w - e), 1e-9))
        out[("foot", s)] = (g[f"{s}Ankle"], g[f"{s}BigToe"])
    return out


def joint_errors(markers: dict, ref: dict, i: int, named=True) -> dict:
    """Per joint (``head``, ``neck``, ``LElbow``… or, unnamed, ``elbow``) → error (m) of frame i.

    ``markers``: our exported marker → (3,) position (NaN: absent). With ``named`` a side name
    is compared with the same side of Pose2Sim, and numbered joints (sides unsure) are paired
    optimally; without, every pair is paired optimally."""
    out = {}
    for name in SINGLE:
        x = markers.get(name)
        if x is not None and not np.isnan(x).any():
            out[name] = float(np.linalg.norm(x - ref[name][i]))
    for stem in PAIRED:
        L, R = ref[f"L{OURS[stem]}"][i], ref[f"R{OURS[stem]}"][i]
        a, b = markers.get(f"L{OURS[stem]}"), markers.get(f"R{OURS[stem]}")
        sided = a is not None and b is not None and not (np.isnan(a).any() or np.isnan(b).any())
        if not sided:
            a, b = markers.get(f"{stem}_1"), markers.get(f"{stem}_2")
            if a is None or b is None or np.isnan(a).any() or np.isnan(b).any():
                continue
        d0 = [np.linalg.norm(a - L), np.linalg.norm(b - R)]
        d1 = [np.linalg.norm(a - R), np.linalg.norm(b - L)]
        d = d0 if (named and sided) or sum(d0) <= sum(d1) else d1
        if named and sided:
            out[f"L{OURS[stem]}"], out[f"R{OURS[stem]}"] = float(d[0]), float(d[1])
        else:
            k = f"{stem}" if not named else f"{stem} (sides unsure)"
            out.setdefault(k, [])
            out[k] = [float(x) for x in d]
    return out


def mpjpe(per_frame_errors: list) -> dict:
    """Median over frames of the per-frame mean, and each joint's median over frames."""
    means, joints = [], {}
    for e in per_frame_errors:
        vals = []
        for k, v in e.items():
            v = v if isinstance(v, list) else [v]
            vals += v
            base = k.replace(" (sides unsure)", "")
            base = base[1:].lower() if base[:1] in "LR" and base[1:].lower() in PAIRED else base
            joints.setdefault(base, []).extend(v)
        if vals:
            means.append(float(np.mean(vals)))
    return {"frames": len(means), "mpjpe": float(np.median(means)) if means else None,
            "mpjpe_p90": float(np.percentile(means, 90)) if means else None,
            "per_joint": {k: float(np.median(v)) for k, v in joints.items()},
            "per_frame": means}


NAMED = SINGLE + tuple(f"{s}{OURS[k]}" for k in PAIRED for s in "LR")


def procrustes_mpjpe(markers, ref, rows) -> dict:
    """PA-MPJPE: per frame of ``rows`` with all 14 joints side-named, our joints rigidly
    aligned (rotation and translation, no scale; Kabsch, :func:`scipy.spatial.transform.
    Rotation.align_vectors`) to Pose2Sim's before the mean error — the error of the
    skeleton's shape alone, the subject's place and facing taken out (the figure pose
    benchmarks such as Human3.6M's protocol 2 report beside the MPJPE, there with a scale
    too). Median over frames (m) and the count."""
    from scipy.spatial.transform import Rotation

    errs = []
    for i in rows:
        X = [markers[i].get(n) for n in NAMED]
        if any(x is None or np.isnan(x).any() for x in X):
            continue
        X, Y = np.array(X), np.array([ref[n][i] for n in NAMED])
        a, b = X - X.mean(axis=0), Y - Y.mean(axis=0)
        R, _ = Rotation.align_vectors(b, a)
        errs.append(float(np.linalg.norm(R.apply(a) - b, axis=1).mean()))
    return {"median": float(np.median(errs)) if errs else None, "frames": len(errs)}


def tracked_parts(pose) -> dict:
    """The pose's parts under their tracked numbered names (``left_hand`` → ``hand_2`` when
    ``diagnostics["chirality"]`` says hand_2 was named left_hand)."""
    chir = pose.diagnostics.get("chirality") or {}
    back = {d["name"]: part for part, d in chir.items()}
    return {back.get(k, k): v for k, v in pose.parts.items()}


def nearest_side(x, segs, kind):
    from topopose.batch.quality import point_segment_distance

    d = [point_segment_distance(np.asarray(x, float), *segs[(kind, s)]) for s in "LR"]
    return "LR"[int(np.argmin(d))]


def identity_switches(part_dicts, ref, rows):
    """Switches of each numbered part's nearest Pose2Sim side between consecutive frames of
    ``rows`` (the frame indices to use)."""
    n = 0
    for kind, a, _b in PAIRS:
        seq = [nearest_side(part_dicts[i][a], pose2sim_segments(ref, i), kind)
               for i in rows if part_dicts[i].get(a) is not None]
        n += sum(x != y for x, y in zip(seq, seq[1:]))
    return n


def chirality(poses, ref, rows):
    from topopose.batch.quality import point_segment_distance as psd

    c = {"right": 0, "wrong": 0, "unsure": 0}
    for i in rows:
        p, segs = poses[i], pose2sim_segments(ref, i)
        for kind, _a, _b in PAIRS:
            a, b = p.parts.get(f"left_{kind}"), p.parts.get(f"right_{kind}")
            if a is None or b is None:
                c["unsure"] += 1
                continue
            a, b = np.asarray(a, float), np.asarray(b, float)
            ok = (psd(a, *segs[(kind, "L")]) + psd(b, *segs[(kind, "R")])
                  < psd(a, *segs[(kind, "R")]) + psd(b, *segs[(kind, "L")]))
            c["right" if ok else "wrong"] += 1
    return c


def score(raw, final, trc_path, ref, model):
    """Every figure (see the module docstring) from the per-frame poses, the motion stage's
    poses and the exported TRC (read back)."""
    from real import RIGHT, frame_errors

    from topopose.pose.export import read_trc

    names, _t, trc = read_trc(trc_path)
    n = len(final)
    right = []
    for i, p in enumerate(raw):
        e = frame_errors(p.parts, ref, i) if p.status != "failed" else None
        right.append(e is not None and all(v <= RIGHT for v in e.values()))
    aha = [p.distance is not None and p.distance <= model.threshold for p in raw]
    markers = []
    for i in range(n):
        w = trc[i][:, [2, 0, 1]]                          # TRC (X, Y, Z) = world (y, z, x)
        markers.append({nm: w[k] for k, nm in enumerate(names)})
    out = {"frames": n, "right_frames": int(sum(right)), "aha_accepted": int(sum(aha)),
           "with_skeleton": int(sum(bool(p.joints) for p in final)),
           "interpolated": int(sum(bool(p.diagnostics.get("interpolated")) for p in final))}
    raw_parts = [p.parts for p in raw]
    trk_parts = [tracked_parts(p) for p in final]
    for label, rows in (("all", list(range(n))), ("right", [i for i in range(n) if right[i]])):
        sk = [i for i in rows if final[i].joints]
        out[label] = {
            "frames": len(rows),
            "mpjpe_named": mpjpe([joint_errors(markers[i], ref, i) for i in sk]),
            "mpjpe_paired": mpjpe([joint_errors(markers[i], ref, i, named=False) for i in sk]),
            "chirality": chirality(final, ref, rows),
            "switches_raw": identity_switches(raw_parts, ref, rows),
            "switches_tracked": identity_switches(trk_parts, ref, rows),
            "held": sum(len(final[i].diagnostics.get("predicted") or []) for i in rows)}
    for label, rows in (("all", list(range(n))), ("right", [i for i in range(n) if right[i]])):
        out[label]["toe_vs_bigtoe"] = toe_errors(markers, ref, rows)
        out[label]["pa_mpjpe"] = procrustes_mpjpe(markers, ref, rows)
    out["temporal_outliers"] = temporal_outliers(final, markers, ref, right)
    return out, markers, right


def temporal_outliers(final, markers, ref, right) -> dict:
    """The frames the fit flags ``temporal_outlier`` (joints off their neighbours' median,
    :func:`topopose.sequence.kinematic_fit.neighbourhood`): which, how many of them are wrong per
    frame, which were bridged (:func:`~topopose.sequence.kinematic_fit.bridge_outliers`), and the
    MPJPE (side names, median over frames, m) of the flagged frames and of the others with a
    skeleton."""
    flagged = [i for i, p in enumerate(final) if p.diagnostics.get("temporal_outlier")]
    judged = [i for i, p in enumerate(final) if "neighbour_distance" in p.diagnostics]

    def med(rows):
        return mpjpe([joint_errors(markers[i], ref, i) for i in rows])["mpjpe"]
    others = [i for i in range(len(final)) if final[i].joints and i not in flagged]
    return {"frames": flagged, "judged": len(judged),
            "bridged": [i for i in flagged if final[i].diagnostics.get("interpolated")],
            "wrong_flagged": sum(not right[i] for i in flagged),
            "wrong": sum(not r for r in right), "mpjpe_flagged": med(flagged),
            "mpjpe_others": med(others), "others": len(others)}


def toe_errors(markers, ref, rows) -> dict:
    """Our toes against Pose2Sim's big toes (paired optimally) on frames ``rows``: median (m)
    over frames × feet and the count."""
    errs = []
    for i in rows:
        a, b = markers[i].get("left_toe"), markers[i].get("right_toe")
        if a is None or b is None or np.isnan(a).any() or np.isnan(b).any():
            continue
        L, R = ref["LBigToe"][i], ref["RBigToe"][i]
        d0 = [np.linalg.norm(a - L), np.linalg.norm(b - R)]
        d1 = [np.linalg.norm(a - R), np.linalg.norm(b - L)]
        errs += [float(x) for x in (d0 if sum(d0) <= sum(d1) else d1)]
    return {"median": float(np.median(errs)) if errs else None, "n": len(errs)}


def person_capture(recording, work):
    """The recording's ``person`` capture under ``work/pose2sim`` (made once) and Pose2Sim's
    3D result, or ``{"absent": why}`` when the reference or MediaPipe is missing."""
    import topopose as tp
    from real import make_capture, read_trc

    recording = Path(recording)
    if not (recording / "reference" / "pose2sim_3d.trc").exists():
        return {"absent": f"{recording}: no reference/pose2sim_3d.trc (recording absent)"}
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        return {"absent": "mediapipe is not installed (pip install topopose[segment])"}
    d = Path(work) / "pose2sim"
    if not (d / "capture").exists():
        make_capture(recording, d / "capture", "person", SILHOUETTES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = tp.load_capture(d / "capture")
    return {"capture": cap, "reference": read_trc(recording / "reference" / "pose2sim_3d.trc"),
            "folder": d}


def run_recording(rec: Path, work: Path, raw_path=None, resolution=100, sequence=None):
    """Per-frame run (gates off) and the motion stage; returns raw poses, motion, capture, TRC."""
    import topopose as tp
    from real import make_capture

    cdir = work / "capture"
    make_capture(rec, cdir, "person", SILHOUETTES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = tp.load_capture(cdir)
    return run_capture(cap, work, raw_path, resolution, sequence)


def run_capture(cap, work: Path, raw_path=None, resolution=100, sequence=None):
    """:func:`run_recording` on a loaded (or in-memory) capture."""
    from topopose.batch import run
    from topopose.pose.export import OPENSIM_LABELS, marker_names, write_trc
    from topopose.pose.model import load_model
    from topopose.sequence.motion import process_sequence
    from topopose.pose.pose import read_poses

    model = load_model("human")
    t0 = time.perf_counter()
    reused = raw_path is not None and Path(raw_path).exists()
    if reused:                                       # --raw of an earlier run: not timed
        raw = read_poses(raw_path)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            raw = run(cap, model=model, resolution=resolution, threshold=1e9, gate=False,
                      output=raw_path or work / "raw.jsonl", progress=False, track=False,
                      sides=False, skeleton=False).poses
    t_frames = None if reused else round(time.perf_counter() - t0, 2)
    raw = sorted(raw, key=lambda p: p.frame)
    t0 = time.perf_counter()
    motion = process_sequence(raw, model, cap.up_vector, sequence,
                              fps=cap.fps)   # as topopose run
    t_motion = time.perf_counter() - t0
    trc_path = work / "motion.trc"
    write_trc(trc_path, motion.poses, marker_names(motion.poses, model.parts),
              fps=cap.fps or 25.0, units=cap.units, up=cap.up, labels=OPENSIM_LABELS)
    return raw, motion, cap, model, trc_path, {"per_frame_run_s": t_frames,
                                               "motion_stage_s": round(t_motion, 3)}


def grid_spread(rec: Path, work: Path, ref, resolutions) -> dict:
    """The whole benchmark's MPJPE (side names) again at other grid resolutions: the voxel
    size and the lattice move, the subject does not — how much of a difference between two
    figures the grid's placement alone can make (the synthetic figures average many seeds;
    this recording has one subject, one take)."""
    out = {}
    for r in resolutions:
        raw, motion, _cap, model, trc_path, _t = run_recording(rec, work / f"r{r}", resolution=r)
        s, _m, _r = score(raw, motion.poses, trc_path, ref, model)
        out[r] = {"right_frames": s["right_frames"],
                  **{w: {k: s[w]["mpjpe_named"][k] for k in ("mpjpe", "mpjpe_p90")}
                     for w in ("all", "right")}}
    return out


# peers of the default motion stage, from the same per-frame poses: sequence options
PEERS = {"the neck and shoulders each on its own target (GIRDLE = False)": {"girdle": False},
         "the smoothing window 9 frames at any rate "
         "(smooth = 9)": {"smooth": 9},
         "temporal outliers kept as fitted, not bridged (BRIDGE = False)":
             {"bridge": False},
         "one frame's swung bones smoothed with the others "
         "(despike = None)": {"despike": None},
         "hanging arms' elbows and wrists at their fractions only "
         "(from_start = {})": {"from_start": set()},
         "neither despike nor from_start (despike = None, from_start = {})":
             {"despike": None, "from_start": set()}}


def peer_scores(raw, cap, model, ref, work) -> dict:
    """The motion stage again from the same per-frame poses with each of :data:`PEERS`'
    settings: MPJPE (side names) on all and on the right frames, as :func:`score` gives it."""
    from topopose.pose.export import OPENSIM_LABELS, marker_names, write_trc
    from topopose.sequence.motion import process_sequence

    out = {}
    for k, (label, consts) in enumerate(PEERS.items()):
        motion = process_sequence(raw, model, cap.up_vector, fps=cap.fps, **consts)
        path = Path(work) / f"peer{k}.trc"
        write_trc(path, motion.poses, marker_names(motion.poses, model.parts),
                  fps=cap.fps or 25.0, units=cap.units, up=cap.up, labels=OPENSIM_LABELS)
        s, _m, _r = score(raw, motion.poses, path, ref, model)
        out[label] = {w: s[w]["mpjpe_named"] for w in ("all", "right")}
    return out


BONES_P2S = [("Head", "Neck"), ("Neck", "LShoulder"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"),
             ("Neck", "RShoulder"), ("RShoulder", "RElbow"), ("RElbow", "RWrist"),
             ("LHip", "RHip"), ("LHip", "LKnee"), ("LKnee", "LAnkle"), ("LAnkle", "LBigToe"),
             ("RHip", "RKnee"), ("RKnee", "RAnkle"), ("RAnkle", "RBigToe")]
BONES_OURS = [("head", "Neck"), ("Neck", "LShoulder"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"),
              ("Neck", "RShoulder"), ("RShoulder", "RElbow"), ("RElbow", "RWrist"),
              ("LHip", "RHip"), ("LHip", "LKnee"), ("LKnee", "LAnkle"), ("LAnkle", "left_toe"),
              ("RHip", "RKnee"), ("RKnee", "RAnkle"), ("RAnkle", "right_toe"),
              ("Neck", "Hip")]


def _view_axes(final, up):
    """The subject's mean forward (from the per-frame facing) and left, horizontal."""
    fwd = np.array([p.diagnostics["facing"] for p in final if p.diagnostics.get("facing")])
    f = fwd.mean(axis=0) if len(fwd) else np.array([1.0, 0, 0])
    f = f - np.dot(f, up) * up
    f /= np.linalg.norm(f)
    return f, np.cross(up, f)


def _sticks(ax, markers, ref, picks, horiz, labels):
    """Stick figures of the frames ``picks`` side by side, Pose2Sim's (thick grey) and ours
    (red: named left, blue: named right, black: trunk), ``horiz`` the view's horizontal axis."""
    for k, i in enumerate(picks):
        off = 1.2 * k
        c0 = ref["Neck"][i]
        xy = lambda x: (off + np.dot(x - c0, horiz), x[2])   # noqa: E731
        for a, b in BONES_P2S:
            A, B = xy(ref[a][i]), xy(ref[b][i])
            ax.plot([A[0], B[0]], [A[1], B[1]], color="0.55", lw=3, alpha=0.6, solid_capstyle="round")
        m = markers[i]
        for a, b in BONES_OURS:
            A, B = m.get(a), m.get(b)
            if A is None or B is None or np.isnan(A).any() or np.isnan(B).any():
                continue
            side = "L" if a.startswith(("L", "left")) or b.startswith(("L", "left")) else \
                "R" if a.startswith(("R", "right")) or b.startswith(("R", "right")) else ""
            col = {"L": "tab:red", "R": "tab:blue"}.get(side, "k")
            A, B = xy(A), xy(B)
            ax.plot([A[0], B[0]], [A[1], B[1]], color=col, lw=1.3)
        ax.text(off, -0.12, labels[k], ha="center", fontsize=7)
    ax.set_aspect("equal")
    ax.axis("off")


def picture(path, markers, ref, right, final, up=np.array([0.0, 0.0, 1.0])):
    """Our exported joints against Pose2Sim's: stick figures of 8 frames (front view) and the
    heights of the wrists and ankles over the 100 frames."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(markers)
    _f, lat = _view_axes(final, up)                         # front view: the subject's left
    fig, (a0, a1) = plt.subplots(2, 1, figsize=(12, 7.5), gridspec_kw={"height_ratios": [1.2, 1]})
    picks = np.linspace(0, n - 1, 8).round().astype(int)
    _sticks(a0, markers, ref, picks, -lat, [f"frame {i}" + (" (right)" if right[i] else "")
                                            for i in picks])   # on the right
    a0.set_title("Pose2Sim balancing trial, front view: Pose2Sim's 3D result (thick grey) and our "
                 "exported skeleton (red: named left, blue: named right, black: trunk)\n"
                 "every frame's best guess (AHA threshold and gate off); '(right)': the per-frame "
                 "head, hands and feet within 0.15 m of Pose2Sim", fontsize=8.5)
    t = np.arange(n)
    for mk, col, ls in (("LWrist", "tab:red", "-"), ("RWrist", "tab:blue", "-"),
                        ("LAnkle", "tab:red", "--"), ("RAnkle", "tab:blue", "--")):
        a1.plot(t, ref[mk][:, 2], color=col, ls=ls, lw=1.2, alpha=0.6, label=f"Pose2Sim {mk}")
        ours = np.array([m.get(mk, np.full(3, np.nan))[2] for m in markers])
        a1.plot(t, ours, "o" if "Wrist" in mk else "s", color=col, ms=2.5, label=f"ours {mk}")
    a1.set_xlabel("frame (the recording: 60 frames/s)")
    a1.set_ylabel("height (m)")
    a1.legend(fontsize=6.5, ncol=4)
    a1.set_title("heights of the wrists and ankles over time (ours: markers by our side names)",
                 fontsize=8.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def worst_picture(path, markers, ref, right, final, up=np.array([0.0, 0.0, 1.0]), k=8):
    """The ``k`` frames with the largest MPJPE (side names): stick figures seen from the front
    and from the subject's left, ours against Pose2Sim's. Returns their (frame, MPJPE m)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    err = []
    for i, m in enumerate(markers):
        v = [x for e in joint_errors(m, ref, i).values() for x in (e if isinstance(e, list) else [e])]
        err.append(float(np.mean(v)) if v else -1.0)
    picks = [int(i) for i in np.argsort(err)[::-1][:k] if err[i] >= 0]
    f, lat = _view_axes(final, up)
    labels = [f"frame {i}: {100 * err[i]:.0f} cm" + (" (right)" if right[i] else "") for i in picks]
    fig, (a0, a1) = plt.subplots(2, 1, figsize=(12, 7.5))
    _sticks(a0, markers, ref, picks, -lat, labels)
    _sticks(a1, markers, ref, picks, f, labels)
    a0.set_title(f"The {len(picks)} frames with the largest MPJPE: Pose2Sim's 3D result (thick "
                 "grey) and our exported skeleton (red: named left, blue: named right, black: "
                 "trunk); front view", fontsize=8.5)
    a1.set_title("the same frames seen from the subject's left (its forward to the right)",
                 fontsize=8.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [(i, round(err[i], 4)) for i in picks]


# (name, our bone's child joint, Pose2Sim's markers at its ends) for the bone-length comparison
BONES_COMPARED = (("upper arm", "elbow_1", "Shoulder", "Elbow"), ("forearm", "wrist_1", "Elbow", "Wrist"),
                  ("thigh", "knee_1", "Hip", "Knee"), ("shank", "ankle_1", "Knee", "Ankle"))


def widths(markers, ref):
    """Shoulder and hip widths (m, median over the frames that have both markers) and their
    ratio, ours (exported markers) against Pose2Sim's: whether a shoulder difference is a
    landmark convention (Pose2Sim's shoulders at the outer shoulder) or our placement. The
    MakeHuman rig's ratio (shoulder ``Arm_head`` / hip ``UpLeg_head`` widths of the synthetic
    ``body`` subject, average build, first frame of a walk) beside them."""
    from topopose.capture import load_capture
    from topopose.synth import synthesize

    def med(get):
        v = [np.linalg.norm(a - b) for a, b in map(get, range(len(markers)))
             if a is not None and b is not None and not (np.isnan(a).any() or np.isnan(b).any())]
        return round(float(np.median(v)), 3) if v else None
    out = {}
    for k, (a, b) in {"shoulder": ("LShoulder", "RShoulder"), "hip": ("LHip", "RHip")}.items():
        out[k] = [med(lambda i: (markers[i].get(a), markers[i].get(b))),
                  med(lambda i: (ref[a][i], ref[b][i]))]
    out["shoulder/hip"] = [None if None in (out["shoulder"][w], out["hip"][w]) else
                           round(out["shoulder"][w] / out["hip"][w], 2) for w in (0, 1)]
    with tempfile.TemporaryDirectory() as tmp:
        synthesize(tmp, subject="body", frames=1, seed=0, cameras=2, noise=0, motion="walk",
                   build="average")
        j = {k: np.asarray(v) for k, v in next(iter(load_capture(tmp).gt["frames"].values()))["joints"].items()}
    rig = [float(np.linalg.norm(j[f"Left{x}"] - j[f"Right{x}"])) for x in ("Arm_head", "UpLeg_head")]
    out["rig (shoulder, hip, ratio)"] = [round(rig[0], 3), round(rig[1], 3), round(rig[0] / rig[1], 2)]
    return out


def reference_spread(ref) -> dict:
    """Pose2Sim's own consistency: per bone of ``BONES_COMPARED``, each side's length (median
    over frames, m) and its standard deviation over the frames (cm). A rigid bone's length
    varies only by the reference's own noise: its spread bounds how closely any other method
    can agree with the reference, and the left / right difference is a per-side bias of it."""
    out = {}
    for name, _j, a, b in BONES_COMPARED:
        L = {sd: np.linalg.norm(ref[f"{sd}{a}"] - ref[f"{sd}{b}"], axis=1) for sd in "LR"}
        out[name] = {sd: [round(float(np.median(v)), 3), round(float(np.std(v)) * 100, 1)]
                     for sd, v in L.items()}
    return out


HULL_MARKERS = ("Neck", "LShoulder", "RShoulder", "LElbow", "RElbow", "LHip", "RHip", "LKnee",
                "RKnee")


def markers_in_hull(cap, markers, ref, rows, up) -> dict:
    """Where Pose2Sim's markers and ours lie against each frame's visual hull (100³, the run's
    silhouettes and tolerance) on frames ``rows``: per marker of :data:`HULL_MARKERS`, the share
    of frames in which it lies outside the hull, and for those inside, the median distance to
    the hull's front and back along Pose2Sim's forward (cm). The hull holds the body when the
    silhouettes and the calibration are right, so a joint centre lies inside it, away from its
    surface; a surface landmark lies near it."""
    from topopose.frame.estimate import FrameEstimator

    est = FrameEstimator(cap, "human", resolution=100, threshold=1e9, gate=False)
    up = np.asarray(up, float) / np.linalg.norm(up)
    acc = {}
    for i in rows:
        vol = est.hull(cap.frame_name(cap.frames[i]))
        org, vs, D = np.asarray(vol.origin, float), vol.voxel_size, vol.data

        def inside(x):
            c = np.round((x - org) / vs).astype(int)
            return bool((c >= 0).all() and (c < D.shape).all() and D[tuple(c)])

        def reach(x, d):          # how far the hull goes from x along d
            k = 0
            while k < 200 and inside(x + (k + 1) * 0.5 * vs * d):
                k += 1
            return k * 0.5 * vs
        lat = ref["LHip"][i] - ref["RHip"][i]
        lat = lat - np.dot(lat, up) * up
        fwd = np.cross(lat / np.linalg.norm(lat), up)
        for who, get in (("pose2sim", lambda n: ref[n][i]), ("ours", lambda n: markers[i].get(n))):
            for n in HULL_MARKERS:
                x = get(n)
                if x is None or np.isnan(x).any():
                    continue
                x = np.asarray(x, float)
                acc.setdefault((who, n), []).append(
                    (reach(x, fwd), reach(x, -fwd)) if inside(x) else None)
    out = {}
    for (who, n), v in acc.items():
        ins = np.array([x for x in v if x is not None]).reshape(-1, 2)
        out.setdefault(n, {})[who] = {
            "outside": round(1.0 - len(ins) / len(v), 2),
            "front_back_cm": [round(100 * float(x), 1) for x in np.median(ins, axis=0)]
            if len(ins) else None}
    return out


def signed_bias(markers, ref, rows, up) -> dict:
    """Per joint, median over ``rows`` (frames) of our marker − Pose2Sim's in Pose2Sim's body
    frame (cm): lateral (outward for a mirror joint, pairs paired optimally, both sides pooled
    and, as ``L…``/``R…``, each side alone; towards the left for Head and Neck), forward, up; the same frame as ``tracking.py --bias`` measures on the
    synthetic body (truth's hips), to compare the biases of 4 and 8 cameras with the real ones."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    acc = {}
    for i in rows:
        lat = ref["LHip"][i] - ref["RHip"][i]
        lat = lat - np.dot(lat, up) * up
        if not np.linalg.norm(lat) or np.isnan(lat).any():
            continue
        lat /= np.linalg.norm(lat)
        fwd = np.cross(lat, up)
        m = markers[i]

        def comp(e, sg=1.0):
            return [100 * sg * float(e @ lat), 100 * float(e @ fwd), 100 * float(e @ up)]
        for name in SINGLE:
            x = m.get(name)
            if x is not None and not np.isnan(x).any():
                acc.setdefault(name, []).append(comp(x - ref[name][i]))
        for stem in PAIRED:
            L, R = ref[f"L{OURS[stem]}"][i], ref[f"R{OURS[stem]}"][i]
            a, b = m.get(f"L{OURS[stem]}"), m.get(f"R{OURS[stem]}")
            if a is None or b is None or np.isnan(a).any() or np.isnan(b).any():
                a, b = m.get(f"{stem}_1"), m.get(f"{stem}_2")
            if a is None or b is None or np.isnan(a).any() or np.isnan(b).any():
                continue
            if np.linalg.norm(a - L) + np.linalg.norm(b - R) > np.linalg.norm(a - R) + np.linalg.norm(b - L):
                a, b = b, a
            acc.setdefault(stem, []).extend([comp(a - L), comp(b - R, -1.0)])
            acc.setdefault(f"L{stem}", []).append(comp(a - L))
            acc.setdefault(f"R{stem}", []).append(comp(b - R, -1.0))
    return {k: [round(float(x), 1) for x in np.median(np.array(v), axis=0)] for k, v in acc.items()}


def _fb(v):
    return "–" if v["front_back_cm"] is None else " / ".join(map(str, v["front_back_cm"]))


def _fmt(v):
    return "–" if v is None else f"{100 * v:.1f}"


def report(doc) -> str:
    m, s = doc["machine"], doc["scores"]
    L = ["# From poses to motion on the real recording (Pose2Sim balancing, against Pose2Sim's 3D result)",
         "", f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}. "
         "Written by `benchmarks/real_motion.py`; 100³, 4 cameras, silhouettes `person` "
         "(scale 0.5).", "",
         f"Per-frame result with the AHA threshold and the confidence gate **off** (best guesses "
         f"of every frame): the AHA distance accepts {s['aha_accepted']}/{s['frames']} frames at "
         f"T_d = {doc['threshold']} (the confidence gate's decision: `real.py`, whose run keeps "
         f"T_d, which the confidence's distance feature is scaled by); {s['right_frames']} frames "
         "are *right* (per-frame head, both hands and both feet within 0.15 m of Pose2Sim). "
         f"Motion stage as `topopose run` (track, skeleton, sides): {s['with_skeleton']} frames "
         f"with a skeleton ({s['interpolated']} interpolated). Errors in cm, exported TRC read "
         "back. Time: " + ", ".join(f"{k} {v}" for k, v in doc["seconds"].items()) + ".", ""]
    if doc.get("settings"):
        L += ["**A development variant, not the defaults** (`--set`): " + ", ".join(
            f"`{k} = {v}`" for k, v in doc["settings"].items()) + ".", ""]
    for label, title in (("all", "all frames"), ("right", "frames whose per-frame pose is right")):
        r = s[label]
        a, b = r["mpjpe_named"], r["mpjpe_paired"]
        joints = list(dict.fromkeys(list(b["per_joint"]) + list(a["per_joint"])))
        c = r["chirality"]
        nc = sum(c.values())
        k = 500.0 / max(r["frames"], 1)
        L += [f"## {title} ({r['frames']})", "",
              f"- MPJPE (14 joints; median over frames of the per-frame mean; p90): with our side "
              f"names {_fmt(a['mpjpe'])} cm (p90 {_fmt(a['mpjpe_p90'])}, {a['frames']} frames); "
              f"pairs paired optimally {_fmt(b['mpjpe'])} cm (p90 {_fmt(b['mpjpe_p90'])})",
              "", "| joint | " + " | ".join(joints) + " |", "|---" * (len(joints) + 1) + "|",
              "| side names | " + " | ".join(_fmt(a["per_joint"].get(j)) for j in joints) + " |",
              "| paired optimally | " + " | ".join(_fmt(b["per_joint"].get(j)) for j in joints) + " |",
              "",
              f"- chirality (frames × hands, feet): right {c['right']}/{nc}"
              + (f" ({100 * c['right'] / nc:.0f} %)" if nc else "")
              + f", wrong {c['wrong']}, unsure {c['unsure']}",
              f"- identity switches of the numbered parts: per-frame numbering {r['switches_raw']}"
              f", tracked {r['switches_tracked']} ({r['switches_raw'] * k:.0f} → "
              f"{r['switches_tracked'] * k:.0f} per 500 frames); {r['held']} part-frames held "
              "by the tracker"]
        t = r.get("toe_vs_bigtoe")
        if t and t["median"] is not None:
            L.append(f"- toes (not in the MPJPE) against Pose2Sim's big toes, paired optimally: "
                     f"{_fmt(t['median'])} cm median ({t['n']} feet)")
        pa = r.get("pa_mpjpe")
        if pa and pa["median"] is not None:
            L.append(f"- PA-MPJPE (each frame's 14 side-named joints rigidly aligned to "
                     f"Pose2Sim's first: the skeleton's shape alone): {_fmt(pa['median'])} cm "
                     f"median ({pa['frames']} frames)")
        L.append("")
    o = s.get("temporal_outliers")
    if o:
        L += [f"Frames the fit flags `temporal_outlier` (joints 0.15 m or more from their "
              f"neighbours' median; {o['judged']} frames judged): {len(o['frames'])} "
              f"({', '.join(map(str, o['frames']))}), {o['wrong_flagged']} of them wrong per "
              f"frame (of {o['wrong']} wrong frames); bridged (interpolated from the frames "
              f"either side): {len(o.get('bridged', []))} "
              f"({', '.join(map(str, o.get('bridged', []))) or 'none'}); MPJPE "
              f"{_fmt(o['mpjpe_flagged'])} cm on the flagged frames as exported against "
              f"{_fmt(o['mpjpe_others'])} cm on the {o['others']} others.", ""]
    for label, pr in doc.get("peers", {}).items():
        L += [f"Peer, the same per-frame poses, {label}: MPJPE all frames "
              f"{_fmt(pr['all']['mpjpe'])} cm (p90 {_fmt(pr['all']['mpjpe_p90'])}), right frames "
              f"{_fmt(pr['right']['mpjpe'])} cm; per joint (all / right): "
              + ", ".join(f"{j} {_fmt(v)} / {_fmt(pr['right']['per_joint'].get(j))}"
                          for j, v in pr["all"]["per_joint"].items()), ""]
    from topopose.sequence.kinematic_fit import BONE_QUANTILE

    L += ["Bone lengths (ours: constant over the sequence, the "
          f"{BONE_QUANTILE}th percentile over its frames' initial "
          "placements; Pose2Sim: left side, median over frames), m: "
          + ", ".join(f"{k} {a} vs {b}" for k, (a, b) in doc["bone_lengths_vs_pose2sim_m"].items()),
          "", "Pose2Sim's own bone lengths, left / right (m, median over frames; its standard "
          "deviation over the frames in cm — a rigid bone's length varies by the reference's "
          "own noise only): "
          + ", ".join(f"{k} {v['L'][0]} ± {v['L'][1]} / {v['R'][0]} ± {v['R'][1]}"
                      for k, v in doc.get("pose2sim_bone_spread", {}).items()),
          "", "Widths (ours vs Pose2Sim, m; median over frames): "
          + ", ".join(f"{k} {' vs '.join(map(str, v))}"
                      for k, v in doc.get("widths_vs_pose2sim_m", {}).items()),
          "", "Against the visual hull, right frames (share of frames outside it; inside, the "
          "median distance to its front / back along Pose2Sim's forward, cm), Pose2Sim vs ours: "
          + ", ".join(f"{n} {v['pose2sim']['outside']} ({_fb(v['pose2sim'])}) vs "
                      f"{v['ours']['outside']} ({_fb(v['ours'])})"
                      for n, v in doc.get("markers_in_hull", {}).items()
                      if "pose2sim" in v and "ours" in v),
          "", f"Hull fatness (hull litres / height³, median over frames): {doc.get('hull_fatness')}"
          " (synthetic body: `tracking_bias_dev.md`).",
          "", "Signed bias on the right frames (ours − Pose2Sim, cm, median; Pose2Sim's body "
          "frame: outward (left for Head/Neck), forward, up; compare `tracking_bias_dev.md`): "
          + ", ".join(f"{k} ({', '.join(f'{x:+.1f}' for x in v)})"
                      for k, v in doc.get("signed_bias_right_cm", {}).items()),
          "", f"Picture: `{doc['picture']}`.", "",
          "The frames with the largest MPJPE (frame: cm): "
          + ", ".join(f"{i}: {100 * e:.0f}" for i, e in doc.get("worst_frames", []))
          + f"; picture `{doc.get('worst_picture')}`.", ""]
    sp = doc.get("grid_spread")
    if sp:
        rows = {100: {"right_frames": s["right_frames"],
                      **{w: s[w]["mpjpe_named"] for w in ("all", "right")}}, **sp}
        vals = {w: [v[w]["mpjpe"] for v in rows.values()] for w in ("all", "right")}
        L += ["## The grid's placement alone (`grid_spread`)", "",
              "The same benchmark at other resolutions (voxel size and lattice moved, the "
              "subject not): MPJPE with side names, cm, all frames (p90) / right frames "
              "(their number).", "",
              "| resolution | all frames | right frames |", "|---|---|---|"]
        L += [f"| {r} | {_fmt(v['all']['mpjpe'])} ({_fmt(v['all']['mpjpe_p90'])}) | "
              f"{_fmt(v['right']['mpjpe'])} ({v['right_frames']}) |" for r, v in sorted(rows.items())]
        L += ["", "Range over the resolutions: all frames "
              f"{_fmt(min(vals['all']))}–{_fmt(max(vals['all']))} cm (mean "
              f"{_fmt(float(np.mean(vals['all'])))}), right frames {_fmt(min(vals['right']))}–"
              f"{_fmt(max(vals['right']))} cm (mean {_fmt(float(np.mean(vals['right'])))}).", ""]
    return "\n".join(L)


def main(argv=None):
    from _machine import machine, results_dir, sequence_settings, write_results

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(DEFAULT))
    ap.add_argument("--raw", default=None, help="per-frame poses.jsonl to reuse (or write)")
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--no-hand-hints", action="store_true",
                    help="the kinematic fit without the hand hints (hints=False): "
                         "the peer of the default")
    ap.add_argument("--spread", default="96,98,102,104",
                    help="other grid resolutions to run the benchmark at (grid_spread; "
                         "'' to skip)")
    ap.add_argument("--quick", action="store_true", help="without the other grids (--spread '')")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE",
                    help="a sequence option (name=value, a SequenceOptions field) for this run "
                         "(a Python literal; repeatable): "
                         "a development variant, never a published figure")
    a = ap.parse_args(argv)
    from topopose.sequence.options import SequenceOptions
    settings = sequence_settings(a.set)
    sequence = SequenceOptions.of(**settings, **({"hints": False} if a.no_hand_hints else {}))
    if a.quick:
        a.spread = ""
    from real import person_recording

    opened = person_recording(a.recording)
    if isinstance(opened, int):
        return opened
    rec, ref = opened
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        raw, motion, cap, model, trc_path, secs = run_recording(rec, Path(tmp), a.raw,
                                                                 sequence=sequence)
        s, markers, right = score(raw, motion.poses, trc_path, ref, model)
        picture(out / "real_motion.png", markers, ref, right, motion.poses,
                np.asarray(cap.up_vector, float))
        worst = worst_picture(out / "real_motion_worst.png", markers, ref, right, motion.poses,
                              np.asarray(cap.up_vector, float))
        peers = peer_scores(raw, cap, model, ref, tmp)
        in_hull = markers_in_hull(cap, markers, ref, [i for i in range(len(right)) if right[i]],
                                  cap.up_vector)
        spread = grid_spread(rec, Path(tmp), ref, [int(r) for r in a.spread.split(",") if r])
    doc = {"recording": str(rec), "machine": machine(resolution=100, cameras=4),
           "threshold": model.threshold, "seconds": secs, "picture": "real_motion.png",
           "hand_hints": not a.no_hand_hints, "settings": settings,
           "bone_lengths_m": {motion.tree.names[j]: round(float(x), 4)
                              for j, x in enumerate(motion.lengths) if np.isfinite(x)},
           "bone_lengths_vs_pose2sim_m": {
               name: [round(float(motion.lengths[motion.tree.names.index(j)]), 3),
                      round(float(np.median(np.linalg.norm(ref[f"{sd}{a}"] - ref[f"{sd}{b}"], axis=1))), 3)]
               for name, j, a, b in BONES_COMPARED for sd in "L"},
           "pose2sim_bone_spread": reference_spread(ref),
           "widths_vs_pose2sim_m": widths(markers, ref),
           "markers_in_hull": in_hull, "peers": peers,
           "hull_fatness": round(float(np.median([p.diagnostics["hull_litres"]
                                                   / p.diagnostics["height"] ** 3 for p in raw
                                                   if p.diagnostics.get("height")])), 2),
           "signed_bias_right_cm": signed_bias(markers, ref, [i for i in range(len(right))
                                                              if right[i]], cap.up_vector),
           "scores": s, "grid_spread": spread, "worst_frames": worst,
           "worst_picture": "real_motion_worst.png"}
    write_results(out / "real_motion", doc, report)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
