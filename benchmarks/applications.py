"""The thesis' applications (§13.3): hull segmentation, pose detection, pose clustering.

1. Segmentation by flooding (§13.3.1.1): synthetic humans — the anatomically real ``body``
   (MakeHuman mesh) and the capsule ``human`` — (random poses, limbs kept 3 voxels apart at
   100³ — 7.5 cm —, silhouette noise 1), pipeline at 100³; voxel accuracy of the label volume
   against ground truth (body: each hull voxel's nearest mesh vertex's dominant skinning bone;
   human: the nearest primitive's link; grouped into the model's arcs; numbered limbs paired
   optimally) on the frames the quality study calls *good*,
   for the plain flooding (the thesis') and the part-weighted one (default); time of the
   flooding call alone and of the whole segment step, beside the peer
   ``skimage.segmentation.watershed`` (constant image, markers, mask: the same multi-source
   flooding) on the same inputs, and how often both agree.
2. Pose detection (§13.3.2.1): synthetic sequences whose poses are drawn to contain the named
   poses (hands up, one hand up, arms spread, inverted bodies) among random ones; each named
   pose evaluated on the pipeline's matched frames and on the gt.json parts of the same frames
   (the truth); precision and recall, with the class balance.
3. Pose clustering (§13.3.2.2): K known base poses (:data:`BASE_POSES`: standing, hands up, arms
   spread, kick, squat, star), frames = a base pose with joint angles jittered by ±5° at a random
   place and heading; (a) the pipeline's matched frames, (b) the gt parts jittered
   by 2 cm; adjusted Rand index against the base-pose labels and the number of clusters found by
   the largest-gap rule and by the silhouette rule.

Writes benchmarks/results/applications.{md,json} and applications_*.png.
Usage: python benchmarks/applications.py [--quick]
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _machine import machine  # noqa: E402

RES = 100
MARGIN = 0.075            # 3 voxels of the human grid at 100³ (benchmarks/quality.py)


# ----------------------------------------------------------------------------- pose samplers
def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _raise(p, s, rng):
    p.update({f"sh_flex_{s}": _u(rng, 155, 180), f"sh_abd_{s}": _u(rng, 0, 25),
              f"elbow_{s}": _u(rng, 0, 30)})


def _lower(p, s, rng):
    p.update({f"sh_flex_{s}": _u(rng, -30, 60), f"sh_abd_{s}": _u(rng, 0, 50),
              f"elbow_{s}": _u(rng, 0, 60)})


def detection_sampler(kind):
    """A human pose sampler mixing named poses with random ones (tagged ``_k``)."""
    from topopose.capture.synth_subjects import human_random

    def sample(rng):
        p = human_random(rng)
        r = rng.random()
        if kind == "acrobatic":
            if r < 0.5:
                p.update(pelvis_pitch=_u(rng, 160, 200), pelvis_roll=_u(rng, -15, 15))
                p["_k"] = "inverted"
            else:
                p["_k"] = "random"
            return p
        if r < 0.25:
            _raise(p, "l", rng)
            _raise(p, "r", rng)
            p["_k"] = "hands-up"
        elif r < 0.45:
            s, o = ("l", "r") if rng.random() < 0.5 else ("r", "l")
            _raise(p, s, rng)
            _lower(p, o, rng)
            p["_k"] = "one-hand-up"
        elif r < 0.65:
            for s in "lr":
                p.update({f"sh_flex_{s}": _u(rng, -10, 10), f"sh_abd_{s}": _u(rng, 80, 100),
                          f"elbow_{s}": _u(rng, 0, 15), f"sh_rot_{s}": _u(rng, -20, 20)})
            p["_k"] = "spread"
        else:
            p["_k"] = "random"
        return p
    return sample


#: K known poses (joint angles, degrees; the rest 0): distinct configurations of the limbs
BASE_POSES = [
    {"sh_abd_l": 35, "sh_abd_r": 35, "elbow_l": 10, "elbow_r": 10},                  # standing
    {"sh_flex_l": 170, "sh_flex_r": 170, "sh_abd_l": 10, "sh_abd_r": 10},           # hands up
    {"sh_abd_l": 90, "sh_abd_r": 90},                                               # arms spread
    {"sh_flex_l": 90, "sh_abd_r": 35, "hip_flex_r": 90, "knee_r": 10},              # kick, arm forward
    {"spine_flex": 20, "sh_flex_l": 80, "sh_flex_r": 80, "hip_flex_l": 70, "hip_flex_r": 70,
     "knee_l": 100, "knee_r": 100, "sh_abd_l": 30, "sh_abd_r": 30},                 # squat, arms forward
    {"sh_flex_l": 150, "sh_abd_l": 40, "sh_abd_r": 60, "hip_abd_l": 35, "hip_abd_r": 35},  # star
]
for _b in BASE_POSES:                   # legs apart: limbs 3 voxels apart in the hull
    _b.setdefault("hip_abd_l", 14)
    _b.setdefault("hip_abd_r", 14)


def cluster_sampler(K, jitter=5.0):
    """Frames from the first K :data:`BASE_POSES`: every angle jittered by ±``jitter``°."""
    from topopose.capture.synth_subjects import HUMAN_DEFAULT

    base = [{**HUMAN_DEFAULT, **b} for b in BASE_POSES[:K]]

    def sample(rng):
        k = int(rng.integers(K))
        p = {a: v + _u(rng, -jitter, jitter) for a, v in base[k].items()}
        p["_k"] = k
        return p
    return sample


@contextlib.contextmanager
def human_poses(sample):
    """Let ``synthetic_capture(subject="human")`` draw its random poses from ``sample`` and
    remember each body's tag (``body.extra["k"]``)."""
    from topopose.capture import synth_subjects as SS

    old_r, old_b = SS.RANDOM["human"], SS.BUILD["human"]

    def build(pose, thickness=1.0):
        body = old_b(pose, thickness)
        body.extra["k"] = pose.get("_k")
        return body

    SS.RANDOM["human"], SS.BUILD["human"] = sample, build
    try:
        yield
    finally:
        SS.RANDOM["human"], SS.BUILD["human"] = old_r, old_b


