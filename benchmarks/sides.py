"""Left/right claims and the ``matched`` gate on data the cues were not designed on.

    python benchmarks/sides.py [--work DIR] [--frames N] [--pose2sim RAW.jsonl] [--child PATH]
                               [--child-step K] [--out DIR] [--quick]

**Synthetic** (the MakeHuman ``body``, :func:`topopose.synth.capture.synthetic_capture`, noise 1,
640×480, 100³, unrelated random poses of one pose family each,
:data:`topopose.synth.body.POSE_FAMILIES`): each capture is run per frame as ``topopose run
--no-track --no-sides --no-skeleton`` with the defaults (gate on), then the side names are
given per frame (:func:`topopose.sequence.chirality.assign_sides`, no time: the poses are
unrelated). The generators are split:

- *development* (:data:`DEV`; what the side margin and the gate's thresholds were chosen on):
  builds ``average`` and ``heavy``, families ``any``, ``feet_out``, ``twist``, ``crouch``,
  ``one_leg``, 8 cameras;
- *held out* (:data:`HELD`): builds ``child``, ``lean``, ``random``, families ``feet_in``,
  ``kneel``, ``arms_crossed``, ``lying``, ``any``, 8 and 4 cameras.

A *claim* is a mirror pair (hands, feet) of a matched frame named ``left_``/``right_``; it is
right when the named parts are nearer their own side's true limb than the other's (one part
found: that part), as ``benchmarks/tracking.py`` scores it. Precision = right / claims;
coverage = claims / (matched frames × pairs). A frame's claim is right when all its claims are.

**matched**: a matched frame is right when it is a TP of :mod:`topopose.batch.quality` (every
placed part within 0.1 × height, at most one unplaced); precision of ``matched`` per source, for
the shipped gate (:mod:`topopose.frame.confidence`) and, offline from the same frames' features,
the alternatives named in the report.

**Pose2Sim** (``--pose2sim RAW.jsonl``: the per-frame poses ``benchmarks/real_motion.py --raw``
writes, gates off): the motion stage as ``topopose run`` runs it, the claims against Pose2Sim's
L/R markers (``real_motion.chirality``), ``matched`` against its markers (``real.RIGHT``).

**child_rope** (``--child PATH``, by path only — no licence): 10 cameras, P matrices, masks;
every ``--child-step``-th frame is run; its matched frames are judged against the masks (the
share of the parts' projections inside the silhouettes) and drawn on a contact sheet
(``sides_child_sheet.png``: parts and skeleton curves on camera 0's mask) to be judged by eye.

Writes ``sides.md`` / ``sides.json`` in ``--out`` (default ``benchmarks/results``).
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _machine import machine, results_dir  # noqa: E402

PAIRS = ("hand", "foot")
FAMILIES = ("any", "feet_out", "feet_in", "twist", "crouch", "kneel", "one_leg", "arms_crossed",
            "lying")
# (build, pose family, cameras); seeds 100 + i (development), 300 + i (held out)
DEV = ([(b, f, 8) for b in ("average", "heavy")
        for f in ("any", "feet_out", "twist", "crouch", "one_leg")]
       + [(b, f, 8) for b in ("child", "lean")
          for f in ("any", "feet_in", "kneel", "arms_crossed", "lying")]
       + [("random", f, 4) for f in ("any", "feet_out", "kneel", "arms_crossed")])
HELD = ([("random", f, 8) for f in FAMILIES]
        + [(b, f, 4) for b in ("child", "heavy") for f in ("any", "twist", "crouch", "kneel", "one_leg")]
        + [("lean", f, 8) for f in ("feet_out", "twist", "crouch", "one_leg", "arms_crossed")])


def capture_dir(work, build, family, cams, seed):
    return Path(work) / f"{build}_{family}_{cams}c_{seed}"


GATES = ("simple", "fitted")    # the gate decided by default, and the fitted confidence (peer)


def estimate_all(cap, gate, out):
    """Per-frame poses of every frame of ``cap`` (as ``topopose run --no-track --no-sides
    --no-skeleton``: 100³, the default gate; ``gate="fitted"``: the fitted confidence decides,
    ``FrameEstimator(gate_rule=False)``), written to ``out`` once and read back after."""
    from topopose.frame.estimate import FrameEstimator
    from topopose.pose.pose import read_poses, write_poses

    out = Path(out)
    if not out.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est = FrameEstimator(cap, "human", 100, support=True,
                                 **({"gate_rule": False} if gate == "fitted" else {}))
            poses = [est.estimate(f) for f in cap.frames]
        write_poses(out, poses)
    return read_poses(out)


def run_config(work, build, family, cams, seed, frames, gate="simple"):
    """The capture (written once) and its per-frame poses under ``gate``: (gt, poses)."""
    from topopose.capture import load_capture
    from topopose.synth.capture import synthetic_capture, write_capture

    d = capture_dir(work, build, family, cams, seed)
    if not (d / "gt.json").exists():
        cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, noise=1,
                                build=build, pose=family)
        write_capture(cap, d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = load_capture(d)
    return cap.gt, estimate_all(cap, gate, d / f"poses_{gate}.jsonl")


def claims_synthetic(poses, gt):
    """Per matched frame: {stem: True (right) / False (wrong) / None (no claim)}."""
    from topopose.batch.quality import point_segment_distance as psd

    out = {}
    for p in poses:
        if not p.matched:
            continue
        segs = gt["frames"][p.frame]["segments"]
        row = {}
        for stem in PAIRS:
            a, b = p.parts.get(f"left_{stem}"), p.parts.get(f"right_{stem}")
            if a is None and b is None:
                row[stem] = None
                continue
            g1, g2 = segs[f"{stem}_1"], segs[f"{stem}_2"]
            d = 0.0
            if a is not None:
                d += psd(np.asarray(a), *g1) - psd(np.asarray(a), *g2)
            if b is not None:
                d += psd(np.asarray(b), *g2) - psd(np.asarray(b), *g1)
            row[stem] = bool(d < 0)
        out[p.frame] = row
    return out


def claim_counts(rows: dict) -> dict:
    """Claims, right claims, frames claimed, frames whose claims are all right, frames."""
    c = {"frames": len(rows), "pairs": 2 * len(rows), "claims": 0, "right": 0,
         "frames_claimed": 0, "frames_right": 0}
    for row in rows.values():
        made = [v for v in row.values() if v is not None]
        c["claims"] += len(made)
        c["right"] += sum(made)
        if made:
            c["frames_claimed"] += 1
            c["frames_right"] += all(made)
    return c


def add(a: dict, b: dict) -> dict:
    return {k: a.get(k, 0) + b.get(k, 0) for k in set(a) | set(b)}


def aligned(p) -> bool:
    """A frame the alignment placed (matched, or rejected by the gate / the AHA distance only):
    the frames any gate decides on."""
    from topopose.frame.confidence import distance_only

    if p.status == "matched":
        return True
    err = str(p.error or "")
    return p.status == "rejected" and (distance_only(err) or " below " in err)


def synthetic(work, frames, quick=False):
    from topopose.batch.quality import TP_CLASSES, evaluate
    from topopose.pose.model import load_model
    from topopose.sequence.chirality import assign_sides

    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    rows = []
    configs = [("dev", c, 100 + i) for i, c in enumerate(DEV)]
    configs += [("held", c, 300 + i) for i, c in enumerate(HELD)]
    if quick:
        configs = configs[:2] + configs[len(DEV):len(DEV) + 2]
    for split, (build, family, cams), seed in configs:
        t0 = time.perf_counter()
        gt, poses = run_config(work, build, family, cams, seed, frames)
        ev = evaluate(gt, poses, model=model)
        right = {f.frame: f.quality in TP_CLASSES for f in ev.frames}
        sided = assign_sides(poses, model, up, use_time=False)
        rows.append({"split": split, "build": build, "family": family, "cameras": cams,
                     "seed": seed, "seconds": round(time.perf_counter() - t0, 1),
                     "claims": claims_synthetic(sided, gt),
                     "frames": [frame_row(p, right[p.frame]) for p in poses]})
    return rows


def frame_row(p, right) -> dict:
    d = p.diagnostics
    return {"frame": p.frame, "status": p.status, "aligned": aligned(p), "right": bool(right),
            "distance": p.distance, "confidence": d.get("confidence"),
            "features": d.get("confidence_features"),
            "chirality": {k: v.get("why") for k, v in (d.get("chirality") or {}).items()}}


# ----------------------------------------------------------------------------- child_rope
class _LazyMasks(dict):
    """frame → the cameras' masks, read from ``folders`` on first use (nothing is copied)."""

    def __init__(self, folders, frames, scale):
        super().__init__()
        self.folders, self.names, self.scale = folders, set(frames), scale

    def __contains__(self, frame):
        return frame in self.names

    def __missing__(self, frame):
        import cv2

        out = []
        for d in self.folders:
            m = cv2.imread(str(d / f"{frame}.png"), cv2.IMREAD_GRAYSCALE)
            if m is None:
                raise SystemExit(f"{d / f'{frame}.png'}: cannot read the mask")
            if self.scale != 1:
                m = cv2.resize(m, None, fx=self.scale, fy=self.scale, interpolation=cv2.INTER_AREA)
            out.append(m > 127)
        if len(self) > 4:
            self.clear()
        self[frame] = out
        return out


