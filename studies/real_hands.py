"""Is Pose2Sim's hand trustworthy where ``run --consistency`` passes a wrong frame?

    python studies/real_hands.py [RECORDING] [--work DIR]

RECORDING (default ``benchmarks/data/pose2sim_balancing/``, as ``benchmarks/real.py``) needs
``videos/``, ``Calib.toml``, ``reference/pose2sim_3d.trc`` (Pose2Sim's 3D result) and
``pose_2d/camNN_json/camNN.FFFF.json`` (the OpenPose BODY_25B 2D keypoints Pose2Sim
triangulated, with their scores); the script says so and stops when they are absent.

The frames: the recording as ``topopose run --consistency`` writes it (``person``
silhouettes, as ``studies/trust_features.py`` computes them: the per-frame records are
cached in ``--work``), the *matched* frames that are wrong by ``benchmarks/real.py``'s rule
(a hand more than 0.15 m from Pose2Sim's wrist → 0.1 m beyond it, or the head or a foot off).
Nothing here chooses a threshold; it only looks.

For each such frame and each of the 4 cameras: Pose2Sim's wrist (and the segment to 0.1 m
beyond it) and our hand projected into the image, the OpenPose 2D wrist and its score, the
``person`` network's silhouette. Also, per frame, Pose2Sim's reprojection error (its 3D
markers projected against the OpenPose keypoints with score ≥ 0.3, Pose2Sim's default
likelihood threshold), and a wrist triangulated here from the OpenPose wrists (DLT weighted by
the scores, the cameras with score ≥ 0.3) as a third, independent 3D point.

Writes ``results/real_hands.{md,json}`` and ``results/real_hands.png``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

#: BODY_25B keypoint index of each marker of Pose2Sim's TRC (OpenPose's BODY_25B order)
BODY_25B = {"Nose": 0, "LShoulder": 5, "RShoulder": 6, "LElbow": 7, "RElbow": 8, "LWrist": 9,
            "RWrist": 10, "LHip": 11, "RHip": 12, "LKnee": 13, "RKnee": 14, "LAnkle": 15,
            "RAnkle": 16, "Neck": 17, "Head": 18, "LBigToe": 19, "LSmallToe": 20, "LHeel": 21,
            "RBigToe": 22, "RSmallToe": 23, "RHeel": 24}
#: Pose2Sim's default likelihood threshold for triangulation
MIN_SCORE = 0.3


def read_openpose(rec: Path, n_cams: int, frame: int) -> np.ndarray:
    """(cameras, 25, 3) OpenPose x, y, score of one frame (NaN when the file has no person)."""
    out = np.full((n_cams, 25, 3), np.nan)
    for c in range(n_cams):
        f = rec / "pose_2d" / f"cam{c + 1:02d}_json" / f"cam{c + 1:02d}.{frame:04d}.json"
        people = json.loads(f.read_text()).get("people") if f.is_file() else None
        kp = (people or [{}])[0].get("pose_keypoints_2d")      # an empty entry: no person
        if kp:
            out[c] = np.asarray(kp, float).reshape(-1, 3)[:25]
    return out


def triangulate(cams, uv, w) -> np.ndarray:
    """DLT of one point from pixel observations ``uv`` (k, 2) in ``cams`` weighted by ``w``
    (lens distortion of this calibration < 0.3 px at the image border: ignored)."""
    A = []
    for cam, (u, v), wi in zip(cams, uv, w):
        P = cam.matrix @ np.hstack([cam.R, cam.translation.reshape(3, 1)])
        A += [wi * (u * P[2] - P[0]), wi * (v * P[2] - P[1])]
    X = np.linalg.svd(np.asarray(A))[2][-1]
    return X[:3] / X[3]


#: Pose2Sim's default reprojection error limit (px) of a triangulated point
MAX_REPROJ = 15.0


def triangulate_robust(cams, uv, w):
    """:func:`triangulate` as Pose2Sim does it: with all views, and while the mean reprojection
    error is above :data:`MAX_REPROJ`, with one more view left out (every combination tried,
    the best kept; at least 2 views): (point, indices of the views kept, their mean
    reprojection error px)."""
    import itertools

    n = len(cams)
    best = None
    for k in range(n, 1, -1):
        for keep in itertools.combinations(range(n), k):
            keep = list(keep)
            X = triangulate([cams[j] for j in keep], uv[keep], w[keep])
            err = float(np.mean([np.linalg.norm(cams[j].project(X[None])[0] - uv[j])
                                 for j in keep]))
            if best is None or err < best[2]:
                best = (X, keep, err)
        if best[2] <= MAX_REPROJ:
            break
        best = None if k > 2 else best
    return best


def hand_points(ref, i):
    """Pose2Sim's hand per side: wrist, wrist + 0.1 m along elbow → wrist (real.py)."""
    import real

    out = {}
    for s in "LR":
        w, e = ref[f"{s}Wrist"][i], ref[f"{s}Elbow"][i]
        out[s] = (w, w + real.HAND_EXT * (w - e) / max(np.linalg.norm(w - e), 1e-9))
    return out


