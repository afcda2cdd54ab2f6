"""Development study: the skeleton's smoothing at another frame rate. The same
development motions (``benchmarks/tracking.py``'s walks 41–43 and random motion 51–53, 1.6 s
each) rendered at 25 frames/s (the rate every development figure was measured at) and at 60
frames/s (the real recording's), and 30 unrelated random poses (seeds 21–24, 8 cameras, 25
frames/s: no smoothing may touch them); the per-frame results cached, the sequence stage re-run
per smoothing window (:func:`topopose.sequence.kinematic_fit.fit_sequence`'s ``smooth``, frames).

    python studies/fps_dev.py [--work DIR] [--setups 8,4p] [--fps 25,60]
                                 [--windows 0,9,15,21,27] [--seconds 1.6] [--out DIR]
                                 [--name NAME] [--no-bridge] [--set NAME=VALUE ...]

Per set-up, rate and window: the full skeleton's MPJPE (cm; median over the pooled frames of
the per-frame mean over the issue's joints) on the matched frames (8 cameras: the gated run as
``tracking.py``) or, for 4 phones (threshold and gate off, as ``real_motion.py``), on the frames
whose per-frame pose is right (``evaluate``: good), bridged temporal outliers
(:func:`~topopose.sequence.kinematic_fit.bridge_outliers`) counted; ``--no-bridge``: its peer,
outliers kept as fitted; ``--set``: any other :mod:`~topopose.sequence.kinematic_fit` constant
(e.g. ``--set DESPIKE=None --set "FROM_START={}"``, the peer of the defaults). Never
the held-out seeds. Writes ``fps_dev.md`` / ``.json``
(``--name``).
"""
import argparse
import json
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import tracking as T  # noqa: E402
from _machine import machine, machine_line, results_dir, sequence_settings  # noqa: E402

SETTINGS = {}     # the sequence options of --set / --no-bridge, for every fit of the run

from topopose.capture import load_capture  # noqa: E402
from topopose.synth.capture import synthetic_capture, write_capture  # noqa: E402
from topopose.sequence import kinematic_fit as kf  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.batch.quality import evaluate  # noqa: E402
from topopose.sequence.track import track  # noqa: E402

SEQUENCES = [s for s in T.DEV_SEQUENCES if s[1] in (41, 42, 43, 51, 52, 53, 21, 22, 23, 24)]
MOTIONS = ("walk", T.SMOOTH, "random")


def sequence(work, motion, seed, build, setup, fps, seconds, model):
    """The capture and its per-frame poses (both cached in ``work``)."""
    d = Path(work) / f"{motion}_{seed}_{build}_{setup}_{fps}"
    if motion == "random":                      # unrelated poses: the length is no duration
        seconds = 30 / fps
    if not (d / "gt.json").exists():
        cams, size, noise, layout = T.SETUPS[setup]
        cap = synthetic_capture("body", frames=int(round(seconds * fps)), seed=seed,
                                cameras=cams, size=size, noise=noise, motion=motion,
                                build=build, layout=layout, fps=fps)
        write_capture(cap, d)
    cap = load_capture(d)
    f = d / "poses.pkl"
    if not f.exists():
        loose = {} if setup == "8" else {"threshold": 1e9, "gate": False}
        res = run(cap, model=model, resolution=100, progress=False, track=False, sides=False,
                  skeleton=False, **loose)
        f.write_bytes(pickle.dumps(res.poses))
    return cap, pickle.loads(f.read_bytes())


