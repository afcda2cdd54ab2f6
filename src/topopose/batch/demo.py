"""``topopose demo``: synthesize a short capture of every built-in subject, run pose
initialization on it, score it against the ground truth (thesis §13.2.2) and draw pictures.

It is the README's first command, so it must work on a fresh machine in a couple of minutes
(Numba compilation and look-up table generation included) and say clearly what it did.
"""
from __future__ import annotations

import time
from pathlib import Path

from topopose.pose.model import BUILTIN, load_model

# the demo's captures: small images keep it quick; limbs separated as in the thesis' data sets
DEMO_SIZE = (480, 360)


# synthetic subjects without a model of their own (body: the MakeHuman mesh, a human)
_MODEL_OF = {"body": "human"}


def run_demo(out="topopose-demo", frames=6, resolution=100, seed=0, subjects=None,
             cameras=8, noise=0, size=DEMO_SIZE, progress=True, print_fn=print) -> int:
    """Run the demo; returns 0 (or 1 if some frame failed)."""
    from topopose.errors import InputError

    subjects = list(subjects or BUILTIN)
    for s in subjects:
        if s not in BUILTIN and s not in _MODEL_OF:
            raise InputError(f"--subjects: {s!r} is not a built-in subject "
                             f"({', '.join(BUILTIN + tuple(_MODEL_OF))})")
    from topopose.capture import load_capture
    from topopose.synth import synthesize
    from topopose.viz.figures import plot_distances, plot_quality
    from topopose.viz.view import render_frame
    from topopose.frame.estimate import FrameEstimator
    from topopose.batch.quality import evaluate
    from topopose.batch.run import run

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    from topopose.batch import warmup

    if warmup.start_warmup().proc is not None:   # first run: built while the capture is made
        print_fn("first run: compiling kernels and building the thinning look-up tables "
                 "(once; cached on disk)…")
    print_fn(f"topopose demo: {len(subjects)} synthetic subjects ({', '.join(subjects)}) × {frames} "
             f"frames, {cameras} cameras {size[0]}×{size[1]}, silhouette noise {noise}, grid "
             f"{resolution}³ → {out.resolve()}")
    rows, status = [], 0
    for subject in subjects:
        t0 = time.perf_counter()
        cap_dir = out / subject
        synthesize(cap_dir, subject=subject, frames=frames, seed=seed, cameras=cameras,
                   size=size, noise=noise, separated=True)
        t_synth = time.perf_counter() - t0
        cap = load_capture(cap_dir)
        model = load_model(_MODEL_OF.get(subject, subject))
        res = run(cap, model=model, resolution=resolution, output=cap_dir / "poses.jsonl",
                  trc=cap_dir / "poses.trc", csv=cap_dir / "poses.csv", progress=progress)
        status = max(status, res.exit_status)
        ev = evaluate(cap.gt, res.poses, model=model)
        plot_quality([(f"{subject} {resolution}³", ev)], cap_dir / "quality.png",
                     threshold=model.threshold)
        plot_distances(res.poses, cap_dir / "distances.png", evaluation=ev,
                       threshold=model.threshold, title=f"{subject}: AHA distance per frame")
        est = FrameEstimator(cap, model, resolution)
        pic = []
        for kind, pose in _pictured(res.poses, ev):          # a typical frame and the worst
            _, det = est.estimate(pose.frame, detail=True)
            pic.append(render_frame(cap_dir / f"frame_{pose.frame}_{kind}.png", model, pose, det,
                                    cap=cap, silhouettes=True, up=cap.up_vector,
                                    title=f"{subject} frame {pose.frame} ({kind}: {pose.status}"
                                          + (f", distance {pose.distance:.3f}"
                                             if pose.distance is not None else "") + ")"))
        first = res.poses[0].frame if res.poses else None       # includes Numba compilation
        comp = [p.timings_ms.get("total", 0) for p in res.poses
                if p.status != "failed" and (p.frame != first or len(res.poses) == 1)]
        ms = sorted(comp)[len(comp) // 2] if comp else float("nan")
        rows.append((subject, res, ev, ms, time.perf_counter() - t0, t_synth, pic))

    print_fn("")
    print_fn(f"{'subject':8} {'frames':>6} {'matched':>7} {'rejected':>8} {'failed':>6} "
             f"{'good':>5} {'miss1':>5} {'partial':>7} {'misplaced':>9} {'bad':>4} {'none':>4} "
             f"{'ms/frame':>8}")
    for subject, res, ev, ms, _, _, _ in rows:
        c = ev.counts
        print_fn(f"{subject:8} {len(res.poses):6d} {res.counts['matched']:7d} {res.counts['rejected']:8d} "
                 f"{res.counts['failed']:6d} {c['good']:5d} {c['missing limb']:5d} {c['partial']:7d} "
                 f"{c['misplaced']:9d} {c['bad']:4d} {c['none']:4d} {ms:8.1f}")
    print_fn("(classes of thesis §13.2.2 against gt.json: good, miss1 = one missing limb, partial, "
             "misplaced, bad, none; ms/frame: median after the first frame, one core)")
    print_fn("")
    for subject, res, ev, _, secs, _, pic in rows:
        d = out / subject
        print_fn(f"{subject}: capture {d}/  poses {d / 'poses.jsonl'}  exports poses.trc, poses.csv")
        print_fn(f"{' ' * len(subject)}  pictures {', '.join(x.name for x in pic)}, distances.png, "
                 f"quality.png  ({secs:.1f} s)")
    print_fn("")
    print_fn(f"done in {time.perf_counter() - t_start:.0f} s. Next: `topopose view {out / 'human'} "
             f"--poses {out / 'human' / 'poses.jsonl'} --frame 000000 --out frame.png`, or "
             f"`topopose run YOUR_CAPTURE --model human`.")
    return status


_ORDER = ("good", "missing limb", "partial", "misplaced", "bad", "none")


def _pictured(poses, ev):
    """The frames the demo draws: a typical one (the median distance among the frames of the
    most common quality class) and the worst one (worst class, then largest distance, failed
    frames first). One picture when they coincide."""
    if not poses:
        return []
    q = {f.frame: f.quality for f in ev.frames}
    rank = {c: i for i, c in enumerate(_ORDER)}

    def badness(p):
        return (p.status == "failed", rank.get(q.get(p.frame, "none"), len(_ORDER)),
                p.distance if p.distance is not None else float("inf"))

    worst = max(poses, key=badness)
    classes = [q.get(p.frame, "none") for p in poses if p.status != "failed"]
    common = max(set(classes), key=classes.count) if classes else None
    pool = sorted((p for p in poses if p.status != "failed" and q.get(p.frame, "none") == common),
                  key=lambda p: (p.distance is None, p.distance or 0.0)) or [worst]
    typical = pool[len(pool) // 2]
    return [("typical", typical)] + ([("worst", worst)] if worst.frame != typical.frame else [])
