"""Fit and check the per-frame confidence that decides ``matched`` (topopose.frame.confidence) on
synthetic captures only: the anatomical ``body`` (builds average/heavy/child/lean/random, one
per seed) and the capsule human, walking and random poses, 100³, and the body benchmark's own
kind of poses (``quality.py --only body``: separated limbs and all random poses) on seeds
POSE_SEED0… (disjoint from its 21, 22), each in every camera set-up of SETUPS (8 cameras
640×480 noise 1; 4 cameras 640×480 noise 1; 4 portrait phone-like cameras 544×960 noise 2).
A frame is *right* when it is a true positive (TP) of the quality classes, as in the body benchmark: quality "good" or
"missing limb" (every placed part within 0.08 × height of its ground-truth segment, junctions
too). The first half of the seeds fits the confidence (``--kind``: boosted trees, TREES, the
default, needing scikit-learn; or the logistic regression) and chooses its minimum
(calibration), the second half checks them (held out). The fit sees the frames matched or
rejected for their AHA distance alone (the fitted confidence replaces T_d), and each right
frame with the head's and a hand's data vertices exchanged (wrong by ground truth, weighted
SWAP_WEIGHT of the real frames), a named failure (a hand given the head), and a few right frames per capture
re-run with a spurious limb (a rod) added to the hull (wrong by construction, :func:`rod_rows`).
Features fitted: FIT_FEATURES.

Refit after a pipeline change (one command; it rewrites the package's coefficients,
``src/topopose/pose/confidence_model.json``, and the results .md/.json)::

    PYTHONPATH=src:/tmp/mpenv python benchmarks/confidence.py --fit --body-benchmark --real

(~20 min on 2 cores, ~3,000 frames; ``/tmp/mpenv``: wherever mediapipe is installed, for the
real recording's person silhouettes; without mediapipe the real check is skipped.)

Without ``--fit`` it only reports (the shipped coefficients against the previous product
confidence, same frames); with it the shipped model before the refit is a row too. A table of
precision / recall at other minima (held out, per set-up) shows the trade-off;
``--body-benchmark`` applies the same rules to quality.py's own body frames (seeds 21, 22, 8
cameras: a check, never fitted on); ``--real`` to the real recording of ``benchmarks/real.py``
(Pose2Sim's balancing trial, 4 phone cameras, person silhouettes: a check, never fitted on).
``--rows results/confidence.json.gz`` reuses the frames of an earlier run, its body-benchmark and
real-recording frames too (no pipeline run: for trying features and models; the kinds of model
are compared by ``studies/confidence_models.py``).

``--foot-rule``: the precision of ``matched`` as a run decides it, with the gate's foot rule and
without it, on synthetic sequences, the unrelated poses of ``benchmarks/sides.py``, Pose2Sim and
child_rope (:mod:`_gate`, whose options follow it; ``gate.md`` / ``gate.json.gz``)::

    python benchmarks/confidence.py --foot-rule [--quick] [--frames N] [--sides-work DIR] ...
"""
from __future__ import annotations

import os
import sys

if "--foot-rule" in sys.argv:   # its sequences run on one Numba thread (_gate.py)
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import gzip  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from topopose.hull.volume import add_rod  # noqa: E402
from topopose.batch.quality import TP_CLASSES  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
BUILDS = ("average", "heavy", "child", "lean", "random")
TOLERANCE = 0.08          # × subject height
SWAP_WEIGHT = 0.1
# deliberate spurious limbs (:func:`rod_rows`): per capture, this many right matched frames get
# a rod of ROD_LENGTH (m) added to the hull, each weighted ROD_WEIGHT × a real frame (they are
# real pipeline runs, on a hull with a limb the subject does not have; at 1 the fit rejects
# too many right frames: body benchmark separated TP 0.908 → 0.817, docs/accuracy.md)
RODS = 2
ROD_WEIGHT = 0.5
ROD_LENGTH = (0.25, 0.5)
# per-part trust (pose/confidence.py judge_frame): each frame with one part left unplaced
# (:func:`drop_rows`) fitted too, DROP_WEIGHT × the real frames' count in all (0: not fitted)
DROP_WEIGHT = 0.0
POSE_KINDS = ("separated", "all")   # the body benchmark's poses (quality.py body_captures)
POSE_SEED0 = 100                    # their seeds: disjoint from quality.py's 21, 22
BASE_FEATURES = ("distance", "missing", "shape", "shape_max", "spurious_share", "head_low",
                 "head_radius", "head_bend", "head_offset", "head_reach", "trunk", "limb_sym",
                 "spurious", "spurious_length", "arc_dev", "end_radius", "foot_high", "fat",
                 "matched_distance")
# the trunk's junctions, thickness ratios and the placed head (h11b), chosen on this
# benchmark's own frames (never quality.py's seeds 21, 22): held-out seeds, 8 cameras, recall of
# the right frames at precision 0.95 0.908 → 0.922 with them (all poses 0.907 → 0.977); at the
# minimum each fit chooses (0.87 → 0.75) precision / recall 0.962 / 0.815 → 0.947 / 0.912 (on
# the pipeline after h11a's short-arm rules: 0.923 → 0.947; 0.72 → 0.64, 0.956 / 0.916 → 0.953
# / 0.947). Alone each gave less (docs/decisions.md).
JUNCTION_FEATURES = ("crotch_radius", "torso_radius", "hip_flex", "crotch_room", "head_torso",
                     "head_placed_offset", "head_placed_bend")
FIT_FEATURES = BASE_FEATURES + JUNCTION_FEATURES
# camera set-ups: name → (cameras, image size (w, h), silhouette noise level). "4p": four
# portrait phone-like cameras (1088×1920 at half scale) with the noisier
# masks of a segmentation network (level 2: borders ±2 px, false blobs, holes)
# "4r": the same phone cameras laid out as the real recording's (two facing pairs 40–80° apart
# within a pair instead of 90° steps: synth.camera_ring layout "pairs"): opposite views see
# nearly the same outline, so the hull keeps more phantom volume (the real frames' features)
SETUPS = {"8": (8, (640, 480), 1), "4": (4, (640, 480), 1), "4p": (4, (544, 960), 2),
          "4r": (4, (544, 960), 2)}
