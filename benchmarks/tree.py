"""Data-tree benchmark (thesis §7.3.3, Alg. 13): skeleton → weighted tree.

Skeletons: the synthetic human (``synthetic_capture("human", separated=False)``, random poses,
8 cameras) → ``tp.visual_hull`` → ``tp.thin(method="d6i1d")`` at each resolution N.  Single
core (NUMBA_NUM_THREADS=1).  Per skeleton, the minimum of ``--repeat`` runs; the table gives
the median over frames.

Contenders, all in the same run on the same skeletons:

- **topopose**: ``tp.data_tree(skel)`` — voxel list (one 8-bytes-at-a-time scan of the grid),
  26-neighbour lookups by binary search, union-find labelling (Numba), cycle handling, Tree.
- **topopose-ndimage**: the same with ``labelling="ndimage"`` (degrees by
  ``scipy.ndimage.convolve``, components by ``scipy.ndimage.label`` on the full grid).
- **ndimage+networkx**: a straightforward Alg. 13 written here — ndimage degree/labels, a
  networkx voxel graph, branch contacts and lengths from it, a networkx multigraph of
  vertices and branches made a tree by ``nx.minimum_spanning_tree``.
- **skan**: ``skan.Skeleton(skel, spacing=voxel) + skan.summarize`` (PyPI ``skan``): the
  branch table of a skeleton (junction pixels as nodes, branch lengths), the closest
  published peer; it does not merge junction clusters nor make a tree.

Checks: topopose and topopose-ndimage give identical trees; topopose and ndimage+networkx give
the same total branch length when no cycle was broken.

Weights: for each extremity found as a leaf, the weight of the tree path from it to the vertex
nearest its junction, with ``weight="length"`` and with the thesis' ``weight="count"``
(× voxel size), divided by the ground-truth length of the limb's bone chain; the mean and
spread of that ratio over limbs, frames and resolutions show which weight agrees with the
model's Euclidean edge lengths (the pipeline's choice).

Repeats: topopose ``--repeat`` times, its ndimage path and skan ``--repeat``/5, the networkx
peer once (it is 3 orders of magnitude slower).

Usage: ``python benchmarks/tree.py [--quick] [--frames N] [--repeat R]``.
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import networkx as nx  # noqa: E402
import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402

import topopose as tp  # noqa: E402
from topopose.synth.capture import synthetic_capture  # noqa: E402
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

HERE = Path(__file__).resolve().parent
OFFS = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if d != (0, 0, 0)])
KERNEL = np.ones((3, 3, 3), np.uint8)
KERNEL[1, 1, 1] = 0
STRUCT = np.ones((3, 3, 3), bool)
MODEL_EDGES = [("torso", "head"), ("torso", "hand_1"), ("torso", "hand_2"), ("torso", "crotch"),
               ("crotch", "foot_1"), ("crotch", "foot_2")]


# --------------------------------------------------------------------------- the straightforward peer
def peer_tree(skel, origin, vs):
    """Alg. 13 the straightforward way: scipy.ndimage labelling + networkx graphs."""
    deg = ndimage.convolve(skel.astype(np.uint8), KERNEL, mode="constant")
    lab_all, n_all = ndimage.label(skel, STRUCT)
    if n_all > 1:  # keep the largest component
        sizes = np.bincount(lab_all.ravel())[1:]
        skel = lab_all == (1 + int(np.argmax(sizes)))
    cls = np.zeros(skel.shape, np.int8)
    cls[skel & (deg <= 1)] = 1
    cls[skel & (deg == 2)] = 2
    cls[skel & (deg > 2)] = 3
    labs = {c: ndimage.label(cls == c, STRUCT) for c in (1, 2, 3)}
    # vertices: E and I components at their centroids
    g = nx.MultiGraph()
    vkey = {}
    for c in (1, 3):
        lab, n = labs[c]
        if n:
            cents = ndimage.center_of_mass(np.ones_like(lab), lab, range(1, n + 1))
            for i, cen in enumerate(cents, 1):
                vkey[(c, i)] = len(vkey)
                g.add_node(vkey[(c, i)], position=np.asarray(origin) + np.asarray(cen) * vs)
    # the voxel graph
    vox = [tuple(p) for p in np.argwhere(skel)]
    vg = nx.Graph()
    vg.add_nodes_from(vox)
    vset = set(vox)
    for p in vox:
        for d in OFFS:
            q = (p[0] + d[0], p[1] + d[1], p[2] + d[2])
            if q in vset:
                vg.add_edge(p, q, length=math.sqrt(d @ d))
    bvox = [p for p in vox if cls[p] == 2]
    for comp in nx.connected_components(vg.subgraph(bvox)):
        length = sum(d["length"] for *_, d in vg.subgraph(comp).edges(data=True))
        ends = []
        for p in comp:
            for q in vg.neighbors(p):
                if cls[q] != 2:
                    ends.append(vkey[(int(cls[q]), int(labs[int(cls[q])][0][q]))])
                    length += vg.edges[p, q]["length"]
        if len(ends) == 2:
            g.add_edge(ends[0], ends[1], weight=length * vs)
    for p in vox:  # E touching I directly
        if cls[p] == 1:
            for q in vg.neighbors(p):
                if cls[q] == 3:
                    g.add_edge(vkey[(1, int(labs[1][0][p]))], vkey[(3, int(labs[3][0][q]))],
                               weight=vg.edges[p, q]["length"] * vs)
    simple = nx.Graph()
    simple.add_nodes_from(g.nodes(data=True))
    for u, v, d in g.edges(data=True):
        if u != v and (not simple.has_edge(u, v) or simple.edges[u, v]["weight"] > d["weight"]):
            simple.add_edge(u, v, weight=d["weight"])
    return nx.minimum_spanning_tree(simple), g


def skan_tree(skel, vs):
    import skan

    sk = skan.Skeleton(skel, spacing=vs)
    return skan.summarize(sk, separator="_")


CHAINS = {"head": ["neck", "head_top"],
          "hand_1": ["neck", "shoulder_l", "elbow_l", "wrist_l", "hand_l"],
          "hand_2": ["neck", "shoulder_r", "elbow_r", "wrist_r", "hand_r"],
          "foot_1": ["pelvis", "hip_l", "knee_l", "ankle_l", "foot_l"],
          "foot_2": ["pelvis", "hip_r", "knee_r", "ankle_r", "foot_r"]}


def limb_ratios(tree, cnt, gt, vs, tol=0.15):
    """(limb, length ratio, count ratio) for each extremity found as a leaf.

    The tree path from the leaf matched to an extremity to the vertex nearest its junction
    (torso for head and hands, crotch for feet), weighed with ``length`` and with
    ``count`` × voxel size, divided by the ground-truth length of the limb (its bone chain,
    e.g. neck–shoulder–elbow–wrist–hand).
    """
    from scipy.optimize import linear_sum_assignment

    limbs = [("head", "torso"), ("hand_1", "torso"), ("hand_2", "torso"),
             ("foot_1", "crotch"), ("foot_2", "crotch")]
    parts, joints = gt["parts"], gt["joints"]
    leaves = [v for v in tree.vertices if tree.degree(v) <= 1]
    if len(leaves) < len(limbs):
        return []
    P = np.array([tree.positions[v] for v in leaves])
    D = np.array([np.linalg.norm(P - parts[e], axis=1) for e, _ in limbs])
    r, c = linear_sum_assignment(D)
    A = np.array([tree.positions[v] for v in tree.vertices])
    gl, gc = tree.to_networkx(), cnt.to_networkx()
    out = []
    for i, j in zip(r, c):
        if D[i, j] > tol:
            continue
        e, jn = limbs[i]
        junction = tree.vertices[int(np.argmin(np.linalg.norm(A - parts[jn], axis=1)))]
        chain = np.array([joints[k] for k in CHAINS[e]])
        gt = float(np.linalg.norm(np.diff(chain, axis=0), axis=1).sum())
        wl = nx.shortest_path_length(gl, leaves[j], junction, weight="weight")
        wc = nx.shortest_path_length(gc, leaves[j], junction, weight="weight") * vs
        out.append((e, wl / gt, wc / gt))
    return out


# --------------------------------------------------------------------------- measurement
def best_of(fn, repeat):
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3, out


def run(resolutions, frames, repeat, seed=0):
    cap = synthetic_capture(subject="human", frames=frames, seed=seed, separated=False)
    have_skan = True
    try:
        import skan  # noqa: F401
    except ImportError:
        have_skan = False
    rows, weights = [], []
    # warm-up (Numba compile/cache load) outside the timings
    f0 = cap.frames[0]
    v0 = tp.visual_hull(cap, f0, resolution=min(resolutions))
    s0 = tp.thin(v0.data, method="d6i1d")
    tp.data_tree(s0)
    if have_skan:
        skan_tree(s0, 1.0)
    for res in resolutions:
        per = {"topopose": [], "topopose-ndimage": [], "ndimage+networkx": [], "skan": [],
               "voxels": [], "vertices": [], "grid": None}
        for f in cap.frames:
            vol = tp.visual_hull(cap, f, resolution=res)
            skel = tp.thin(vol.data, method="d6i1d")
            o, vs = vol.origin, vol.voxel_size
            per["grid"] = list(skel.shape)
            t_ours, tree = best_of(lambda: tp.data_tree(skel, origin=o, voxel_size=vs), repeat)
            t_nd, tree_nd = best_of(lambda: tp.data_tree(skel, origin=o, voxel_size=vs,
                                                         labelling="ndimage"), max(1, repeat // 5))
            assert tree.edges == tree_nd.edges, "labelling paths disagree"
            t_peer, (ptree, pg) = best_of(lambda: peer_tree(skel, o, vs), 1)
            d = tree.diagnostics
            if d["cycles_broken"] == d["loops"] == d["triangles"] == 0 and not d["dropped_components"]:
                tw = tree.total_weight()
                assert abs(tw - ptree.size(weight="weight")) < 1e-6 * (1 + tw), \
                    "peer and topopose disagree on the total branch length"
            per["topopose"].append(t_ours)
            per["topopose-ndimage"].append(t_nd)
            per["ndimage+networkx"].append(t_peer)
            if have_skan:
                per["skan"].append(best_of(lambda: skan_tree(skel, vs), max(1, repeat // 5))[0])
            per["voxels"].append(int(skel.sum()))
            per["vertices"].append(tree.n_vertices)
            # weight consistency with the model: leaf-to-junction path weights vs ground truth
            cnt = tp.data_tree(skel, origin=o, voxel_size=vs, weight="count")
            for limb, ratio_l, ratio_c in limb_ratios(tree, cnt, cap.gt["frames"][f], vs):
                weights.append({"resolution": res, "frame": f, "limb": limb,
                                "length": ratio_l, "count": ratio_c})
        rows.append({"resolution": res, "grid": per["grid"], "frames": len(cap.frames),
                     "voxels_median": float(np.median(per["voxels"])),
                     "vertices_median": float(np.median(per["vertices"])),
                     **{k: (float(np.median(per[k])) if per[k] else None)
                        for k in ("topopose", "topopose-ndimage", "ndimage+networkx", "skan")}})
        r = rows[-1]
        print(f"N={res:4d} grid {r['grid']} voxels {r['voxels_median']:.0f} vertices "
              f"{r['vertices_median']:.0f}: topopose {r['topopose']:.3f} ms, ndimage path "
              f"{r['topopose-ndimage']:.2f} ms, ndimage+networkx {r['ndimage+networkx']:.1f} ms"
              + (f", skan {r['skan']:.1f} ms" if r["skan"] is not None else ""), flush=True)
    return rows, weights


def weight_summary(weights):
    out = {"n": len(weights)}
    for key in ("length", "count"):
        v = np.array([w[key] for w in weights])
        out[key] = {"mean": float(v.mean()), "cv": float(v.std() / v.mean()),
                    "per_resolution": {}}
        for res in sorted({w["resolution"] for w in weights}):
            vr = np.array([w[key] for w in weights if w["resolution"] == res])
            out[key]["per_resolution"][res] = {"mean": float(vr.mean()), "cv": float(vr.std() / vr.mean())}
    return out


def report(rows, wsum, mach, quick):
    name = "tree_quick" if quick else "tree"
    lines = [f"# Data tree benchmark ({'quick' if quick else 'full'})", "",
             f"Machine: {mach['cpu']}, {mach['cores']} cores, Python {mach['python']}, "
             f"Numba {mach['numba']}, NumPy {mach['numpy']}, {mach['threads']}, {mach['date']}.", "",
             "Skeletons: synthetic human (random poses, limbs may touch), visual hull at N, D6I1D "
             "thinning. Times per skeleton in ms (min of repeats, median over frames); ratio = "
             "peer / topopose.", "",
             "| N | grid | skeleton voxels | tree vertices | topopose ms | topopose-ndimage ms "
             "(ratio) | ndimage+networkx ms (ratio) | skan ms (ratio) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        t = r["topopose"]
        sk = f"{r['skan']:.2f} ({r['skan'] / t:.0f}×)" if r["skan"] is not None else "n/a"
        lines.append(f"| {r['resolution']} | {'×'.join(map(str, r['grid']))} | {r['voxels_median']:.0f} | "
                     f"{r['vertices_median']:.0f} | {t:.3f} | {r['topopose-ndimage']:.2f} "
                     f"({r['topopose-ndimage'] / t:.0f}×) | {r['ndimage+networkx']:.1f} "
                     f"({r['ndimage+networkx'] / t:.0f}×) | {sk} |")
    lines += ["", "Target: ≤ 1 ms for a 100³ human skeleton on one core.", "",
              "## Which weight matches the model", "",
              "For each extremity found as a leaf (within 15 cm of its ground-truth part), the "
              "weight of the tree path from that leaf to the vertex nearest its junction (torso "
              "for head and hands, crotch for feet) divided by the ground-truth length of "
              "the limb's bone chain (e.g. neck–shoulder–elbow–wrist–hand); over all limbs, "
              "frames and resolutions. A weight consistent with the "
              "model's Euclidean edge lengths gives a ratio near 1 that does not change with the "
              "limb's direction in the grid (small CV).", "",
              "| weight | mean ratio | CV (all) | " + " | ".join(
                  f"N={res}: mean (CV)" for res in wsum["length"]["per_resolution"]) + " |",
              "|---|---|---|" + "---|" * len(wsum["length"]["per_resolution"])]
    for key in ("length", "count"):
        w = wsum[key]
        lines.append(f"| {key} | {w['mean']:.3f} | {w['cv']:.3f} | " + " | ".join(
            f"{v['mean']:.3f} ({v['cv']:.3f})" for v in w["per_resolution"].values()) + " |")
    lines += ["", "Why the ratios are not exactly 1: thinning shortens limb ends and the junction "
              "vertex sits inside the junction (below 1, coarse grids); a digital 26-path zigzags "
              "around the limb's axis and spurious side branches lengthen paths (above 1, fine "
              "grids). The count weight also under-measures diagonal runs (a run of length L has "
              "only L/√2 or L/√3 voxels), so its ratio is far below 1 and spreads more with the "
              "limb's direction: the pipeline uses `weight=\"length\"`.",
              f"Limb samples: {wsum['n']}."]
    text = "\n".join(lines) + "\n"
    out = results_dir()
    out.mkdir(exist_ok=True)
    (out / f"{name}.md").write_text(text)
    (out / f"{name}.json").write_text(json.dumps({"machine": mach, "rows": rows, "weights": wsum}, indent=1))
    print(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="4 frames at 64 and 100 (< 1 minute)")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=None)
    a = ap.parse_args()
    if a.quick:
        res, frames, repeat = [64, 100], a.frames or 4, a.repeat or 5
    else:
        res, frames, repeat = [50, 64, 100, 150, 200], a.frames or 20, a.repeat or 15
    mach = machine(threads="1 (NUMBA_NUM_THREADS=1)")
    rows, weights = run(res, frames, repeat)
    report(rows, weight_summary(weights), mach, a.quick)


if __name__ == "__main__":
    main()
