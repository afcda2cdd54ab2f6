"""Per-frame features that separate right from wrong frames with 4 cameras:
analysis by synthesis in 2D — the frame's placed result rendered into each camera and compared
with that camera's silhouette.

    python studies/trust_features.py [RECORDING] [--work DIR] [--setups 4,4p,8]
                                        [--dev-seeds 41,...] [--test-seeds 1,...] [--frames 40]

(``person`` silhouettes need MediaPipe; ``--work``: cache of the per-frame records.)

Frames: (a) the synthetic walks of ``benchmarks/consistency.py`` (the ``body`` subject, set-ups
``4`` and ``4p``; development seeds to choose anything, held-out seeds to report) and ``8``;
(b) the real recording (``benchmarks/real.py``, ``person`` silhouettes; only reported, never
used to choose). Each frame is estimated without the gate (:class:`FrameEstimator`,
``gate=False``) with its stages kept; right: synthetic a true positive (TP) of the quality classes
(``benchmarks/consistency.py``), real: head, both hands and both feet within 0.15 m of
Pose2Sim's 3D result (``benchmarks/real.py``).

Features (:func:`topopose.frame.support.support_features`, computed from the frame's curves,
hull and silhouettes exactly as the estimator records ``diagnostics["unexplained"]``) are
scored by their AUC (the probability that a random right frame scores better than a random
wrong one), alone and with the run's confidence (mean of the ranks). Then ``matched`` of the
real recording as ``topopose run --consistency`` writes it, with the rule before the
silhouette support and with the module's defaults (chosen on the synthetic development seeds
by ``benchmarks/consistency.py``).
"""
from __future__ import annotations

import argparse
import copy
import json
import pickle
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

SETUPS = ("4", "4p", "8")


def frame_record(p, det, cams, masks):
    """What the features need of one frame, small enough to cache (bit-packed arrays)."""
    rec = {"pose": p, "cams": cams, "masks": [(m.shape, np.packbits(m)) for m in masks]}
    if det is not None and det.volume is not None:
        v = det.volume
        rec.update(vol=(v.data.shape, np.packbits(v.data.astype(bool))), origin=v.origin,
                   voxel_size=v.voxel_size)
    return rec


def unpack(a):
    shape, bits = a
    return np.unpackbits(bits, count=int(np.prod(shape))).reshape(shape).astype(bool)


def synthetic_records(setup, seed, frames, work):
    """Per frame of one synthetic walk: record, right flag; cached in ``work``."""
    import consistency as C
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.confidence import temporal_confidence
    from topopose.frame.estimate import FrameEstimator
    from topopose.pose.model import load_model

    f = Path(work) / f"syn_{setup}_{seed}_{frames}.pkl"
    if f.exists():
        return pickle.loads(f.read_bytes())
    cams, size, noise = C.SETUPS[setup]
    cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, size=size,
                            noise=noise, motion="walk", build=C.BUILDS[seed % len(C.BUILDS)])
    est = FrameEstimator(cap, "human", 100, gate=False)
    recs, poses = [], []
    for fr in cap.frames:
        p, det = est.estimate(fr, detail=True)
        poses.append(p)
        recs.append(frame_record(p, det, list(cap.cameras), cap.silhouettes(fr)))
    temporal_confidence(poses, {x: i for i, x in enumerate(cap.frames)}, gate=False)
    right = C.right_frames(poses, cap.gt, load_model("human"))
    out = (recs, right)
    Path(work).mkdir(parents=True, exist_ok=True)
    f.write_bytes(pickle.dumps(out))
    return out


