"""Precision of ``matched`` as a run decides it, with the gate's foot rule and without it.

    python benchmarks/confidence.py --foot-rule [--work DIR] [--frames N] [--sides-work DIR]
                                    [--pose2sim RECORDING] [--child CHILD_ROPE] [--sheets DIR]
                                    [--child-by-eye JSON] [--child-tracker] [--out DIR] [--quick]

The ``--foot-rule`` mode of ``benchmarks/confidence.py``: with it, the options are these.

``matched`` is decided by the gate (:class:`topopose.frame.confidence.GateOptions`) and then, in
a sequence, by the run's consistency, which matches a frame the gate alone rejected when its
neighbours agree (:func:`topopose.sequence.consistency.judge_sequence`). The gate's foot rule
(``max_foot_rise``, :func:`topopose.frame.confidence.foot_rise`) rejects a frame whose foot lies
too high for its leg, and the consistency leaves that rejection alone. The peer is the gate
without the rule (``GateOptions(max_foot_rise=None)``), in the same run: every frame is
estimated once with the default gate, and the peer's decision is the same frame's with the
rule's clause taken off (:func:`without_rule`: the rule only ever adds its clause after the
others' decision). Both are then put through the sequence stages as ``topopose run`` runs them
(:func:`topopose.sequence.motion.process_sequence`; the tracker after it only turns matched
frames into tracked ones).

Sources:

- **synthetic sequences** (the MakeHuman ``body``, 100³, noise 1, 640×480): the continuous
  motions whose limbs touch the body (``hang``, ``hips``, ``fold``, ``jump`` with the feet
  together, ``crouch``; :data:`topopose.synth.body.TOUCHING`) and ``random-smooth``, per build
  and camera count. :data:`DEV` chose ``max_foot_rise`` (the lowest tenth above every right
  frame the alignment placed there, :func:`choose_rise`); :data:`HELD` (other builds and seeds)
  checks it. A matched frame is right when it is a true positive of
  :mod:`topopose.batch.quality` (every placed part within 0.1 × height, at most one unplaced).
- **unrelated poses** (``--sides-work DIR``: the per-frame poses ``benchmarks/sides.py``
  kept, with the default gate, ``poses_simple.jsonl``): its development and held-out
  generators (9 pose families, 5 builds, 4 and 8 cameras), per frame (no sequence); the rule
  applied to the stored frames as the gate applies it (their curves and up).
- **Pose2Sim** (``--pose2sim``, default ``benchmarks/data/pose2sim_balancing``; ``person``
  silhouettes, MediaPipe needed): right against Pose2Sim's 3D markers (``real.RIGHT``).
- **child_rope** (``--child PATH``, by path only — no licence): its 410 frames as
  ``benchmarks/_tracker.py`` sets the capture up (links, nothing copied); no 3D reference, so
  the matched frames of each gate are drawn on a contact sheet (``gate_child_<gate>.png`` in
  ``--sheets``, never in the repository) and judged by eye (``--child-by-eye`` writes the
  verdicts into the report).

Writes ``gate.md`` / ``gate.json.gz`` in ``--out`` (default ``benchmarks/results``).
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import gzip  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _machine import machine, results_dir  # noqa: E402

MOTIONS = ("hang", "hips", "fold", "jump", "crouch", "random-smooth")
# (build, motion, cameras); seeds 500 + i (development), 700 + i (held out)
DEV = ([(b, m, 8) for b in ("average", "child") for m in MOTIONS]
       + [("heavy", m, 4) for m in ("hang", "jump", "crouch")])
HELD = ([(b, m, 8) for b in ("lean", "random") for m in MOTIONS]
        + [("child", m, 4) for m in ("hang", "jump", "crouch")])
GATES = ("rule", "peer")        # the default gate; the same without its foot rule
ANATOMY = "anatomy: "            # the foot rule's clause (frame.confidence.gate_decision)


def without_rule(p):
    """The pose as the gate without the foot rule decided it: the rule's clause taken off (a
    frame only the rule rejected is matched)."""
    e = p.error or ""
    if p.status != "rejected" or ANATOMY not in e:
        return p
    if e.startswith(ANATOMY):
        return dataclasses.replace(p, status="matched", error=None)
    return dataclasses.replace(p, error=e.split("; " + ANATOMY)[0])


def estimate(cap, out):
    """Per-frame poses of ``cap`` with the default gate (as ``topopose run``: 100³), written to
    ``out`` once and read back after."""
    from topopose.frame.estimate import FrameEstimator
    from topopose.pose.pose import read_poses, write_poses

    out = Path(out)
    if not out.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est = FrameEstimator(cap, "human", 100, support=True)
            write_poses(out, [est.estimate(f) for f in cap.frames])
    return sorted(read_poses(out), key=lambda p: p.frame)


def as_run(poses, up, fps):
    """``poses`` after the run's sequence stages (consistency and all)."""
    from topopose.pose.model import load_model
    from topopose.sequence.motion import process_sequence

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return process_sequence([dataclasses.replace(p) for p in poses], load_model("human"),
                                up, fps=fps).poses