# Not in the default --setups: refitted with it (--rows … --add-setups 4r,
# results/confidence_refit_4r.md) the real recording still had none of its right frames at the
# 4-camera minimum (0.85; at 0.5 8 right of 14) and the 8-camera minimum fell to 0.58 (held out
# precision 0.947): its frames do not reproduce the recording's radius features (see
# results/confidence_real_torso.md)
LAYOUTS = {"4r": "pairs"}           # camera layout of a set-up (default: the even ring)
# set-ups whose capture volume is fitted to the silhouettes (hull.py fit_box), as the real
# recording's ("person" silhouettes): the grid spans the subject, not a 2.5 m cube
FITTED = {"4r"}
# set-ups that also get the real recording's kind of pose: random balancing poses (one leg lifted
# sideways, synth_body.body_balance) tilted by up to LEAN degrees (synthetic_capture lean)
BALANCE = {"4r"}
LEAN = 45.0
# the minimum: the smallest whose out-of-fold precision of matched reaches this in every set-up
# and every group of it (subject and motion or pose kind)
PRECISION = 0.95
MIN_COUNT = 10          # (a set-up with fewer matched frames at a minimum does not judge it)
FOLDS = 2               # out-of-fold confidences of the minimum: folds by seed (seed % FOLDS)


def collect(a) -> list:
    """Run the pipeline (gate off) on every capture of every set-up (:data:`SETUPS`); one row
    per processed frame."""
    from quality import BODY_MARGIN
    from topopose.synth.capture import synthetic_capture

    rows = []
    for setup in a.setups.split(","):
        cams, size, noise = SETUPS[setup]
        for subject in a.subjects.split(","):
            seeds = a.seeds if subject != "body" else a.body_seeds
            for motion, seed in itertools.product(("walk", "random"), range(seeds)):
                build = BUILDS[seed % len(BUILDS)] if subject == "body" else None
                cap = synthetic_capture(subject, frames=a.frames, seed=seed, cameras=cams,
                                        size=size, noise=noise, motion=motion, build=build,
                                        layout=LAYOUTS.get(setup, "ring"))
                rows += capture_rows(fitted(cap, setup), subject, build, setup, motion, seed)
        # the poses of the body benchmark (quality.py --only body: separated limbs / all random
        # poses), on seeds POSE_SEED0… disjoint from its 21, 22
        if "body" in a.subjects.split(","):
            pose_seeds = range(POSE_SEED0, POSE_SEED0 + a.pose_seeds)
            kinds = POSE_KINDS + (("balance",) if setup in BALANCE else ())
            for kind, seed in itertools.product(kinds, pose_seeds):
                build = BUILDS[seed % len(BUILDS)]
                sep = kind == "separated"
                cap = synthetic_capture("body", frames=a.pose_frames, seed=seed, cameras=cams,
                                        size=size, noise=noise, separated=sep, build=build,
                                        margin=BODY_MARGIN if sep else None,
                                        layout=LAYOUTS.get(setup, "ring"),
                                        lean=LEAN if kind == "balance" else 0.0)
                rows += capture_rows(fitted(cap, setup), "body", build, setup, kind, seed)
    return rows


def fitted(cap, setup):
    """``cap``, with its volume fitted to the silhouettes when ``setup`` is in :data:`FITTED`."""
    return dataclasses.replace(cap, volume=None) if setup in FITTED else cap


def minimum(r, model) -> float:
    """The minimum of ``model`` for the camera count of row ``r``'s set-up."""
    from topopose.frame.confidence import min_confidence_for

    return min_confidence_for(SETUPS[r["cameras"]][0], model)


def fixed(model, t) -> dict:
    """``model`` with the minimum ``t`` whatever the camera count."""
    return {**model, "min_confidence": t, "min_confidence_by_cameras": {}}


def candidate(r, model) -> bool:
    """Whether the frame of row ``r`` reaches the gate of ``model``: matched before the gate, or
    rejected for its AHA distance alone when the model replaces T_d."""
    from topopose.frame.confidence import distance_only, replaces_threshold

    return r["status"] == "matched" or (replaces_threshold(model) and distance_only(r.get("error")))


def capture_rows(cap, subject, build, setup, motion, seed) -> list:
    """Run the pipeline (gate off) on one capture; one row per processed frame, then the
    deliberate swaps."""
    from topopose.frame.confidence import temporal_confidence
    from topopose.frame.estimate import FrameEstimator

    rows = []
    est = FrameEstimator(cap, "human", 100, gate=False)
    out = [est.estimate(f, detail=True) for f in cap.frames]
    poses = [p for p, _ in out]
    temporal_confidence(poses, {f: i for i, f in enumerate(cap.frames)}, gate=False)
    ev = score(cap, poses, est.model)
    for (p, det), s in zip(out, ev.frames):
        if p.status == "failed":
            continue
        dg = p.diagnostics
        fac = dg.get("confidence_factors") or {}
        rows.append({"subject": subject, "build": build, "cameras": setup,
                     "motion": motion, "seed": seed, "frame": p.frame,
                     "status": p.status, "error": p.error, "good": s.quality in TP_CLASSES,
                     "quality": s.quality, "distance": p.distance,
                     "wrong": sorted(k for k, v in s.right.items() if v is False),
                     "features": dg["confidence_features"],
                     "time": fac.get("time"), "volume": fac.get("volume"),
                     "drops": drop_variants(cap, est, p, det)})
    like = {"subject": subject, "build": build, "cameras": setup, "motion": motion, "seed": seed}
    rows += swapped_rows(cap, est, out, ev, like)
    rows += rod_rows(cap, est, out, ev, like)
    print(f"{subject} {build or ''} set-up {setup} {motion} seed {seed}: "
          f"{len(poses)} frames",
          file=sys.stderr, flush=True)
    return rows


def drop_variants(cap, est, p, det, score_with=None) -> dict:
    """Per-part trust (:func:`topopose.frame.confidence.drop_part_features`): for a frame with
    every part placed, per part of DROP_PARTS the features of the frame with that part left
    unplaced and the quality of the pose without it (a right "missing limb" when every other
    part is right)."""
    from topopose.frame.confidence import DROP_PARTS, drop_part_features
    from topopose.frame.thickness import vertex_radii
    from topopose.pose.pose import Pose

    if p.status == "failed" or det.alignment is None or any(x is None for x in p.parts.values()):
        return {}
    dg = p.diagnostics
    radii = vertex_radii(det.volume, det.data, est.thickness_reach)
    out = {}
    for part in DROP_PARTS:
        if p.parts.get(part) is None:
            continue
        f = drop_part_features(det.volume, dg["hull_voxels"], det.data, est.model, est.up,
                               p.distance, est.threshold, len(dg["missing"]), det.alignment,
                               dg.get("thickness_cost", 0.0), radii, dg.get("missing_cost", 0.0),
                               p.parts, part)
        q = (score_with or score)(cap, [Pose(p.frame, "matched", p.distance,
                                             {**p.parts, part: None})], est.model)
        out[part] = {"features": f, "quality": q.frames[0].quality}
    return out


def score(cap, poses, model):
    """Scored as the body benchmark (quality.py body_study): 0.08 × height for every part."""
    from topopose.batch.quality import evaluate

    return evaluate(cap.gt, poses, model=model, tolerance=TOLERANCE * float(cap.gt["height"]),
                    junction_factor=1.0)


