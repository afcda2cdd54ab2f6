"""Photo-consistency of the hand branches on the real recording (docs/decisions.md).

    PYTHONPATH=src:/path/to/mediapipe python studies/real_leaf_colour.py [RECORDING] [--frames N]

Does a hand's skeleton branch whose colours disagree between the 4 cameras tell a misplaced
hand (a phantom branch of the 4-camera hull: cones of different body parts intersecting)?
Per frame of the recording (``person`` silhouettes, :class:`FrameEstimator` defaults, gate
off): each data-tree leaf matched to ``hand_1``/``hand_2``; its branch = the hull's surface
voxels whose nearest skeleton voxel lies on the leaf's edge or vertex, within ``--radius`` of
the leaf; each voxel seen by a camera when its depth is within 1.5 voxels of that camera's
z-buffer of the hull surface; its colour = normalised chroma (r, g) = (R, G) / (R + G + B) of
the image at 1/4 size. Scores: *voxel spread* (median over the voxels seen by ≥ 2 cameras of
the standard deviation of their chroma across cameras) and *view spread* (largest distance
between the per-camera mean chromas of the branch, cameras seeing ≥ 3 of its voxels). A hand
is *wrong* when its leaf lies more than 0.15 m from both true hands (``real.py``'s segments).

Reported: the AUC (wrong above right) of each score, the wrong hands flagged at thresholds set
at the right hands' 90/95/98/100th percentile (set on the recording: an upper bound), and the
effect on ``real.py``'s scores of leaving the flagged hands unplaced.
"""
from __future__ import annotations

import argparse
import copy
import json
import shutil
import tempfile
import warnings
import sys
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage as ndi

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import real  # noqa: E402