def capture(sample, frames, seed, noise=1):
    from topopose.capture.synth import synthetic_capture

    with human_poses(sample):
        return synthetic_capture("human", frames=frames, seed=seed, noise=noise, separated=True,
                                 margin=MARGIN)


# ----------------------------------------------------------------------------- 1. segmentation
def bench_segmentation(n_frames, seeds, log, subject="human"):
    from skimage.segmentation import watershed

    from topopose.capture.synth_subjects import human_random
    from topopose.pose.estimate import FrameEstimator
    from topopose.pose.quality import evaluate
    from topopose.pose.segment import (_box, arc_names, flood_labels, renumbered_accuracy,
                                       segment, skeleton_labels, synthetic_truth)

    rows = []
    for seed in seeds:
        if subject == "body":
            from topopose.capture.synth import synthetic_capture

            cap = synthetic_capture("body", frames=n_frames, seed=seed, noise=1, separated=True,
                                    margin=MARGIN)
        else:
            cap = capture(lambda rng: human_random(rng), n_frames, seed)
        est = FrameEstimator(cap, "human", RES)
        names = arc_names(est.model)
        dets, poses = [], []
        for f in cap.frames:
            pose, det = est.estimate(f, detail=True)
            poses.append(pose)
            dets.append(det)
        ev = evaluate(cap.gt, poses, est.model)
        quality = {fs.frame: fs.quality for fs in ev.frames}
        for fi, (pose, det) in enumerate(zip(poses, dets)):
            if pose.status != "matched":
                continue
            vol = det.volume
            truth = synthetic_truth(vol, cap.options["bodies"][fi], names)
            row = {"subject": subject, "seed": seed, "frame": pose.frame,
                   "quality": quality.get(pose.frame),
                   "hull_voxels": int(vol.data.sum())}
            seeds_grid, _ = skeleton_labels(det.skeleton, det.alignment, det.data, names)
            bbox = vol.diagnostics.get("bbox")
            for w in ("none", "part"):
                lab, _ = segment(vol, det.skeleton, det.alignment, det.data, names=names, weighting=w)
                row[f"acc_{w}"] = renumbered_accuracy(lab, truth, names)
            # timings: best of 5 (shared machine)
            t_seg, t_flood, t_ws = [], [], []
            for _ in range(5):
                t0 = time.perf_counter()
                segment(vol, det.skeleton, det.alignment, det.data, names=names)
                t_seg.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                plain = flood_labels(vol.data, seeds_grid, 26, "none", bbox=bbox)
                t_flood.append(time.perf_counter() - t0)
                box = _box(vol.data, bbox)
                t0 = time.perf_counter()
                m = vol.data[box]
                ws = watershed(np.zeros(m.shape, np.uint8), markers=seeds_grid[box], mask=m,
                               connectivity=3)
                t_ws.append(time.perf_counter() - t0)
            row.update(segment_ms=min(t_seg) * 1e3, flood_ms=min(t_flood) * 1e3,
                       watershed_ms=min(t_ws) * 1e3,
                       agree_watershed=float(np.mean(ws[m] == plain[box][m])))
            rows.append(row)
        log(f"segmentation {subject} seed {seed}: {sum(r['seed'] == seed for r in rows)} matched frames")
    return rows