def pair_hands(parts, segs):
    """Our hand_1/hand_2 → side L/R as real.frame_errors pairs them."""
    import real

    a, b = parts.get("hand_1"), parts.get("hand_2")
    s1 = real.seg_dist(a, *segs["L"]) + real.seg_dist(b, *segs["R"])
    s2 = real.seg_dist(a, *segs["R"]) + real.seg_dist(b, *segs["L"])
    return {"L": a, "R": b} if s1 <= s2 else {"L": b, "R": a}


def run_poses(recording, work):
    """The per-frame records (trust_features.real_records) and the poses as ``run
    --consistency`` writes them, with the right flag per frame."""
    import real
    import trust_features as T

    recs, _ = T.real_records(recording, work)
    ps, idx, ref = T.as_run_consistency(recording, recs, [T.features_of(r) for r in recs], True)
    rows = []
    for p in ps:
        i = idx[p.frame]
        e = real.frame_errors(p.parts, ref, i) if p.status != "failed" else None
        rows.append({"i": i, "pose": p, "errors": e, "record": recs[i],
                     "right": e is not None and all(v <= real.RIGHT for v in e.values())})
    return rows, ref


def reprojection(cams, ref, i, kp):
    """Pose2Sim's 3D markers of frame ``i`` projected against the OpenPose keypoints (score ≥
    MIN_SCORE): per camera the median error (px), and per wrist and camera the error."""
    per_cam, wrist = [], {}
    for c, cam in enumerate(cams):
        errs = []
        for name, k in BODY_25B.items():
            x, y, s = kp[c, k]
            if not np.isfinite(s) or s < MIN_SCORE:
                continue
            d = float(np.linalg.norm(cam.project(ref[name][i][None])[0] - (x, y)))
            errs.append(d)
            if name.endswith("Wrist"):
                wrist.setdefault(name[0], [None] * len(cams))[c] = round(d, 1)
        per_cam.append(round(float(np.median(errs)), 1) if errs else None)
    return per_cam, wrist


