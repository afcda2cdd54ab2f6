"""`topopose run` and `topopose evaluate`: arguments to a run and its scores."""
from __future__ import annotations

import sys
from pathlib import Path

from topopose.batch.quality import evaluate, evaluation_tolerance, summary_table
from topopose.batch.run import MIN_FRAMES_PER_WORKER, run, run_inputs, select_frames, summary_text
from topopose.errors import InputError


def run_cli(a) -> int:
    """``topopose run``: prints a summary; exit 1 when some frames failed."""
    workers = a.workers
    if workers and workers > 1 and not a.scheduler:
        from topopose.capture import load_capture

        n = len(select_frames(load_capture(a.capture), getattr(a, "frames", None)))
        if n < MIN_FRAMES_PER_WORKER * workers:
            print(f"topopose: note: --workers {workers}: {n} frames run faster in this process "
                  f"(starting {workers} worker processes costs more than they save below "
                  f"{MIN_FRAMES_PER_WORKER * workers} frames)", file=sys.stderr)
            workers = 1
    if getattr(a, "rerun", None):
        from topopose import _paths
        from topopose.viz.rerun import require_rerun
        require_rerun()                      # fail before the run, not after
        _paths.check_outputs({"--output": a.output, "--trc": a.trc, "--csv": a.csv,
                              "--c3d": getattr(a, "c3d", None), "--bvh": getattr(a, "bvh", None),
                              "--rerun": a.rerun}, run_inputs(a.capture, a.model))
    res = run(a.capture, model=a.model, resolution=a.resolution, threshold=a.threshold,
              output=a.output, frames=getattr(a, "frames", None), workers=workers,
              scheduler=a.scheduler, resume=a.resume, progress=True, trc=a.trc, csv=a.csv,
              c3d=getattr(a, "c3d", None),
              constraints=not getattr(a, "no_constraints", False),
              tolerance=getattr(a, "tolerance", None),
              refocus=getattr(a, "refocus", False),
              on_pose=None, gate={"on": True, "off": False}.get(getattr(a, "confidence_gate", "auto")),
              thickness=getattr(a, "thickness", None), track=getattr(a, "track", True),
              sides=getattr(a, "sides", True), skeleton=getattr(a, "skeleton", True),
              smooth=getattr(a, "smooth", None), bvh=getattr(a, "bvh", None),
              consistency=getattr(a, "consistency", None),
              support_test=getattr(a, "support", None) or False, trim=getattr(a, "trim", None),
              centre=getattr(a, "centre", None))
    if getattr(a, "rerun", None):
        from topopose._paths import atomic_output
        from topopose.viz.rerun import record_run
        with atomic_output(a.rerun, "--rerun") as tmp:
            record_run(tmp, a.capture, res.poses, model=a.model, resolution=a.resolution,
                       tolerance=getattr(a, "tolerance", None))
        print(f"recorded {a.rerun} (open it with `rerun {a.rerun}`)")
    print(summary_text(res))
    for p in res.failed[:10]:
        print(f"  failed {p.frame}: {p.error}")
    if len(res.failed) > 10:
        print(f"  ... {len(res.failed) - 10} more failed frames"
              + (f" (see {a.output})" if res.written else ""))
    extra = [x for x in (a.trc, a.csv, getattr(a, "c3d", None), getattr(a, "bvh", None)) if x]
    if extra and res.written:
        print("exports: " + ", ".join(str(x) for x in extra))
    return res.exit_status


def evaluate_cli(a) -> int:
    """``topopose evaluate CAPTURE --poses POSES.jsonl [--out DIR] [--tolerance T | --tolerance-m D]
    [--junction-factor F]``."""
    from topopose.capture import load_capture
    from topopose.pose.pose import read_poses

    cap = load_capture(a.capture)
    gt = cap.gt
    if gt is None:
        raise InputError(f"{a.capture}: no gt.json; evaluation needs ground truth "
                         "(synthetic captures from `topopose synth` have it)")
    poses = read_poses(a.poses)
    tol, jf = evaluation_tolerance(gt, getattr(a, "tolerance", None), getattr(a, "tolerance_m", None),
                                   getattr(a, "junction_factor", None))
    ev = evaluate(gt, poses, tolerance=tol, junction_factor=jf)
    h = gt.get("height")
    print(f"tolerance {tol:.4g} capture units" + (f" = {tol / float(h):.3g} x height" if h else "")
          + f", junctions x {jf:g}")
    print(summary_table(ev))
    out = Path(a.out) if a.out else Path(a.poses).resolve().parent
    out.mkdir(parents=True, exist_ok=True)
    from topopose.viz.figures import plot_quality

    from topopose._paths import atomic_output

    fig = out / (Path(a.poses).stem + "_quality.png")
    with atomic_output(fig, "--out") as tmp:
        plot_quality([(f"{gt.get('subject', 'capture')}", ev)], tmp)
    print(f"wrote {fig}")
    return 0
