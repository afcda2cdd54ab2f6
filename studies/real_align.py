"""Why the alignment puts a part on the wrong leaf of the real recording, and the trunk rule.

    python studies/real_align.py [RECORDING] [--set key=value ...]

For every frame of the recording (``person`` silhouettes, as ``benchmarks/real.py``) scored
wrong while a data-tree leaf lies within 0.10 m of a wrong part's reference point (the
*alignment/placement* stage of ``studies/real_diagnose.py``), it compares the chosen
alignment with the *right mapping* built from Pose2Sim's 3D result: each leaf part on the data
leaf nearest its reference point, the torso on the tree median of the head and hand leaves,
the crotch on the median of the torso and the foot leaves; a part without a leaf within
0.10 m is deleted (missing) in it (details in :func:`right_mapping`). Both are costed with the same terms
(thesis §10, AHA with γ = |w − w′|, data normalized to total weight 1):

- *length*: Σ over the model arcs |w − L| (L: the data path's length; a deleted model arc
  costs w) + the data weight left off every matched path (deleted spurious branches);
- *thickness*: the arc cost term of ``FrameEstimator`` (``estimate.THICKNESS``);
- the coordinate constraints of the human model (a violated one forbids the mapping);
- *share edges*: two model arcs of the right mapping run over the same data edges (e.g. a
  hand's leaf branches off a leg's path: the data tree's topology is wrong there, and no
  alignment — a homeomorphism — can give the right mapping).

The chosen alignment's terms are its own (``al.distance``, ``matched_arc_cost``); *trunk
contracted*: its torso → crotch arc is deleted (both junctions on one data vertex). Each frame
gets the term that prefers the wrong mapping. The frames are computed twice, with the trunk
rule (``topopose.match.align.KEEP_CONSTRAINED_JUNCTIONS``) off and on, from the same hulls.

Writes ``results/real_align.md`` / ``.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import real  # noqa: E402
import real_diagnose  # noqa: E402

ARCS = (("torso", "head"), ("torso", "hand_1"), ("torso", "hand_2"), ("torso", "crotch"),
        ("crotch", "foot_1"), ("crotch", "foot_2"))
ABOVE = (("head", "torso"), ("torso", "crotch"), ("crotch", "foot_1"), ("crotch", "foot_2"))


def tree_path(adj, a, b):
    """Vertices and length of the data-tree path a → b."""
    prev = {a: None}
    stack = [a]
    while stack:
        x = stack.pop()
        for y, w in adj[x]:
            if y not in prev:
                prev[y] = (x, w)
                stack.append(y)
    out, length = [b], 0.0
    while out[-1] != a:
        x, w = prev[out[-1]]
        out.append(x)
        length += w
    return out[::-1], length


def tree_median(adj, a, b, c):
    """The vertex where the paths a → b and a → c part."""
    pb, _ = tree_path(adj, a, b)
    pc, _ = tree_path(adj, a, c)
    m = a
    for x, y in zip(pb, pc):
        if x != y:
            break
        m = x
    return m


def mapping_terms(est, data, arc_cost, M) -> dict:
    """Length and thickness terms of the mapping ``M`` (part → data vertex, None: deleted)."""
    weights = {(u, v): w for u, v, w in est.pattern.edges}
    adj = data.adjacency()
    lengths, edges, shared = {}, {}, set()
    arcs = [a for a in ARCS if M[a[1]] is not None]
    for a in arcs:
        p, L = tree_path(adj, M[a[0]], M[a[1]])
        for e in map(frozenset, zip(p[:-1], p[1:])):
            if e in edges:
                shared.add(f"{edges[e][1]}/{a[1]}")
            edges[e] = a
        lengths[a] = L
    length = (sum(abs(weights[a] - L) for a, L in lengths.items())
              + sum(weights[a] for a in ARCS if a not in lengths)
              + data.total_weight() - sum(lengths.values()))
    thick = 0.0
    if arc_cost is not None:
        C = arc_cost([a[0] for a in arcs], [a[1] for a in arcs], [M[a[0]] for a in arcs],
                     [M[a[1]] for a in arcs])
        thick = float(np.trace(np.asarray(C)))
    h = {p: float(data.positions[v] @ est.up) for p, v in M.items() if v is not None}
    return {"length": round(length, 3), "thickness": round(thick, 3),
            "violated": [f"{a} above {b}" for a, b in ABOVE if a in h and b in h and h[a] <= h[b]],
            "shared_edges": sorted(shared), "missing": [p for p, v in M.items() if v is None]}


def right_mapping(data, pts, ref_hip) -> dict:
    """Each leaf part on the data leaf nearest its reference point, or None (deleted, a
    missing part) when none lies within ``real_diagnose.LEAF_NEAR``; the torso on the tree
    median of the head and hand leaves (a foot leaf for a missing one), the crotch on the
    median of the torso and the foot leaves (with a foot missing: the vertex of the path torso
    → the other foot nearest the mid-hip reference)."""
    leaves = [v for v in data.vertices if data.degree(v) == 1]

    def near(P):
        v = min(leaves, key=lambda v: float(np.linalg.norm(data.positions[v] - P)))
        return v if np.linalg.norm(data.positions[v] - P) <= real_diagnose.LEAF_NEAR else None

    M = {"head": near(pts["head"]), "hand_1": near(pts["hand_L"]), "hand_2": near(pts["hand_R"]),
         "foot_1": near(pts["foot_L"]), "foot_2": near(pts["foot_R"])}
    adj = data.adjacency()
    up = [M[k] for k in ("head", "hand_1", "hand_2") if M[k] is not None]
    feet = [M[k] for k in ("foot_1", "foot_2") if M[k] is not None]
    if len(up) + len(feet) < 3 or not feet or len(set(up + feet)) < len(up + feet):
        return None
    M["torso"] = tree_median(adj, *(up + feet)[:3]) if len(up) >= 2 else None
    if M["torso"] is None:
        return None
    if len(feet) == 2:
        M["crotch"] = tree_median(adj, M["torso"], *feet)
    else:
        path, _ = tree_path(adj, M["torso"], feet[0])
        M["crotch"] = min(path, key=lambda v: float(np.linalg.norm(data.positions[v] - ref_hip)))
    return M


def cause(ch, rt) -> str:
    if rt["violated"]:
        return "right mapping violates a constraint"
    if rt["shared_edges"]:
        return "no tree alignment gives it: " + ", ".join(rt["shared_edges"]) + " share edges"
    if ch["trunk_contracted"]:
        return "trunk contracted"
    dl = rt["length"] - ch["length"]
    dt = rt["thickness"] - ch["thickness"]
    if dl <= 0 and dt <= 0:
        return "right mapping cheaper (placement)"
    if dl > 0 and dt > 0:
        return "length and thickness"
    return "length" if dl > 0 else "thickness"


def run(est, cap, ref, volumes) -> dict:
    from topopose.frame.thickness import matched_arc_cost

    est.hull = lambda name: volumes[name]
    rows, right = [], 0
    per = {"hand": [], "foot": [], "head": []}
    for i, f, p, det, e in real.estimated_frames(est, cap, ref):
        if e is None:
            rows.append({"frame": f, "failed": p.error})
            continue
        per["head"].append(e["head"])
        per["hand"] += [e["hand_L"], e["hand_R"]]
        per["foot"] += [e["foot_L"], e["foot_R"]]
        bad = {k: round(v, 3) if np.isfinite(v) else None for k, v in e.items() if v > real.RIGHT}
        right += not bad
        if not bad:
            continue
        data, al = det.data, det.alignment
        pts = real_diagnose.reference_points(ref, i)
        leaves = np.array([data.positions[v] for v in data.vertices if data.degree(v) == 1])
        near = {k: float(np.min(np.linalg.norm(leaves - pts[k], axis=1))) for k in bad}
        placeable = [k for k in bad if near[k] <= real_diagnose.LEAF_NEAR]
        row = {"frame": f, "wrong": bad, "leaves": len(leaves), "placeable": placeable}
        if placeable:
            arc_cost = est.arc_cost(det.volume, data)
            thick = matched_arc_cost(al, arc_cost)
            deleted = {frozenset(e) for e in (al.deleted_pattern or [])}
            ch = {"length": round(float(al.distance) - thick, 3), "thickness": round(thick, 3),
                  "trunk_contracted": frozenset(("torso", "crotch")) in deleted}
            g = {k: v[i] for k, v in ref.items()}
            R = right_mapping(data, pts, (g["LHip"] + g["RHip"]) / 2)
            if R is None:
                row.update(chosen=ch, cause="no right mapping (two parts share a leaf or lack one)")
            else:
                rt = mapping_terms(est, data, arc_cost, R)
                row.update(chosen=ch, right=rt, cause=cause(ch, rt))
        rows.append(row)
    stats = {}
    for k, v in per.items():
        v = np.asarray(v, float)
        stats[k] = {"median": round(float(np.median(v)), 3),
                    "p90": round(float(np.percentile(v, 90)), 3),
                    "over_0.5m": int(np.sum(v > 0.5))}
    return {"right": right, "frames": len(cap.frames), "errors": stats, "rows": rows}


def main(argv=None):
    from _machine import machine
    from topopose.frame.estimate import FrameEstimator

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording", nargs="?", default=str(real.DEFAULT))
    ap.add_argument("--set", action="append", default=[],
                    help="extra [silhouettes] setting, as studies/real_diagnose.py")
    ap.add_argument("--out", default=str(HERE / "results" / "real_align"))
    a = ap.parse_args(argv)
    opened = real.open_recording(a.recording)
    if opened is None:
        return 2
    rec, ref = opened
    runs = {}
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = real.person_capture(rec, Path(tmp) / "c", a.set)
        est = FrameEstimator(cap, "human", 100, gate=False)
        volumes = {cap.frame_name(f): est.hull(cap.frame_name(f)) for f in cap.frames}
        for name, keep in (("trunk rule off", False), ("trunk rule on (default)", True)):
            runs[name] = run(FrameEstimator(cap, "human", 100, gate=False, keep_junctions=keep),
                             cap, ref, volumes)
    doc = {"machine": machine(), "settings": a.set, "runs": runs}
    Path(a.out).with_suffix(".json").write_text(json.dumps(doc, indent=1))
    L = ["# Real recording: why the alignment chooses a wrong leaf, and the trunk rule", "",
         "Written by `studies/real_align.py` (the definitions are in its docstring; "
         f"settings {a.set or 'default'}; `person` silhouettes, 100³, gate off).", "",
         "| run | right frames | head median / p90 m | hands median / p90 m | feet median / p90 m "
         "| parts > 0.5 m |", "| --- | --- | --- | --- | --- | --- |"]
    for name, r in runs.items():
        s = r["errors"]
        L.append(f"| {name} | {r['right']} / {r['frames']} | "
                 + " | ".join(f"{s[k]['median']} / {s[k]['p90']}" for k in ("head", "hand", "foot"))
                 + f" | {sum(s[k]['over_0.5m'] for k in s)} |")
    for name, r in runs.items():
        causes = {}
        for row in r["rows"]:
            if "cause" in row:
                k = row["cause"].split(":")[0]
                causes[k] = causes.get(k, 0) + 1
        L += ["", f"## {name}", "", "Frames with a wrong part that has a leaf within 0.10 m, by "
              "the term that prefers the chosen (wrong) mapping: "
              + ", ".join(f"{k} {v}" for k, v in sorted(causes.items(), key=lambda x: -x[1])) + ".",
              "", "| frame | wrong parts (m) | leaves | chosen length / thickness | trunk contracted "
              "| right length / thickness | right violates | cause |",
              "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for row in r["rows"]:
            if "cause" not in row:
                continue
            ch, rt = row["chosen"], row.get("right") or {"length": "–", "thickness": "–",
                                                          "violated": []}
            wrong = ", ".join(f"{k} {v}" for k, v in row["wrong"].items())
            L.append(f"| {row['frame']} | {wrong} | {row['leaves']} | {ch['length']} / "
                     f"{ch['thickness']} | {'yes' if ch['trunk_contracted'] else ''} | "
                     f"{rt['length']} / {rt['thickness']} | {', '.join(rt['violated'])} | "
                     f"{row['cause']} |")
    Path(a.out).with_suffix(".md").write_text("\n".join(L) + "\n")
    print("\n".join(L[:8]), f"\nwrote {a.out}.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