def analyse(rec: Path, rows, ref, cams):
    """Per frame (wrong matched ones in detail, all frames for the reprojection baseline)."""
    from scipy.ndimage import distance_transform_edt

    import trust_features as T

    base_all, base_wrist = [], []
    detail = []
    for r in rows:
        kp = read_openpose(rec, len(cams), r["i"])
        per_cam, wrist = reprojection(cams, ref, r["i"], kp)
        base_all += [x for x in per_cam if x is not None]
        base_wrist += [x for v in wrist.values() for x in v if x is not None]
        if not (r["pose"].status == "matched" and not r["right"]):
            continue
        segs = hand_points(ref, r["i"])
        ours = pair_hands(r["pose"].parts, segs)
        masks = [T.unpack(m) for m in r["record"]["masks"]]
        scams = r["record"]["cams"]
        sides = {}
        for s in "LR":
            k = BODY_25B[f"{s}Wrist"]
            ok = [c for c in range(len(cams)) if np.isfinite(kp[c, k, 2]) and kp[c, k, 2] >= MIN_SCORE]
            tri = (triangulate([cams[c] for c in ok], kp[ok, k, :2], kp[ok, k, 2])
                   if len(ok) >= 2 else None)
            rob = (triangulate_robust([cams[c] for c in ok], kp[ok, k, :2], kp[ok, k, 2])
                   if len(ok) >= 2 else None)
            w, tip = segs[s]
            o = ours[s]
            views = []
            for c, cam in enumerate(cams):
                sc = scams[c].matrix[0, 0] / cam.matrix[0, 0]     # silhouette's scale
                dist_out = distance_transform_edt(~masks[c])     # px (small) to the silhouette

                def outside(X):
                    u, v = np.round(scams[c].project(np.asarray(X, float)[None])[0]).astype(int)
                    H, W = masks[c].shape
                    if not (0 <= u < W and 0 <= v < H):
                        return None
                    return round(float(dist_out[v, u]) / sc, 1)  # full-size px, 0 inside
                op = kp[c, k]
                pw = cam.project(w[None])[0]
                view = {"openpose": None if not np.isfinite(op[2]) else
                        [round(float(op[0]), 1), round(float(op[1]), 1), round(float(op[2]), 3)],
                        "p2s_wrist_px": pw.round(1).tolist(),
                        "p2s_wrist_vs_openpose_px": None if not np.isfinite(op[2]) else
                        round(float(np.linalg.norm(pw - op[:2])), 1),
                        "p2s_wrist_outside_px": outside(w), "p2s_tip_outside_px": outside(tip)}
                if o is not None:
                    po = cam.project(np.asarray(o, float)[None])[0]
                    view.update(ours_px=po.round(1).tolist(), ours_outside_px=outside(o),
                                ours_vs_openpose_px=None if not np.isfinite(op[2]) else
                                round(float(np.linalg.norm(po - op[:2])), 1))
                views.append(view)
            import real
            sides[s] = {
                "ours_to_p2s_hand_m": None if o is None else round(real.seg_dist(o, w, tip), 3),
                "triangulated_cameras": len(ok),
                "triangulated_to_p2s_wrist_m": None if tri is None else
                round(float(np.linalg.norm(tri - w)), 3),
                "ours_to_triangulated_hand_m": None if tri is None or o is None else round(
                    real.seg_dist(o, tri, tri + (tip - w)), 3),
                "robust_cameras": None if rob is None else [ok[j] + 1 for j in rob[1]],
                "robust_reprojection_px": None if rob is None else round(rob[2], 1),
                "robust_to_p2s_wrist_m": None if rob is None else
                round(float(np.linalg.norm(rob[0] - w)), 3),
                "ours_to_robust_hand_m": None if rob is None or o is None else round(
                    real.seg_dist(o, rob[0], rob[0] + (tip - w)), 3),
                "views": views}
        detail.append({"frame": r["i"], "errors_m": {k: round(v, 3) for k, v in r["errors"].items()},
                       "unexplained": r["pose"].diagnostics.get("unexplained"),
                       "p2s_reprojection_median_px": per_cam, "p2s_wrist_reprojection_px": wrist,
                       "sides": sides})
    return detail, {"p2s_reprojection_px_median_all_frames": round(float(np.median(base_all)), 1),
                    "p2s_reprojection_px_p90_all_frames": round(float(np.percentile(base_all, 90)), 1),
                    "p2s_wrist_reprojection_px_median": round(float(np.median(base_wrist)), 1),
                    "p2s_wrist_reprojection_px_p90": round(float(np.percentile(base_wrist, 90)), 1)}


