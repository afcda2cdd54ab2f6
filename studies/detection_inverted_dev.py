"""Where the capsule human's hands are in inverted frames, on fresh development seeds.

Thesis §13.3.2.1 (specific pose detection): `ask a question` and `hands up` compare a hand's
height with the head's along the capture's up axis. Held out (``benchmarks/applications.py``,
*human acrobatic*, seeds 1–2) the wrong ask-a-question decisions have the pipeline's hands on
average 19 cm below their truth points, while on the development seeds 3–4 the inverted hands
are unbiased. This script draws more development sequences with the same generator and settings
as the acrobatic rows (``detection_sampler("acrobatic")``, 100 frames, noise 1, limbs separated,
100³, ``FrameEstimator(constraints=False)``) on seeds not used by any reported set (20–25) and
counts the hands ≥ 10 cm below (or above) their truth points (``pipeline_points``: the middle of
the hand's last bone) along up, per generator tag, and the parts each wrong decision hangs on
(``applications.detection_row``'s blame). Writes ``results/detection_inverted_dev.{md,json}`` and
pictures of the most telling frames (``results/detection_inverted_hands_dev_*.png``).
Usage: ``python studies/detection_inverted_dev.py [--seeds 20 21 ...] [--frames 100]``.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _machine import machine  # noqa: E402

import applications as A  # noqa: E402

HANDS = ("hand_1", "hand_2")


def frame_figure(path, det, pose, gt, up, title):
    """Hull (grey), skeleton (black), pipeline parts (red, labelled) and their truth points
    (blue) of one frame, seen from the front and from the side (up vertical)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from topopose.viz.view import _up_rotation

    R = _up_rotation(_up(up))
    gt = dict(gt)
    for a, b in (("hand_1", "hand_2"), ("foot_1", "foot_2")):    # paired optimally
        P, G = pose.parts, {k: None if v is None else np.asarray(v, float) for k, v in gt.items()}
        if all(x is not None for x in (P.get(a), P.get(b), G.get(a), G.get(b))) and (
                np.linalg.norm(P[a] - G[b]) + np.linalg.norm(P[b] - G[a])
                < np.linalg.norm(P[a] - G[a]) + np.linalg.norm(P[b] - G[b])):
            gt[a], gt[b] = gt[b], gt[a]
    vol = det.volume
    w = vol.world(np.argwhere(vol.data)) @ R.T
    s = vol.world(np.argwhere(det.skeleton)) @ R.T
    c = w[:, :2].mean(0)
    xy = w[:, :2] - c
    _, vec = np.linalg.eigh(xy.T @ xy)
    fig, axs = plt.subplots(1, 2, figsize=(10, 6), dpi=70)
    for ax, v, name in zip(axs, (vec[:, 1], vec[:, 0]), ("front", "side")):
        ax.scatter((w[:, :2] - c) @ v, w[:, 2], s=4, c="0.85", lw=0)
        ax.scatter((s[:, :2] - c) @ v, s[:, 2], s=5, c="k", lw=0)
        for k, x in pose.parts.items():
            if x is None:
                continue
            p = np.asarray(x, float) @ R.T
            ax.plot((p[:2] - c) @ v, p[2], "o", color="red", ms=6)
            ax.annotate(k, ((p[:2] - c) @ v, p[2]), color="red", fontsize=8)
            if gt.get(k) is not None:
                q = np.asarray(gt[k], float) @ R.T
                ax.plot((q[:2] - c) @ v, q[2], "x", color="blue", ms=7, mew=2)
                ax.plot([(p[:2] - c) @ v, (q[:2] - c) @ v], [p[2], q[2]], "b:", lw=1)
        ax.set_aspect("equal")
        ax.set_title(f"{name} (red: pipeline, blue x: truth point)", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[20, 21, 22, 23, 24, 25])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    from topopose.frame.estimate import FrameEstimator

    t0 = time.time()
    rows, caps = [], {}
    for seed in a.seeds:
        cap = A.capture(A.detection_sampler("acrobatic"), a.frames, seed)
        est = FrameEstimator(cap, "human", A.RES, constraints=False)
        caps[seed] = (cap, est)
        rng = np.random.default_rng(0)
        for fi, f in enumerate(cap.frames):
            p = est.estimate(f)
            row = {"seed": seed, "frame": fi, "tag": cap.options["bodies"][fi].extra.get("k"),
                   "status": p.status}
            if p.status == "matched":
                gt = A.pipeline_points(cap.gt["frames"][p.frame])
                r = A.detection_row(p, cap.gt["frames"][p.frame], cap.up, rng)
                row.update(offsets=r["part_offsets"],
                           wrong={n: {"value": d["m0"], "truth": d["truth"], "blame": d.get("blame")}
                                  for n, d in r["detect"].items()
                                  if d["m0"] is not None and d["m0"] != d["truth"]},
                           truth_up={k: float(np.asarray(gt[k], float) @ _up(cap.up))
                                     for k in HANDS + ("head",) if gt.get(k) is not None})
            rows.append(row)
        print(f"seed {seed}: {sum(r['seed'] == seed and r['status'] == 'matched' for r in rows)}"
              f"/{a.frames} matched", flush=True)

    # ---- counts
    summary = {}
    for tag in ("inverted", "random"):
        rs = [r for r in rows if r["tag"] == tag and r["status"] == "matched"]
        dz = np.array([r["offsets"][h][0] for r in rs for h in HANDS if h in r["offsets"]])
        near = dz[np.abs(dz) < 0.3]
        summary[tag] = {"frames": sum(r["tag"] == tag for r in rows), "matched": len(rs),
                        "hands": int(dz.size), "below_10cm": int((dz <= -0.10).sum()),
                        "above_10cm": int((dz >= 0.10).sum()),
                        "mean": float(dz.mean()), "median": float(np.median(dz)),
                        "sd": float(dz.std()), "mean_within_30cm": float(near.mean()),
                        "sd_within_30cm": float(near.std())}
    wrong = []
    for r in rows:
        for n, d in (r.get("wrong") or {}).items():
            if n in ("ask-a-question", "hands-up"):
                wrong.append({"seed": r["seed"], "frame": r["frame"], "tag": r["tag"], "pose": n,
                              **d, "dz": {k: r["offsets"][k][0] for k in d["blame"] or []
                                          if k in r["offsets"]},
                              "truth_up": r["truth_up"]})

    # ---- pictures: the hand farthest below its truth point (any tag), the hand farthest
    # above (inverted), a wrong inverted decision whose blamed hand is within 5 cm of its truth
    def worst(sign, tag=None):
        c = [(sign * r["offsets"][h][0], r, h) for r in rows if r["status"] == "matched"
             and (tag is None or r["tag"] == tag) for h in HANDS if h in r["offsets"]]
        return max(c, key=lambda t: t[0]) if c else None
    picks = []
    b = worst(-1)
    if b:
        picks.append(("below", b[1], f"{b[2]} {-b[0] * 100:.0f} cm below its truth point"))
    b = worst(+1, "inverted")
    if b:
        picks.append(("above", b[1], f"{b[2]} {b[0] * 100:+.0f} cm along up from its truth point"))
    floor = [w for w in wrong if w["tag"] == "inverted" and w["pose"] == "ask-a-question"
             and w["dz"] and all(abs(v) < 0.05 for v in w["dz"].values())]
    if floor:
        w = floor[0]
        r = next(r for r in rows if r["seed"] == w["seed"] and r["frame"] == w["frame"])
        picks.append(("floor", r, f"ask-a-question {w['value']} (truth {w['truth']}), blamed "
                      + ", ".join(f"{k} {v * 100:+.1f} cm" for k, v in w["dz"].items())))
    figs = []
    for name, r, what in picks:
        cap, est = caps[r["seed"]]
        pose, det = est.estimate(cap.frames[r["frame"]], detail=True)
        path = out / f"detection_inverted_hands_dev_{name}.png"
        frame_figure(path, det, pose, A.pipeline_points(cap.gt["frames"][pose.frame]), cap.up,
                     f"seed {r['seed']} frame {r['frame']} ({r['tag']}): {what}")
        figs.append(path.name)

    mach = machine(resolution=A.RES, wall_s=round(time.time() - t0, 1))
    (out / "detection_inverted_dev.json").write_text(json.dumps(
        {"machine": mach, "seeds": a.seeds, "summary": summary, "wrong": wrong,
         "figures": figs}, indent=1))
    L = ["# Hands in inverted frames, fresh development seeds (thesis §13.3.2.1)", "",
         f"Machine: {mach['cpu']}, {mach['cores']} cores, load {mach['load_average']}, {mach['date']}; "
         f"wall time {mach['wall_s']} s. Produced by "
         "`studies/detection_inverted_dev.py`.", "",
         f"Capsule human, `detection_sampler(\"acrobatic\")`, seeds {a.seeds} × {a.frames} "
         "frames (none used by a reported set), no coordinate constraints. Offset = pipeline "
         "hand − its truth point (mid-hand) along the capture's up axis; hands paired optimally.",
         "", "| tag | frames | matched | hands | ≤ −10 cm | ≥ +10 cm | mean | median | sd | "
         "mean / sd within 30 cm |", "|---|---|---|---|---|---|---|---|---|---|"]
    for tag, s in summary.items():
        L.append(f"| {tag} | {s['frames']} | {s['matched']} | {s['hands']} | {s['below_10cm']} | "
                 f"{s['above_10cm']} | {s['mean']:+.3f} | {s['median']:+.3f} | {s['sd']:.3f} | "
                 f"{s['mean_within_30cm']:+.3f} / {s['sd_within_30cm']:.3f} |")
    L += ["", "Wrong `ask-a-question` / `hands-up` decisions (margin 0): blamed parts and their "
          "offsets along up (m); truth heights of head and hands (m).", "",
          "| seed | frame | tag | pose | detected / truth | blamed: offset | truth up: head, hand_1, hand_2 |",
          "|---|---|---|---|---|---|---|"]
    for w in wrong:
        tu = w["truth_up"]
        L.append(f"| {w['seed']} | {w['frame']} | {w['tag']} | {w['pose']} | {w['value']} / "
                 f"{w['truth']} | " + (", ".join(f"{k} {v:+.3f}" for k, v in w["dz"].items())
                                       or "none") + " | "
                 + ", ".join(f"{tu.get(k, float('nan')):.2f}" for k in ("head",) + HANDS) + " |")
    L += ["", "Pictures: " + ", ".join(f"`{f}`" for f in figs), ""]
    (out / "detection_inverted_dev.md").write_text("\n".join(L))
    print("\n".join(L))


def _up(up):
    from topopose.apps.detect import up_frame

    return up_frame(up)[2]


if __name__ == "__main__":
    main()