def counts(poses, right) -> dict:
    """Matched frames, the right ones among them, and the right frames (``right``: frame →
    bool, the per-frame pose right by ground truth)."""
    m = [p.frame for p in poses if p.matched]
    return {"matched": len(m), "right": int(sum(bool(right.get(f)) for f in m)),
            "right_frames": int(sum(bool(v) for v in right.values()))}


def synthetic(work, frames, quick=False):
    """Every generator of :data:`DEV` and :data:`HELD`: per gate, matched / right as run, and
    per frame the rule's feature and whether the frame is right (for :func:`choose_rise`)."""
    from topopose.batch.quality import TP_CLASSES, evaluate
    from topopose.capture import load_capture
    from topopose.pose.model import load_model
    from topopose.synth.capture import synthetic_capture, write_capture

    model = load_model("human")
    configs = [("dev", c, 500 + i) for i, c in enumerate(DEV)]
    configs += [("held", c, 700 + i) for i, c in enumerate(HELD)]
    if quick:
        configs = [configs[3], configs[len(DEV) + 3]]
    rows = []
    for split, (build, motion, cams), seed in configs:
        d = Path(work) / f"{build}_{motion}_{cams}c_{seed}"
        if not (d / "gt.json").exists():
            write_capture(synthetic_capture("body", frames=frames, seed=seed, cameras=cams,
                                            noise=1, build=build, motion=motion), d)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cap = load_capture(d)
        poses = estimate(cap, d / "poses.jsonl")
        ev = evaluate(cap.gt, poses, model=model)
        right = {f.frame: f.quality in TP_CLASSES for f in ev.frames}
        row = {"split": split, "build": build, "motion": motion, "cameras": cams, "seed": seed,
               "frames": len(poses), "rise": rises(poses, right, cap.up_vector)}
        for gate in GATES:
            raw = poses if gate == "rule" else [without_rule(p) for p in poses]
            row[gate] = {"per_frame": counts(raw, right),
                         "as_run": counts(as_run(raw, cap.up_vector, cap.fps), right)}
        rows.append(row)
        print(f"{split} {build} {motion} {cams}c: rule {row['rule']['as_run']} "
              f"peer {row['peer']['as_run']}", flush=True)
    return rows


def choose_rise(rows, step=0.1) -> float | None:
    """``max_foot_rise`` from the development rows (sequences, and the unrelated poses'
    ``"dev"`` rows): the lowest multiple of ``step`` above every right frame's
    :func:`topopose.frame.confidence.foot_rise`."""
    r = [x for row in rows if row["split"] == "dev" for _, ok, x in row["rise"]
         if ok and x is not None]
    return round((np.floor(max(r) / step) + 1) * step, 3) if r else None


def rises(poses, right, up) -> list:
    """Per frame with skeleton curves: [frame, right, foot rise]."""
    from topopose.frame.confidence import foot_rise

    return [[p.frame, bool(right[p.frame]), foot_rise(p.diagnostics["curves"], up)[1]]
            for p in poses if (p.diagnostics or {}).get("curves")]