def leaf_colours(cap, frame, det, ref_i, radius, scale=0.25):
    """Per hand-matched leaf: error of the leaf (m), voxel spread, view spread."""
    from topopose.capture.images import read_images

    vol, data, al = det.volume, det.data, det.alignment
    sk = np.asarray(det.skeleton, dtype=bool)
    _, ind = ndi.distance_transform_edt(~sk, return_indices=True)
    near = np.ravel_multi_index(tuple(ind), sk.shape)
    lab_e = np.full(sk.size, -2)
    lab_v = np.full(sk.size, -2)
    lab_e[data.voxels["index"]] = data.voxels["edge"]
    lab_v[data.voxels["index"]] = data.voxels["vertex"]
    surf = vol.data & ~ndi.binary_erosion(vol.data, border_value=0)
    ijk = np.argwhere(surf)
    s_near = near[tuple(ijk.T)]
    pts = vol.world(ijk)
    chroma = np.full((len(cap.cameras), len(pts), 2), np.nan)
    for c, (cam, img) in enumerate(zip(cap.cameras, read_images(cap, frame))):
        small = cv2.GaussianBlur(cv2.resize(img, None, fx=scale, fy=scale,
                                            interpolation=cv2.INTER_AREA).astype(float), (3, 3), 0)
        h, w = small.shape[:2]
        uv = cam.project(pts) * scale
        z = cam.to_camera(pts)[:, 2]
        ok = (np.isfinite(uv).all(1) & (uv[:, 0] >= 0) & (uv[:, 1] >= 0)
              & (uv[:, 0] < w - 1) & (uv[:, 1] < h - 1))
        uv = np.where(ok[:, None], uv, 0)
        key = (uv[:, 1] // 2).astype(int) * (w + 1) + (uv[:, 0] // 2).astype(int)
        zbuf = np.full((h + 1) * (w + 1), np.inf)
        np.minimum.at(zbuf, key[ok], z[ok])
        seen = ok & (z <= zbuf[key] + 1.5 * vol.voxel_size)
        px = small[uv[seen, 1].astype(int), uv[seen, 0].astype(int)]
        tot = px.sum(1) + 1e-6
        chroma[c, seen] = np.stack([px[:, 2] / tot, px[:, 1] / tot], 1)
    segs = []
    for side in "LR":
        wr, el = ref_i[f"{side}Wrist"], ref_i[f"{side}Elbow"]
        segs.append((wr, wr + real.HAND_EXT * (wr - el) / np.linalg.norm(wr - el)))
    edges_of = {}
    for k, (u, v, _) in enumerate(data.edges):
        edges_of.setdefault(u, []).append(k)
        edges_of.setdefault(v, []).append(k)
    out = {}
    for part in ("hand_1", "hand_2"):
        v = al.mapping.get(part)
        if v is None or len(edges_of.get(v, ())) != 1 or data.positions.get(v) is None:
            continue
        pos = np.asarray(data.positions[v])
        m = (((lab_e[s_near] == edges_of[v][0]) | (lab_v[s_near] == v))
             & (np.linalg.norm(pts - pos, axis=1) <= radius))
        cc = chroma[:, m]
        multi = np.isfinite(cc[..., 0]).sum(0) >= 2
        voxel = (float(np.median(np.nanstd(cc[:, multi], axis=0).mean(-1)))
                 if multi.any() else np.nan)
        means = np.array([np.nanmean(cc[c], 0) for c in range(len(cc))
                          if np.isfinite(cc[c, :, 0]).sum() >= 3])
        view = (float(np.max(np.linalg.norm(means[:, None] - means[None], axis=-1)))
                if len(means) >= 2 else np.nan)
        out[part] = {"error": min(real.seg_dist(pos, *s) for s in segs),
                     "voxel_spread": voxel, "view_spread": view}
    return out


def auc(pos, neg):
    pos, neg = np.asarray(pos, float), np.asarray(neg, float)
    pos, neg = pos[np.isfinite(pos)], neg[np.isfinite(neg)]
    return float((pos[:, None] > neg[None]).mean() + 0.5 * (pos[:, None] == neg[None]).mean())


def main(argv=None):
    import topopose as tp
    from _machine import machine
    from topopose.frame.confidence import temporal_confidence
    from topopose.frame.estimate import FrameEstimator, default_gate

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--frames", type=int, default=0, help="first N frames only (0: all)")
    ap.add_argument("--radius", type=float, default=0.08, help="branch within this of the leaf (m)")
    ap.add_argument("--out", default=str(real.HERE / "results" / "real_leaf_colour"))
    a = ap.parse_args(argv)
    rec = Path(a.recording)
    if not (rec / "videos").is_dir():
        print(f"{rec}: recording not found; pass its path")
        return 2
    ref = real.read_trc(rec / "reference" / "pose2sim_3d.trc")
    tmp = Path(tempfile.mkdtemp())
    try:
        warnings.simplefilter("ignore")
        real.make_capture(rec, tmp / "c", "person")
        cap = tp.load_capture(tmp / "c")
        frames = cap.frames[:a.frames] if a.frames else cap.frames
        est = FrameEstimator(cap, "human", 100, gate=False)
        poses, hands = [], []
        for i, f in enumerate(frames):
            p, det = est.estimate(f, detail=True)
            poses.append(p)
            if p.status != "failed":
                for part, r in leaf_colours(cap, f, det, {k: v[i] for k, v in ref.items()},
                                            a.radius).items():
                    hands.append({"frame": p.frame, "part": part, **r})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    idx = {f: i for i, f in enumerate(cap.frames)}
    temporal_confidence(poses, idx, gate=False)
    mc = est.min_confidence

    def score(ps):
        res = real.summarize(ps, ref, idx, mc)
        run = real.summarize(real.as_run(ps, est.model, cap.up_vector,
                                         mc if default_gate(cap) else None), ref, idx, mc)
        return {"right": res["right"], "right_as_run": run["right"],
                "hands": res["errors"]["hand"], "hands_as_run": run["errors"]["hand"]}

    wrong = [h for h in hands if h["error"] > real.RIGHT]
    right = [h for h in hands if h["error"] <= real.RIGHT]
    doc = {"machine": machine(), "frames": len(frames), "radius_m": a.radius, "hands": len(hands),
           "wrong": len(wrong), "default": score(poses), "scores": {}}
    for k in ("voxel_spread", "view_spread"):
        rk = np.array([h[k] for h in right], float)
        rows = []
        for q in (90, 95, 98, 100):
            t = float(np.nanpercentile(rk, q))
            flag = {(h["frame"], h["part"]) for h in hands if h[k] > t}
            ps = copy.deepcopy(poses)
            for p in ps:
                for part in ("hand_1", "hand_2"):
                    if (p.frame, part) in flag:
                        p.parts[part] = None
            rows.append({"right_percentile": q, "threshold": round(t, 4),
                         "wrong_flagged": sum((h["frame"], h["part"]) in flag for h in wrong),
                         "right_flagged": sum((h["frame"], h["part"]) in flag for h in right),
                         "left_unplaced": score(ps)})
        doc["scores"][k] = {"auc_wrong_above_right": round(auc([h[k] for h in wrong], rk), 3),
                            "thresholds": rows}
    doc["per_hand"] = hands
    out = Path(a.out)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    m = doc["machine"]
    lines = [f"# Photo-consistency of the hand branches (real recording, `person`, "
             f"{len(frames)} frames)", "", f"Machine: {m['cpu']}, {m['cores']} cores, {m['date']}. Written by `studies/real_leaf_colour.py` "
             f"(branch within {a.radius} m of the leaf). Hands matched to a leaf: {len(hands)}, "
             f"wrong (> {real.RIGHT} m from both true hands): {len(wrong)}. Default: right "
             f"{doc['default']['right']} per frame, {doc['default']['right_as_run']} as run.", "",
             "| score | AUC wrong > right | threshold (right hands' percentile) | wrong flagged "
             "| right flagged | right frames, flagged hands unplaced (per frame / as run) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for k, s in doc["scores"].items():
        for r in s["thresholds"]:
            u = r["left_unplaced"]
            lines.append(f"| {k} | {s['auc_wrong_above_right']} | {r['threshold']} "
                         f"({r['right_percentile']}) | {r['wrong_flagged']}/{len(wrong)} | "
                         f"{r['right_flagged']}/{len(right)} | {u['right']} / {u['right_as_run']} |")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