def swapped_rows(cap, est, out, ev, like):
    """The failure the issue names (a hand given the head, the head a hand), made on purpose:
    for each right, matched frame the head's and each hand's data vertices exchanged, with
    their features and their own quality (``augmented``: the hand; not counted in the tables)."""
    from types import SimpleNamespace

    from topopose.frame.confidence import frame_features
    from topopose.frame.thickness import vertex_radii
    from topopose.pose.pose import Pose
    rows = []
    for (p, det), s in zip(out, ev.frames):
        if not candidate({"status": p.status, "error": p.error}, {"replaces_threshold": True}) \
                or s.quality not in TP_CLASSES:
            continue
        al = det.alignment
        radii = vertex_radii(det.volume, det.data, est.thickness_reach)
        for hand in ("hand_1", "hand_2"):
            m = dict(al.mapping)
            m["head"], m[hand] = m[hand], m["head"]
            f = frame_features(det.volume, p.diagnostics["hull_voxels"], det.data, est.model,
                               est.up, p.distance, est.threshold, len(p.diagnostics["missing"]),
                               SimpleNamespace(mapping=m, pairs=al.pairs),
                               p.diagnostics.get("thickness_cost", 0.0), radii,
                               p.diagnostics.get("missing_cost", 0.0),
                               {**p.parts, "head": p.parts[hand]})
            parts = {**p.parts, "head": p.parts[hand], hand: p.parts["head"]}
            q = score(cap, [Pose(p.frame, "matched", p.distance, parts)], est.model).frames[0].quality
            rows.append({**like, "frame": p.frame, "status": p.status, "error": p.error,
                         "good": q in TP_CLASSES, "quality": q, "features": f, "time": None,
                         "volume": None, "augmented": hand, "wrong": []})
    return rows


def rod_rows(cap, est, out, ev, like, rods=RODS):
    """A spurious limb made on purpose: for ``rods`` right, matched frames of the capture
    (random, seeded by the capture), a rod of ROD_LENGTH added to the hull, attached on the
    ground-truth trunk (crotch → torso → beyond, at random) and pointing away from the real
    limbs (of 32 directions, elevation −30°…+45°, the one whose tip is farthest from head,
    hands and feet), the frame re-run; wrong by construction (``augmented``: "rod")."""
    rng = np.random.default_rng([like["seed"], len(cap.cameras), sum(map(ord, like["motion"]))])
    ok = [i for i, ((p, _), s) in enumerate(zip(out, ev.frames))
          if candidate({"status": p.status, "error": p.error}, {"replaces_threshold": True})
          and s.quality in TP_CLASSES]
    rows = []
    for k in rng.permutation(ok)[:rods]:
        frame = cap.frames[k]
        parts = {n: np.asarray(v, float) for n, v in cap.gt["frames"][frame]["parts"].items()
                 if v is not None}
        if "torso" not in parts or "crotch" not in parts:
            continue
        start = parts["crotch"] + rng.uniform(0.2, 1.2) * (parts["torso"] - parts["crotch"])
        length = rng.uniform(*ROD_LENGTH)
        ends = [parts[n] for n in ("head", "hand_1", "hand_2", "foot_1", "foot_2") if n in parts]
        az = rng.uniform(0, 2 * np.pi, 32)
        el = rng.uniform(-np.pi / 6, np.pi / 4, 32)
        dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
        d = max(dirs, key=lambda u: min(np.linalg.norm(start + length * u - e) for e in ends))
        hull = est.hull
        est.hull = lambda name: add_rod(hull(name), start, d, length)
        try:
            p = est.estimate(frame)
        finally:
            del est.hull
        if p.status == "failed":
            continue
        dg = p.diagnostics
        rows.append({**like, "frame": p.frame, "status": p.status, "error": p.error,
                     "good": False, "quality": "rod", "features": dg["confidence_features"],
                     "time": None, "volume": None, "augmented": "rod", "wrong": [],
                     "rod": {"length": round(float(length), 3),
                             "start": np.round(start, 3).tolist(),
                             "direction": np.round(d, 3).tolist()}})
    return rows


def gated_quality(r, model, cameras, part_trust=True, head_doubt=True):
    """The quality of the pose the gate of ``model`` (None: T_d only) outputs for the frame of
    row ``r`` at ``cameras`` cameras, None when not matched: as judge_frame decides, with
    per-part trust (``part_trust``) the frame without the part of its ``drops`` that scores
    highest when the whole frame falls below the minimum, else (``head_doubt``) without the
    head when the frame with a typical head reaches it (confidence.head_doubt; True: a head
    the alignment left unmatched — no head reach —, "any": any head)."""
    from topopose.frame.confidence import (fitted_confidence, head_doubt as _head_doubt,
                                          min_confidence_for, min_drop_for)

    if r["status"] == "failed":
        return None
    if model is None:
        return r["quality"] if r["status"] == "matched" else None
    if not candidate(r, model):
        return None
    t = min_confidence_for(cameras, model)
    f = r["features"]
    if fitted_confidence(f, 1.0 - f["lost"], model=model)["confidence"] >= t:
        return r["quality"]
    if part_trust and r.get("drops"):
        from topopose.frame.confidence import untrusted_part

        cs = {p: fitted_confidence(v["features"], 1.0 - f["lost"], model=model)["confidence"]
              for p, v in r["drops"].items()}
        p = untrusted_part(cs, min_drop_for(t, model))
        if p is not None:
            return r["drops"][p]["quality"]
        unmatched = f["head_reach"] == 0 and f["head_radius"] == 0
        c = (_head_doubt(f, 1.0 - f["lost"], model=model)
             if head_doubt == "any" or (head_doubt and unmatched) else None)
        if "head" in r["drops"] and c is not None and c["confidence"] >= min_drop_for(t, model):
            return r["drops"]["head"]["quality"]
    return None


def drop_rows(rows) -> list:
    """The frames of ``rows`` (not augmented) with one part left unplaced (their ``drops``,
    :func:`drop_variants`) as rows of their own (``augmented``: "drop:<part>"), right when
    the pose without that part is a TP."""
    return [{**r, "features": v["features"], "quality": v["quality"],
             "good": v["quality"] in TP_CLASSES, "augmented": f"drop:{part}", "drops": {}}
            for r in rows if not r.get("augmented") for part, v in (r.get("drops") or {}).items()]