# ----------------------------------------------------------------------------- 2. detection
STABLE_SIGMA = 0.03        # m
STABLE_TRIALS = 20


def stable_truth(expr, parts, up, aliases, value, rng):
    """Whether the truth keeps its value when every gt part moves by N(0, 3 cm) (20 draws):
    a frame near a decision boundary (a hand at head height) is not *stable* — a few cm of
    difference between the pipeline's part and gt.json's flips it."""
    from topopose.pose.detect import evaluate

    for _ in range(STABLE_TRIALS):
        q = {k: None if v is None else np.asarray(v) + rng.normal(0, STABLE_SIGMA, 3)
             for k, v in parts.items()}
        if evaluate(expr, q, up, aliases) != value:
            return False
    return True


def bench_detection(n_frames, seeds, log):
    from topopose.pose.detect import detect, evaluate, load_library
    from topopose.pose.estimate import FrameEstimator

    library, aliases = load_library()
    out = {}
    for kind, constraints in (("upright", True), ("acrobatic", False)):
        per = {n: {"tp": 0, "fp": 0, "fn": 0, "tn": 0, "undecided": 0, "truth_true": 0,
                   "stable": {"tp": 0, "fp": 0, "fn": 0, "tn": 0}}
               for n in library}
        tags, frames, matched = {}, 0, 0
        rng = np.random.default_rng(0)
        examples = []
        for seed in seeds:
            cap = capture(detection_sampler(kind), n_frames, seed)
            est = FrameEstimator(cap, "human", RES, constraints=constraints)
            poses = [est.estimate(f) for f in cap.frames]
            frames += len(poses)
            for fi, p in enumerate(poses):
                tag = cap.options["bodies"][fi].extra.get("k")
                tags[tag] = tags.get(tag, 0) + 1
                if p.status != "matched":
                    continue
                matched += 1
                gt = cap.gt["frames"][p.frame]["parts"]
                for n, np_ in library.items():
                    v = detect([p], np_.expr, up=cap.up, aliases=aliases)[0]["value"]
                    t = evaluate(np_.expr, gt, cap.up, aliases)
                    c = per[n]
                    c["truth_true"] += bool(t)
                    if v is None:
                        c["undecided"] += 1
                        continue
                    key = ("tp" if t else "fp") if v else ("fn" if t else "tn")
                    c[key] += 1
                    if stable_truth(np_.expr, gt, cap.up, aliases, t, rng):
                        c["stable"][key] += 1
                    if v != t and len(examples) < 12:
                        examples.append({"kind": kind, "seed": seed, "frame": p.frame, "pose": n,
                                         "detected": v, "truth": t, "tag": tag})
        for c in per.values():
            for d in (c, c["stable"]):
                d["precision"] = d["tp"] / (d["tp"] + d["fp"]) if d["tp"] + d["fp"] else None
                d["recall"] = d["tp"] / (d["tp"] + d["fn"]) if d["tp"] + d["fn"] else None
        out[kind] = {"frames": frames, "matched": matched, "constraints": constraints,
                     "tags": tags, "poses": per, "disagreements": examples}
        log(f"detection {kind}: {matched}/{frames} matched")
    return out


