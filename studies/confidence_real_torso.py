"""Why the real recording's right frames lie outside the synthetic 4-camera calibration: per
frame, where the *alignment's* trunk vertices are against the reference, and the
hull's inscribed-ball radii in voxels, on the real recording and on synthetic 4-camera body
captures (set-ups 4p and 4r of ``benchmarks/confidence.py``, their balancing poses too).

Real: Pose2Sim's balancing trial (``benchmarks/real.py``, ``person`` silhouettes, 100³; never
fitted on); reference torso = Pose2Sim's Neck, crotch = mid-hip, lean = angle of mid-hip → Neck
from the vertical. Synthetic: the ground truth's torso and crotch. Right: real.py's (head, hands,
feet within 0.15 m) on the recording, TP of the quality classes on synthetic frames.

    PYTHONPATH=$PWD/src python studies/confidence_real_torso.py --real PATH [--step 1]

Writes ``results/confidence_real_torso.{md,json}``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

FEATURES = ("head_bend", "head_offset", "torso_radius", "head_torso", "end_radius", "fat",
            "spurious")


def frame_row(est, frame, trunk):
    """One frame: the alignment's torso / crotch data vertices and the placed ones against
    ``trunk`` (name → reference position), the hull's largest inscribed ball (voxels, metres)."""
    from topopose.frame.thickness import taxicab_radii

    p, det = est.estimate(frame, detail=True)
    if p.status == "failed":
        return None, p
    al, vol = det.alignment, det.volume
    pos = {k: det.data.positions.get(v) for k, v in ((al.mapping or {}) if al else {}).items()
           if v is not None}
    err = lambda x, g: None if x is None else round(float(np.linalg.norm(np.subtract(x, g))), 3)  # noqa: E731
    dt, _ = taxicab_radii(vol)
    fe = p.diagnostics["confidence_features"]
    row = {"frame": frame, "voxel_m": round(float(vol.voxel_size), 4), "max_ball_vox": int(dt.max()),
           "max_ball_m": round(float(dt.max() * vol.voxel_size), 3),
           "hull_m3": round(float(vol.data.sum() * vol.voxel_size ** 3), 4),
           **{f: round(float(fe[f]), 3) for f in FEATURES}}
    for k, g in trunk.items():
        row[f"{k}_vertex_err"] = err(pos.get(k), g)
        row[f"{k}_placed_err"] = err(p.parts.get(k), g)
    return row, p


def real_rows(rec, step):
    import real as R
    import topopose as tp
    from topopose.frame.estimate import FrameEstimator

    ref = R.read_trc(rec / "reference" / "pose2sim_3d.trc")
    rows = []
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        R.make_capture(rec, Path(tmp) / "cap", "person", "")
        cap = tp.load_capture(Path(tmp) / "cap")
        est = FrameEstimator(cap, "human", 100, gate=False)
        for i, f in list(enumerate(cap.frames))[::step]:
            neck, hip = ref["Neck"][i], (ref["RHip"][i] + ref["LHip"][i]) / 2
            row, p = frame_row(est, f, {"torso": neck, "crotch": hip})
            if row is None:
                continue
            e = R.frame_errors(p.parts, ref, i)
            up = (neck - hip) / np.linalg.norm(neck - hip)
            row.update(source="real", right=bool(e) and all(v <= R.RIGHT for v in e.values()),
                       lean_deg=round(float(np.degrees(np.arccos(up[2]))), 1))
            rows.append(row)
            print(f"real {f}", file=sys.stderr, flush=True)
    return rows


def synthetic_rows(seeds, frames):
    import confidence as B
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    rows = []
    for setup, kind, seed in [(s, k, x) for s in ("4p", "4r") for k in ("random", "balance")
                              for x in range(seeds) if not (s == "4p" and k == "balance")]:
        cams, size, noise = B.SETUPS[setup]
        cap = synthetic_capture("body", frames=frames, seed=200 + seed, cameras=cams, size=size,
                                noise=noise, build=B.BUILDS[seed % len(B.BUILDS)],
                                layout=B.LAYOUTS.get(setup, "ring"),
                                lean=B.LEAN if kind == "balance" else 0.0)
        if setup in B.FITTED:
            cap = dataclasses.replace(cap, volume=None)
        est = FrameEstimator(cap, "human", 100, gate=False)
        gt = cap.options["gt"]["frames"]
        out = [frame_row(est, f, {k: gt[f]["parts"][k] for k in ("torso", "crotch")})
               for f in cap.frames]
        ev = B.score(cap, [p for _, p in out], est.model)
        for (row, _), s in zip(out, ev.frames):
            if row is not None:
                row.update(source=f"{setup} {kind}", right=s.quality in B.TP_CLASSES)
                rows.append(row)
        print(f"synthetic {setup} {kind} seed {seed}", file=sys.stderr, flush=True)
    return rows


