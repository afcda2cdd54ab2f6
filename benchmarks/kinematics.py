"""Benchmark of the kinematics stage (Mukasa et al., ELCVIA 2009): learn-model.

Measures, in one run on this machine:

1. time per frame of each step at 100³ (visual hull, marching cubes, μ, Reeb/pERG,
   coherence, deformation, clustering, fit), and μ by Hilaga base-point sampling against
   the exact eq. 1 (all-pairs Dijkstra: the "peer", the paper's definition);
2. the paper's metrics R_detection (eq. 7–8) and E_dist (eq. 9), normalized by height, on
   the synthetic walking human (``synthetic_capture(motion="walk")``, gt.json joints) and
   on the voxelized capsule walker (independent of cameras and hull), for the paper's
   eq. 5 clustering and the distance-rigidity alternative; paper: R ≈ 0.6, E < 0.075;
   targets R ≥ 0.8, E ≤ 0.05; the learned reduced tree must be isomorphic to ``human``;
3. closing the loop: ``topopose run`` on a fresh capture of the same subject with the
   learned model vs the hand-written ``human`` model (true-positive rate, evaluate).

Writes benchmarks/results/kinematics.md and .json. ``--quick``: fewer frames (< 1 min).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

HERE = Path(__file__).resolve().parent


def metrics(res, truth_joints, height):
    from topopose.kinematics import joint_metrics

    R, E, prec = [], [], []
    for f in range(len(res.frames)):
        r, e = joint_metrics(res.joints[f], truth_joints[f], height)
        R.append(r)
        E.append(e)
        prec.append(r * len(truth_joints[f]) / max(len(res.joints[f]), 1))
    return {"R_detection": float(np.mean(R)), "R_min": float(np.min(R)), "E_dist": float(np.mean(E)),
            "precision": float(np.mean(prec)),
            "E_max": float(np.max(E)), "detected_points": len(res.full.vertices) if res.full else 0,
            "truth_joints": len(truth_joints[0])}


def isomorphic_to_human(res) -> bool:
    import networkx as nx

    from topopose.pose import load_model

    if res.model is None:
        return False
    return nx.is_isomorphic(res.model.tree.to_networkx(), load_model("human").tree.to_networkx())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--no-run", action="store_true", help="skip the closing-the-loop run")
    a = ap.parse_args(argv)
    T = a.frames or (12 if a.quick else 50)
    T_run = 8 if a.quick else 30
    res_all = {"machine": machine(), "frames": T, "resolution": 100}
    lines = []

    from topopose.synth import synthetic_capture
    from topopose.hull import visual_hull
    from topopose.kinematics import learn_structure
    from topopose.synth.walker import walker_sequence
    from topopose.kinematics.reeb import integral_geodesic, perg, surface_mesh

    # ---------------------------------------------------------------- data
    t = time.perf_counter()
    cap = synthetic_capture("human", frames=T, seed=0, motion="walk")
    t_synth = time.perf_counter() - t
    t = time.perf_counter()
    vols = [visual_hull(cap, f, resolution=100) for f in cap.frames]
    hull_ms = 1e3 * (time.perf_counter() - t) / T
    gt = cap.gt
    truth = [gt["frames"][f]["joints"] for f in cap.frames]
    print(f"synthetic walk: {T} frames ({t_synth:.1f} s), hull {hull_ms:.0f} ms/frame, grid {vols[0].data.shape}",
          flush=True)

    # ---------------------------------------------------------------- μ: sampled vs exact
    v = vols[T // 2]
    # --quick: a coarser mesh (marching-cubes step 2) so that the exact eq. 1 stays short
    mesh = surface_mesh(v.data, v.origin, v.voxel_size, step_size=2 if a.quick else 1)
    tm = {}
    for nb in (32, 64, 128):
        best = np.inf
        for _ in range(2):
            t = time.perf_counter()
            mu = integral_geodesic(mesh, n_base=nb)
            best = min(best, time.perf_counter() - t)
        tm[nb] = (best, mu)
    sub = mesh.n
    t = time.perf_counter()
    from scipy.sparse.csgraph import dijkstra

    G = mesh.graph()
    rows = dijkstra(G, directed=True, indices=np.arange(sub))
    t_exact = (time.perf_counter() - t) * mesh.n / sub
    mu_exact = rows.sum(0)
    mu_exact = (mu_exact - mu_exact.min()) / np.ptp(mu_exact)
    geo = {"mesh_vertices": int(mesh.n), "exact_s_estimated": t_exact,
           "exact_sources_used": int(sub)}
    lines.append("## μ (eq. 1): Hilaga base-point sampling vs exact all-pairs geodesics\n")
    lines.append(f"Mesh of frame {T // 2}: {mesh.n} vertices. Exact eq. 1 = {mesh.n} Dijkstra runs"
                 + (f" (timed on {sub}, extrapolated)" if sub < mesh.n else "") + ".\n")
    lines.append("| base points | time (ms) | exact / sampled time | corr. with exact |\n|---|---|---|---|")
    for nb, (tt, mu) in tm.items():
        c = float(np.corrcoef(mu, mu_exact)[0, 1])
        geo[f"sampled_{nb}"] = {"s": tt, "corr": c}
        lines.append(f"| {nb} | {1e3 * tt:.0f} | {t_exact / tt:.0f}× | {c:.4f} |")
    lines.append(f"| exact ({mesh.n}) | {1e3 * t_exact:.0f} | 1× | 1 |\n")
    res_all["geodesic"] = geo
    print("\n".join(lines[-6:]), flush=True)

    # ---------------------------------------------------------------- learn on the synthetic walk
    t = time.perf_counter()
    P = [perg(v.data, v.origin, v.voxel_size, coarse=16, fine=64) for v in vols]
    t_perg = time.perf_counter() - t
    runs = {}
    variants = [("eq. 5 correlation (default)", {}, P),
                ("distance rigidity", {"criterion": "rigidity"}, P)]
    if not a.quick:
        for coarse in (8, 32):
            Pc = [perg(v.data, v.origin, v.voxel_size, coarse=coarse, fine=64) for v in vols]
            variants.append((f"eq. 5, pERG {coarse}→64 levels", {"coarse": coarse}, Pc))
    for label, kw, Pv in variants:
        t = time.perf_counter()
        r = learn_structure(vols, frames=cap.frames, up=cap.up_vector, pergs=Pv, source="synthetic walk", **kw)
        dt = time.perf_counter() - t
        m = metrics(r, truth, gt["height"])
        m.update({"status": r.status, "isomorphic_to_human": isomorphic_to_human(r),
                  "parts": r.model.parts if r.model else None,
                  "coherent_frames": int(sum(r.coherent)), "seconds_after_perg": dt})
        runs[label] = (r, m)
        print(label, {k: m[k] for k in ("R_detection", "E_dist", "detected_points", "isomorphic_to_human")}, flush=True)
    learned = runs["eq. 5 correlation (default)"][0]
    timings = dict(learned.diagnostics["timings_ms_per_frame"])
    timings = {"hull": hull_ms, **timings}

    # ---------------------------------------------------------------- capsule walker (no cameras)
    w = walker_sequence(frames=T if not a.quick else 12, resolution=100)
    rw = learn_structure(w.volumes, frames=w.frames, source="capsule walker")
    mw = metrics(rw, w.joints, w.height)
    mw.update({"status": rw.status, "isomorphic_to_human": isomorphic_to_human(rw)})
    print("capsule walker", mw, flush=True)

    lines.append("## Time per frame at 100³ (synthetic walking human, ms)\n")
    lines.append("| step | ms / frame |\n|---|---|")
    for k, v in timings.items():
        lines.append(f"| {k} | {v:.1f} |")
    lines.append(f"| total | {sum(timings.values()):.1f} |\n")
    lines.append("deform_fit: the initial model deformed onto every frame (§2.3.1, and the fit of §2.5); "
                 "cluster_integrate: eq. 5 clustering per coherent interval, integration per branch (§2.4) "
                 "and joint placement; model: naming and the model trees. "
                 "These per-sequence steps are divided by the frame count. "
                 "μ uses 64 base points (Hilaga sampling); the pERG has 16→64 levels with T-sets. "
                 f"pERG of all {T} frames: {t_perg:.1f} s.\n")

    lines.append("## The paper's metrics (normalized by height)\n")
    lines.append("Paper (CG walking human, 15 cameras): R_detection ≈ 0.6, E_dist < 0.075. "
                 "Targets: R ≥ 0.8, E ≤ 0.05.\n")
    lines.append("| sequence | clustering | frames (coherent) | R_detection (min) | E_dist (max) | detected points / gt joints | matched / detected | reduced tree ≅ human |")
    lines.append("|---|---|---|---|---|---|---|---|")
    out_runs = {}
    for label, (r, m) in runs.items():
        lines.append(f"| synthetic walk | {label} | {T} ({m['coherent_frames']}) | {m['R_detection']:.3f} ({m['R_min']:.2f}) | "
                     f"{m['E_dist']:.4f} ({m['E_max']:.3f}) | {m['detected_points']} / {m['truth_joints']} | {m['precision']:.2f} | {m['isomorphic_to_human']} |")
        out_runs[label] = m
    lines.append(f"| capsule walker | eq. 5 correlation (default) | {len(w.frames)} ({int(sum(rw.coherent))}) | "
                 f"{mw['R_detection']:.3f} ({mw['R_min']:.2f}) | {mw['E_dist']:.4f} ({mw['E_max']:.3f}) | "
                 f"{mw['detected_points']} / {mw['truth_joints']} | {mw['precision']:.2f} | {mw['isomorphic_to_human']} |\n")
    lines.append("R_detection counts a ground-truth joint (gt.json `joints`, end points included) as "
                 "detected when it and a learned point (joint, end point or junction) are each "
                 "other's nearest (eq. 7); we divide by the number of joints. More learned points "
                 "can only lower E_dist, so the share of learned points that are matched is shown too.\n")
    lines.append("Learned model (eq. 5): parts " + ", ".join(learned.model.parts) + "; edges "
                 + ", ".join(f"{u}–{v} {w:.2f}" for u, v, w in learned.model.tree.edges) + ".\n")
    res_all.update({"timings_ms_per_frame": timings, "synthetic_walk": out_runs, "capsule_walker": mw,
                    "learned_model": learned.model.to_dict()})

    # ---------------------------------------------------------------- other subjects
    if not a.quick:
        import networkx as nx

        from topopose.kinematics import learn_model
        from topopose.pose import load_model

        lines.append("## Other subjects: a model for free\n")
        lines.append("Synthetic captures (30 frames, seed 0), learned with the defaults; the reduced tree "
                     "is compared with the built-in model of the subject.\n")
        lines.append("| subject / motion | status | coherent frames | R_detection | E_dist | points / gt joints | reduced tree ≅ built-in | parts |")
        lines.append("|---|---|---|---|---|---|---|---|")
        others = {}
        for subj, motion in (("dog", "trot"), ("dog", "walk"), ("spider", "walk")):
            c = synthetic_capture(subj, frames=30, seed=0, motion=motion)
            r = learn_model(c, resolution=100)
            m = metrics(r, [c.gt["frames"][f]["joints"] for f in r.frames], c.gt["height"])
            iso = r.model is not None and nx.is_isomorphic(r.model.tree.to_networkx(),
                                                           load_model(subj).tree.to_networkx())
            others[f"{subj} {motion}"] = {**m, "status": r.status, "isomorphic": iso,
                                          "coherent_frames": int(sum(r.coherent)),
                                          "fallback": r.diagnostics.get("coherence_fallback")}
            lines.append(f"| {subj} {motion} | {r.status} | {int(sum(r.coherent))}/30 | {m['R_detection']:.3f} | "
                         f"{m['E_dist']:.4f} | {m['detected_points']} / {m['truth_joints']} | {iso} | "
                         f"{', '.join(r.model.parts) if r.model else '-'} |")
            print(subj, motion, others[f"{subj} {motion}"], flush=True)
        lines.append("")
        res_all["other_subjects"] = others

    # ---------------------------------------------------------------- closing the loop
    loop = None
    if not a.no_run:
        try:
            from topopose.pose import load_model
            from topopose.batch import run
            from topopose.batch.quality import evaluate
        except ImportError as exc:  # pose stage absent
            loop = {"pending": str(exc)}
        else:
            loop = {"frames": T_run}
            for motion, label, model in ((m, lab, mod) for m in ("walk", "random")
                                         for lab, mod in (("hand-written human", load_model("human")),
                                                          ("learned", learned.model))):
                fresh = synthetic_capture("human", frames=T_run, seed=7, motion=motion)
                t = time.perf_counter()
                rr = run(fresh, model=model, resolution=100, progress=False)
                ev = evaluate(fresh.gt, rr.poses, model=load_model("human"))
                st = ev.at_status()
                best = max(ev.rates(th)["tp_rate"] for th in np.arange(0, 2.001, 0.01))
                failed = [p for p in rr.poses if p.status == "failed"]
                loop.setdefault(motion, {})[label] = {"tp_rate": st["tp_rate"], "fp_rate": st["fp_rate"], "matched": st["matched"],
                               "failed": len(failed), "first_error": failed[0].error if failed else None,
                               "best_tp_rate_any_threshold": best, "seconds": time.perf_counter() - t}
                print("run", motion, label, loop[motion][label], flush=True)
            for motion in ("walk", "random"):
                hw, le = loop[motion]["hand-written human"]["tp_rate"], loop[motion]["learned"]["tp_rate"]
                loop[motion]["ratio"] = le / hw if hw else None
        lines.append("## Closing the loop: `topopose run` with the learned model\n")
        if "pending" in loop:
            lines.append(f"Pending: {loop['pending']}\n")
        else:
            lines.append(f"Fresh synthetic captures of the same subject (seed 7, {T_run} frames, 8 cameras): "
                         "walking, and random poses; 100³, default thresholds; scored like "
                         "`topopose evaluate` (parts within 0.1 × height of their gt segment).\n")
            lines.append("| fresh capture | model | TP rate | FP rate | matched | failed | best TP rate (any T_d) |")
            lines.append("|---|---|---|---|---|---|---|")
            for motion in ("walk", "random"):
                for label in ("hand-written human", "learned"):
                    x = loop[motion][label]
                    lines.append(f"| {motion} | {label} | {x['tp_rate']:.3f} | {x['fp_rate']:.3f} | {x['matched']} | "
                                 f"{x['failed']} | {x['best_tp_rate_any_threshold']:.3f} |")
            lines.append("")
            for motion in ("walk", "random"):
                r_ = loop[motion]["ratio"]
                lines.append(f"- {motion}: learned / hand-written TP rate = **{r_:.2f}** (target ≥ 0.90)"
                             if r_ is not None else f"- {motion}: hand-written TP rate is 0")
            lines.append("")
        res_all["closing_the_loop"] = loop

    mach = res_all["machine"]
    head = [f"# Kinematics benchmark (learn-model, Mukasa et al.){' — quick' if a.quick else ''}\n",
            f"Machine: {mach['cpu']}, {mach['cores']} cores, Python {mach['python']}, numba {mach['numba']}, "
            f"{mach['date']}. Shared machine: timings are noisy (best of 2 for μ).\n"]
    text = "\n".join(head + lines)
    outdir = results_dir()
    outdir.mkdir(exist_ok=True)
    name = "kinematics_quick" if a.quick else "kinematics"
    (outdir / f"{name}.md").write_text(text)
    (outdir / f"{name}.json").write_text(json.dumps(res_all, indent=1, default=float))
    print(text)


if __name__ == "__main__":
    sys.exit(main())