def _fit(rows, features, l2, kind="logistic"):
    """The deliberate swaps weigh SWAP_WEIGHT × the real frames' count in all (they are
    many and easy: at full weight the model becomes a swap detector); the deliberate spurious
    limbs (rods, few) ROD_WEIGHT × a real frame each. ``kind``: "logistic"
    (L2 penalty ``l2``) or "trees" (:func:`_fit_trees`)."""
    from topopose.frame.confidence import fit_logistic

    X = np.array([[r["features"][f] for f in features] for r in rows], float)
    y = np.array([r["good"] for r in rows], float)
    aug = np.array([bool(r.get("augmented")) for r in rows])
    drop = np.array([str(r.get("augmented")).startswith("drop:") for r in rows])
    swap = np.array([r.get("augmented") not in (None, False, "rod") for r in rows]) & ~drop
    w = np.ones(len(rows))
    if swap.any():
        w[swap] = SWAP_WEIGHT * (~aug).sum() / swap.sum()
    if drop.any():
        w[drop] = DROP_WEIGHT * (~aug).sum() / drop.sum()
    w[aug & ~swap & ~drop] = ROD_WEIGHT
    if kind == "trees":
        return _fit_trees(X, y, w, features)
    real = X[~aug]                      # standardized on the real frames
    mean, scale = real.mean(axis=0), real.std(axis=0)
    scale[scale == 0] = 1.0
    coef, icpt = fit_logistic((X - mean) / scale, y, l2, weights=w)
    return {"models": ["human"], "replaces_threshold": True, "features": list(features),
            "mean": mean.round(6).tolist(), "scale": scale.round(6).tolist(),
            "coef": coef.round(4).tolist(), "intercept": round(icpt, 4)}


# the boosted trees (scikit-learn's GradientBoostingClassifier, log-loss): few shallow trees
TREES = {"n_estimators": 100, "max_depth": 3, "learning_rate": 0.1}


def _fit_trees(X, y, w, features, **params):
    from sklearn.ensemble import GradientBoostingClassifier

    from topopose.frame.confidence import trees_from_sklearn

    gb = GradientBoostingClassifier(random_state=0, **{**TREES, **params})
    return trees_from_sklearn(gb.fit(X, y.astype(int), sample_weight=w), features)


def fit(rows, features, half, l2, kind="logistic"):
    """Coefficients (or trees, ``kind``) on the calibration seeds' candidate frames (matched,
    or rejected for their AHA distance alone: the fitted confidence replaces T_d), and per
    camera count the smallest minimum (0.30–0.99, step 0.01) whose precision of matched
    reaches PRECISION in every set-up of that many cameras and in every group (subject, motion
    or pose kind) of it (each of at least MIN_COUNT matched frames) at it and every higher
    minimum (``min_confidence_by_cameras``;
    ``min_confidence``: the largest, for fewer cameras than any) —
    judged on out-of-fold confidences (two folds by seed parity, each scored by a model fitted
    on the other), which behave like held-out ones: the in-sample confidences of the wrong
    frames are optimistic."""
    from topopose.frame.confidence import model_confidence

    flag = {"replaces_threshold": True}
    cal = [r for r in rows if r["seed"] < half_of(r, half) and candidate(r, flag)]
    if DROP_WEIGHT > 0:
        cal += drop_rows(cal)
    model = {**_fit(cal, features, l2, kind), "typical_head": typical_head(cal)}
    oof, folds = [], []
    for k in range(FOLDS):
        part = [r for r in cal if r["seed"] % FOLDS != k]
        m = {**_fit(part, features, l2, kind), "typical_head": typical_head(part)}
        folds.append(m)
        for r in cal:
            if r["seed"] % FOLDS == k and not r.get("augmented"):
                c = model_confidence(r["features"], m)
                oof += [(c, r["good"], r["cameras"]),
                        (c, r["good"], r["cameras"], r["subject"], r["motion"])]
    model["min_confidence_by_cameras"] = minima(oof)
    model["min_confidence"] = max(model["min_confidence_by_cameras"].values())
    model["drop_margin"] = drop_margin(
        [(r, folds[r["seed"] % FOLDS]) for r in cal if not r.get("augmented")], model)
    return model


def typical_head(rows) -> dict:
    """The head's features (confidence.HEAD_FEATURES) of a right frame: their medians over the
    right, real (not augmented) frames of ``rows`` (confidence.head_doubt)."""
    from topopose.frame.confidence import HEAD_FEATURES

    right = [r["features"] for r in rows if r["good"] and not r.get("augmented")]
    return {f: round(float(np.median([x[f] for x in right])), 5) for f in HEAD_FEATURES}


DROP_MARGINS = (0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3)


def drop_margin(oof, model) -> float:
    """Per-part trust's margin above the minimum (``min_drop_for``): the smallest of
    DROP_MARGINS at which the out-of-fold decisions (``oof``: (row, the fold's model) pairs,
    :func:`gated_quality` with the minima of ``model``) keep the precision of matched at
    PRECISION in every set-up and group (each of at least MIN_COUNT matched frames) where the
    gate without per-part trust reaches it; the largest if none."""
    keep = {k: model[k] for k in ("min_confidence", "min_confidence_by_cameras")}
    groups = {(r["cameras"], r["subject"], r["motion"]) for r, _ in oof}
    for margin in DROP_MARGINS:
        ok = True
        for g in groups:
            rs = [(r, m) for r, m in oof if (r["cameras"], r["subject"], r["motion"]) == g]
            for pt in (False, True):
                qs = [gated_quality(r, {**m, **keep, "drop_margin": margin},
                                    SETUPS[r["cameras"]][0], pt) for r, m in rs]
                qs = [q for q in qs if q is not None]
                prec = np.mean([q in TP_CLASSES for q in qs]) if qs else 1.0
                if not pt:
                    base = len(qs) < MIN_COUNT or prec >= PRECISION
                elif base and len(qs) >= MIN_COUNT and prec < PRECISION:
                    ok = False
        if ok:
            return margin
    return DROP_MARGINS[-1]


def minima(oof) -> dict:
    """Per camera count (str), the minimum of :func:`fit` from (confidence, right, set-up[,
    group]) tuples: precision in every set-up (and every group of it, when given)."""
    by = {}
    for n in sorted({SETUPS[x[2]][0] for x in oof}):
        best = 0.99
        for t in np.arange(0.99, 0.295, -0.01):
            ok = True
            for setup in {x[2:] for x in oof if SETUPS[x[2]][0] == n}:
                y = [x[1] for x in oof if x[2:] == setup and x[0] >= t]
                ok &= len(y) < MIN_COUNT or np.mean(y) >= PRECISION
            if not ok:
                break
            best = round(float(t), 2)
        by[str(n)] = best
    return by


def mins(model) -> str:
    """The minima of ``model`` as text (per camera count when it has them)."""
    by = model.get("min_confidence_by_cameras") or {}
    return (", ".join(f"{v} ({k} cameras)" for k, v in sorted(by.items(), key=lambda x: int(x[0])))
            or str(model["min_confidence"]))