def main(argv=None):
    from _machine import machine, results_dir

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--real", required=True, help="the Pose2Sim balancing recording's folder")
    ap.add_argument("--step", type=int, default=1, help="every step-th frame of the recording")
    ap.add_argument("--seeds", type=int, default=4, help="synthetic captures per kind")
    ap.add_argument("--frames", type=int, default=10)
    a = ap.parse_args(argv)
    rec = Path(a.real)
    if not (rec / "videos").is_dir():
        sys.exit(f"{rec}: recording not found")
    rows = real_rows(rec, a.step) + synthetic_rows(a.seeds, a.frames)
    med = lambda x: f"{np.median(x):.3f}" if len(x) else "–"  # noqa: E731
    L = ["# The real recording's right frames against synthetic 4-camera ones", "",
         f"Machine: {machine()}. Written by `studies/confidence_real_torso.py` "
         f"(step {a.step}, {a.seeds} synthetic seeds × {a.frames} frames per kind).", "",
         "Right frames only; medians. *off*: the alignment's torso data vertex more than 0.3 m "
         "from the reference torso (real: Pose2Sim's Neck).", "",
         "| frames | n | torso vertex err (m) | placed torso err (m) | share off | largest ball "
         "(vox / m) | voxel (m) | hull (m³) | " + " | ".join(FEATURES) + " |",
         "|" + " --- |" * (9 + len(FEATURES))]
    for src in dict.fromkeys(r["source"] for r in rows):
        rs = [r for r in rows if r["source"] == src and r["right"]]
        tv = [r["torso_vertex_err"] for r in rs if r["torso_vertex_err"] is not None]
        L.append(f"| {src} | {len(rs)} | {med(tv)} | "
                 f"{med([r['torso_placed_err'] for r in rs if r['torso_placed_err'] is not None])} | "
                 f"{(sum(x > 0.3 for x in tv) / len(tv)) if tv else 0:.2f} | "
                 f"{med([r['max_ball_vox'] for r in rs])} / {med([r['max_ball_m'] for r in rs])} | "
                 f"{med([r['voxel_m'] for r in rs])} | {med([r['hull_m3'] for r in rs])} | "
                 + " | ".join(med([r[f] for r in rs]) for f in FEATURES) + " |")
    real = [r for r in rows if r["source"] == "real" and r["right"]]
    for name, sel in (("off", lambda r: (r["torso_vertex_err"] or 0) > 0.3),
                      ("on", lambda r: (r["torso_vertex_err"] or 0) <= 0.3)):
        rs = [r for r in real if sel(r)]
        L.append(f"| real right, torso vertex {name} | {len(rs)} | "
                 f"{med([r['torso_vertex_err'] or 0 for r in rs])} | "
                 f"{med([r['torso_placed_err'] for r in rs if r['torso_placed_err'] is not None])} | "
                 f"– | {med([r['max_ball_vox'] for r in rs])} / {med([r['max_ball_m'] for r in rs])}"
                 f" | {med([r['voxel_m'] for r in rs])} | {med([r['hull_m3'] for r in rs])} | "
                 + " | ".join(med([r[f] for r in rs]) for f in FEATURES) + " |")
    lean = [r["lean_deg"] for r in rows if r["source"] == "real"]
    L += ["", f"The recording's trunk lean (mid-hip → Neck from the vertical): median "
          f"{np.median(lean):.1f}°, 90th percentile {np.percentile(lean, 90):.1f}°, max "
          f"{max(lean):.1f}°."]
    res = results_dir()
    (res / "confidence_real_torso.md").write_text("\n".join(L) + "\n")
    (res / "confidence_real_torso.json").write_text(json.dumps(
        {"machine": machine(), "step": a.step, "rows": rows}, separators=(",", ":")))
    print("\n".join(L))


if __name__ == "__main__":
    main()