def picture(rec: Path, rows, ref, cams, detail, path, zoom=None):
    """Per wrong frame (rows) and camera (columns): the image around the subject, the
    silhouette's contour, Pose2Sim's wrist → hand segment, OpenPose's wrist, our hand.
    ``zoom`` (px): per wrong frame and hand more than 0.15 m off instead, a square of that
    size around its two projections (ours, Pose2Sim's wrist)."""
    import cv2
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import trust_features as T

    by = {r["i"]: r for r in rows}
    caps = [cv2.VideoCapture(str(rec / "videos" / f"cam{c + 1:02d}.mp4")) for c in range(len(cams))]
    import real
    panels = [(d, None) for d in detail] if not zoom else [
        (d, s) for d in detail for s, v in d["sides"].items()
        if v["ours_to_p2s_hand_m"] is not None and v["ours_to_p2s_hand_m"] > real.RIGHT]
    fig, axes = plt.subplots(len(panels), len(cams), squeeze=False,
                             figsize=(3.2 * len(cams), (3.4 if zoom else 4.2) * len(panels)))
    for row, (d, side) in zip(axes, panels):
        r = by[d["frame"]]
        masks = [T.unpack(m) for m in r["record"]["masks"]]
        for c, ax in enumerate(row):
            caps[c].set(cv2.CAP_PROP_POS_FRAMES, d["frame"])
            ok, img = caps[c].read()
            if not ok:
                img = np.zeros((1920, 1080, 3), np.uint8)
            H, W = img.shape[:2]
            m = cv2.resize(masks[c].astype(np.uint8), (int(cams[c].size[0]), int(cams[c].size[1])),
                           interpolation=cv2.INTER_NEAREST)[:H, :W]
            if side is None:
                ys, xs = np.nonzero(m)
                x0, x1 = max(xs.min() - 80, 0), min(xs.max() + 80, W)
                y0, y1 = max(ys.min() - 80, 0), min(ys.max() + 80, H)
            else:
                v = d["sides"][side]["views"][c]
                cx, cy = (np.asarray(v["p2s_wrist_px"]) + np.asarray(v["ours_px"])) / 2
                x0 = int(np.clip(cx - zoom / 2, 0, max(W - zoom, 0)))
                y0 = int(np.clip(cy - zoom / 2, 0, max(H - zoom, 0)))
                x1, y1 = min(x0 + zoom, W), min(y0 + zoom, H)
            ax.imshow(img[y0:y1, x0:x1, ::-1], extent=(x0, x1, y1, y0))
            ax.contour(np.arange(x0, x1), np.arange(y0, y1), m[y0:y1, x0:x1], [0.5],
                       colors="yellow", linewidths=0.8)
            for s, col in (("L", "cyan"), ("R", "magenta")):
                v = d["sides"][s]["views"][c]
                w, tip = hand_points(ref, d["frame"])[s]
                pw, pt = cams[c].project(np.array([w, tip]))
                ax.plot([pw[0], pt[0]], [pw[1], pt[1]], "-", color=col, lw=2)
                ax.plot(*pw, "o", mfc="none", mec=col, ms=9, mew=1.5)
                if v["openpose"] is not None:
                    ax.plot(v["openpose"][0], v["openpose"][1], "+", color=col, ms=12, mew=2)
                    ax.text(v["openpose"][0] + 12, v["openpose"][1], f"{v['openpose'][2]:.2f}",
                            color=col, fontsize=7, clip_on=True)
                if "ours_px" in v:
                    ax.plot(*v["ours_px"], "x", color="red", ms=10, mew=2.5)
                    ax.plot(*v["ours_px"], "x", color=col, ms=6, mew=1)
            ax.set_xlim(x0, x1)
            ax.set_ylim(y1, y0)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"frame {d['frame']}, cam{c + 1:02d}"
                         + (f", hand {side} (zoom)" if side else ""), fontsize=8)
    for cp in caps:
        cp.release()
    fig.suptitle("○ Pose2Sim wrist, line → 0.1 m beyond (its hand); + OpenPose wrist (score); "
                 "× ours (red); cyan L, magenta R; yellow: person silhouette", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=70 if zoom else 60)
    plt.close(fig)


def hand_depth(parts, cams, masks) -> float:
    """The deepest hand's depth inside the silhouettes: per hand (parts whose name holds
    ``hand``), its projection's distance to each silhouette's contour over that silhouette's
    largest inscribed radius, the second deepest of the views; the largest over the hands."""
    from scipy.ndimage import distance_transform_edt

    dts = []
    for m in masks:
        d = distance_transform_edt(np.asarray(m, bool))
        dts.append((d, max(float(d.max()), 1.0)))
    depth = 0.0
    for name, x in parts.items():
        if "hand" not in name or x is None:
            continue
        ds = []
        for cam, (d, dm) in zip(cams, dts):
            u, v = np.round(cam.project(np.asarray(x, float)[None])[0]).astype(int)
            ds.append(d[v, u] / dm if 0 <= v < d.shape[0] and 0 <= u < d.shape[1] else 0.0)
        depth = max(depth, sorted(ds)[-2] if len(ds) > 1 else 0.0)
    return float(depth)


def geometric_tests(rows) -> dict:
    """Could a per-frame geometric test tell the wrong matched frames from the right ones?
    Per matched frame, its most suspicious hand by: *depth* — the hand's projection's distance
    to the silhouette's contour over the silhouette's largest inscribed radius, the second
    deepest of the 4 views (a hand in a phantom volume in front of the trunk lies deep in two
    views); *arm* — the hand arc's skeleton-curve length over the run's own
    (:func:`topopose.sequence.consistency.length_ratios`), the farthest from 1. Ranges over the
    right and the wrong frames."""
    import trust_features as T
    from topopose.sequence import consistency as C
    from topopose.pose.model import load_model

    model = load_model("human")
    lengths = C.run_lengths([r["pose"] for r in rows], model)
    out = {"right": {"depth": [], "arm": []}, "wrong": {"depth": [], "arm": []}, "frames": {}}
    for r in rows:
        p = r["pose"]
        if p.status != "matched":
            continue
        depth = hand_depth(p.parts, r["record"]["cams"], [T.unpack(m) for m in r["record"]["masks"]])
        ratios = [v for k, v in C.length_ratios(p, model, lengths).items() if k.startswith("hand")]
        arm = max(ratios, key=lambda x: abs(np.log(x))) if ratios else 1.0
        key = "right" if r["right"] else "wrong"
        out[key]["depth"].append(round(float(depth), 3))
        out[key]["arm"].append(round(float(arm), 3))
        out["frames"][r["i"]] = {"right": r["right"], "depth": round(float(depth), 3),
                                 "arm": round(float(arm), 3)}
    return out