def real_records(recording, work):
    """Per frame of the real recording (``person`` silhouettes): record, right flag."""
    import real
    from topopose.capture.background import foreground_maps, scaled_camera
    from topopose.frame.confidence import temporal_confidence
    from topopose.frame.estimate import FrameEstimator

    f = Path(work) / "real_person.pkl"
    if f.exists():
        return pickle.loads(f.read_bytes())
    opened = real.open_recording(recording)
    if opened is None:
        return None
    rec, ref = opened
    recs, poses, right = [], [], []
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = real.person_capture(rec, Path(tmp) / "c")
        est = FrameEstimator(cap, "human", 100, gate=False)
        scale = float(cap.options["silhouettes"]["scale"])
        cams = [scaled_camera(c, scale) for c in cap.cameras]
        for i, fr, p, det, e in real.estimated_frames(est, cap, ref):
            masks = [q >= 128 for q in foreground_maps(cap, fr)]
            poses.append(p)
            recs.append(frame_record(p, det, cams, masks))
            right.append(e is not None and all(v <= real.RIGHT for v in e.values()))
        temporal_confidence(poses, {x: i for i, x in enumerate(cap.frames)}, gate=False)
    out = (recs, right)
    Path(work).mkdir(parents=True, exist_ok=True)
    f.write_bytes(pickle.dumps(out))
    return out


def features_of(rec):
    """The frame's confidence, AHA distance and support features; ``ms``: the time of
    ``unexplained`` alone as the estimator computes it (its inscribed distances at hand)."""
    from topopose.frame.support import support_features
    from topopose.frame.tips import inscribed_distances

    p = rec["pose"]
    out = {"confidence": p.diagnostics.get("confidence"), "distance": p.distance}
    if "vol" not in rec or not p.diagnostics.get("curves"):
        return out
    occ = unpack(rec["vol"])
    masks = [unpack(m) for m in rec["masks"]]
    args = (p.diagnostics["curves"], p.parts, rec["cams"], masks, occ, rec["origin"],
            rec["voxel_size"], inscribed_distances(occ))
    out.update(support_features(*args))
    t0 = time.perf_counter()
    support_features(*args, extras=False)
    out["ms"] = (time.perf_counter() - t0) * 1e3
    return out