def unrelated(sides_work):
    """``benchmarks/sides.py``'s stored per-frame poses (default gate without the rule): per
    split and camera count, matched / right per gate; with the rule, a stored matched frame
    whose :func:`topopose.frame.confidence.foot_rise` is above ``max_foot_rise`` is rejected,
    as the gate would (unrelated poses: no sequence stage). Returns (counts, rows of
    :func:`rises` per generator for :func:`choose_rise`)."""
    import glob

    from topopose.batch.quality import TP_CLASSES, evaluate
    from topopose.frame.confidence import GATE, foot_rise
    from topopose.pose.model import load_model
    from topopose.pose.pose import read_poses

    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    out, rows = {}, []
    for d in sorted(glob.glob(str(Path(sides_work) / "*_*c_*"))):
        f = Path(d) / "poses_simple.jsonl"
        if not f.exists():
            continue
        gt = json.loads((Path(d) / "gt.json").read_text())
        poses = list(read_poses(f))
        ev = evaluate(gt, poses, model=model)
        right = {q.frame: q.quality in TP_CLASSES for q in ev.frames}
        seed = int(Path(d).name.rsplit("_", 1)[1])
        key = f"{'dev' if seed < 300 else 'held'} {Path(d).name.split('_')[-2]}"
        rows.append({"split": key.split()[0], "rise": rises(poses, right, up)})

        def ruled(p):
            r = foot_rise((p.diagnostics or {}).get("curves"), up)[1]
            if p.matched and r is not None and r > GATE.max_foot_rise:
                return dataclasses.replace(p, status="rejected", error=ANATOMY + "foot rise")
            return p

        for gate, ps in (("rule", [ruled(p) for p in poses]), ("peer", poses)):
            o = out.setdefault(key, {}).setdefault(gate, {"matched": 0, "right": 0,
                                                          "right_frames": 0})
            for k, v in counts(ps, right).items():
                o[k] += v
    return out, rows


def pose2sim(work, recording):
    """The Pose2Sim balancing trial (``person`` silhouettes, as ``benchmarks/real_motion.py``):
    per gate, matched / right per frame and as run, right against Pose2Sim's markers."""
    import real
    import real_motion as rm

    got = rm.person_capture(recording, work)
    if "absent" in got:
        return got
    cap, ref, d = got["capture"], got["reference"], got["folder"]
    poses = estimate(cap, d / "poses.jsonl")
    right = {}
    for i, p in enumerate(poses):
        e = real.frame_errors(p.parts, ref, i) if p.status != "failed" else None
        right[p.frame] = e is not None and all(v <= real.RIGHT for v in e.values())
    out = {}
    for gate in GATES:
        raw = poses if gate == "rule" else [without_rule(p) for p in poses]
        out[gate] = {"per_frame": counts(raw, right),
                     "as_run": counts(as_run(raw, cap.up_vector, cap.fps), right)}
    return out


def followed(poses, cap):
    """``poses`` through the whole sequence stage of ``topopose run``: the sequence stages,
    then the subject's body followed through every frame
    (:func:`topopose.sequence.follow.follow_run`; ``matched`` / ``tracked`` / ``lost``)."""
    from topopose.pose.model import load_model
    from topopose.sequence.follow import follow_run
    from topopose.sequence.motion import process_sequence

    model = load_model("human")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        motion = process_sequence([dataclasses.replace(p) for p in poses], model,
                                  cap.up_vector, fps=cap.fps)
        return follow_run(motion.poses, motion, model, cap, 100, None)


def child(work, path, sheets, tracker=False):
    """The child recording's 410 frames, per gate: matched per frame and as run, the matched
    frames as run, and their contact sheet (``gate_child_<gate>.png`` in ``sheets``); with
    ``tracker``, also the statuses after the tracker (:func:`followed`), the matched frames
    and the fitted body's silhouette IoU (per frame and per camera, median and 10th
    percentile)."""
    import _real_child
    import _tracker

    from topopose.capture import load_capture
    from topopose.pose.pose import write_poses

    if not Path(path).exists():
        return {"absent": f"{path}: child_rope recording absent"}
    d = Path(work) / "child_rope"
    if not (d / "capture" / "calibration.toml").exists():
        _tracker.child_rope_capture(Path(path), d / "capture")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = load_capture(d / "capture")
    poses = estimate(cap, d / "poses.jsonl")
    out = {}
    for gate in GATES:
        raw = poses if gate == "rule" else [without_rule(p) for p in poses]
        final = as_run(raw, cap.up_vector, cap.fps)
        write_poses(d / f"as_run_{gate}.jsonl", final)
        sheet = Path(sheets) / f"gate_child_{gate}.png"
        n = _real_child.contact_sheet(d / "capture", d / f"as_run_{gate}.jsonl", sheet,
                                      cams=(0, 3, 6), height=200, columns=3)
        out[gate] = {"frames": len(raw), "failed": sum(p.status == "failed" for p in raw),
                     "matched_per_frame": sum(p.matched for p in raw),
                     "matched": [p.frame for p in final if p.matched],
                     "sheet": str(sheet) if n else None}
        if tracker:
            tr = followed(raw, cap)
            fit = [p.fit for p in tr if p.fit is not None]
            cams = [x for p in tr for x in (p.diagnostics.get("fit_cameras") or [])
                    if x is not None]
            q = lambda v, k: round(float(np.quantile(v, k)), 3) if v else None  # noqa: E731
            out[gate]["tracker"] = {
                "statuses": {s: sum(p.status == s for p in tr)
                             for s in ("matched", "tracked", "lost", "failed")},
                "matched": [p.frame for p in tr if p.status == "matched"],
                "fit": [q(fit, 0.5), q(fit, 0.1)], "fit_cameras": [q(cams, 0.5), q(cams, 0.1)]}
    return out