def child_capture(path, step=10, scale=0.5):
    """The child_rope recording as an in-memory capture: ``camXX/cam_par.txt`` (camera name and
    the 12 numbers of P, row-major) decomposed into K, R, t (no distortion); masks
    ``camXX/<i>.png`` read by path when a frame is used, every ``step``-th frame, halved
    (``scale``); the capture volume fitted to the silhouettes (+z up, metres)."""
    import cv2

    from topopose.capture.capture import Capture
    from topopose.geometry.camera import Camera

    path = Path(path)
    folders = sorted(d for d in path.iterdir() if d.is_dir() and (d / "cam_par.txt").exists())
    if not folders:
        raise SystemExit(f"{path}: no camXX/cam_par.txt (child_rope recording absent)")
    cams = []
    for d in folders:
        fields = (d / "cam_par.txt").read_text().split()
        P = np.array([float(x) for x in fields[1:13]]).reshape(3, 4)
        K, R, C = cv2.decomposeProjectionMatrix(P)[:3]
        K = K / K[2, 2]
        K[:2] *= scale
        t = -R @ (C[:3, 0] / C[3, 0])
        h, w = cv2.imread(str(d / "0.png"), cv2.IMREAD_GRAYSCALE).shape
        cams.append(Camera(fields[0], (round(w * scale), round(h * scale)), K, np.zeros(5),
                           cv2.Rodrigues(R)[0].ravel(), t))
    n = len([f for f in folders[0].glob("*.png") if f.stem.isdigit()])
    frames = [str(i) for i in range(0, n, step)]
    return Capture(cams, frames, None, "+z", "m", 25.0, None, {},
                   _LazyMasks(folders, frames, scale)), folders