def auc(score, right) -> float | None:
    """P(score of a right frame > score of a wrong one), ties count half; None without both."""
    s = np.asarray(score, float)
    r = np.asarray(right, bool)
    ok = np.isfinite(s)
    s, r = s[ok], r[ok]
    pos, neg = s[r], s[~r]
    if not len(pos) or not len(neg):
        return None
    gt = (pos[:, None] > neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()
    return float(gt / (len(pos) * len(neg)))


def rank01(x):
    from scipy.stats import rankdata
    x = np.asarray(x, float)
    x = np.where(np.isfinite(x), x, np.nanmin(np.where(np.isfinite(x), x, np.nan)) - 1
                 if np.isfinite(x).any() else 0)
    return (rankdata(x) - 1) / max(len(x) - 1, 1)


FEATURES = ("unexplained", "unexplained_mean", "outside", "tip_depth", "beyond", "confidence",
            "distance")
#: expected direction: +1 higher on right frames, −1 lower
SIGN = {"confidence": 1}


def auc_table(groups) -> dict:
    """Per group: frames, right, AUC of each feature (oriented by :data:`SIGN`), of the
    confidence and ``unexplained`` combined (mean of their ranks), median ms."""
    out = {}
    for g, rows in groups.items():
        right = [ok for _, ok in rows]

        def col(k):
            return np.array([np.nan if f.get(k) is None else f[k] for f, _ in rows], float)

        t = {"frames": len(rows), "right": int(sum(right)), "auc": {}}
        for k in FEATURES:
            t["auc"][k] = auc(SIGN.get(k, -1) * col(k), right)
        c = np.nan_to_num(col("confidence"), nan=-1.0)
        u = np.nan_to_num(col("unexplained"), nan=9.0)
        t["auc"]["confidence + unexplained"] = auc(rank01(c) + rank01(-u), right)
        ms = [f["ms"] for f, _ in rows if "ms" in f]
        t["ms_median"] = round(float(np.median(ms)), 2) if ms else None
        t["ms_p90"] = round(float(np.percentile(ms, 90)), 2) if ms else None
        out[g] = t
    return out


def as_run_consistency(recording, recs, feats, settings):
    """The real recording's per-frame records as ``run`` writes them, ``matched`` by the
    consistency with ``settings`` (True, or :func:`judge_sequence` keywords; the frames'
    ``unexplained`` as the estimator records it): the poses, each frame's record index and
    Pose2Sim's markers."""
    import real
    from topopose.frame.confidence import min_confidence_for
    from topopose.pose.model import load_model

    _, ref = real.open_recording(recording)
    poses = []
    for r, f in zip(recs, feats):
        p = copy.deepcopy(r["pose"])
        if np.isfinite(f.get("unexplained", np.nan)):
            p.diagnostics["unexplained"] = round(f["unexplained"], 4)
        poses.append(p)
    idx = {p.frame: i for i, p in enumerate(poses)}
    ps = real.as_run(poses, load_model("human"), np.array([0.0, 0.0, 1.0]),
                     min_confidence_for(4), consistency=settings)
    return ps, idx, ref


def real_matched(recording, recs, feats, settings) -> dict:
    """The real recording as ``run`` writes it, ``matched`` by the consistency with
    ``settings`` (:func:`as_run_consistency`): frames passing, right among them, right
    frames."""
    import real

    ps, idx, ref = as_run_consistency(recording, recs, feats, settings)
    m = rt = nr = 0
    for p in ps:
        e = real.frame_errors(p.parts, ref, idx[p.frame]) if p.status != "failed" else None
        ok = e is not None and all(v <= real.RIGHT for v in e.values())
        nr += ok
        if p.status == "matched":
            m += 1
            rt += ok
    return {"frames": len(ps), "right": nr, "matched": m, "right_matched": rt,
            "precision": round(rt / m, 3) if m else None,
            "share_of_right": round(rt / nr, 3) if nr else None}


def main(argv=None):
    from _machine import machine, write_results
    import real
    from consistency import BEFORE
    from topopose.sequence import consistency as C
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--work", default=None, help="cache of the per-frame records")
    ap.add_argument("--setups", default=",".join(SETUPS))
    ap.add_argument("--dev-seeds", default=",".join(map(str, range(41, 59))))
    ap.add_argument("--test-seeds", default="1,2,3,4")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--real-json", default=None,
                    help="results of benchmarks/real.py (its as_run_consistency rows: the "
                         "estimator's own unexplained, end to end)")
    ap.add_argument("--out", default=str(HERE / "results" / "trust_features"))
    a = ap.parse_args(argv)
    work = a.work or tempfile.mkdtemp(prefix="trust_features_")
    groups = {}
    for setup in a.setups.split(","):
        for part, seeds in (("development", a.dev_seeds), ("held-out", a.test_seeds)):
            rows = []
            for s in seeds.split(","):
                recs, right = synthetic_records(setup, int(s), a.frames, work)
                rows += [(features_of(r), ok) for r, ok in zip(recs, right)]
            groups[f"synthetic {setup}, {part}"] = rows
            print(f"{setup} {part}: {len(rows)} frames", file=sys.stderr, flush=True)
    doc = {"machine": machine(), "frames": a.frames, "dev_seeds": a.dev_seeds,
           "test_seeds": a.test_seeds, "dilation": None}
    from topopose.frame.support import DILATION
    doc["dilation"] = DILATION
    rr = real_records(a.recording, work)
    if rr is not None:
        feats = [features_of(r) for r in rr[0]]
        groups["real (person silhouettes)"] = list(zip(feats, rr[1]))
        now = {"max_deviation": C.MAX_DEVIATION, "neighbours": C.NEIGHBOURS,
               "min_rank": C.MIN_RANK, "max_unexplained": C.MAX_UNEXPLAINED}
        doc["real_matched"] = {"before": real_matched(a.recording, rr[0], feats, BEFORE),
                               "after": real_matched(a.recording, rr[0], feats, now)}
        doc["settings"] = {"before": BEFORE, "after": now}
    doc["auc"] = auc_table(groups)
    if a.real_json and Path(a.real_json).is_file():
        rj = json.loads(Path(a.real_json).read_text())
        doc["real_py"] = {"machine": rj.get("machine"), "methods": {
            k: {"matched": r["as_run_consistency"]["matched"],
                "precision": r["as_run_consistency"]["matched_precision"],
                "right": r["as_run"]["right"],
                "support_ms": r["speed"]["stages_median_ms"].get("support"),
                "total_ms": r["speed"]["stages_median_ms"].get("total")}
            for k, r in rj["methods"].items() if "as_run_consistency" in r}}
    write_results(a.out, doc, report)
    return 0