# ----------------------------------------------------------------------------- 3. clustering
def bench_clustering(K, n_frames, seeds, log, figure=None):
    from topopose.pose.cluster import adjusted_rand_index, cluster_figure, cluster_poses
    from topopose.pose.estimate import FrameEstimator
    from topopose.pose.pose import Pose

    rows = []
    for seed in seeds:
        cap = capture(cluster_sampler(K), n_frames, seed)
        truth = [b.extra["k"] for b in cap.options["bodies"]]
        est = FrameEstimator(cap, "human", RES)
        poses = [est.estimate(f) for f in cap.frames]
        m = [i for i, p in enumerate(poses) if p.status == "matched"]
        rng = np.random.default_rng(seed)
        gt_poses = [Pose(f, "matched", 0.0, {k: np.asarray(v) + rng.normal(0, 0.02, 3)
                                             for k, v in cap.gt["frames"][f]["parts"].items()})
                    for f in cap.frames]
        for source, ps, idx in (("pipeline", poses, m), ("gt+2cm", gt_poses, list(range(len(poses))))):
            for auto in ("gap", "silhouette"):
                t0 = time.perf_counter()
                res = cluster_poses(ps, auto=auto)
                ms = (time.perf_counter() - t0) * 1e3
                lab = [res.labels[i] for i in idx]
                rows.append({"seed": seed, "source": source, "auto": auto, "frames": len(idx),
                             "K_true": len({truth[i] for i in idx}), "K_found": res.k,
                             "ari": adjusted_rand_index(lab, [truth[i] for i in idx]),
                             "ms": ms})
                if figure and source == "pipeline" and auto == "silhouette" and seed == seeds[0]:
                    cluster_figure(ps, res, figure)
        log(f"clustering seed {seed}: {len(m)}/{len(poses)} matched")
    return rows


# ----------------------------------------------------------------------------- report
def _mean(x):
    x = [v for v in x if v is not None]
    return float(np.mean(x)) if x else float("nan")