def pc(right, matched) -> str:
    return f"{right} / {matched} ({100 * right / matched:.1f} %)" if matched else "0 / 0"


def report(doc) -> str:
    m = doc["machine"]
    L = ["# `matched` with the gate's foot rule and without it", "",
         f"Machine: {m['cpu']}, {m['cores']} cores (shared), load {m['load_average']}, "
         f"{m['threads']}; {m['date']}. `python benchmarks/confidence.py --foot-rule "
         f"{' '.join(doc['argv'])}`.", "",
         "*rule*: the default gate (`GateOptions`, `max_foot_rise` = "
         f"{doc['max_foot_rise']}); *peer*: the same without the foot rule, same frames. Each "
         "cell: right / matched (precision); *of right*: the right matched frames over the "
         "frames whose per-frame pose is right (recall).", ""]
    syn = doc.get("synthetic") or []
    if syn:
        L += ["## Synthetic sequences (MakeHuman body, 100³, noise 1)", "",
              f"`max_foot_rise` chosen on the development rows (these and the unrelated poses'): "
              f"{doc['chosen_rise']} (the lowest tenth above every right frame's foot rise "
              "there).", "",
              "| split | build | motion | cameras | frames | rule as run | of right | "
              "peer as run | of right |", "|" + "---|" * 9]
        tot = {}
        for r in syn:
            a, b = r["rule"]["as_run"], r["peer"]["as_run"]
            L.append(f"| {r['split']} | {r['build']} | {r['motion']} | {r['cameras']} | "
                     f"{r['frames']} | {pc(a['right'], a['matched'])} | {a['right']} / "
                     f"{a['right_frames']} | {pc(b['right'], b['matched'])} | {b['right']} / "
                     f"{b['right_frames']} |")
            for g in GATES:
                t = tot.setdefault((r["split"], r["cameras"], g), {"matched": 0, "right": 0,
                                                                   "right_frames": 0})
                for k in t:
                    t[k] += r[g]["as_run"][k]
        L += ["", "| split | cameras | rule as run | of right | peer as run | of right |",
              "|" + "---|" * 6]
        for split, cams in sorted({(s, c) for s, c, _ in tot}):
            a, b = tot[(split, cams, "rule")], tot[(split, cams, "peer")]
            L.append(f"| {split} | {cams} | {pc(a['right'], a['matched'])} | {a['right']} / "
                     f"{a['right_frames']} | {pc(b['right'], b['matched'])} | {b['right']} / "
                     f"{b['right_frames']} |")
    un = doc.get("unrelated") or {}
    if un:
        L += ["", "## Unrelated poses per frame (`benchmarks/sides.py`'s stored frames)", "",
              "| split, cameras | rule | of right | peer | of right |", "|" + "---|" * 5]
        for k, v in sorted(un.items()):
            a, b = v["rule"], v["peer"]
            L.append(f"| {k} | {pc(a['right'], a['matched'])} | {a['right']} / "
                     f"{a['right_frames']} | {pc(b['right'], b['matched'])} | {b['right']} / "
                     f"{b['right_frames']} |")
    ps = doc.get("pose2sim") or {}
    L += ["", "## Pose2Sim balancing trial (4 phone cameras, person silhouettes)", ""]
    if "absent" in ps or not ps:
        L.append(f"Not measured: {ps.get('absent', 'not asked')}.")
    else:
        L += ["| gate | per frame | as run | of right (as run) |", "|---|---|---|---|"]
        for g in GATES:
            a, b = ps[g]["per_frame"], ps[g]["as_run"]
            L.append(f"| {g} | {pc(a['right'], a['matched'])} | {pc(b['right'], b['matched'])} "
                     f"| {b['right']} / {b['right_frames']} |")
    ch = doc.get("child") or {}
    L += ["", "## child_rope (10 studio cameras, real masks; by path only)", ""]
    if "absent" in ch or not ch:
        L.append(f"Not measured: {ch.get('absent', 'not asked (--child)')}.")
    else:
        L += ["No 3D reference: the matched frames as run, drawn on cameras 0, 3 and 6's masks, "
              "judged by eye.", "",
              "| gate | frames | failed | matched per frame | matched as run | judged by eye |",
              "|---|---|---|---|---|---|"]
        for g in GATES:
            c = ch[g]
            L.append(f"| {g} | {c['frames']} | {c['failed']} | {c['matched_per_frame']} | "
                     f"{len(c['matched'])}: {', '.join(str(int(f)) for f in c['matched'])} | "
                     f"{doc.get('child_by_eye', {}).get(g, 'see the sheet')} |")
        if all("tracker" in ch[g] for g in GATES):
            L += ["", "After the tracker (`topopose run`'s whole sequence stage): statuses, the "
                  "matched frames (an initialization of the tracker each), the fitted body's "
                  "silhouette IoU per frame and per camera (median / 10th percentile).", "",
                  "| gate | matched / tracked / lost | matched frames | IoU per frame | "
                  "IoU per camera |", "|---|---|---|---|---|"]
            for g in GATES:
                t = ch[g]["tracker"]
                st = t["statuses"]
                L.append(f"| {g} | {st['matched']} / {st['tracked']} / {st['lost']} | "
                         f"{', '.join(str(int(f)) for f in t['matched'])} | "
                         f"{t['fit'][0]} / {t['fit'][1]} | {t['fit_cameras'][0]} / "
                         f"{t['fit_cameras'][1]} |")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="confidence.py --foot-rule",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=None, help="where captures and per-frame poses are kept")
    ap.add_argument("--frames", type=int, default=40, help="frames per synthetic sequence")
    ap.add_argument("--sides-work", default="",
                    help="benchmarks/sides.py's --work folder (its stored per-frame poses)")
    ap.add_argument("--pose2sim", default=str(HERE / "data" / "pose2sim_balancing"),
                    help="the Pose2Sim balancing recording ('' to skip)")
    ap.add_argument("--child", default="", help="the child_rope recording (by path only)")
    ap.add_argument("--sheets", default=None,
                    help="where the child's contact sheets go (default: --work; never the "
                         "repository)")
    ap.add_argument("--child-by-eye", default="{}",
                    help='JSON {"rule": "...", "peer": "..."}: verdicts on the sheets')
    ap.add_argument("--child-tracker", action="store_true",
                    help="also follow the child's body through every frame (the tracker "
                         "stage of topopose run; ~2 × 3 min)")
    ap.add_argument("--out", default=str(results_dir()))
    ap.add_argument("--quick", action="store_true", help="one development and one held-out "
                                                         "sequence")
    a = ap.parse_args(argv)
    from topopose.frame.confidence import GATE

    work = Path(a.work or tempfile.mkdtemp(prefix="topopose_gate_"))
    work.mkdir(parents=True, exist_ok=True)
    doc = {"argv": sys.argv[1:] if argv is None else list(argv),
           "max_foot_rise": GATE.max_foot_rise, "child_by_eye": json.loads(a.child_by_eye)}
    doc["synthetic"] = synthetic(work, a.frames, a.quick)
    doc["unrelated"], unrelated_rows = unrelated(a.sides_work) if a.sides_work else ({}, [])
    doc["chosen_rise"] = choose_rise(doc["synthetic"] + unrelated_rows)
    doc["pose2sim"] = pose2sim(work, a.pose2sim) if a.pose2sim else {}
    doc["child"] = (child(work, a.child, Path(a.sheets or work), a.child_tracker)
                    if a.child else {})
    doc["machine"] = machine()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "gate.md").write_text(report(doc))
    with gzip.open(out / "gate.json.gz", "wt") as f:
        json.dump(doc, f)
    print(report(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