#: a confident OpenPose keypoint (score), an agreement and a disagreement in pixels (full size)
CONFIDENT, AGREE_PX, FAR_PX = 0.5, 35.0, 100.0


def summary(detail) -> list:
    """Per wrong hand (more than 0.15 m from Pose2Sim's): which cameras see a confident
    OpenPose wrist, in which of them Pose2Sim's wrist agrees with it and ours is far from it,
    and whether Pose2Sim's wrist is the robust triangulation of the OpenPose wrists."""
    import real

    out = []
    for d in detail:
        for s, v in d["sides"].items():
            if v["ours_to_p2s_hand_m"] is None or v["ours_to_p2s_hand_m"] <= real.RIGHT:
                continue
            conf = [c for c, x in enumerate(v["views"])
                    if x["openpose"] is not None and x["openpose"][2] >= CONFIDENT]
            agree = [c + 1 for c in conf if v["views"][c]["p2s_wrist_vs_openpose_px"] <= AGREE_PX]
            far = [c + 1 for c in conf if (v["views"][c].get("ours_vs_openpose_px") or 0) >= FAR_PX]
            out.append(f"frame {d['frame']} hand {s} ({v['ours_to_p2s_hand_m']} m off): OpenPose "
                       f"confident (score ≥ {CONFIDENT:g}) in cameras {[c + 1 for c in conf]}; "
                       f"Pose2Sim's wrist within {AGREE_PX:g} px of it in {agree}; ours ≥ "
                       f"{FAR_PX:g} px from it in {far}; Pose2Sim's wrist is the robust "
                       f"triangulation of cameras {v['robust_cameras']} to "
                       f"{v['robust_to_p2s_wrist_m']} m")
    return out


