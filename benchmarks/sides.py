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


def run_config(work, build, family, cams, seed, frames):
    """The capture (written once) and its per-frame poses (run once, gate on, no sequence
    stages): (gt, poses)."""
    from topopose.batch import run
    from topopose.capture import load_capture
    from topopose.pose.pose import read_poses
    from topopose.synth.capture import synthetic_capture, write_capture

    d = capture_dir(work, build, family, cams, seed)
    if not (d / "gt.json").exists():
        cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, noise=1,
                                build=build, pose=family)
        write_capture(cap, d)
    out = d / "poses.jsonl"
    if not out.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cap = load_capture(d)
            run(cap, model="human", resolution=100, output=d / "poses.part.jsonl", progress=False,
                track=False, sides=False, skeleton=False, consistency=False, support=True)
        (d / "poses.part.jsonl").rename(out)
    return json.loads((d / "gt.json").read_text()), read_poses(out)


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