COLOURS = {"head": (0, 0, 255), "torso": (255, 255, 255), "crotch": (255, 255, 0),
           "hand_1": (0, 255, 0), "hand_2": (255, 0, 0), "foot_1": (0, 255, 255),
           "foot_2": (255, 0, 255)}


def contact_sheet(cap, poses, path, views=(0, 5), tile=(150, 190), columns=8, label=None):
    """One tile per pose: the masks of cameras ``views`` (cropped to the silhouette) with the
    skeleton curves (grey) and the parts (head red, torso white, crotch cyan, hand_1 green,
    hand_2 blue, foot_1 yellow, foot_2 magenta) projected, the frame name and ``label(pose)``
    written on it. Written as a PNG at ``path``."""
    import cv2

    from topopose.sequence.chirality import numbered
    from topopose.pose.model import load_model

    model = load_model("human")
    tw, th = tile
    rows = (len(poses) + columns - 1) // columns
    sheet = np.zeros((max(rows, 1) * th, columns * tw * len(views), 3), np.uint8)
    for k, p in enumerate(poses):
        p = numbered(p, model)
        ms = cap.silhouettes(p.frame)
        for j, v in enumerate(views):
            cam, m = cap.cameras[v], ms[v]
            ys, xs = np.nonzero(m)
            if not len(xs):
                continue
            x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
            pad = int(0.08 * (y1 - y0)) + 4
            x0, y0 = max(x0 - pad, 0), max(y0 - pad, 0)
            x1, y1 = min(x1 + pad, m.shape[1] - 1), min(y1 + pad, m.shape[0] - 1)
            s = min(tw / (x1 - x0 + 1), (th - 14) / (y1 - y0 + 1))
            img = cv2.cvtColor((m[y0:y1 + 1, x0:x1 + 1] * 90).astype(np.uint8), cv2.COLOR_GRAY2BGR)
            img = cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)

            def px(X):
                u = cam.project(np.asarray(X, float).reshape(-1, 3))
                return np.round((u - [x0, y0]) * s).astype(np.int32)
            for c in (p.diagnostics.get("curves") or {}).values():
                cv2.polylines(img, [px(c)], False, (160, 160, 160), 1)
            for part, col in COLOURS.items():
                x = p.parts.get(part)
                if x is not None:
                    cv2.circle(img, tuple(int(a) for a in px(x)[0]), 3, col, -1)
            r0, c0 = (k // columns) * th + 14, (k % columns) * tw * len(views) + j * tw
            h, w = img.shape[:2]
            sheet[r0:r0 + h, c0:c0 + w] = img[:th - 14, :tw]
        text = p.frame + ("" if label is None else " " + label(p))
        cv2.putText(sheet, text, ((k % columns) * tw * len(views) + 2, (k // columns) * th + 11),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1)
    cv2.imwrite(str(path), sheet)
