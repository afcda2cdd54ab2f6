"""Alignment precision under structural noise and weight variation (thesis §11.2, Fig. 11.3–11.5).

Protocol (§11.2.1), per trial:

1. a random pattern tree P with 10 or 20 vertices (max degree 4, weights U(1, 10));
2. a data tree D from P: every weight multiplied by 1 + U(−v, v) (v = 0, 10 %, 50 %), then
   k structural noise operations, each chosen at random among the three noises of §11.2.1:
   *split vertex* (a vertex of degree ≥ 2 is split in two, a random part of its neighbours
   moves to the copy, the two linked by a 0-weight edge), *useless degree-2 vertex* (an edge is
   subdivided at a random point in its middle 80 %) and *spurious branch* (a new leaf hung on a
   random vertex by an edge of weight U(0, 0.1), shorter than the shortest piece of a limb —
   skeleton noise. Longer ones make exact ties with |w − w′|: a spurious branch longer than the
   rest of a subdivided limb can replace that rest at the same cost);
3. α, η and AHA with the pattern rooted at its first vertex and the data unrooted (Alg. 17 and
   its α / AHA counterparts), with and without cut;
4. precision = share of pattern vertices mapped to their own data vertex (a split vertex's two
   halves both count as its own).

Points: k = 0..10 (P of 10 vertices) / 0..20 (20 vertices) structural noises, 1,000 trials per
point (``--trials``; ``--quick`` = 30 trials, fewer points). Peers, in the same run: α (classic
alignment) and η (homeomorphic alignment) against AHA. Expected (§11.2.3): η and AHA at 100 %
without weight variation whatever the structural noise; AHA ≥ the others everywhere.

Usage: ``python benchmarks/alignment_accuracy.py [--quick] [--trials N]``.
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from topopose.match import Matcher, Tree  # noqa: E402
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

RESULTS = results_dir()
METHODS = (("alignment", "α"), ("ha", "η"), ("aha", "AHA"))
SPURIOUS = 0.1      # spurious branch weights U(0, 0.1): shorter than a tenth of any limb (>= 1)


def random_pattern(rng, n, max_deg=4):
    deg = [0] * n
    edges = []
    for v in range(1, n):
        u = int(rng.choice([x for x in range(v) if deg[x] < max_deg]))
        edges.append((u, v, float(rng.uniform(1.0, 10.0))))
        deg[u] += 1
        deg[v] += 1
    return edges


def make_data(rng, P, n, variation, k):
    """Data tree from pattern P (§11.2.1); returns (edges, owner) where owner[v] = pattern vertex or None."""
    edges = [[u, v, w * (1.0 + rng.uniform(-variation, variation))] for u, v, w in P]
    owner = {v: v for v in range(n)}
    nxt = n
    for _ in range(k):
        adj = {}
        for e in edges:
            adj.setdefault(e[0], []).append(e)
            adj.setdefault(e[1], []).append(e)
        kind = int(rng.integers(3))
        if kind == 0:                                   # split vertex
            cand = [v for v, es in adj.items() if len(es) >= 2]
            if not cand:
                kind = 1
            else:
                v = cand[int(rng.integers(len(cand)))]
                es = adj[v]
                m = int(rng.integers(1, len(es)))       # move 1..deg-1 neighbours to the copy
                for e in [es[i] for i in rng.permutation(len(es))[:m]]:
                    if e[0] == v:
                        e[0] = nxt
                    else:
                        e[1] = nxt
                edges.append([v, nxt, 0.0])
                owner[nxt] = owner[v]
                nxt += 1
                continue
        if kind == 1:                                   # useless degree-2 vertex
            e = edges[int(rng.integers(len(edges)))]
            t = rng.uniform(0.1, 0.9)
            u, v, w = e
            e[1], e[2] = nxt, w * t
            edges.append([nxt, v, w * (1 - t)])
            owner[nxt] = None
            nxt += 1
        else:                                           # spurious branch
            verts = list(owner)
            v = verts[int(rng.integers(len(verts)))]
            edges.append([v, nxt, float(rng.uniform(0.0, SPURIOUS))])
            owner[nxt] = None
            nxt += 1
    return [tuple(e) for e in edges], owner


def run(args):
    rng = np.random.default_rng(args.seed)
    out = {"machine": machine(), "trials": args.trials, "points": []}
    sizes = (10, 20)
    for n in sizes:
        ks = list(range(0, n + 1, 2 if n == 10 else 4))
        if args.quick:
            ks = ks[::2]
        for variation in (0.0, 0.1, 0.5):
            for k in ks:
                acc = {(m, c): 0.0 for m, _ in METHODS for c in (False, True)}
                t0 = time.perf_counter()
                for _ in range(args.trials):
                    P = random_pattern(rng, n)
                    D, owner = make_data(rng, P, n, variation, k)
                    Dt = Tree(D)
                    for m, _ in METHODS:
                        for cut in (False, True):
                            al = Matcher(Tree(P, root=0), method=m, cut=cut).align(Dt)
                            good = sum(1 for p, d in al.mapping.items() if d is not None and owner[d] == p)
                            acc[(m, cut)] += good / n
                row = {"size": n, "variation": variation, "noise": k,
                       **{f"{m}{'_cut' if c else ''}": 100.0 * v / args.trials for (m, c), v in acc.items()}}
                out["points"].append(row)
                print(f"  n={n:2d} var={variation:4.0%} noise={k:2d}: " + "  ".join(
                    f"{lab}{'+cut' if c else ''} {row[f'{m}_cut' if c else m]:5.1f}%"
                    for c in (False, True) for m, lab in METHODS) + f"  ({time.perf_counter() - t0:.1f}s)",
                    flush=True)
    return out


def plot(out, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = []
    for fig_no, variation in (("11.3", 0.0), ("11.4", 0.1), ("11.5", 0.5)):
        fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharey=True)
        for i, n in enumerate((10, 20)):
            for j, cut in enumerate((False, True)):
                ax = axes[i, j]
                pts = [r for r in out["points"] if r["size"] == n and r["variation"] == variation]
                for (m, lab), style in zip(METHODS, ("s-", "o-", "^-")):
                    key = f"{m}_cut" if cut else m
                    ax.plot([r["noise"] for r in pts], [r[key] for r in pts], style, label=lab)
                ax.set_title(f"{n} vertices, {'with' if cut else 'without'} cut")
                ax.set_xlabel("structural noise (added vertices)")
                ax.set_ylabel("good matchings (%)")
                ax.set_ylim(0, 102)
                ax.legend(loc="lower left")
        fig.suptitle(f"Fig. {fig_no}: precision with {variation:.0%} weight variation")
        fig.tight_layout()
        path = RESULTS / f"{name}_fig{fig_no.replace('.', '_')}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        figs.append(path.name)
    return figs


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--trials", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    args.trials = args.trials or (30 if args.quick else 1000)
    t0 = time.perf_counter()
    out = run(args)
    out["seconds"] = time.perf_counter() - t0
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = "alignment_accuracy_quick" if args.quick else "alignment_accuracy"
    figs = plot(out, name)
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    mc = out["machine"]
    lines = [f"# Alignment precision (thesis §11.2, Fig. 11.3–11.5){' — quick' if args.quick else ''}", "",
             f"{args.trials} trials per point; pattern rooted at a vertex, data unrooted. Machine: {mc['cpu']}, "
             f"{mc['cores']} cores, Python {mc['python']}, Numba {mc['numba']}, {mc['date']}; "
             f"{out['seconds']:.0f} s.", "",
             "Good matchings (%) — α / η / AHA, without cut | with cut.", "",
             "| size | weight var. | noise | α | η | AHA | α+cut | η+cut | AHA+cut |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in out["points"]:
        lines.append(f"| {r['size']} | {r['variation']:.0%} | {r['noise']} | {r['alignment']:.1f} | {r['ha']:.1f} | "
                     f"{r['aha']:.1f} | {r['alignment_cut']:.1f} | {r['ha_cut']:.1f} | {r['aha_cut']:.1f} |")
    zero = [r for r in out["points"] if r["variation"] == 0]
    lines += ["", "Checks: at 0 % weight variation, min over noise of η = "
              f"{min(min(r['ha'], r['ha_cut']) for r in zero):.1f} %, AHA = "
              f"{min(min(r['aha'], r['aha_cut']) for r in zero):.1f} %; points where AHA is below α or η "
              "(beyond 1 point): " + str(sum(1 for r in out["points"] for c in ("", "_cut")
                                               if r["aha" + c] + 1.0 < max(r["alignment" + c], r["ha" + c]))),
              "", "Figures: " + ", ".join(f"`{f}`" for f in figs)]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
