"""``matched`` by the run's own consistency: precision of ``matched`` and frames
passing, ours (``topopose run --consistency``, :mod:`topopose.sequence.consistency`) against the
run's confidence gate, on synthetic sequences and the real recording.

    python benchmarks/consistency.py [--setups 8,4,4p] [--dev-seeds 41,...] [--test-seeds 1,...]
                                     [--frames 40] [--work DIR] [--real-json FILE] [--out PATH]

Sequences: the anatomically real ``body`` subject walking (``motion="walk"``, builds by seed as
``benchmarks/confidence.py``), 40 frames at 25 frames/s, 100³, in the camera set-ups of
``benchmarks/confidence.py``: ``8`` (8 cameras 640×480, silhouette noise 1), ``4`` (4 cameras
640×480, noise 1), ``4p`` (4 portrait phone-like cameras 544×960, noise 2). Each sequence is
run as ``topopose run`` does (:func:`topopose.batch.run.run`, the default gate: on with fewer
than 6 cameras), then its sequence stages (:func:`topopose.sequence.motion.process_sequence`: track,
skeleton, sides) with ``matched`` decided either way.

A frame is *right* when it is a true positive (TP) of the quality classes as in ``benchmarks/confidence.py`` (quality
"good" or "missing limb": every placed part within 0.08 × height of its ground-truth segment,
at most one part unplaced), scored on the poses as the run writes them (numbered parts).

**Choice of the settings** (never on the real recording): every combination of
:data:`GRID` is scored on the development seeds; the one kept has precision ≥ 0.95 in every
4-camera set-up and the most right frames passing in the worst of them. The held-out seeds
and the real recording (``benchmarks/real.py``, read from ``--real-json`` when given: the
column *matched (consistency)*) then measure it. A run of unrelated random poses (8 cameras,
``motion="random"``) checks that such runs are left as they are (no coherent sequence).
"""
from __future__ import annotations

import argparse
import copy
import itertools
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

#: camera set-ups: cameras, image size, silhouette noise (as benchmarks/confidence.py SETUPS)
SETUPS = {"8": (8, (640, 480), 1), "4": (4, (640, 480), 1), "4p": (4, (544, 960), 2)}
BUILDS = ("average", "heavy", "child", "lean", "random")
DEV_SEEDS = tuple(range(41, 59))
TEST_SEEDS = (1, 2, 3, 4)
TOLERANCE = 0.08          # × subject height (benchmarks/confidence.py)
TP_CLASSES = ("good", "missing limb")
#: settings tried on the development seeds (judge_sequence keyword arguments)
#: (``max_length_ratio`` 1.5 only removed right frames on the first development seeds: not tried)
GRID = {"max_deviation": (0.04, 0.05, 0.06, 0.08, 0.1),
        "neighbours": (1, 2, 3),
        "min_rank": (0.0, 0.25, 0.5),
        "max_length_ratio": (None,),
        "max_unexplained": (None, 0.06, 0.07, 0.08, 0.09, 0.1, 0.12)}
#: the rule without the silhouette support: the peer
BEFORE = {"max_deviation": 0.05, "neighbours": 2, "min_rank": 0.5, "max_length_ratio": None,
          "max_unexplained": None}


def sequence(setup, seed, frames, work=None, motion="walk", make=None):
    """Per-frame poses of one synthetic sequence as ``topopose run`` computes them (default
    gate, sequence stages off, the silhouette support recorded: ``run(support=True)``) and its
    ground truth; cached in ``work`` when given. ``make``: a function returning the capture
    (another set-up than :data:`SETUPS`)."""
    from topopose.synth.capture import synthetic_capture
    from topopose.batch import run
    from topopose.pose.pose import read_poses, write_poses

    if work is not None:
        f = Path(work) / f"{motion}_{setup}_{seed}_support.jsonl"
        g = f.with_suffix(".gt.json")
        if f.exists() and g.exists():
            return read_poses(f), json.loads(g.read_text())
    if make is not None:
        cap = make()
    else:
        cams, size, noise = SETUPS[setup]
        cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, size=size,
                                noise=noise, motion=motion, build=BUILDS[seed % len(BUILDS)])
    res = run(cap, model="human", resolution=100, progress=False, track=False, sides=False,
              skeleton=False, support=True)
    if work is not None:
        Path(work).mkdir(parents=True, exist_ok=True)
        write_poses(f, res.poses, {})
        g.write_text(json.dumps(cap.gt))
    return res.poses, cap.gt


