"""Why the real recording's wrong frames are wrong (``person`` silhouettes): which part, which stage.

    python studies/real_diagnose.py [RECORDING] [--set person_track=true]

For each frame scored wrong by ``benchmarks/real.py`` (a head, hand or foot more than 0.15 m
from Pose2Sim's 3D result), each wrong part's reference point (head marker; wrist + 0.05 m
along elbow → wrist; mid ankle–big toe) is classified by the first stage that loses it:

- *silhouette*: the point lies outside the visual hull (> 1.5 voxels from it) and at least one
  camera's person probability there is below 0.5 (that camera's mask misses the part);
- *hull/skeleton*: the point is inside the hull (or within 1.5 voxels) but no leaf of the data
  tree lies within 0.10 m of it: the part has no skeleton branch end of its own (it touches or
  overlaps the body in some views, and the hull's *phantom volume* joins it to the body, or
  its branch ends elsewhere);
- *alignment/placement*: a data-tree leaf lies within 0.10 m of the point, but the part was
  placed elsewhere (another leaf chosen, or the placement rules moved it).

Writes ``results/real_diagnose.md`` / ``.json`` and ``real_diagnose_hands.png`` (crops around
the wrongest hands: Pose2Sim's forearm, the placed hand, the mask contour, the hull).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import real  # noqa: E402

LEAF_NEAR = 0.10


def reference_points(ref, i) -> dict:
    g = {k: v[i] for k, v in ref.items()}
    pts = {"head": g["Head"]}
    for s in "LR":
        w, el = g[f"{s}Wrist"], g[f"{s}Elbow"]
        pts[f"hand_{s}"] = w + 0.05 * (w - el) / np.linalg.norm(w - el)
        pts[f"foot_{s}"] = (g[f"{s}Ankle"] + g[f"{s}BigToe"]) / 2
    return pts


def classify(cap, maps, vol, data, pts, scale) -> dict:
    """Per reference point: cameras' probabilities there, distance to the hull, to the nearest
    data-tree leaf, and the stage that lost it (module docstring)."""
    from scipy.ndimage import distance_transform_edt

    from topopose.capture.background import scaled_camera

    occ = vol.data.astype(bool)
    dt = distance_transform_edt(~occ) * vol.voxel_size
    leaves = np.array([data.positions[v] for v in data.vertices
                       if data.degree(v) == 1 and data.positions.get(v) is not None]).reshape(-1, 3)
    out = {}
    for k, P in pts.items():
        probs = []
        for c, cam in enumerate(cap.cameras):
            u, v = np.round(scaled_camera(cam, scale).project(P[None])[0]).astype(int)
            q = maps[c]
            probs.append(int(q[v, u]) if 0 <= u < q.shape[1] and 0 <= v < q.shape[0] else -1)
        ii = np.round((P - vol.origin) / vol.voxel_size).astype(int)
        hd = float(dt[tuple(ii)]) if all(0 <= a < n for a, n in zip(ii, occ.shape)) else float("inf")
        ld = float(np.min(np.linalg.norm(leaves - P, axis=1))) if len(leaves) else float("inf")
        if hd > 1.5 * vol.voxel_size and min(probs) < 128:
            stage = "silhouette"
        elif ld > LEAF_NEAR:
            stage = "hull/skeleton"
        else:
            stage = "alignment/placement"
        out[k] = {"p_cameras": probs, "hull_m": round(hd, 3), "leaf_m": round(ld, 3),
                  "stage": stage, "missed_by": [cap.cameras[c].name for c, p in enumerate(probs)
                                                if 0 <= p < 128]}
    return out


def picture(cap, est, ref, frames, side, path):
    """Crops around one side's hand in the 4 cameras for ``frames``."""
    import cv2
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from topopose.capture.background import foreground_maps
    from topopose.capture.images import read_images

    fig, ax = plt.subplots(len(frames), len(cap.cameras), figsize=(14, 3.6 * len(frames)),
                           squeeze=False)
    for r, f in enumerate(frames):
        i = cap.frames.index(f)
        p, det = est.estimate(f, detail=True)
        g = {k: v[i] for k, v in ref.items()}
        w, el = g[f"{side}Wrist"], g[f"{side}Elbow"]
        P = min((np.asarray(p.parts[k]) for k in ("hand_1", "hand_2") if p.parts.get(k) is not None),
                key=lambda x: np.linalg.norm(x - w))
        maps, imgs = foreground_maps(cap, f), read_images(cap, f)
        vol = det.volume
        W = vol.world(np.argwhere(vol.data))
        W = W[np.linalg.norm(W - w, axis=1) < 0.45]
        for c, cam in enumerate(cap.cameras):
            img = imgs[c][:, :, ::-1]
            uv = cam.project(np.array([el, w, P]))
            x0, y0 = (int(max(x - 170, 0)) for x in uv[1])
            x1, y1 = (int(x + 170) for x in uv[1])
            a = ax[r][c]
            a.imshow(img[y0:y1, x0:x1])
            q = cv2.resize(maps[c], (img.shape[1], img.shape[0]))[y0:y1, x0:x1]
            a.contour(q, levels=[127], colors="r", linewidths=0.8)
            hv = cam.project(W)
            a.scatter(hv[:, 0] - x0, hv[:, 1] - y0, s=1, c="c", alpha=0.08)
            a.plot(uv[:2, 0] - x0, uv[:2, 1] - y0, "g-o", ms=3)
            a.scatter([uv[2, 0] - x0], [uv[2, 1] - y0], c="yellow", s=50, marker="*")
            a.set_xlim(0, x1 - x0)
            a.set_ylim(y1 - y0, 0)
            a.set_title(f"frame {f} {cam.name}", fontsize=8)
            a.axis("off")
    fig.suptitle(f"{side} hand: green elbow → wrist (Pose2Sim), yellow star: the placed hand, red: "
                 "person mask (p = 0.5), cyan: hull voxels within 0.45 m of the wrist", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=65)
    plt.close(fig)