def half_of(r, half):
    """The first seed of the held-out half of ``r``'s kind of capture."""
    if r["motion"] in POSE_KINDS:
        return POSE_SEED0 + half["pose"]
    return half[r["subject"]]


def kinds_of(subjects, pose_seeds) -> list:
    """(subject, motion) groups of the tables."""
    k = list(itertools.product(subjects, ("walk", "random")))
    return k + [("body", m) for m in POSE_KINDS + ("balance",)
                if pose_seeds and "body" in subjects]


def report(rows, model, half, kinds, before=None):
    """Rows of the table: before (gate off; previous product ≥ 0.7) and after, per seed half."""
    from topopose.frame.confidence import fitted_confidence, frame_confidence

    for r in rows:
        f = r["features"]
        tv = ((r["time"] if r["time"] is not None else 1.0)
              * (r["volume"] if r["volume"] is not None else 1.0))
        # the previous confidence: the product of factors (still used by the other models)
        r["product"] = round(frame_confidence(f["distance"], 1.0, 1.0 - f["lost"], f["missing"],
                                              fatness=f["fat"])["confidence"] * tv, 4)
        c = fitted_confidence(f, 1.0 - f["lost"], model=model)["confidence"]
        r["confidence"] = c
        r["confidence_t"] = round(c * tv, 4)
        if before is not None:
            r["confidence_before"] = fitted_confidence(f, 1.0 - f["lost"], model=before)["confidence"]
    base = lambda r: r["status"] == "matched"                     # noqa: E731
    rules = [("no gate (T_d)", base),
             ("previous: product × time ≥ 0.7", lambda r: base(r) and r["product"] >= 0.7),
             (f"new: fitted ≥ {mins(model)}",
              lambda r: candidate(r, model) and r["confidence"] >= minimum(r, model)),
             (f"new + per-part trust ≥ {mins(model)}",
              lambda r: gated_quality(r, model, SETUPS[r["cameras"]][0])),
             (f"new × time factors ≥ {mins(model)} (not used)",
              lambda r: candidate(r, model) and r["confidence_t"] >= minimum(r, model))]
    if before is not None:          # the shipped model before this refit, on the same frames
        rules.insert(2, (f"before refit: fitted ≥ {mins(before)}",
                         lambda r: candidate(r, before)
                         and r["confidence_before"] >= minimum(r, before)))
    table = []
    for part, sel in (("calibration", lambda r: r["seed"] < half_of(r, half)),
                      ("held out", lambda r: r["seed"] >= half_of(r, half))):
        for cams in list(dict.fromkeys(r["cameras"] for r in rows)) + [None]:
            for name, rule in rules:
                rs = [r for r in rows if sel(r) and (cams is None or r["cameras"] == cams)]
                row = {"seeds": part, "cameras": cams or "all", "rule": name}
                groups = [("all", rs)] + [("/".join(k), [r for r in rs if (r["subject"], r["motion"]) == k])
                                          for k in kinds]
                for g, rr in groups:
                    dec = [(r, rule(r)) for r in rr]
                    m = [r for r, d in dec if d]
                    good = sum(r["good"] for r in rr)
                    # a rule may output another pose than the frame's (per-part trust: its quality)
                    tp = sum((d in TP_CLASSES) if isinstance(d, str) else r["good"]
                             for r, d in dec if d)
                    row[g] = {"matched": len(m), "good": good,
                              "precision": round(tp / len(m), 3) if m else None,
                              "recall": round(tp / good, 3) if good else None}
                table.append(row)
    return table


MINIMA = (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.94, 0.97)


def curve(rows, half, kinds, model, minima=MINIMA):
    """Held-out, per set-up: precision / recall of the right frames per group at each minimum
    of the fitted confidence (``r["confidence"]``, set by :func:`report`), and without gate."""
    out = []
    for setup in dict.fromkeys(r["cameras"] for r in rows):
        rs = [r for r in rows if r["seed"] >= half_of(r, half) and r["cameras"] == setup]
        for t in (None,) + tuple(minima):
            row = {"setup": setup, "min": t}
            for k in [None] + list(kinds):
                rr = [r for r in rs if k is None or (r["subject"], r["motion"]) == k]
                m = [r for r in rr if (r["status"] == "matched" if t is None else
                                       candidate(r, model) and r["confidence"] >= t)]
                tp, good = sum(r["good"] for r in m), sum(r["good"] for r in rr)
                row["all" if k is None else "/".join(k)] = (
                    round(tp / len(m), 3) if m else None, round(tp / good, 3) if good else None)
            out.append(row)
    return out


def swap_summary(aug, model, half):
    from topopose.frame.confidence import fitted_confidence, head_doubt, min_drop_for

    out = {}
    for kind, part in itertools.product(("swaps", "rods"), ("calibration", "held out")):
        wrong = [r for r in aug if (r["seed"] < half_of(r, half)) == (part == "calibration")
                 and not r["good"] and (r["augmented"] == "rod") == (kind == "rods")
                 and candidate(r, {"replaces_threshold": True})]
        c = [fitted_confidence(r["features"], 1.0 - r["features"]["lost"], model=model)["confidence"]
             for r in wrong]
        # the head doubt (opt-in) would match a rejected one when its typical head reaches
        # the per-part minimum (every part of these frames is placed)
        h = [(head_doubt(r["features"], 1.0 - r["features"]["lost"], model=model)
              or {"confidence": 0.0})["confidence"] for r in wrong]       # for any head
        unmatched = [r["features"]["head_reach"] == 0 and r["features"]["head_radius"] == 0
                     for r in wrong]
        out[f"{kind}, {part}"] = {
            "wrong": len(wrong),
            "rejected": sum(x < minimum(r, model) for x, r in zip(c, wrong)),
            "rejected with the head doubt": sum(
                x < minimum(r, model) and not (u and y >= min_drop_for(minimum(r, model), model))
                for x, y, u, r in zip(c, h, unmatched, wrong)),
            "rejected with the head doubt any": sum(
                x < minimum(r, model) and y < min_drop_for(minimum(r, model), model)
                for x, y, r in zip(c, h, wrong))}
    return out


def separation(rows, features, half):
    """Per feature: median among right and among wrong base-matched calibration frames."""
    out = {}
    cal = [r for r in rows if r["seed"] < half_of(r, half)
           and candidate(r, {"replaces_threshold": True})]
    for f in features:
        g = [r["features"][f] for r in cal if r["good"]]
        b = [r["features"][f] for r in cal if not r["good"]]
        out[f] = (round(float(np.median(g)), 3) if g else None,
                  round(float(np.median(b)), 3) if b else None)
    return out