def right_frames(poses, gt, model) -> list:
    """Per pose (numbered parts), whether it is a true positive (TP) of the quality classes (module docstring)."""
    from topopose.sequence.chirality import numbered
    from topopose.batch.quality import evaluate

    ps = [numbered(p, model) for p in poses]
    ev = evaluate(gt, ps, model=model, tolerance=TOLERANCE * float(gt["height"]),
                  junction_factor=1.0)
    q = {fs.frame: fs.quality for fs in ev.frames}
    return [q.get(p.frame) in TP_CLASSES for p in ps]


def as_run(poses, model, up, trim=None):
    """The sequence stages of ``topopose run`` (track, the hands' trim, skeleton, sides),
    consistency off (the confidence gate's ``matched``: ``run --no-consistency``);
    ``trim=False``: without the trim."""
    from topopose.sequence.motion import process_sequence

    return process_sequence(copy.deepcopy(poses), model, up, trim=trim,
                            consistency=False).poses


def judged(poses, model, settings):
    """``poses`` (as the run writes them) with ``matched`` decided by the run's consistency
    (as ``process_sequence(consistency=settings)`` does last); (poses, coherent)."""
    from topopose.sequence.consistency import judge_sequence, mirror_groups
    from topopose.sequence.track import frame_index

    # judge_sequence sets status, error and diagnostics["consistency"]: those are copied
    ps = [replace(p, diagnostics=dict(p.diagnostics)) for p in poses]
    ok = judge_sequence(ps, model, frame_index(ps), groups=mirror_groups(model), **settings)
    return ps, ok


def score(poses, right) -> dict:
    m = [p.status == "matched" for p in poses]
    n, rt = sum(m), sum(a and b for a, b in zip(m, right))
    return {"matched": n, "right_matched": rt, "precision": round(rt / n, 3) if n else None}