def measure(cap, poses, model, window, setup):
    """MPJPE (median over the frames counted, see the module docstring) with ``window``."""
    fitted, tree, _ = kf.fit_sequence(track(poses, model), model, **{**SETTINGS,
                                                                      "smooth": window})
    keep = None
    if setup != "8":
        keep = {fs.frame for fs in evaluate(cap.gt, poses, model=model).frames
                if fs.quality == "good"}
    errs, flagged = [], {True: [], False: []}
    for p in fitted:
        if not p.joints or p.diagnostics.get("interpolated") and not p.matched:
            continue
        P = np.array([p.joints[n] for n in tree.names])
        e = T.joint_errors(tree.names, P, cap.gt["frames"][p.frame]["joints"])
        if "neighbour_distance" in p.diagnostics:     # every fitted frame, right or not
            flagged[bool(p.diagnostics.get("temporal_outlier"))] += T.mpjpe([e])[3]
        if p.matched and (keep is None or p.frame in keep):
            errs.append(e)
    m = T.mpjpe(errs)
    return {"mpjpe": m[0], "frames": m[2], "per_frame": m[3], "outliers": flagged[True],
            "inliers": flagged[False],
            "smoothed": sum(bool(p.diagnostics.get("smoothed")) for p in fitted),
            "bridged": sum(bool(p.matched and p.diagnostics.get("interpolated")) for p in fitted)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default=None,
                    help="keep the captures and per-frame results here (default: a temp dir)")
    ap.add_argument("--setups", default="8,4p")
    ap.add_argument("--fps", default="25,60")
    ap.add_argument("--windows", default="0,9,15,21,27")
    ap.add_argument("--seconds", type=float, default=1.6)
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--name", default="fps_dev")
    ap.add_argument("--no-bridge", action="store_true",
                    help="temporal outliers kept as fitted (bridge=False): the "
                         "peer of the default")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE",
                    help="a sequence option (SequenceOptions field) for this run (a Python literal; "
                         "repeatable)")
    a = ap.parse_args(argv)
    settings = sequence_settings(a.set)
    if a.no_bridge:
        settings["bridge"] = False
    SETTINGS.update(settings)
    if a.work is None:
        import tempfile

        a.work = tempfile.mkdtemp(prefix="fps_dev_")
    model = load_model("human")
    setups, rates = a.setups.split(","), [int(x) for x in a.fps.split(",")]
    windows = [int(x) for x in a.windows.split(",")]
    rows = []
    for st in setups:
        for fps in rates:
            for motion, seed, build in SEQUENCES:
                if motion == "random" and (st != "8" or fps != rates[0]):
                    continue
                cap, poses = sequence(a.work, motion, seed, build, st, fps, a.seconds, model)
                for w in windows:
                    r = measure(cap, poses, model, w, st)
                    r.update(setup=st, fps=fps, motion=motion, seed=seed, window=w)
                    rows.append(r)
                    print(json.dumps({k: r[k] for k in ("setup", "fps", "motion", "seed",
                                                        "window", "frames", "mpjpe", "smoothed",
                                                        "bridged")}),
                          flush=True)
    info = machine(resolution=100, subject="body", seconds=a.seconds, settings=settings)
    lines = ["# The skeleton's smoothing window at 25 and 60 frames/s (development "
             "seeds)", "", machine_line(info), "",
             f"Walks 41–43 and random motion 51–53, {a.seconds} s each, rendered at each rate, "
             "and 30 unrelated random poses (seeds 21–24, 8 cameras, the first rate); MPJPE "
             f"(cm) median over the pooled frames (8 cameras: matched; 4p: good)"
             f"{'; temporal outliers not bridged (`--no-bridge`)' if a.no_bridge else ''}"
             f"{''.join(f'; `{k} = {v}`' for k, v in settings.items())}, per "
             "Savitzky–Golay window in frames (in brackets: its length in seconds, the frames "
             "counted, those smoothed and the temporal outliers bridged, "
             "`kinematic_fit.bridge_outliers`; 0: off).", "",
             "| set-up | frames/s | motion | " + " | ".join(str(w) for w in windows) + " |",
             "|---|---|---|" + "---|" * len(windows)]
    for st in setups:
        for fps in rates:
            for motion in MOTIONS + ("all",):
                cells = []
                for w in windows:
                    rs = [r for r in rows if r["setup"] == st and r["fps"] == fps
                          and r["window"] == w and (r["motion"] == motion or motion == "all"
                                                    and r["motion"] != "random")]
                    pf = [x for r in rs for x in r["per_frame"]]
                    cells.append(f"{100 * np.median(pf):.2f} ({w / fps:.2f} s, n {len(pf)}, "
                                 f"{sum(r['smoothed'] for r in rs)} smoothed, "
                                 f"{sum(r['bridged'] for r in rs)} bridged)" if pf else "–")
                if all(c == "–" for c in cells):
                    continue
                lines.append(f"| {st} | {fps} | {motion} | " + " | ".join(cells) + " |")
    lines += ["", "Temporal outliers (`diagnostics[\"temporal_outlier\"]`: a frame's joints 0.15 m "
              "or more from its neighbours' median, the default window's neighbourhood), every "
              "fitted frame not interpolated, right or not: frames flagged / judged, MPJPE (cm, "
              "median over frames) of the flagged and of the others.", "",
              "| set-up | frames/s | flagged | MPJPE flagged | MPJPE others |", "|---|---|---|---|---|"]
    for st in setups:
        for fps in rates:
            w = kf.smooth_window(fps)
            rs = [r for r in rows if r["setup"] == st and r["fps"] == fps and r["window"] == w
                  and r["motion"] != "random"]
            o = [x for r in rs for x in r["outliers"]]
            i = [x for r in rs for x in r["inliers"]]
            if rs:
                lines.append(f"| {st} | {fps} | {len(o)} / {len(o) + len(i)} | "
                             + (f"{100 * np.median(o):.1f}" if o else "–") + " | "
                             + (f"{100 * np.median(i):.1f}" if i else "–") + " |")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{a.name}.json").write_text(json.dumps(
        {"machine": info, "rows": [{k: v for k, v in r.items()
                                    if k not in ("per_frame", "outliers", "inliers")}
                                   for r in rows]}))
    text = "\n".join(lines) + "\n"
    (out / f"{a.name}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