def body_benchmark(models, frames=12, seeds=(21, 22), cached=None):
    """The body benchmark's own frames (quality.py body_captures: 5 builds × seeds 21, 22,
    separated / all poses, 8 cameras, noise 1, 100³), run once with the gate off (or
    ``cached``: the ``rows`` of an earlier call); each rule (name → fitted model, or None: no
    gate) decides ``matched`` from the frames' features. Scored as quality.py (TP rate = TP /
    frames, FP/match = FP / (TP + FP)). Checks only: these seeds are never fitted on."""
    from quality import BODY_TOLERANCE, body_captures
    from topopose.frame.estimate import FrameEstimator
    from topopose.batch.quality import evaluate

    out = {"rows": list(cached or [])}
    for kind in POSE_KINDS:
        if cached is None:
            for cap in body_captures(kind == "separated", 1, seeds, frames):
                est = FrameEstimator(cap, "human", 100, gate=False)
                out_d = [est.estimate(f, detail=True) for f in cap.frames]
                poses = [p for p, _ in out_d]
                ev = evaluate(cap.gt, poses, model=est.model,
                              tolerance=BODY_TOLERANCE * float(cap.gt["height"]),
                              junction_factor=1.0)
                drops = [drop_variants(cap, est, p, det) for p, det in out_d]
                # the frames themselves (for refits without re-running the pipeline)
                out["rows"] += [{"kind": kind, "frame": p.frame, "status": p.status,
                                 "error": p.error, "quality": s.quality,
                                 "cameras": len(cap.cameras),
                                 "features": p.diagnostics.get("confidence_features"),
                                 "drops": d}
                                for p, s, d in zip(poses, ev.frames, drops)]
        rows = [r for r in out["rows"] if r["kind"] == kind]
        rules = [(name, m, False) for name, m in models.items()]
        trusted = [(name, m) for name, m in models.items()
                   if m is not None and name not in {f"fitted ≥ {t}" for t in MINIMA}]
        rules += [(f"{name} + per-part trust", m, True) for name, m in trusted]
        # the head doubt (FrameEstimator(head_doubt=)): off, and for any head (opt-in)
        rules += [(f"{name} + per-part trust, {v}", m, v) for name, m in trusted
                  if m.get("typical_head") for v in ("no head doubt", "head doubt any")]
        for name, m, pt in rules:
            qs = [gated_quality(r, m, r["cameras"], bool(pt),
                                {True: True, "no head doubt": False}.get(pt, "any"))
                  for r in rows]
            tp = sum(q in TP_CLASSES for q in qs)
            fp = sum(q in ("misplaced", "bad") for q in qs)
            right = sum(r["quality"] in TP_CLASSES for r in rows)
            out[f"{kind}|{name}"] = {"frames": len(rows), "right": right, "tp": tp, "fp": fp,
                                     "tp_rate": round(tp / len(rows), 3),
                                     "fp_per_match": round(fp / (tp + fp), 3) if tp + fp else None}
        print(f"body benchmark {kind}: {len(rows)} frames", file=sys.stderr, flush=True)
    return out


def real_check(recording, models, method="person", cached=None):
    """The real recording (``benchmarks/real.py``: Pose2Sim's balancing trial, 4 phone cameras,
    silhouettes by ``method``; never fitted on), run once with the gate off (or ``cached``: the
    result of an earlier call); each rule (name →
    fitted model, or None: T_d only) decides ``matched`` from the frames' features. Right = head,
    both hands and both feet within real.RIGHT (0.15 m) of Pose2Sim's 3D result."""
    import tempfile

    import real as R
    from topopose.frame.confidence import fitted_confidence, min_confidence_for

    rec = Path(recording)
    if cached is None:
        cameras = len(list((rec / "videos").iterdir()))
        ref = R.read_trc(rec / "reference" / "pose2sim_3d.trc")
        with tempfile.TemporaryDirectory() as tmp:
            res, poses = R.run_method(rec, method, 100, 0, Path(tmp), ref)
        frames = [{"frame": p.frame, "right": row["right"], "status": p.status, "error": p.error,
                   "features": p.diagnostics.get("confidence_features")}
                  for p, row in zip(poses, res["rows"]) if p.status != "failed"]
        n = len(poses)
    else:
        cameras, frames, n = cached.get("cameras", 4), cached["rows"], cached["frames"]
    out = {"recording": str(rec), "method": method, "frames": n, "cameras": cameras,
           "right": sum(f["right"] for f in frames), "rules": {}, "rows": frames}
    for name, m in models.items():
        conf = [None if m is None else fitted_confidence(
            f["features"], 1.0 - f["features"]["lost"], model=m)["confidence"] for f in frames]
        ok = [f for f, c in zip(frames, conf)
              if (f["status"] == "matched" if m is None else
                  candidate(f, m) and c >= min_confidence_for(cameras, m))]
        tp = sum(f["right"] for f in ok)
        out["rules"][name] = {"matched": len(ok), "right_matched": tp,
                              "precision": round(tp / len(ok), 3) if ok else None,
                              "confidence_right": None if m is None else
                              [c for f, c in zip(frames, conf) if f["right"]]}
    print(f"real {method}: {n} frames", file=sys.stderr, flush=True)
    return out


def fit_features(spec: str) -> tuple:
    """The features of ``--features``: FIT_FEATURES when empty; ``base``: BASE_FEATURES;
    ``base+a,b``: BASE_FEATURES and a, b; otherwise the comma list itself."""
    if not spec:
        return FIT_FEATURES
    if spec.startswith("base"):
        extra = tuple(f for f in spec[5:].split(",") if f)
        return BASE_FEATURES + tuple(f for f in extra if f not in BASE_FEATURES)
    return tuple(spec.split(","))


