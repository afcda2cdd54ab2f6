"""Left/right claims and the ``matched`` gate on data the cues were not designed on.

    python benchmarks/sides.py [--work DIR] [--frames N] [--pose2sim RECORDING] [--child PATH]
                               [--child-step K] [--sheets DIR] [--child-by-eye JSON]
                               [--out DIR] [--quick]

**Synthetic** (the MakeHuman ``body``, :func:`topopose.synth.capture.synthetic_capture`, noise 1,
640×480, 100³, unrelated random poses of one pose family each,
:data:`topopose.synth.body.POSE_FAMILIES`): each capture is estimated per frame as ``topopose
run --no-track --no-sides --no-skeleton`` does, twice: with the default gate
(:class:`topopose.frame.confidence.GateOptions`) and with the fitted confidence
(``FrameEstimator(gate_rule=False)``, the peer). The side names are then given per frame
(:func:`topopose.sequence.chirality.assign_sides`, no time: the poses are unrelated). The
generators (:data:`DEV`, :data:`HELD`: build, pose family, cameras) are split:

- *development*: builds ``average``, ``heavy``, ``child``, ``lean`` with 8 cameras (families
  ``any``, ``feet_out``, ``twist``, ``crouch``, ``one_leg``, ``feet_in``, ``kneel``,
  ``arms_crossed``, ``lying``) and ``random`` with 4 — what the side cues, their margin and the
  gate's thresholds (:func:`choose_gate`, run again here) were designed and chosen on;
- *held out*: ``random`` with 8 cameras in every family, ``child`` and ``heavy`` with 4,
  ``lean`` with 8, other seeds.

A *claim* is a mirror pair (hands, feet) of a matched frame named ``left_``/``right_``; it is
right when the named parts are nearer their own side's true limb than the other's (one part
found: that part), as ``benchmarks/tracking.py`` scores it. Precision = right / claims;
coverage = claims / (matched frames × pairs). A frame's claim is right when all its claims are.
The peer of the claims: the same frames named with ``SideOptions(min_agree=0)`` (no minimum
agreement of the facing cues).

**matched**: a matched frame is right when it is a TP of :mod:`topopose.batch.quality` (every
placed part within 0.1 × height, at most one unplaced); precision of ``matched`` per source and
pose family, for both gates.

**Pose2Sim** (``--pose2sim RECORDING``, default ``benchmarks/data/pose2sim_balancing``; ``person``
silhouettes, MediaPipe needed): both gates per frame, then the sequence stages as ``topopose
run`` runs them; ``matched`` against Pose2Sim's markers (``real.RIGHT``), the claims of the
matched frames against its L/R markers (``real_motion.chirality``).

**child_rope** (``--child PATH``, by path only — no licence): 10 cameras, P matrices, masks
(:func:`child_capture`); every ``--child-step``-th frame is run with both gates; the matched
frames are judged against the masks (the share of the parts' projections inside every
silhouette) and drawn on a contact sheet per gate (``sides_child_<gate>.png`` in ``--sheets``,
never in the repository: parts and skeleton curves on cameras 0 and 5's masks) to be judged by
eye (``--child-by-eye`` writes the verdicts into the report).

Writes ``sides.md`` / ``sides.json.gz`` in ``--out`` (default ``benchmarks/results``).
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
    from topopose.sequence.consistency import gated

    return gated(p) or (p.status == "rejected" and distance_only(p.error))


def synthetic(work, frames, quick=False):
    """Every generator of :data:`DEV` and :data:`HELD` under both gates: per generator, per gate,
    the frames' rows (right by ground truth, matched, the gate's features) and the side claims
    of the matched frames — and of every frame the alignment placed (the cue's own precision,
    whatever gate lets the frame through)."""
    from topopose.batch.quality import TP_CLASSES, evaluate
    from topopose.pose.model import load_model
    from topopose.sequence.chirality import SideOptions, assign_sides

    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    # the side claims' peer: the default options without the cues' minimum agreement
    any_agreement = SideOptions(min_agree=0.0)
    rows = []
    configs = [("dev", c, 100 + i) for i, c in enumerate(DEV)]
    configs += [("held", c, 300 + i) for i, c in enumerate(HELD)]
    if quick:
        configs = configs[:2] + configs[len(DEV):len(DEV) + 2]
    for split, (build, family, cams), seed in configs:
        row = {"split": split, "build": build, "family": family, "cameras": cams, "seed": seed}
        for gate in GATES:
            gt, poses = run_config(work, build, family, cams, seed, frames, gate)
            ev = evaluate(gt, poses, model=model)
            right = {f.frame: f.quality in TP_CLASSES for f in ev.frames}
            sided = assign_sides(poses, model, up, use_time=False)
            placed = [replace_status(p) for p in poses if aligned(p)]
            row[gate] = {"frames": [frame_row(p, right[p.frame]) for p in sided],
                         "claims": claims_synthetic(sided, gt),
                         "claims_any_agreement": claims_synthetic(assign_sides(
                             poses, model, up, use_time=False, options=any_agreement), gt),
                         "claims_placed": claims_synthetic(
                             assign_sides(placed, model, up, use_time=False), gt)}
        rows.append(row)
    return rows


def replace_status(p):
    from dataclasses import replace

    return replace(p, status="matched", error=None)


def frame_row(p, right) -> dict:
    d = p.diagnostics
    f = d.get("confidence_features") or {}
    return {"frame": p.frame, "matched": p.matched, "aligned": aligned(p), "right": bool(right),
            "unplaced": sum(x is None for x in p.parts.values()),
            "distance": f.get("distance"), "shape": f.get("shape"),
            "unexplained": d.get("unexplained"), "confidence": d.get("confidence"),
            "why": sorted({v["why"] for v in (d.get("chirality") or {}).values()
                           if v.get("why")})}


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


# ----------------------------------------------------------------------------- Pose2Sim
def pose2sim(work, recording):
    """The Pose2Sim balancing trial (``person`` silhouettes, as ``benchmarks/real_motion.py``):
    per gate, per frame ``matched`` against Pose2Sim's markers (``real.RIGHT``), then the
    sequence stages as ``topopose run`` runs them and the side claims of the matched frames
    against Pose2Sim's L/R markers (``real_motion.chirality``)."""
    import real
    import real_motion as rm

    from topopose.pose.model import load_model
    from topopose.sequence.chirality import SideOptions, assign_sides, numbered
    from topopose.sequence.motion import process_sequence

    model = load_model("human")
    got = rm.person_capture(recording, work)
    if "absent" in got:
        return got
    cap, ref, d = got["capture"], got["reference"], got["folder"]
    out = {}
    for gate in GATES:
        raw = sorted(estimate_all(cap, gate, d / f"poses_{gate}.jsonl"), key=lambda p: p.frame)
        right = []
        for i, p in enumerate(raw):
            e = real.frame_errors(p.parts, ref, i) if p.status != "failed" else None
            right.append(e is not None and all(v <= real.RIGHT for v in e.values()))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            final = process_sequence(raw, model, cap.up_vector, fps=cap.fps).poses
        rows = [i for i, p in enumerate(final) if p.matched]
        out[gate] = {"frames": len(raw), "right": int(sum(right)),
                     "matched": frame_counts([(p, r) for p, r in zip(raw, right)]),
                     "matched_as_run": frame_counts([(p, r) for p, r in zip(final, right)]),
                     "claims_as_run": rm.chirality(final, ref, rows)}
        # the cues' minimum agreement against none: the run's matched frames named again (the
        # tracking segments as the run made them), with the default options and without it
        for key, o in (("claims_again", SideOptions()),
                       ("claims_again_any_agreement", SideOptions(min_agree=0.0))):
            again = assign_sides([numbered(p, model) for p in final], model, cap.up_vector,
                                 options=o)
            out[gate][key] = rm.chirality(again, ref, rows)
    return out