def _f(x):
    return "—" if x is None else f"{x:.3f}"


def report(doc) -> str:
    from _machine import machine_line

    m = doc["machine"]
    L = ["# Which per-frame feature tells right from wrong frames", "",
         f"{machine_line(m)}. "
         "Written by `studies/trust_features.py` (see its docstring). Synthetic: body subject "
         f"walking, {doc['frames']} frames per sequence, development seeds {doc['dev_seeds']}, "
         f"held-out seeds {doc['test_seeds']}; real: Pose2Sim's balancing trial, `person` "
         "silhouettes (reported only, never used to choose). Right: synthetic a true positive (TP) of the quality classes; "
         "real: head, hands and feet within 0.15 m of Pose2Sim.", "",
         "AUC: the probability that a right frame scores better than a wrong one (0.5: chance); "
         "every support feature is expected lower on right frames, the confidence higher. "
         f"*unexplained* dilates the model by {doc['dilation']} × the silhouette's largest "
         "inscribed radius (`pose/support.py`).", ""]
    groups = list(doc["auc"])
    feats = list(next(iter(doc["auc"].values()))["auc"])
    L += _table(["feature", *groups],
                [["frames (right)", *(f"{doc['auc'][g]['frames']} ({doc['auc'][g]['right']})"
                                      for g in groups)]]
                + [[k, *(_f(doc["auc"][g]["auc"][k]) for g in groups)] for k in feats]
                + [["ms per frame, median / p90 (unexplained alone)",
                    *(f"{doc['auc'][g]['ms_median']} / {doc['auc'][g]['ms_p90']}"
                      for g in groups)]])
    if doc.get("real_matched"):
        st = doc["settings"]
        L += ["", "## `matched` on the real recording, `topopose run --consistency`", "",
              f"As `run` writes it (confidence gate, then tracking, skeleton, sides, then the "
              f"consistency). Before: {st['before']}; after (the module's defaults, chosen on "
              f"the synthetic development seeds, `results/consistency.md`): {st['after']}.", ""]
        L += _table(["rule", "frames", "right", "matched", "right among matched",
                     "precision (target ≥ 95 %)", "right frames passing"],
                    [[k, r["frames"], r["right"], r["matched"], r["right_matched"],
                      _f(r["precision"]), _f(r["share_of_right"])]
                     for k, r in doc["real_matched"].items()])
    if doc.get("real_py"):
        rp = doc["real_py"]
        L += ["", "End to end (`benchmarks/real.py`, the estimator recording `unexplained` itself, "
              f"after; load {(rp['machine'] or {}).get('load_average')}):", ""]
        L += _table(["silhouettes", "right as run writes it", "matched (after)",
                     "precision (after)", "support ms/frame (median)",
                     "frame total ms (median)"],
                    [[k, r["right"], r["matched"], _f(r["precision"]), r["support_ms"],
                      r["total_ms"]] for k, r in rp["methods"].items()])
    return "\n".join(L) + "\n"


def _table(head, rows):
    return ["| " + " | ".join(map(str, head)) + " |", "|" + " --- |" * len(head)] + \
           ["| " + " | ".join(map(str, r)) + " |" for r in rows]


if __name__ == "__main__":
    sys.exit(main())
