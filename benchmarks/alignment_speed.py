"""Alignment speed (thesis §11.3 and §11.4): α, η (HA) and AHA.

§11.3 — general speed: n random trees T_0..T_{n-1} (n = 32) of each size, every ordered pair
(T_i, T_j) aligned, for rooted/rooted, rooted/unrooted and unrooted/unrooted trees; average
time per alignment.

§11.4 — frequencies in the motion-capture setting: the human model (7 vertices, max degree 4,
rooted at the torso) against unrooted data trees of 7–25 vertices with max degree 3–7, and the
hand model (8 vertices, rooted at the arm) against data trees rooted at their border vertex;
frequency = n / elapsed for n data trees (random, weights normalized to sum 1).

Peer, in the same run: the straightforward memoized recursion of the same propositions
(tests/match_reference.py, the shape in which the thesis writes them, with the min over
rootings of Prop. 22–23), on a subset of the same data trees; the table gives the ratio.
The thesis' figures (C++, 2.33 GHz Core 2 Q8200): AHA of the human model ≥ 708/s on average,
≥ 89/s in the worst case (17-vertex degree-5 data tree). Targets here, one process, one core:
≥ 7,000/s against 10–12-vertex data trees and ≥ 900/s against 25-vertex degree-5 data trees.

Timings: CPU time of the process (``time.process_time``: the machine is shared with other jobs,
wall time would mostly measure them), minimum over ``--repeat`` passes. ``Matcher.align`` is timed
as the pipeline calls it (distance + mapping); a second column also reads ``.arcs``.

Usage: ``python benchmarks/alignment_speed.py [--quick] [--repeat R] [--n N]``.
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from topopose.match import Matcher, Tree  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from match_reference import memo_distance  # noqa: E402
from _machine import machine, results_dir  # noqa: E402  (benchmarks/_machine.py)

RESULTS = results_dir()

HUMAN = [("torso", "head", 0.15), ("torso", "hand_1", 0.7), ("torso", "hand_2", 0.7),
         ("torso", "crotch", 0.5), ("crotch", "foot_1", 0.9), ("crotch", "foot_2", 0.9)]
HAND = [("arm", "palm", math.inf), ("palm", "thumb", 0.7), ("palm", "index", 1.0), ("palm", "middle", 1.1),
        ("palm", "ring", 1.0), ("palm", "little", 0.8)]


def random_tree(rng, n, max_deg, exact=True, normalize=True):
    """Random tree with n vertices, max degree max_deg (reached when ``exact``), weights U(0.1, 1)."""
    for _ in range(1000):
        deg = [0] * n
        edges = []
        for v in range(1, n):
            cand = [u for u in range(v) if deg[u] < max_deg]
            if exact and max(deg) < max_deg and v >= n - max_deg:
                top = max(range(v), key=lambda u: deg[u] if deg[u] < max_deg else -1)
                u = top
            else:
                u = int(rng.choice(cand))
            edges.append((u, v, float(rng.uniform(0.1, 1.0))))
            deg[u] += 1
            deg[v] += 1
        if not exact or max(deg) == max_deg or n <= max_deg:
            break
    if normalize:
        s = sum(w for _, _, w in edges)
        edges = [(u, v, w / s) for u, v, w in edges]
    return edges


def hand_data(rng, n, max_deg):
    """A data tree for the hand: vertex 0 is the border vertex, its edge is infinite."""
    body = random_tree(rng, n - 1, max_deg, exact=True)
    # attach the border vertex to a vertex of degree < max_deg, by an infinite edge
    deg = np.zeros(n - 1, int)
    for u, v, _ in body:
        deg[u] += 1
        deg[v] += 1
    leaf = int(np.flatnonzero(deg < max_deg)[0])
    return [(u + 1, v + 1, w) for u, v, w in body] + [(0, leaf + 1, math.inf)]


def clock():
    """CPU time of this process: the machine is shared, so wall time mostly measures the others."""
    return time.process_time()


def best_rate(fn, items, repeat):
    best = math.inf
    for _ in range(repeat):
        t = clock()
        for x in items:
            fn(x)
        best = min(best, clock() - t)
    return len(items) / best


# ---------------------------------------------------------------------- §11.4
def frequencies(args, out):
    rng = np.random.default_rng(1)
    sizes = [7, 10, 11, 12, 15, 17, 20, 25] if not args.quick else [7, 11, 17, 25]
    degrees = [3, 4, 5, 6, 7] if not args.quick else [3, 5]
    human = Tree(HUMAN, root="torso").normalized()
    hand = Tree(HAND, root="arm").normalized()
    rows = []
    for model_name, model, kind in (("human", human, "unrooted"), ("hand", hand, "rooted")):
        for cut in (False, True):
            m = Matcher(model, method="aha", cut=cut)
            for d in degrees:
                for s in sizes:
                    if s <= d:
                        continue
                    if model_name == "human":
                        trees = [Tree(random_tree(rng, s, d)) for _ in range(args.n_freq)]
                        root = None
                    else:
                        trees = [Tree(hand_data(rng, s, d), root=0) for _ in range(args.n_freq)]
                        root = 0
                    m.align(trees[0])
                    rate = best_rate(lambda t: m.align(t, root), trees, args.repeat)
                    rate_arcs = best_rate(lambda t: m.align(t, root).arcs, trees, max(1, args.repeat // 2))
                    rows.append({"model": model_name, "data": kind, "cut": cut, "size": s, "max_degree": d,
                                 "per_s": rate, "per_s_with_arcs": rate_arcs})
                    print(f"  {model_name:5s} cut={cut!s:5s} size {s:2d} deg {d}: {rate:9.0f}/s "
                          f"(with arcs {rate_arcs:8.0f}/s)", flush=True)
    out["frequencies"] = rows
    # the two targets: human model, unrooted data, no cut
    hum = [r for r in rows if r["model"] == "human" and not r["cut"]]
    avg = [r["per_s"] for r in hum if 10 <= r["size"] <= 12]
    avg35 = [r["per_s"] for r in hum if 10 <= r["size"] <= 12 and r["max_degree"] <= 5]
    worst = [r["per_s"] for r in hum if r["size"] == 25 and r["max_degree"] == 5]
    out["targets"] = {"human_10_12_mean_per_s": float(np.mean(avg)) if avg else None,
                      "human_10_12_deg3_5_mean_per_s": float(np.mean(avg35)) if avg35 else None,
                      "human_25_deg5_per_s": worst[0] if worst else None,
                      "thesis_avg_per_s": 708, "thesis_worst_per_s": 89,
                      "target_avg_per_s": 7000, "target_worst_per_s": 900}


def plain_vs_matcher(args, out):
    """``topopose.align(model, tree)`` called again and again (its Matcher cache) vs one
    ``Matcher(model).align(tree)``: human model, 11-vertex data trees, interleaved rounds."""
    import topopose as tp

    rng = np.random.default_rng(3)
    human = Tree(HUMAN, root="torso").normalized()
    trees = [Tree(random_tree(rng, 11, d)) for d in (3, 4, 5) for _ in range(args.n_freq // 3 or 1)]
    m = Matcher(human, method="aha")
    tp.align(human, trees[0])
    m.align(trees[0])
    plain, matcher = [], []
    for _ in range(max(3, args.repeat)):
        plain.append(best_rate(lambda t: tp.align(human, t), trees, 1))
        matcher.append(best_rate(lambda t: m.align(t), trees, 1))
    out["plain_vs_matcher"] = {"trees": len(trees), "size": 11, "max_degree": [3, 4, 5],
                               "plain_per_s": max(plain), "matcher_per_s": max(matcher),
                               "ratio": max(plain) / max(matcher), "target_plain_per_s": 7000}
    print(f"  plain align(): {max(plain):.0f}/s, Matcher.align: {max(matcher):.0f}/s", flush=True)


def peer_ratio(args, out):
    """Same trees, the memoized recursion of the propositions (the papers' shape) vs the kernels."""
    rng = np.random.default_rng(2)
    human = Tree(HUMAN, root="torso").normalized()
    rows = []
    cases = [(11, 4), (17, 5)] if args.quick else [(7, 3), (11, 4), (17, 5), (25, 5)]
    for method in ("aha", "ha", "alignment"):
        m = Matcher(human, method=method)
        for s, d in cases:
            trees = [random_tree(rng, s, d) for _ in range(args.n_peer)]
            m.align(trees[0])
            ours = best_rate(lambda t: m.align(t), trees, args.repeat)
            t0 = clock()
            for t in trees:
                ref = memo_distance(human.edges, t, method, "torso", None, False)
            memo = len(trees) / (clock() - t0)
            assert abs(ref - m.align(trees[-1]).distance) < 1e-9
            rows.append({"method": method, "size": s, "max_degree": d, "ours_per_s": ours,
                         "memo_per_s": memo, "ratio": ours / memo})
            print(f"  peer {method:9s} size {s:2d} deg {d}: ours {ours:8.0f}/s  memo {memo:7.1f}/s  "
                  f"x{ours / memo:7.0f}", flush=True)
    out["peer"] = rows


# ---------------------------------------------------------------------- §11.3
def general(args, out):
    rng = np.random.default_rng(3)
    sizes = [5, 10, 15, 20, 25] if not args.quick else [5, 10, 15]
    rows = []
    n = args.n_general
    for s in sizes:
        trees = [random_tree(rng, s, 4, exact=False) for _ in range(n)]
        for method in ("alignment", "ha", "aha"):
            for mode, (pr, dr) in (("rooted/rooted", (0, 0)), ("rooted/unrooted", (0, None)),
                                   ("unrooted/unrooted", (None, None))):
                matchers = [Matcher(Tree(t, root=pr), method=method) for t in trees]
                datas = [Tree(t, root=dr) for t in trees]
                matchers[0].align(datas[0])
                best = math.inf
                for _ in range(max(1, args.repeat // 2)):
                    t0 = clock()
                    for mt in matchers:
                        for dt in datas:
                            mt.align(dt)
                    best = min(best, clock() - t0)
                per = best / (n * n)
                rows.append({"size": s, "method": method, "trees": mode, "ms_per_alignment": per * 1e3})
                print(f"  §11.3 size {s:2d} {method:9s} {mode:17s}: {per * 1e3:8.3f} ms", flush=True)
    out["general"] = rows


def plot(out, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, mode in zip(axes, ("rooted/rooted", "rooted/unrooted", "unrooted/unrooted")):
        for method, style in (("alignment", "s-"), ("ha", "o-"), ("aha", "^-")):
            pts = [(r["size"], r["ms_per_alignment"]) for r in out["general"]
                   if r["trees"] == mode and r["method"] == method]
            if pts:
                x, y = zip(*pts)
                ax.plot(x, y, style, label={"alignment": "α", "ha": "η", "aha": "AHA"}[method])
        ax.set_title(f"§11.3 {mode}")
        ax.set_xlabel("tree size")
        ax.set_ylabel("ms / alignment")
        ax.set_yscale("log")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--n", type=int, default=None, help="data trees per frequency point")
    args = ap.parse_args()
    args.n_freq = args.n or (100 if args.quick else 1000)
    args.n_peer = 5 if args.quick else 20
    args.n_general = 8 if args.quick else 32
    if args.quick:
        args.repeat = min(args.repeat, 3)
    out = {"machine": machine(), "quick": args.quick}
    print("§11.4 frequencies (AHA, human rooted at the torso vs unrooted data; hand rooted/rooted)")
    frequencies(args, out)
    print("plain align(model, tree) vs Matcher(model).align(tree), human vs 11-vertex trees")
    plain_vs_matcher(args, out)
    print("peer: memoized recursion of the same propositions")
    peer_ratio(args, out)
    print("§11.3 general speed (n = %d trees, all pairs)" % args.n_general)
    general(args, out)
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = "alignment_speed_quick" if args.quick else "alignment_speed"
    plot(out, RESULTS / f"{name}.png")
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    t = out["targets"]
    lines = [f"# Alignment speed (thesis §11.3–11.4){' — quick' if args.quick else ''}", "",
             f"Machine: {out['machine']['cpu']}, {out['machine']['cores']} cores (shared), Python "
             f"{out['machine']['python']}, Numba {out['machine']['numba']}, {out['machine']['date']}. "
             "One process, one core; CPU time of the process, minimum over repeats.", "",
             "## Targets (AHA, human model rooted at the torso, unrooted data, no cut)", "",
             "| | ours | thesis (C++, 2.33 GHz) | target |", "|---|---:|---:|---:|",
             f"| mean over 10–12-vertex data trees, max degree 3–7 | {t['human_10_12_mean_per_s']:.0f}/s | "
             "≥ 708/s | ≥ 7,000/s |" if t["human_10_12_mean_per_s"] else "| mean 10–12 | n/a | | |",
             f"| mean over 10–12-vertex data trees, max degree 3–5 | {t['human_10_12_deg3_5_mean_per_s']:.0f}/s | "
             "| |" if t["human_10_12_deg3_5_mean_per_s"] else "| mean 10–12, deg 3–5 | n/a | | |",
             f"| 25-vertex degree-5 data trees | {t['human_25_deg5_per_s']:.0f}/s | ≥ 89/s (17 v.) | ≥ 900/s |"
             if t["human_25_deg5_per_s"] else "| 25 v. deg 5 | n/a | | |", "",
             "## The plain call vs the Matcher (human model, 11-vertex data trees, max degree 3–5)", "",
             "| `topopose.align(model, tree)` | `Matcher(model).align(tree)` | ratio | target (plain) |",
             "|---:|---:|---:|---:|",
             "| {plain_per_s:.0f}/s | {matcher_per_s:.0f}/s | {ratio:.2f} | ≥ 7,000/s |".format(
                 **out["plain_vs_matcher"]), "",
             "The plain call reuses the model's Matcher (a bounded LRU keyed by the model tree's "
             "content), so it pays only the key and the look-up per call.", "",
             "## §11.4 frequencies (alignments per second; second figure also builds `.arcs`)", "",
             "| model | cut | max deg | "
             + " | ".join(f"{s} v." for s in sorted({r['size'] for r in out['frequencies']})) + " |",
             "|---|---|---|" + "---:|" * len({r["size"] for r in out["frequencies"]})]
    sizes = sorted({r["size"] for r in out["frequencies"]})
    for model in ("human", "hand"):
        for cut in (False, True):
            for d in sorted({r["max_degree"] for r in out["frequencies"]}):
                cells = []
                for s in sizes:
                    r = [x for x in out["frequencies"] if x["model"] == model and x["cut"] == cut
                         and x["max_degree"] == d and x["size"] == s]
                    cells.append(f"{r[0]['per_s']:.0f} / {r[0]['per_s_with_arcs']:.0f}" if r else "")
                lines.append(f"| {model} | {cut} | {d} | " + " | ".join(cells) + " |")
    lines += ["", "## Peer: memoized recursion of the same propositions (same trees, same results)", "",
              "| method | size | max deg | ours /s | memoized /s | ratio |", "|---|---:|---:|---:|---:|---:|"]
    for r in out["peer"]:
        lines.append(f"| {r['method']} | {r['size']} | {r['max_degree']} | {r['ours_per_s']:.0f} | "
                     f"{r['memo_per_s']:.1f} | {r['ratio']:.0f}× |")
    lines += ["", f"## §11.3 general speed (n = {args.n_general} trees, all n² pairs, max degree 4)", "",
              "| size | method | trees | ms / alignment |", "|---:|---|---|---:|"]
    for r in out["general"]:
        lines.append(f"| {r['size']} | {r['method']} | {r['trees']} | {r['ms_per_alignment']:.3f} |")
    lines += ["", f"Figure: `{name}.png`."]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