def frame_counts(pairs) -> dict:
    """Matched frames and the right ones among them, of (pose, right) pairs."""
    m = [r for p, r in pairs if p.matched]
    return {"matched": len(m), "right": int(sum(m))}


# ----------------------------------------------------------------------------- child_rope
def child(work, path, step, out_dir):
    """The child recording, per gate: frames matched / failed, the share of the matched frames'
    parts whose projections fall inside every camera's silhouette, and a contact sheet of the
    matched frames (``sides_child_<gate>.png``) to be judged by eye."""
    if not Path(path).exists():
        return {"absent": f"{path}: child_rope recording absent"}
    cap, _ = child_capture(path, step=step)
    d = Path(work) / f"child_rope_{step}"
    d.mkdir(parents=True, exist_ok=True)
    out = {}
    for gate in GATES:
        poses = sorted(estimate_all(cap, gate, d / f"poses_{gate}.jsonl"), key=lambda p: int(p.frame))
        matched = [p for p in poses if p.matched]
        inside = []
        for p in matched:
            ms = cap.silhouettes(p.frame)
            for x in p.parts.values():
                if x is None:
                    continue
                ok = True
                for cam, m in zip(cap.cameras, ms):
                    u = np.round(cam.project(np.asarray(x, float).reshape(1, 3))[0]).astype(int)
                    ok &= bool(0 <= u[0] < m.shape[1] and 0 <= u[1] < m.shape[0]
                               and m[u[1], u[0]])
                inside.append(ok)
        sheet = Path(out_dir) / f"sides_child_{gate}.png"
        if matched:
            contact_sheet(cap, matched, sheet, columns=6)
        out[gate] = {"frames": len(poses), "matched": len(matched),
                     "failed": sum(p.status == "failed" for p in poses),
                     "matched_frames": [p.frame for p in matched],
                     "parts_inside_every_silhouette": (round(float(np.mean(inside)), 3)
                                                       if inside else None),
                     "sheet": sheet.name if matched else None}
    return out