def collect(setups, seeds, frames, work, model, up):
    """Per set-up, per seed: (as-run poses, right flags); ``collect.timings``: per set-up,
    the per-frame timings (ms) of the silhouette support and of the whole frame (each
    sequence's first frame left out: compilation)."""
    out = {}
    collect.timings = {}
    for setup in setups:
        for seed in seeds:
            t0 = time.perf_counter()
            poses, gt = sequence(setup, seed, frames, work)
            t = collect.timings.setdefault(setup, {"support": [], "total": []})
            for p in poses[1:]:
                if "support" in p.timings_ms:
                    t["support"].append(p.timings_ms["support"])
                    t["total"].append(p.timings_ms.get("total", np.nan))
            ps = as_run(poses, model, up)
            out[(setup, seed)] = (ps, right_frames(ps, gt, model))
            print(f"{setup} seed {seed}: {sum(out[(setup, seed)][1])} right of {len(ps)} "
                  f"({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)
    return out


def evaluate_settings(data, setups, model, settings, peer=False, union=None) -> dict:
    """Per set-up, pooled over its seeds: frames, right, the gate's, ours (the consistency
    instead of the gate, ``run --consistency``) and the union (the run's default: the gate's
    frames and the consistent ones it alone rejected; with ``peer`` also the rule before the
    silhouette support, :data:`BEFORE`; ``union``: the union whether or not ``peer``)."""
    union = peer if union is None else union
    out = {}
    keys = ("gate", "ours", "union", "before")
    for setup in setups:
        tot = {"frames": 0, "right": 0, **{k: [0, 0] for k in keys}}
        for (s, _), (ps, right) in data.items():
            if s != setup:
                continue
            tot["frames"] += len(ps)
            tot["right"] += sum(right)
            for key, qs in (("gate", ps), ("ours", judged(ps, model, settings)[0]),
                            ("union", judged(ps, model, {**settings, "union": True})[0]
                             if union else []),
                            ("before", judged(ps, model, BEFORE)[0] if peer else [])):
                sc = score(qs, right)
                tot[key][0] += sc["matched"]
                tot[key][1] += sc["right_matched"]
        for key in keys:
            n, rt = tot[key]
            tot[key] = {"matched": n, "right_matched": rt,
                        "precision": round(rt / n, 3) if n else None,
                        "share_of_right": round(rt / tot["right"], 3) if tot["right"] else None}
        out[setup] = tot
    return out


def choose(data, model) -> tuple:
    """The settings of :data:`GRID` kept on the development seeds (module docstring), for
    the consistency instead of the gate (``ours``) and in union with it (``union``), and the
    table of every combination."""
    four = [s for s in SETUPS if SETUPS[s][0] == 4 and any(k[0] == s for k in data)]
    table, best, best_key = [], {}, {}
    for values in itertools.product(*GRID.values()):
        settings = dict(zip(GRID, values))
        r = evaluate_settings(data, four, model, settings, union=True)
        table.append({"settings": settings, "per_setup": r})
        for mode in ("ours", "union"):
            ok = all(r[s][mode]["precision"] is not None and r[s][mode]["precision"] >= 0.95
                     for s in four)
            key = min(r[s][mode]["share_of_right"] or 0 for s in four)
            if ok and (best_key.get(mode) is None or key > best_key[mode]):
                best[mode], best_key[mode] = settings, key
    return best, table


def unrelated(model, up, frames, work) -> dict:
    """A run of unrelated random poses (8 cameras): whether it is judged coherent and how many
    statuses the consistency changes, instead of the gate or in union with it (must be
    none)."""
    poses, _ = sequence("8", 11, frames, work, motion="random")
    ps = as_run(poses, model, up)
    js, coherent = judged(ps, model, {})
    ju, _ = judged(ps, model, {"union": True})
    return {"frames": len(ps), "coherent": coherent,
            "changed": sum(a.status != b.status for a, b in zip(ps, js)),
            "changed_union": sum(a.status != b.status for a, b in zip(ps, ju))}


def main(argv=None):
    from _machine import machine, write_results
    from topopose.sequence import consistency as C
    from topopose.pose.model import load_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--setups", default=",".join(SETUPS))
    ap.add_argument("--dev-seeds", default=",".join(map(str, DEV_SEEDS)))
    ap.add_argument("--test-seeds", default=",".join(map(str, TEST_SEEDS)))
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--work", default=None, help="cache of the per-frame poses")
    ap.add_argument("--real-json", default=None,
                    help="results of benchmarks/real.py (its as_run_consistency figures)")
    ap.add_argument("--out", default=str(HERE / "results" / "consistency"))
    a = ap.parse_args(argv)
    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    setups = a.setups.split(",")
    dev = collect(setups, [int(x) for x in a.dev_seeds.split(",")], a.frames, a.work, model, up)
    support_ms = {k: {"frames": len(v["support"]),
                      "support_median": round(float(np.median(v["support"])), 2),
                      "support_p90": round(float(np.percentile(v["support"], 90)), 2),
                      "frame_median": round(float(np.nanmedian(v["total"])), 1)}
                  for k, v in collect.timings.items() if v["support"]}
    best, table = choose(dev, model)
    default = {"max_deviation": C.MAX_DEVIATION, "neighbours": C.NEIGHBOURS,
               "min_rank": C.MIN_RANK, "max_length_ratio": None,
               "max_unexplained": C.MAX_UNEXPLAINED}
    test = collect(setups, [int(x) for x in a.test_seeds.split(",") if x], a.frames, a.work,
                   model, up)          # --test-seeds "": the development seeds alone
    doc = {"machine": machine(), "setups": {k: list(map(str, v)) for k, v in SETUPS.items()},
           "frames": a.frames, "dev_seeds": a.dev_seeds, "test_seeds": a.test_seeds,
           "chosen": best, "default": default,
           "before": BEFORE,
           "dev": evaluate_settings(dev, setups, model, default, peer=True),
           "test": evaluate_settings(test, setups, model, default, peer=True) if test else {},
           "test_chosen": {m: evaluate_settings(test, setups, model, b, union=m == "union")
                           for m, b in best.items()} if test else None,
           "unrelated": unrelated(model, up, a.frames, a.work),
           "support_ms": support_ms,
           "grid": table}
    if a.real_json and Path(a.real_json).is_file():
        rj = json.loads(Path(a.real_json).read_text())
        def pick(r, key):
            return {k: r[key][k] for k in ("matched", "matched_precision")}

        doc["real"] = {m: {"frames": r["as_run"]["frames"], "right": r["as_run"]["right"],
                           "gate": pick(r, "as_run_gate" if "as_run_gate" in r else "as_run"),
                           "ours": pick(r, "as_run_consistency"),
                           **({"union": pick(r, "as_run")} if "as_run_gate" in r else {})}
                       for m, r in rj["methods"].items() if "as_run_consistency" in r}
    write_results(a.out, doc, report)
    return 0


def _pct(x):
    return "—" if x is None else f"{100 * x:.0f} %"


def report(doc) -> str:
    from _machine import machine_line

    m = doc["machine"]
    L = ["# `matched` by the run's own consistency", "",
         f"{machine_line(m)}. "
         "Written by `benchmarks/consistency.py` (see its docstring). Synthetic: body subject "
         f"walking, {doc['frames']} frames per sequence, 100³; set-ups "
         + "; ".join(f"{k}: {v[0]} cameras {v[1]} noise {v[2]}" for k, v in doc["setups"].items())
         + ". Right: TP of the quality classes (0.08 × height), on the poses as `run` writes them (the "
         "hands' trim on). *Gate*: `topopose run --no-consistency` (the "
         "confidence gate on with fewer than 6 cameras, T_d alone with 8); *ours*: "
         "`topopose run --consistency` (the consistency instead of the gate); *union*: "
         "`topopose run` by default (the gate's frames, unless a part was held at its tracked "
         "prediction, and the frames the gate alone rejected that are consistent); *before*: "
         "`--consistency` before the silhouette "
         f"support (`pose/support.py`), {doc['before']}. The real recording's figures: "
         "`results/real.md`.", "",
         "Settings the grid keeps on the development seeds "
         f"({doc['dev_seeds']}; precision ≥ 95 % in every 4-camera set-up, the most right "
         "frames passing in the worst): "
         + "; ".join(f"{m}: {b}" for m, b in doc["chosen"].items())
         + f". The module's defaults (both modes): {doc['default']}.", ""]
    for name, key in (("Held-out seeds " + doc["test_seeds"], "test"),
                      ("Development seeds " + doc["dev_seeds"], "dev")):
        if not doc[key]:
            continue
        rows = []
        for setup, r in doc[key].items():
            rows.append([setup, r["frames"], f"{r['right']} ({_pct(r['right'] / r['frames'])})",
                         *(x for k in ("gate", "before", "ours", "union")
                           for x in (r[k]["matched"], _pct(r[k]["precision"]),
                                     _pct(r[k]["share_of_right"])))])
        L += [f"## {name} (the module's defaults)", ""]
        L += _table(["set-up", "frames", "right",
                     *(x for k in ("gate", "before", "ours", "union (default)")
                       for x in (f"matched ({k})", f"precision ({k})",
                                 f"right frames passing ({k})"))], rows)
        L.append("")
    if doc.get("real"):
        L += ["## The real recording (`benchmarks/real.py`, Pose2Sim's balancing trial, "
              "4 phone cameras; as `run` writes it)", ""]
        keys = [k for k in ("gate", "ours", "union") if all(k in r for r in doc["real"].values())]
        L += _table(["silhouettes", "frames", "right",
                     *(x for k in keys for x in (f"matched ({k})", f"precision ({k})"))],
                    [[k, r["frames"], r["right"],
                      *(x for c in keys for x in (r[c]["matched"],
                                                  _pct(r[c]["matched_precision"])))]
                     for k, r in doc["real"].items()])
        L.append("")
    if doc.get("support_ms"):
        L += ["The silhouette support's cost (`pose/support.py`, recorded by default since the "
              "run's default reads it; timed in the development runs, each sequence's first "
              "frame left out, on a shared machine): "
              + "; ".join(f"{k}: {v['support_median']} ms a frame (p90 {v['support_p90']}) of "
                          f"{v['frame_median']} ms" for k, v in doc["support_ms"].items())
              + ".", ""]
    u = doc["unrelated"]
    L += [f"Unrelated random poses (8 cameras, {u['frames']} frames): coherent sequence "
          f"{u['coherent']}, statuses changed by `--consistency`: {u['changed']}, by the union "
          f"(the default): {u.get('changed_union', '—')}.", "",
          "## Every setting on the development seeds (4-camera set-ups pooled per set-up)", ""]
    rows = []
    for t in doc["grid"]:
        s = t["settings"]
        rows.append([s["max_deviation"], s["neighbours"], s["min_rank"], s["max_unexplained"],
                     *(f"{v[m]['right_matched']}/{v[m]['matched']}"
                       for m in ("ours", "union") for v in t["per_setup"].values())])
    setups = list(doc["grid"][0]["per_setup"]) if doc["grid"] else []
    L += _table(["max deviation (× height)", "neighbours", "min rank", "max unexplained",
                 *(f"{s}: right/matched ({m})" for m in ("ours", "union") for s in setups)],
                rows)
    return "\n".join(L) + "\n"


def _table(head, rows):
    return ["| " + " | ".join(map(str, head)) + " |", "|" + " --- |" * len(head)] + \
           ["| " + " | ".join(map(str, r)) + " |" for r in rows]


if __name__ == "__main__":
    sys.exit(main())