def segmentation_figure(path):
    """One segmented frame of the body subject (the README picture)."""
    from topopose.capture.synth import synthetic_capture
    from topopose.pose.estimate import FrameEstimator
    from topopose.pose.segment import segmentation_figure as fig

    cap = synthetic_capture("body", frames=3, seed=5, noise=1, separated=True, margin=MARGIN)
    est = FrameEstimator(cap, "human", RES)
    for f in cap.frames:
        pose, det = est.estimate(f, detail=True)
        if pose.status == "matched":
            fig(path, cap, f, est.model, det, up=cap.up_vector)
            return


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    suffix = "_quick" if a.quick else ""
    log = lambda s: print(s, flush=True)  # noqa: E731
    t0 = time.time()
    # warm the kernels (compilation is not what is measured)
    bench_segmentation(2, [99], lambda s: None)
    if a.quick:
        seg = bench_segmentation(8, [2], log) + bench_segmentation(6, [2], log, "body")
        det = bench_detection(30, [1], log)
        clu = bench_clustering(4, 30, [1], log, out / f"applications_clusters{suffix}.png")
    else:
        # seed 1 chose the flooding's delay
        seg = bench_segmentation(25, [2, 3], log) + bench_segmentation(20, [2, 3], log, "body")
        det = bench_detection(100, [1, 2], log)
        clu = bench_clustering(5, 60, [1, 2, 3], log, out / f"applications_clusters{suffix}.png")
    segmentation_figure(out / f"applications_segmentation{suffix}.png")
    mach = machine(resolution=RES, wall_s=round(time.time() - t0, 1))
    (out / f"applications{suffix}.json").write_text(json.dumps(
        {"machine": mach, "segmentation": seg, "detection": det, "clustering": clu}, indent=1))


    L = [f"# Applications (thesis §13.3){' — quick run' if a.quick else ''}", "",
         f"Machine: {mach['cpu']}, {mach['cores']} cores, load {mach['load_average']}, "
         f"{mach['date']}; Python {mach['python']}, NumPy {mach['numpy']}, Numba {mach['numba']}. "
         f"Wall time {mach['wall_s']} s. Produced by `benchmarks/applications.py{' --quick' if a.quick else ''}`.",
         "", "## 1. Hull segmentation by flooding (§13.3.1.1)", "",
         f"Synthetic humans (random poses, limbs ≥ 7.5 cm apart, silhouette noise 1, 8 cameras), "
         f"pipeline at {RES}³ with the `human` model, on seeds the flooding's delay was not chosen "
         "on. `body`: the anatomically real MakeHuman mesh; truth: the dominant skinning bone of "
         "the nearest posed mesh vertex, grouped into the model's arcs "
         "(`topopose.pose.segment.body_bone_arc`). `human`: the capsule subject; truth: the "
         "nearest primitive's link. Numbered limbs paired optimally. *Good*: the quality "
         "study's class (every part right).", "",
         "| subject | frames | voxel accuracy, plain flooding (thesis) | voxel accuracy, part-weighted (default) |",
         "|---|---|---|---|"]
    for subject in ("body", "human"):
        sr = [r for r in seg if r["subject"] == subject]
        good = [r for r in sr if r["quality"] == "good"]
        for name, rs in (("good", good), ("all matched", sr)):
            if rs:
                L.append(f"| {subject} | {name} ({len(rs)}) | mean {_mean([r['acc_none'] for r in rs]):.3f}, "
                         f"min {min(r['acc_none'] for r in rs):.3f} | mean "
                         f"{_mean([r['acc_part'] for r in rs]):.3f}, min {min(r['acc_part'] for r in rs):.3f} |")
    if seg:
        L += ["", "Speed per frame (both subjects; median over frames of the best of 5 runs; hull "
              f"{int(np.median([r['hull_voxels'] for r in seg]))} voxels median):", "",
              "| step | ms |", "|---|---|",
              f"| whole segment step (`tp.segment`: skeleton labels + part-weighted flooding) | "
              f"{np.median([r['segment_ms'] for r in seg]):.2f} |",
              f"| flooding call alone (`flood_labels`, plain, 26-adjacency) | "
              f"{np.median([r['flood_ms'] for r in seg]):.2f} |",
              f"| peer: `skimage.segmentation.watershed` (constant image, markers, mask) | "
              f"{np.median([r['watershed_ms'] for r in seg]):.2f} |",
              f"| ratio peer / ours (flooding) | "
              f"{np.median([r['watershed_ms'] / r['flood_ms'] for r in seg]):.1f} |", "",
              f"Voxels on which the peer and our plain flooding agree: mean "
              f"{_mean([r['agree_watershed'] for r in seg]):.4f} (they differ only on ties).", ""]
    L += ["## 2. Specific pose detection (§13.3.2.1)", "",
          "Synthetic sequences drawn to contain the named poses (tags: the generator's intent); "
          "truth = the same description evaluated on gt.json parts; measured on the pipeline's "
          "matched frames whose value is decided (undecided: a part the description needs is "
          "missing, counted apart). *Stable* frames: the truth keeps its value when every gt part "
          "moves by N(0, 3 cm) (20 draws) — the others sit at a decision boundary (a hand at head "
          "height), where the few cm between a skeleton end and gt.json's part flip the value.", ""]
    for kind, d in det.items():
        L += [f"**{kind}** ({'model constraints on' if d['constraints'] else 'no coordinate constraints (--no-constraints)'}): "
              f"{d['matched']} matched of {d['frames']} frames; generator tags {d['tags']}.", "",
              "| pose | truth true / matched | TP | FP | FN | undecided | precision | recall | "
              "stable frames | precision (stable) | recall (stable) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
        f3 = lambda x: "–" if x is None else f"{x:.3f}"  # noqa: E731
        for n, c in d["poses"].items():
            st = c["stable"]
            L.append(f"| {n} | {c['truth_true']} / {d['matched']} | {c['tp']} | {c['fp']} | "
                     f"{c['fn']} | {c['undecided']} | {f3(c['precision'])} | {f3(c['recall'])} | "
                     f"{st['tp'] + st['fp'] + st['fn'] + st['tn']} | {f3(st['precision'])} | "
                     f"{f3(st['recall'])} |")
        L.append("")
    L += ["## 3. Pose clustering (§13.3.2.2)", "",
          f"K known base poses ({', '.join(['standing', 'hands up', 'arms spread', 'kick', 'squat', 'star'][:5])}), each frame a base pose with every joint angle jittered by ±5°, random "
          "place and heading. Similarity: Jaccard of the R_b relation sets, best over the "
          "renumberings of hands and feet; average linkage.", "",
          "| source | auto rule | runs | frames | ARI mean (min) | K found − K true |", "|---|---|---|---|---|---|"]
    for source in ("pipeline", "gt+2cm"):
        for auto in ("gap", "silhouette"):
            rs = [r for r in clu if r["source"] == source and r["auto"] == auto]
            if rs:
                L.append(f"| {source} | {auto} | {len(rs)} | {int(np.mean([r['frames'] for r in rs]))} | "
                         f"{_mean([r['ari'] for r in rs]):.3f} ({min(r['ari'] for r in rs):.3f}) | "
                         + ", ".join(f"{r['K_found'] - r['K_true']:+d}" for r in rs) + " |")
    (out / f"applications{suffix}.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