# ----------------------------------------------------------------------------- choosing
GRID = {"max_distance": (0.6, 0.8, 1.0, 1.2, 1.4), "max_unexplained": (0.15, 0.2, 0.25, 0.3, 9.0),
        "far_unexplained": (0.06, 0.08, 0.1, 0.12, 0.15), "far_shape": (0.1, 0.125, 0.15, 0.175, 0.2)}


def choose_gate(rows, precision=0.98):
    """The gate's thresholds from the development generators' frames (their default-gate run:
    the features of every placed frame): over :data:`GRID`, the largest mean over generators of
    the share of their right frames matched, with the precision of ``matched`` at least
    ``precision`` in each camera set-up — no generator, build or pose family weighs more than
    another. Returns (options dict, mean share) or None."""
    import itertools

    from topopose.frame.confidence import GateOptions, gate_decision

    gens = []
    for r in rows:
        if r["split"] != "dev":
            continue
        fr = [f for f in r["simple"]["frames"] if f["aligned"]]
        gens.append((r["cameras"], sum(f["right"] for f in r["simple"]["frames"]), fr))
    best = None
    for vals in itertools.product(*GRID.values()):
        o = GateOptions(**dict(zip(GRID, vals)))
        if o.far_unexplained > o.max_unexplained:
            continue
        per_setup, shares = {}, []
        for cams, n_right, fr in gens:
            m = [f for f in fr if gate_decision("matched", None, {
                "confidence_features": {"distance": f["distance"], "shape": f["shape"]},
                **({} if f["unexplained"] is None else {"unexplained": f["unexplained"]})}, o,
                f["unplaced"])[0] == "matched"]
            k = sum(f["right"] for f in m)
            t = per_setup.setdefault(cams, [0, 0])
            t[0], t[1] = t[0] + len(m), t[1] + k
            if n_right:
                shares.append(k / n_right)
        if any(n and k / n < precision for n, k in per_setup.values()):
            continue
        score = float(np.mean(shares))
        if best is None or score > best[1] + 1e-12:
            best = (dict(zip(GRID, vals)), score)
    return best


# ----------------------------------------------------------------------------- report
def pc(k, n):
    return f"{k}/{n} ({100 * k / n:.1f} %)" if n else "–"