def main(argv=None):
    global ROD_WEIGHT, DROP_WEIGHT
    argv = sys.argv[1:] if argv is None else list(argv)
    if "--foot-rule" in argv:
        import _gate
        return _gate.main([x for x in argv if x != "--foot-rule"])
    from _machine import machine, read_rows, results_dir
    from topopose.frame import confidence as C
    ap = argparse.ArgumentParser()
    ap.add_argument("--foot-rule", action="store_true",
                    help="instead: the precision of matched with the gate's foot rule and "
                         "without it (_gate.py; gate.md); the options are then its own: "
                         "confidence.py --foot-rule --help")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--seeds", type=int, default=6, help="capsule human seeds")
    ap.add_argument("--body-seeds", type=int, default=20,
                    help="body seeds (build: average, heavy, child, lean, random by seed)")
    ap.add_argument("--pose-seeds", type=int, default=10,
                    help="body captures of the body benchmark's poses (separated, all), "
                         f"seeds {POSE_SEED0}…")
    ap.add_argument("--pose-frames", type=int, default=12)
    ap.add_argument("--subjects", default="body,human")
    ap.add_argument("--fit", action="store_true",
                    help="refit and rewrite src/topopose/pose/confidence_model.json")
    ap.add_argument("--rows", help="reuse the frames of an earlier run's .json")
    ap.add_argument("--setups", default="8,4,4p",
                    help="camera set-ups, of SETUPS (8: 8 cameras 640×480 noise 1; 4: 4 cameras "
                         "640×480 noise 1; 4p: 4 portrait cameras 544×960 noise 2; 4r: as 4p, cameras "
                         "in facing pairs, fitted volume, also balancing poses: not by default)")
    ap.add_argument("--add-setups", default="",
                    help="with --rows: collect these set-ups too (e.g. 4r) and fit on all")
    ap.add_argument("--real", nargs="?", const=str(HERE / "data" / "pose2sim_balancing"),
                    help="also check the rules on the real recording (benchmarks/real.py's, "
                         "person silhouettes: needs mediapipe; ~2 min; never fitted on)")
    ap.add_argument("--l2", type=float, default=1.0)
    ap.add_argument("--drop-weight", type=float, default=DROP_WEIGHT,
                    help="weight (share of the real frames') of the frames with one part "
                         "left unplaced in the fit (per-part trust)")
    ap.add_argument("--rod-weight", type=float, default=ROD_WEIGHT,
                    help="weight of a deliberate spurious-limb frame (× a real frame's)")
    ap.add_argument("--kind", choices=("logistic", "trees"), default="trees",
                    help="the model --fit fits: boosted trees (TREES; needs scikit-learn, the "
                         "bench extra) or the logistic regression")
    ap.add_argument("--features", default="",
                    help="features fitted: comma list (default FIT_FEATURES); 'base': "
                         "BASE_FEATURES (without JUNCTION_FEATURES); 'base+a,b': BASE_FEATURES "
                         "and a, b")
    ap.add_argument("--body-benchmark", action="store_true",
                    help="also check the rules on quality.py's body frames (seeds 21, 22; ~2 min)")
    a = ap.parse_args(argv)
    ROD_WEIGHT, DROP_WEIGHT = a.rod_weight, a.drop_weight
    subjects = a.subjects.split(",")
    old = {}
    if a.rows:
        old = read_rows(a.rows)
        rows, a.frames, a.seeds, a.body_seeds = (old["rows"], old["frames_per_capture"],
                                                 old["seeds"], old["body_seeds"])
        a.setups = old.get("setups", a.setups)
        a.pose_seeds, a.pose_frames = old.get("pose_seeds", 0), old.get("pose_frames", 0)
        if a.add_setups:            # the new set-ups' frames, collected as the earlier run's
            have = a.setups.split(",")
            new = [x for x in a.add_setups.split(",") if x not in have]
            rows = [r for r in rows if r["cameras"] in have] + collect(
                argparse.Namespace(**{**vars(a), "setups": ",".join(new)}))
            a.setups = ",".join(have + new)
    else:
        rows = collect(a)
    half = {"body": max(1, a.body_seeds // 2), "human": max(1, a.seeds // 2),
            "pose": max(1, a.pose_seeds // 2)}
    model = before = C.CONFIDENCE_MODEL
    if a.fit:
        model = fit(rows, fit_features(a.features), half, a.l2, a.kind)
        model["fitted_by"] = "python benchmarks/confidence.py --fit"
        model["frames"] = sum(r["seed"] < half_of(r, half)
                              and candidate(r, {"replaces_threshold": True}) for r in rows)
        C.MODEL_PATH.write_text("{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v)}"
                                                    for k, v in model.items()) + "\n}\n")
    real = [r for r in rows if not r.get("augmented")]
    kinds = kinds_of(subjects, a.pose_seeds)
    table = report(real, model, half, kinds, before if a.fit else None)
    chosen = set((model.get("min_confidence_by_cameras") or {}).values()) | {model["min_confidence"]}
    trade = curve(real, half, kinds, model, sorted(set(MINIMA) | chosen))
    swaps = swap_summary([r for r in rows if r.get("augmented")], model, half)
    out = {"machine": machine(), "frames": len(real), "swaps": swaps, "frames_per_capture": a.frames,
           "setups": a.setups, "seeds": a.seeds, "body_seeds": a.body_seeds, "pose_seeds": a.pose_seeds,
           "pose_frames": a.pose_frames, "model": model,
           "separation": separation(real, model["features"], half), "table": table,
           "curve": trade,
           "rows": rows}
    rules = {"no gate": None}
    if a.fit:
        rules[f"before refit ≥ {mins(before)}"] = before
    rules[f"fitted ≥ {mins(model)} (shipped)"] = model
    for t in MINIMA:
        rules.setdefault(f"fitted ≥ {t}", fixed(model, t))
    if a.real and old.get("real"):              # the recording's frames of the earlier run
        out["real"] = real_check(old["real"]["recording"], rules, old["real"]["method"],
                                 old["real"])
    elif a.real:
        if not (Path(a.real) / "videos").is_dir():
            print(f"{a.real}: recording not found: the real check is skipped", file=sys.stderr)
        else:
            try:
                import mediapipe  # noqa: F401
                out["real"] = real_check(a.real, rules)
            except ImportError:
                print("mediapipe not installed: the real check is skipped", file=sys.stderr)
    if a.body_benchmark:
        out["body_benchmark"] = body_benchmark(rules, cached=old.get("body_rows"))
        out["body_rows"] = out["body_benchmark"].pop("rows")
    res = results_dir()
    # the rows (each frame with its one-part-left-out variants) are large: gzip, for --rows
    (res / "confidence.json.gz").write_bytes(gzip.compress(json.dumps(out, separators=(",", ":")).encode(), 9))
    groups = ["all"] + ["/".join(k) for k in kinds]
    setups = "; ".join(f"{k}: {c} cameras {w}×{h} noise {n}" for k in a.setups.split(",")
                       for c, (w, h), n in [SETUPS[k]])
    L = ["# The per-frame confidence that decides `matched` (fitted on synthetic subjects only)",
         "",
         f"{len(real)} processed frames ({', '.join(subjects)}; camera set-ups {setups}; "
         "each × walk/random; "
         f"body: {a.body_seeds} seeds, build by seed ({', '.join(BUILDS)}); human: {a.seeds} "
         f"seeds; {a.frames} frames each; and the body benchmark's poses, body/separated and "
         f"body/all as `quality.py --only body` but seeds {POSE_SEED0}–"
         f"{POSE_SEED0 + a.pose_seeds - 1}, each set-up, {a.pose_frames} frames each; "
         f"100³). Right = quality \"good\" or \"missing limb\" (TP of the quality classes) at {TOLERANCE} × "
         f"height for every part. Calibration = the first half of the seeds (fits the "
         f"coefficients on the frames matched or rejected for their AHA distance alone — the "
         f"fitted confidence replaces T_d — and the minimum: the smallest whose out-of-fold "
         f"precision of matched reaches {PRECISION} in every set-up), held out = the rest. "
         f"Machine: {out['machine']['cpu']}, {out['machine']['date']}. Written by "
         "`benchmarks/confidence.py`.", "",
         "Cells: matched frames / right frames present, precision of matched, recall of the "
         "right frames.", "",
         "| seeds | cameras | rule | " + " | ".join(groups) + " |",
         "| --- | --- | --- | " + " | ".join("---" for _ in groups) + " |"]
    for t in table:
        cells = [f"{t[g]['matched']}/{t[g]['good']}, P {t[g]['precision']}, R {t[g]['recall']}"
                 for g in groups]
        L.append(f"| {t['seeds']} | {t['cameras']} | {t['rule']} | " + " | ".join(cells) + " |")
    L += ["", "Held out, per set-up: precision / recall of the right frames at other minima of "
          "the fitted confidence (the trade-off the minimum chooses).", "",
          "| set-up | minimum | " + " | ".join(groups) + " |",
          "| --- | --- | " + " | ".join("---" for _ in groups) + " |"]
    for t in trade:
        L.append(f"| {t['setup']} | {'no gate (T_d)' if t['min'] is None else t['min']} | "
                 + " | ".join(f"P {t[g][0]}, R {t[g][1]}" for g in groups) + " |")
    if a.body_benchmark:
        bb = out["body_benchmark"]
        names = list(dict.fromkeys(k.split("|")[1] for k in bb))
        L += ["", "The body benchmark's own frames (`quality.py --only body`: builds × seeds 21, 22 "
              "× 12 frames, separated / all poses, 8 cameras, noise 1, 100³; never fitted on), "
              "one run with the gate off, each rule applied to its frames' features: TP rate "
              "(TP / frames; right frames present: the no-gate row's TP at best), FP/match, "
              "and TP, FP counts.", "",
              "| rule | " + " | ".join(POSE_KINDS) + " |", "| --- | --- | --- |"]
        for n in names:
            L.append(f"| {n} | " + " | ".join(
                (lambda v: f"TP {v['tp_rate']} ({v['tp']}/{v['right']} right), FP/match "
                           f"{v['fp_per_match']} ({v['fp']})")(bb[f"{k}|{n}"])
                for k in POSE_KINDS) + " |")
    if "real" in out:
        rr = out["real"]
        L += ["", f"The real recording (`benchmarks/real.py`: Pose2Sim's balancing trial, 4 phone "
              f"cameras 1088×1920, {rr['method']} silhouettes, 100³; never fitted on): "
              f"{rr['right']} of {rr['frames']} frames right (head, both hands, both feet within "
              "0.15 m of Pose2Sim's 3D result); each rule on the same run's frames.", "",
              "| rule | matched | right among them | precision of matched |",
              "| --- | --- | --- | --- |"]
        for n, v in rr["rules"].items():
            L.append(f"| {n} | {v['matched']} | {v['right_matched']} | {v['precision']} |")
        L += ["", "The recording's right frames against the synthetic 4-camera body frames: each "
              "fitted feature's median [10th, 90th percentile] on the recording's right frames, "
              "the synthetic 4-camera body frames (set-ups 4, 4p, 4r, all seeds) right and "
              "wrong, and the right frames of set-up 4r (the recording's layout) and of its "
              "balancing poses (a check: the recording is not fitted on).", "",
              "| feature | real, right | synthetic 4 cameras, right | synthetic 4 cameras, wrong "
              "| 4r, right | 4r balance, right |",
              "| --- | --- | --- | --- | --- | --- |"]
        syn = [r for r in real if SETUPS[r["cameras"]][0] == 4 and r["subject"] == "body"]
        r4 = [r for r in syn if r["cameras"] in BALANCE and r["good"]]
        spread = lambda x: (f"{np.median(x):.3f} [{np.percentile(x, 10):.3f}, "  # noqa: E731
                            f"{np.percentile(x, 90):.3f}]" if len(x) else "–")
        for f in model["features"]:
            L.append(f"| {f} | " + " | ".join(spread([r["features"][f] for r in rs]) for rs in (
                [x for x in rr["rows"] if x["right"]], [r for r in syn if r["good"]],
                [r for r in syn if not r["good"]], r4,
                [r for r in r4 if r["motion"] == "balance"])) + " |")
    L += ["", "Deliberate head ↔ hand swaps of the right matched frames (wrong by ground truth) "
          f"and deliberate spurious limbs ({RODS} right matched frames per capture re-run with "
          f"a rod of {ROD_LENGTH[0]}–{ROD_LENGTH[1]} m added to the hull on the trunk, pointing "
          "away from the real limbs; wrong by construction), reaching the gate; the calibration "
          "half's are fitted on too: share the gate rejects — "
          + "; ".join(f"{k}: {v['rejected']}/{v['wrong']}" for k, v in swaps.items()) + "."
          + " With the head doubt (default): "
          + "; ".join(f"{k}: {v['rejected with the head doubt']}/{v['wrong']}"
                      for k, v in swaps.items()) + "."
          + " With the head doubt for any head (opt-in, `head_doubt=\"any\"`): "
          + "; ".join(f"{k}: {v['rejected with the head doubt any']}/{v['wrong']}"
                      for k, v in swaps.items()) + "."]
    L += ["", "## Model (`src/topopose/pose/confidence_model.json`)", ""]
    if model.get("kind") == "trees":
        splits = Counter(model["features"][f] for t in model["trees"]
                         for f, l in zip(t["feature"], t["left"]) if l >= 0)
        L += [f"confidence = σ(b + Σ_t v_t(x)): {len(model['trees'])} boosted trees of depth ≤ "
              f"{TREES['max_depth']} (scikit-learn GradientBoostingClassifier {TREES}), "
              f"b = {model['base']:.4f}, `matched` needs ≥ {mins(model)}.", "",
              "| feature | splits on it | median right / wrong (calibration) |",
              "| --- | --- | --- |"]
        for f in model["features"]:
            L.append(f"| {f} | {splits[f]} | {out['separation'][f][0]} / "
                     f"{out['separation'][f][1]} |")
    else:
        L += [f"confidence = σ(b + Σ c_i (x_i − mean_i) / scale_i), b = {model['intercept']}, "
              f"`matched` needs ≥ {mins(model)}.", "",
              "| feature | coefficient | mean | scale | median right / wrong (calibration) |",
              "| --- | --- | --- | --- | --- |"]
        for f, c, m, s in zip(model["features"], model["coef"], model["mean"], model["scale"]):
            L.append(f"| {f} | {c} | {m} | {s} | {out['separation'][f][0]} / "
                     f"{out['separation'][f][1]} |")
    (res / "confidence.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    sys.exit(main())
