"""Where the tracker's error comes from on the development sequences: the track against a fit
of every frame started from the true pose (the objective's own minimum near the truth), on
the body's calibrated bone lengths or on the truth's.

    python studies/tracker_bounds.py [--work DIR] [--frames 40] [--truth-lengths]
                                     [--recover 0.9] [--out studies/results]

Development sequences only (``_tracker.py``'s ``DEV_SEEDS``: walk, random-smooth and the
motions whose limbs touch the body; ``body`` subject, 8 cameras, 100³). Each sequence is run
as ``topopose run`` does (``FollowOptions()``, ``TrackOptions.recover`` from ``--recover``:
above 1 every frame is fitted again from its limbs' other starts), and every frame is then
fitted once more by :func:`~topopose.sequence.tracker.fit_frame` from the truth's joints
(the track's where the rig has none: the chest, the tips), on the same frame data. Per
sequence: the MPJPE (``tracking.py``'s joints, mean over frames) of the track and of the
from-truth fits, the arms' (elbows, wrists), the silhouette IoU of both and on how many
frames the from-truth fit's is higher (whether the track's judge would choose it).
With ``--truth-lengths`` the calibrated body's bones with both ends in the rig take the
truth's median lengths.

Writes ``tracker_bounds_dev.md``.
"""
import argparse
import sys
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import machine, machine_line  # noqa: E402
from _tracker import BUILDS, DEV_SEEDS, MOTIONS  # noqa: E402
from tracking import MPJPE_JOINTS, RIG, make_sequence  # noqa: E402

import topopose.sequence.follow as follow_module  # noqa: E402
import topopose.sequence.tracker as tracker_module  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.capture import load_capture  # noqa: E402
from topopose.sequence.follow import FollowOptions  # noqa: E402
from topopose.sequence.tracker import TrackOptions, fit_frame  # noqa: E402


def truth_joints(names, gtj, near):
    """The rig's joints in the body's order (mirror pairs ordered as ``near``, NaN: none)."""
    J = {k: np.asarray(v, float) for k, v in gtj.items()}
    T = np.full((len(names), 3), np.nan)
    for k, n in enumerate(names):
        base, _, side = n.rpartition("_")
        if side in ("1", "2") and base in RIG and len(RIG[base]) == 2:
            a, b = names.index(base + "_1"), names.index(base + "_2")
            x, y = J[RIG[base][0]], J[RIG[base][1]]
            if (np.linalg.norm(near[a] - x) + np.linalg.norm(near[b] - y)
                    > np.linalg.norm(near[a] - y) + np.linalg.norm(near[b] - x)):
                x, y = y, x
            T[k] = x if k == a else y
        elif n == "pelvis":
            T[k] = 0.5 * (J[RIG[n][0]] + J[RIG[n][1]])
        elif n in RIG and len(RIG[n]) == 1:
            T[k] = J[RIG[n][0]]
    return T


def sequence(d, truth_lengths, recover):
    cap = load_capture(d)
    frames = sorted(cap.gt["frames"])
    seen = {}
    track_sequence, calibrate = follow_module.track_sequence, tracker_module.calibrate

    def tracked(body, data_of, align, opts=None, **kw):
        tr = track_sequence(body, data_of, align, opts, **kw)
        seen.update(body=body, data_of=data_of, opts=opts, track=tr, quality=kw["quality"])
        return tr

    def calibrated(body, cal_frames, *a, **kw):
        body = calibrate(body, cal_frames, *a, **kw)
        if not truth_lengths:
            return body
        L = body.lengths.copy()
        T = np.array([truth_joints(body.names, cap.gt["frames"][f]["joints"],
                                   np.zeros((len(body.names), 3))) for f in frames])
        for j, p in enumerate(body.parents):
            if p >= 0 and np.isfinite(T[:, [j, p]]).all():
                L[j] = float(np.median(np.linalg.norm(T[:, j] - T[:, p], axis=1)))
        return replace(body, lengths=L)

    follow_module.track_sequence, tracker_module.calibrate = tracked, calibrated
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run(cap, resolution=100, progress=False,
                follow=FollowOptions(track=TrackOptions(recover=recover)))
    finally:
        follow_module.track_sequence, tracker_module.calibrate = track_sequence, calibrate
    body, tr, quality = seen["body"], seen["track"], seen["quality"]
    names = list(body.names)
    scored = [k for k, n in enumerate(names) if n.rpartition("_")[0] in MPJPE_JOINTS
              or n in MPJPE_JOINTS]
    arms = [k for k in scored if names[k].startswith(("elbow", "wrist"))]
    rows = []
    for i, f in enumerate(frames):
        Pt = tr.joints[i]
        if np.isnan(Pt).any():
            continue
        T = truth_joints(names, cap.gt["frames"][f]["joints"], Pt)
        start = np.where(np.isnan(T), Pt, T)
        data = seen["data_of"](i)
        Pf = fit_frame(body, data, start, seen["opts"])

        def err(P, ks):
            return float(np.mean(np.linalg.norm(P[ks] - T[ks], axis=1)))

        rows.append((err(Pt, scored), err(Pf, scored), err(Pt, arms), err(Pf, arms),
                     quality(i, data, Pt), quality(i, data, Pf)))
    return np.array(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=None, help="folder for the sequences (default: a temporary one)")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--truth-lengths", action="store_true")
    ap.add_argument("--recover", type=float, default=TrackOptions().recover)
    ap.add_argument("--out", default="studies/results")
    a = ap.parse_args()
    work = Path(a.work or tempfile.mkdtemp(prefix="tracker_bounds_"))
    lines = ["# The tracker against fits from the true pose (development sequences, 8 cameras)",
             "", machine_line(machine()),
             f"Bone lengths: {'the truth' if a.truth_lengths else 'calibrated'}; "
             f"`TrackOptions.recover = {a.recover}`", "",
             "| motion | seed | build | MPJPE cm: track / from truth | arms cm: track / from truth "
             "| IoU: track / from truth | from truth's IoU higher |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    means = []
    for motion in MOTIONS:
        seed, build = DEV_SEEDS[motion], BUILDS[MOTIONS.index(motion)]
        d = make_sequence(work, motion, seed, build, a.frames)
        R = sequence(d, a.truth_lengths, a.recover)
        m = R.mean(axis=0)
        means.append(m)
        lines.append(f"| {motion} | {seed} | {build} | {100 * m[0]:.1f} / {100 * m[1]:.1f} | "
                     f"{100 * m[2]:.1f} / {100 * m[3]:.1f} | {m[4]:.3f} / {m[5]:.3f} | "
                     f"{int((R[:, 5] > R[:, 4]).sum())} / {len(R)} |")
        print(lines[-1], flush=True)
    m = np.mean(means, axis=0)
    lines += ["", f"Mean over the motions: track {100 * m[0]:.2f} cm, from the truth "
                  f"{100 * m[1]:.2f} cm (arms {100 * m[2]:.1f} / {100 * m[3]:.1f})"]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "tracker_bounds_dev" + ("_truth_lengths" if a.truth_lengths else "") + ".md"
    (out / name).write_text("\n".join(lines) + "\n")
    print(lines[-1])


if __name__ == "__main__":
    main()