def report(doc) -> str:
    L = ["# Pose2Sim's hand on the real frames `run --consistency` passes wrongly", "",
         f"{doc['machine_line']}. Written by `studies/real_hands.py`.", "",
         "Frames: matched by `topopose run --consistency` (`person` silhouettes) but wrong by "
         "`benchmarks/real.py`'s rule (head, both hands, both feet within 0.15 m of Pose2Sim). "
         "Pixel figures at full image size (1088×1920). *outside*: distance (px) from the "
         "projected point to the `person` silhouette, 0 inside. OpenPose: BODY_25B wrist, "
         f"score; Pose2Sim triangulates keypoints with score ≥ {MIN_SCORE}. *Triangulated here*: "
         "the OpenPose wrists with score ≥ 0.3, DLT weighted by the scores; *robust*: as "
         f"Pose2Sim, views left out (every combination, the best kept) while the mean "
         f"reprojection error is above {MAX_REPROJ:g} px, the cameras kept listed. Pictures: `real_hands.png` (whole "
         "subject), `real_hands_zoom.png` (around each hand more than 0.15 m off).", "",
         "Pose2Sim's reprojection error against the OpenPose keypoints over all 100 frames "
         f"(per camera and frame, the median over its keypoints): median "
         f"{doc['baseline']['p2s_reprojection_px_median_all_frames']} px, p90 "
         f"{doc['baseline']['p2s_reprojection_px_p90_all_frames']} px; wrists alone: median "
         f"{doc['baseline']['p2s_wrist_reprojection_px_median']} px, p90 "
         f"{doc['baseline']['p2s_wrist_reprojection_px_p90']} px.", "",
         "| frame | side | ours → Pose2Sim hand (m) | OpenPose wrist score cam1–4 | Pose2Sim wrist − OpenPose (px) cam1–4 | ours − OpenPose wrist (px) cam1–4 | ours outside silhouette (px) | Pose2Sim wrist / hand end outside (px) | wrist triangulated here − Pose2Sim wrist (m, cameras) | ours → triangulated hand (m) | robust: cameras kept, − Pose2Sim wrist (m) | ours → robust hand (m) |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def j(xs):
        return " / ".join("–" if x is None else f"{x:g}" for x in xs)
    for d in doc["frames"]:
        for s, v in d["sides"].items():
            vs = v["views"]
            L.append(f"| {d['frame']} | {s} | {v['ours_to_p2s_hand_m']} | "
                     f"{j([None if x['openpose'] is None else x['openpose'][2] for x in vs])} | "
                     f"{j([x['p2s_wrist_vs_openpose_px'] for x in vs])} | "
                     f"{j([x.get('ours_vs_openpose_px') for x in vs])} | "
                     f"{j([x.get('ours_outside_px') for x in vs])} | "
                     f"{j([x['p2s_wrist_outside_px'] for x in vs])} ; "
                     f"{j([x['p2s_tip_outside_px'] for x in vs])} | "
                     f"{v['triangulated_to_p2s_wrist_m']} ({v['triangulated_cameras']}) | "
                     f"{v['ours_to_triangulated_hand_m']} | "
                     f"{v['robust_cameras']}, {v['robust_to_p2s_wrist_m']} | "
                     f"{v['ours_to_robust_hand_m']} |")
    L += ["", "Per frame: errors (m) by part against Pose2Sim; the unexplained share; Pose2Sim's "
          "reprojection median per camera (px).", "",
          "| frame | errors (m) | unexplained | Pose2Sim reprojection median cam1–4 (px) |",
          "|---|---|---|---|"]
    for d in doc["frames"]:
        L.append(f"| {d['frame']} | " + ", ".join(f"{k} {v:g}" for k, v in d["errors_m"].items())
                 + f" | {d['unexplained']} | {j(d['p2s_reprojection_median_px'])} |")
    g = doc.get("geometric")
    if g and g["wrong"]["depth"]:
        def rng(x):
            return f"{min(x):.2f}–{max(x):.2f}" if x else "–"
        L += ["", "Could a per-frame geometric test see them? (`geometric_tests`; matched frames, "
              "the most suspicious hand; not used to choose anything)", "",
              "| frames | n | hand depth in its 2nd deepest view (× largest inscribed radius) | "
              "hand arc length / the run's own |", "|---|---|---|---|"]
        for k in ("right", "wrong"):
            L.append(f"| {k} | {len(g[k]['depth'])} | {rng(g[k]['depth'])} | {rng(g[k]['arm'])} |")
    if doc.get("summary"):
        L += ["", "Per wrong hand:", ""] + [f"- {x}" for x in doc["summary"]]
    if doc.get("finding"):
        L += ["", "**Finding** (by eye on the pictures, and the figures above). " + doc["finding"]]
    return "\n".join(L) + "\n"


def main(argv=None):
    import real
    from _machine import machine, machine_line

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--work", default=None, help="cache of the per-frame records "
                    "(studies/trust_features.py's, reused)")
    ap.add_argument("--finding", default=None, help="a sentence appended to the report")
    ap.add_argument("--out", default=str(HERE / "results" / "real_hands"))
    a = ap.parse_args(argv)
    rec = Path(a.recording)
    need = [rec / "videos", rec / "Calib.toml", rec / "reference" / "pose2sim_3d.trc",
            rec / "pose_2d"]
    missing = [str(p) for p in need if not p.exists()]
    if missing:
        print(f"{rec}: recording not found or incomplete (missing {', '.join(missing)}); "
              "pass its path")
        return 1
    import topopose as tp
    work = a.work or tempfile.mkdtemp(prefix="real_hands_")
    rows, ref = run_poses(rec, work)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        real.make_capture(rec, Path(tmp) / "c", "person")
        cams = list(tp.load_capture(Path(tmp) / "c").cameras)
    detail, base = analyse(rec, rows, ref, cams)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if detail:
        picture(rec, rows, ref, cams, detail, out.with_suffix(".png"))
        picture(rec, rows, ref, cams, detail, out.with_name(out.name + "_zoom.png"), zoom=420)
    mach = machine()
    doc = {"machine": mach, "machine_line": machine_line(mach), "baseline": base,
           "matched": sum(r["pose"].status == "matched" for r in rows),
           "wrong_matched": [d["frame"] for d in detail], "frames": detail,
           "summary": summary(detail), "geometric": geometric_tests(rows),
           "finding": a.finding}
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1, default=float))
    out.with_suffix(".md").write_text(report(doc))
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