def synthetic_tables(rows) -> list:
    L = ["## Side claims (synthetic, the default gate's matched frames; no time)", "",
         "A claim: a mirror pair of a matched frame named left_/right_. Precision = right claims "
         "/ claims; coverage = claims / (matched frames × 2 pairs); frames: frames with a claim "
         "whose claims are all right. *Placed*: the same on every frame the alignment placed "
         "(whatever the gate), the cue's own precision.", "",
         "| split | build | pose family | cameras | matched | claims right | coverage | frames "
         "right | placed: claims right | placed coverage |", "|" + "---|" * 10]
    tot = {}
    for r in rows:
        c = claim_counts(r["simple"]["claims"])
        c2 = claim_counts(r["simple"]["claims_placed"])
        c3 = claim_counts(r["simple"].get("claims_any_agreement", {}))
        for key in (r["split"], (r["split"], r["family"]), (r["split"], r["build"]),
                    (r["split"], f"{r['cameras']} cameras")):
            t = tot.setdefault(key, ({}, {}, {}))
            tot[key] = (add(t[0], c), add(t[1], c2), add(t[2], c3))
        L.append(f"| {r['split']} | {r['build']} | {r['family']} | {r['cameras']} | "
                 f"{c['frames']} | {pc(c['right'], c['claims'])} | {pc(c['claims'], c['pairs'])} "
                 f"| {pc(c['frames_right'], c['frames_claimed'])} | {pc(c2['right'], c2['claims'])} "
                 f"| {pc(c2['claims'], c2['pairs'])} |")
    L += ["", "Totals (by split, pose family, build, cameras); *any agreement*: the same matched "
          "frames with `SideOptions(min_agree=0)` (the peer):", "",
          "| group | claims right | coverage | frames right | placed: claims right | placed "
          "coverage | any agreement: claims right | coverage |", "|" + "---|" * 8]
    for key, (c, c2, c3) in sorted(tot.items(), key=lambda kv: str(kv[0])):
        L.append(f"| {key if isinstance(key, str) else ' / '.join(key)} | {pc(c['right'], c['claims'])} | "
                 f"{pc(c['claims'], c['pairs'])} | {pc(c['frames_right'], c['frames_claimed'])} | "
                 f"{pc(c2['right'], c2['claims'])} | {pc(c2['claims'], c2['pairs'])} | "
                 f"{pc(c3['right'], c3['claims'])} | {pc(c3['claims'], c3['pairs'])} |")
    why = {}
    for r in rows:
        for f in r["simple"]["frames"]:
            for w in f["why"]:
                k = w.split(": ", 1)[-1].split(" (")[0]
                why[k] = why.get(k, 0) + 1
    L += ["", "Why numbered names were kept (pairs of matched frames): "
          + "; ".join(f"{k}: {v}" for k, v in sorted(why.items(), key=lambda kv: -kv[1])), ""]
    L += ["## matched (synthetic): precision per source and gate", "",
          "Right = TP of `topopose.batch.quality` (every placed part within 0.1 × height, at most "
          "one unplaced). *default*: the gate (`frame.confidence.GateOptions`); *fitted*: the "
          "fitted confidence (`gate_rule=False`, the peer).", "",
          "| split | cameras | pose family | frames | right | default: matched right | recall | "
          "fitted: matched right | recall |", "|" + "---|" * 9]
    groups = {}
    for r in rows:
        for key in ((r["split"], r["cameras"], "all"), (r["split"], r["cameras"], r["family"])):
            g = groups.setdefault(key, {"frames": 0, "right": 0, "simple": [0, 0], "fitted": [0, 0]})
            fr = r["simple"]["frames"]
            g["frames"] += len(fr)
            g["right"] += sum(f["right"] for f in fr)
            for gate in GATES:
                m = [f for f in r[gate]["frames"] if f["matched"]]
                g[gate][0] += len(m)
                g[gate][1] += sum(f["right"] for f in m)
    for key, g in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2] != "all", kv[0][2])):
        L.append(f"| {key[0]} | {key[1]} | {key[2]} | {g['frames']} | {g['right']} | "
                 f"{pc(g['simple'][1], g['simple'][0])} | {pc(g['simple'][1], g['right'])} | "
                 f"{pc(g['fitted'][1], g['fitted'][0])} | {pc(g['fitted'][1], g['right'])} |")
    return L


