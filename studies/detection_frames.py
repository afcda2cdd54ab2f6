"""Pictures of the frames a named pose (§13.3.2.1) decides wrongly, on the development seeds.

For each frame given: the visual hull (max projections, front and side), the skeleton, the
points the detection compares (``topopose.apps.detect.description_parts``, crosses; the pose's
own crotch, dropped by ``pose/anatomy.py`` CROTCH_DROP, a small square) and the corresponding
ground-truth points (``applications.pipeline_points``, circles), with the decision and the
truth in the title. Development seeds only (capsule human 3–4, body 1–2: ``applications.py
--dev``); the frames are the wrong decisions that run lists.

Usage: python studies/detection_frames.py KIND SEED FRAME [FRAME ...] --pose NAME --out PNG
(KIND: upright, acrobatic or body).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

import applications as A  # noqa: E402

COLORS = {"head": "tab:red", "torso": "tab:orange", "crotch": "tab:purple", "hand_1": "tab:blue",
          "hand_2": "tab:cyan", "foot_1": "tab:green", "foot_2": "olive"}


def main(argv=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from topopose.synth.capture import synthetic_capture
    from topopose.apps.detect import description_parts, evaluate, load_library, up_frame
    from topopose.frame.estimate import FrameEstimator

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kind", choices=("upright", "acrobatic", "body"))
    ap.add_argument("seed", type=int)
    ap.add_argument("frames", nargs="+", type=int)
    ap.add_argument("--pose", required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    if a.kind == "body":
        with A.body_poses(A.body_detection_sampler()):
            cap = synthetic_capture("body", frames=40, seed=a.seed, noise=1, separated=True,
                                    margin=A.MARGIN)
        est = FrameEstimator(cap, "human", A.RES)
    else:
        cap = A.capture(A.detection_sampler(a.kind), 100, a.seed)
        est = FrameEstimator(cap, "human", A.RES, constraints=a.kind == "upright")
    library, aliases = load_library()
    expr = library[a.pose].expr
    R = up_frame(cap.up)
    fig, axes = plt.subplots(2, len(a.frames), figsize=(3.2 * len(a.frames), 7), squeeze=False)
    for j, fi in enumerate(a.frames):
        pose, det = est.estimate(cap.frames[fi], detail=True)
        gt = A.pipeline_points(cap.gt["frames"][pose.frame])
        parts = description_parts(pose)
        vol = det.volume
        idx = np.argwhere(vol.data)
        xyz = (np.asarray(vol.origin) + idx * vol.voxel_size) @ R.T
        sk = (np.asarray(vol.origin) + np.argwhere(det.skeleton) * vol.voxel_size) @ R.T \
            if det.skeleton is not None else np.zeros((0, 3))
        for i, (h, name) in enumerate(((0, "front (x, up)"), (1, "side (y, up)"))):
            ax = axes[i, j]
            ax.scatter(xyz[:, h], xyz[:, 2], s=1, c="0.85", lw=0)
            ax.scatter(sk[:, h], sk[:, 2], s=2, c="0.3", lw=0)
            for k, c in COLORS.items():
                if gt.get(k) is not None:
                    g = R @ np.asarray(gt[k], float)
                    ax.scatter(g[h], g[2], s=60, facecolors="none", edgecolors=c, lw=1.5)
                if parts.get(k) is not None:
                    p = R @ np.asarray(parts[k], float)
                    ax.scatter(p[h], p[2], s=60, marker="x", c=c, lw=1.5)
            if pose.parts.get("crotch") is not None:
                p = R @ np.asarray(pose.parts["crotch"], float)
                ax.scatter(p[h], p[2], s=25, marker="s", facecolors="none", edgecolors="tab:purple")
            ax.set_aspect("equal")
            ax.set_title(f"{a.kind} seed {a.seed} frame {pose.frame}\n"
                         f"{a.pose}: detected {evaluate(expr, parts, cap.up, aliases)}, "
                         f"truth {evaluate(expr, gt, cap.up, aliases)}" if i == 0 else name,
                         fontsize=8)
            ax.tick_params(labelsize=6)
    fig.suptitle("o truth point, x detection point, □ the pose's dropped crotch\ncolours: head "
                 "red, torso orange, crotch purple, hands blue/cyan, feet green", fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(a.out)


if __name__ == "__main__":
    main()
