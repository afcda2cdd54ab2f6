"""Speed of the sequence stages (``topopose run`` after the per-frame stage: identities, the
hands' trim, the kinematic skeleton, left and right, the consistency), with the skeleton fit's
exact Jacobian against the finite-difference one it replaced (the peer), in one run.

    python benchmarks/motion_speed.py [--work DIR] [--frames 40] [--real RECORDING]
                                      [--out benchmarks/results] [--quick]

Subjects: the anatomically real ``body`` walking, seen by 8 cameras (640×480, noise 1) and by
4 phones in facing pairs (``tracking.py``'s ``4p``: the AHA threshold and the confidence gate
off, every frame fitted, as ``real_motion.py``), ``--frames`` frames each; and, when its path
exists and MediaPipe is installed, the real recording (``real_motion.py``'s per-frame run, 100
frames). Per subject: the per-frame stage's time per frame (``run`` with the sequence stages
off, for scale), then :func:`topopose.sequence.motion.process_sequence` timed three times with each
Jacobian (the best of three, per frame), and the largest difference between the joints the two
give (they minimize the same residuals: the fit is unchanged).

The peer is the same fit with ``least_squares``' own finite differences (what
:func:`topopose.sequence.kinematic_fit.fit_frame` did before): ``kinematic_fit.least_squares`` is
wrapped to drop the ``jac`` argument. Writes ``motion_speed.md`` and ``.json``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _machine import machine, machine_line, write_results  # noqa: E402


def finite_differences():
    """A context in which the skeleton fit uses least_squares' finite differences (the peer)."""
    from contextlib import contextmanager

    from topopose.sequence import kinematic_fit as kf
    @contextmanager
    def ctx():
        orig = kf.least_squares

        def fd(fun, x0, jac=None, **kw):
            return orig(fun, x0, **kw)
        kf.least_squares = fd
        try:
            yield
        finally:
            kf.least_squares = orig
    return ctx()


def timed_sequence(poses, model, up, repeats=3):
    """(best seconds of ``repeats`` runs of process_sequence, its poses)."""
    from topopose.sequence.motion import process_sequence

    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = process_sequence(poses, model, up)
        best = min(best, time.perf_counter() - t0)
    return best, out.poses


def joints_diff(a, b) -> float:
    """Largest distance (m) between the joints of two runs' poses."""
    d = [np.linalg.norm(np.asarray(p.joints[k]) - np.asarray(q.joints[k]))
         for p, q in zip(a, b) for k in p.joints if k in q.joints]
    return float(max(d)) if d else 0.0


def measure(name, poses, per_frame_s, model, up) -> dict:
    exact, pe = timed_sequence(poses, model, up)
    with finite_differences():
        fd, pf = timed_sequence(poses, model, up)
    n = len(poses)
    row = {"subject": name, "frames": n, "per_frame_stage_ms": round(1e3 * per_frame_s / n, 1)
           if per_frame_s else None, "sequence_ms_exact": round(1e3 * exact / n, 1),
           "sequence_ms_finite_differences": round(1e3 * fd / n, 1),
           "speed_up": round(fd / exact, 2), "max_joint_difference_mm": round(1e3 * joints_diff(pe, pf), 4),
           "with_skeleton": sum(bool(p.joints) for p in pe)}
    print(row, flush=True)
    return row


def synthetic(work, setup, frames, model):
    import tracking as T

    from topopose.capture import load_capture
    from topopose.batch import run
    cap = load_capture(T.make_sequence(work, "walk", 3, "average", frames, setup))
    loose = {} if setup == "8" else {"threshold": 1e9, "gate": False}
    t0 = time.perf_counter()
    res = run(cap, model=model, resolution=100, progress=False, track=False, sides=False,
              skeleton=False, **loose)
    return res.poses, time.perf_counter() - t0, cap.up_vector


def real(path, work, model):
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        print("mediapipe not installed: the real recording is skipped (pip install topopose[segment])")
        return None
    rec = Path(path)
    if not (rec / "videos").is_dir():
        print(f"{rec}: recording not found (needs videos/ and Calib.toml); skipped")
        return None
    import real_motion as RM
    from real import make_capture

    import topopose as tp
    from topopose.batch import run
    cdir = Path(work) / "real"
    make_capture(rec, cdir, "person", RM.SILHOUETTES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = tp.load_capture(cdir)
        t0 = time.perf_counter()
        res = run(cap, model=model, resolution=100, threshold=1e9, gate=False, progress=False,
                  track=False, sides=False, skeleton=False)
    return res.poses, time.perf_counter() - t0, cap.up_vector


def report(doc) -> str:
    L = ["# Speed of the sequence stages: the skeleton fit's exact Jacobian against finite "
         "differences", "", f"{machine_line(doc['machine'])}. Written by "
         "`benchmarks/motion_speed.py`; `process_sequence` (what `topopose run` does after the "
         "per-frame stage), best of 3 runs, ms a frame; the per-frame stage (hull, thinning, "
         "alignment, placement, 100³, one process) beside it for scale (its first frames "
         "include the kernels' compilation when the cache is cold).", "",
         "| subject | frames (with a skeleton) | per-frame stage | sequence stages, exact Jacobian "
         "| finite differences (peer) | speed-up | largest joint difference |",
         "|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        L.append(f"| {r['subject']} | {r['frames']} ({r['with_skeleton']}) | "
                 f"{r['per_frame_stage_ms']} ms | **{r['sequence_ms_exact']} ms** | "
                 f"{r['sequence_ms_finite_differences']} ms | {r['speed_up']} × | "
                 f"{r['max_joint_difference_mm']} mm |")
    return "\n".join(L) + "\n"


def main(argv=None):
    from _machine import results_dir

    from topopose.pose.model import load_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=None, help="folder for the synthetic captures (default: a temporary one)")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--real", default=str(HERE / "data" / "pose2sim_balancing"))
    ap.add_argument("--out", default=None)
    ap.add_argument("--quick", action="store_true", help="12 frames per synthetic walk")
    a = ap.parse_args(argv)
    if a.quick:
        a.frames = 12
    model = load_model("human")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(a.work or tmp)
        for setup, label in (("8", "body walk, 8 cameras"), ("4p", "body walk, 4 phones (4p)")):
            poses, secs, up = synthetic(work, setup, a.frames, model)
            rows.append(measure(label, poses, secs, model, up))
        got = real(a.real, work, model)
        if got is not None:
            rows.append(measure("real recording (4 phones, person)", got[0], got[1], model, got[2]))
    doc = {"machine": machine(), "rows": rows}
    write_results(Path(a.out or results_dir()) / ("motion_speed_quick" if a.quick
                                                  else "motion_speed"), doc, report)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