def report(doc) -> str:
    L = ["# Side claims and the matched gate on data the cues were not designed on", "",
         f"`python benchmarks/sides.py {' '.join(doc['argv'])}` — machine: "
         + ", ".join(f"{k} {v}" for k, v in doc["machine"].items()), "",
         "Development generators (the side margin and the gate's thresholds chosen on them): "
         + ", ".join(f"{b}/{f}/{c}" for b, f, c in DEV) + ". Held out: "
         + ", ".join(f"{b}/{f}/{c}" for b, f, c in HELD) + f". {doc['frames']} frames each, "
         "seeds 100 + i (development), 300 + i (held out), noise 1, 640×480, 100³.", ""]
    if doc.get("synthetic"):
        from dataclasses import asdict

        from topopose.frame.confidence import GATE

        ch = doc.get("chosen_gate")
        L += [f"The gate's thresholds chosen again on the development frames "
              f"(`choose_gate`: mean share of each generator's right frames matched, precision "
              f"≥ 0.98 per camera set-up): {ch[0] if ch else 'none reaches it'}"
              + (f" (mean share {ch[1]:.3f})" if ch else "")
              + f"; shipped: {dict((k, v) for k, v in asdict(GATE).items() if k in GRID)}.", ""]
        L += synthetic_tables(doc["synthetic"])
    L += ["", "## Pose2Sim balancing trial (4 phone cameras, MediaPipe `person` silhouettes)", ""]
    ps = doc.get("pose2sim") or {}
    if "absent" in ps or not ps:
        L.append(f"Not measured: {ps.get('absent', 'not asked (--pose2sim)')}.")
    else:
        L += ["Right frame: head, hands, feet within 0.15 m of Pose2Sim's markers (`real.py`). "
              "*Per frame*: the gate's decision; *as run*: after the sequence stages (track, "
              "skeleton, sides, matched with the run's consistency, as `topopose run`). Claims: "
              "matched frames × pairs, against Pose2Sim's L/R markers.", "",
              "*Named again*: the run's matched frames named once more after the run, with the "
              "default side options and with `min_agree=0` (the peer).", "",
              "| gate | frames | right | matched per frame: right | matched as run: right | "
              "claims as run: right / wrong / numbered | named again | named again, "
              "`min_agree=0` |", "|" + "---|" * 8]
        for gate in GATES:
            g = ps[gate]
            c, c1, c0 = (g.get(k) or {} for k in ("claims_as_run", "claims_again",
                                                  "claims_again_any_agreement"))
            L.append(f"| {'default' if gate == 'simple' else 'fitted'} | {g['frames']} | {g['right']} | "
                     f"{pc(g['matched']['right'], g['matched']['matched'])} | "
                     f"{pc(g['matched_as_run']['right'], g['matched_as_run']['matched'])} | "
                     + " | ".join(f"{x.get('right')} / {x.get('wrong')} / {x.get('unsure')}"
                                  for x in (c, c1, c0)) + " |")
    L += ["", "## child_rope (10 studio cameras, P matrices, real masks; no licence: by path only)", ""]
    ch = doc.get("child") or {}
    if "absent" in ch or not ch:
        L.append(f"Not measured: {ch.get('absent', 'not asked (--child)')}.")
    else:
        L += [f"Every {doc['child_step']}th frame, masks halved, the capture volume fitted to the "
              "silhouettes. No 3D reference: a matched frame is judged by whether its parts project "
              "inside every camera's silhouette and by eye on the contact sheet (camera 0 and 5, "
              "parts drawn: head red, torso white, crotch cyan, hand_1 green, hand_2 blue, foot_1 "
              "yellow, foot_2 magenta).", "",
              "| gate | frames | failed | matched | parts inside every silhouette | judged right by eye | sheet |",
              "|" + "---|" * 7]
        for gate in GATES:
            g = ch[gate]
            L.append(f"| {'default' if gate == 'simple' else 'fitted'} | {g['frames']} | {g['failed']} | "
                     f"{g['matched']} | {g['parts_inside_every_silhouette']} | "
                     f"{doc.get('child_by_eye', {}).get(gate, 'see the sheet')} | {g['sheet']} |")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=None, help="where captures and per-frame poses are kept")
    ap.add_argument("--frames", type=int, default=30, help="frames per synthetic generator")
    ap.add_argument("--pose2sim", default=str(HERE / "data" / "pose2sim_balancing"),
                    help="the Pose2Sim balancing recording ('' to skip)")
    ap.add_argument("--child", default="", help="the child_rope recording (by path only)")
    ap.add_argument("--child-step", type=int, default=5)
    ap.add_argument("--sheets", default=None,
                    help="where the child recording's contact sheets go (default: --work; never "
                         "the repository: the recording has no licence)")
    ap.add_argument("--child-by-eye", default="{}",
                    help='JSON {"simple": "k of n", "fitted": "..."}: the sheets judged by eye')
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    import tempfile

    work = Path(a.work or tempfile.mkdtemp(prefix="topopose_sides_"))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    doc = {"argv": sys.argv[1:] if argv is None else list(argv), "frames": a.frames,
           "child_step": a.child_step, "child_by_eye": json.loads(a.child_by_eye)}
    doc["synthetic"] = synthetic(work, a.frames, a.quick)
    doc["chosen_gate"] = choose_gate(doc["synthetic"])
    doc["pose2sim"] = pose2sim(work, a.pose2sim) if a.pose2sim else {}
    doc["child"] = child(work, a.child, a.child_step, Path(a.sheets or work)) if a.child else {}
    doc["machine"] = machine(seconds=round(time.perf_counter() - t0, 1))
    import gzip

    with gzip.open(out / "sides.json.gz", "wt") as fh:    # every frame's row: large
        json.dump(doc, fh, default=str)
    (out / "sides.md").write_text(report(doc))
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