def main(argv=None):
    from _machine import machine
    from topopose.capture.background import foreground_maps
    from topopose.frame.estimate import FrameEstimator

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--out", default=str(HERE / "results" / "real_diagnose"))
    a = ap.parse_args(argv)
    opened = real.open_recording(a.recording)
    if opened is None:
        return 2
    rec, ref = opened
    rows = []
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = real.person_capture(rec, Path(tmp) / "c", a.set)
        est = FrameEstimator(cap, "human", 100, gate=False)
        scale = float(cap.options["silhouettes"]["scale"])
        for i, f, p, det, e in real.estimated_frames(est, cap, ref):
            if e is None:
                rows.append({"frame": f, "failed": p.error})
                continue
            bad = {k: v for k, v in e.items() if v > real.RIGHT}
            if not bad:
                continue
            c = classify(cap, foreground_maps(cap, f), det.volume, det.data,
                         reference_points(ref, i), scale)
            rows.append({"frame": f, "parts": {k: dict(c[k], error_m=round(v, 3) if np.isfinite(v)
                                                       else None) for k, v in bad.items()}})
        hands = sorted(((r["parts"][k]["error_m"] or 9, r["frame"], k[-1]) for r in rows
                        if "parts" in r for k in r["parts"]
                        if k.startswith("hand") and r["parts"][k]["stage"] == "hull/skeleton"),
                       reverse=True)
        side = Counter(s for _, _, s in hands).most_common(1)[0][0] if hands else "R"
        pick = sorted({f for _, f, s in hands if s == side})[-3:]
        pic = Path(a.out).with_name(Path(a.out).name + "_hands.png")
        if pick:
            picture(cap, est, ref, pick, side, pic)
    stages = Counter(v["stage"] for r in rows if "parts" in r for v in r["parts"].values())
    kinds = Counter((k.split("_")[0], v["stage"]) for r in rows if "parts" in r
                    for k, v in r["parts"].items())
    doc = {"machine": machine(), "settings": a.set, "wrong_frames": len(rows),
           "stages": dict(stages), "rows": rows, "picture": pic.name if pick else None}
    Path(a.out).with_suffix(".json").write_text(json.dumps(doc, indent=1))
    L = ["# Real recording: why the wrong frames are wrong (`person` silhouettes)", "",
         f"Written by `studies/real_diagnose.py` (settings {a.set or 'default'}). "
         f"{len(rows)} wrong frames of {len(cap.frames)}; the stages are defined in the script's "
         "docstring.", "", "| part | stage | wrong parts |", "| --- | --- | --- |"]
    L += [f"| {k} | {s} | {n} |" for (k, s), n in sorted(kinds.items())]
    L += ["", "| frame | part | error m | stage | camera probabilities ×255 | hull m | nearest leaf m |",
          "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        for k, v in (r.get("parts") or {}).items():
            L.append(f"| {r['frame']} | {k} | {v['error_m']} | {v['stage']} | {v['p_cameras']} "
                     f"| {v['hull_m']} | {v['leaf_m']} |")
    if pick:
        L += ["", f"Picture: `{pic.name}` (frames {', '.join(pick)}, {side} hand)."]
    Path(a.out).with_suffix(".md").write_text("\n".join(L) + "\n")
    print(dict(stages), f"wrote {a.out}.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
