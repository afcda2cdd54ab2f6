"""Draws docs/design_stages.png: topopose's stages in data-flow order and the data types between
them.

    python docs/design_stages.py [--out docs/design_stages.png]
"""
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

# (stage, package, what it does), in data-flow order; the data type each hands to the next
STAGES = [
    ("Capture", "capture/ · geometry/", "calibration, images or videos,\nsilhouette methods"),
    ("Visual hull", "hull/ · geometry/", "carve the voxels every\ncamera sees as subject"),
    ("Thinning", "topology/", "topology-preserving\nparallel thinning (D6I1D)"),
    ("Data tree", "skeleton/", "end and junction points,\nbranch lengths"),
    ("Alignment", "match/", "AHA of the model tree\ninto the data tree"),
    ("Placement, trust", "frame/", "parts placed on the hull,\nconfidence, gate"),
    ("Sequence", "sequence/", "identities, trim, kinematic\nskeleton, sides, consistency"),
    ("Outputs", "pose/ · apps/ · viz/", "poses.jsonl, TRC, C3D, BVH, CSV;\nsegment, detect, cluster"),
]
DATA = ["Capture\n(cameras, masks)", "Volume\n(bool grid, origin,\nvoxel size)", "skeleton\n(bool grid)",
        "Tree\n(vertices, weighted\nedges)", "Alignment\n(distance, mapping)",
        "Pose per frame\n(status, parts,\nconfidence)", "Motion\n(poses + joints,\nsides, flags)"]


def draw(out: Path) -> None:
    fig, ax = plt.subplots(figsize=(15, 7.4))
    ax.set_xlim(0, 15)
    ax.set_ylim(-0.5, 6.6)
    ax.axis("off")
    w, h = 2.9, 1.35
    xs = [0.3 + i * 3.65 for i in range(4)]
    pos = [(x, 3.9) for x in xs] + [(x, 0.9) for x in reversed(xs)]
    colours = ["#dbe9f6"] * 6 + ["#e3f1dc", "#f6e7d2"]
    for (name, pkg, what), (x, y), c in zip(STAGES, pos, colours):
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.05", fc=c, ec="#34495e"))
        ax.text(x + w / 2, y + h - 0.25, name, ha="center", va="center", fontsize=12, weight="bold")
        ax.text(x + w / 2, y + h - 0.55, pkg, ha="center", va="center", fontsize=9,
                family="monospace", color="#2c3e50")
        ax.text(x + w / 2, y + 0.33, what, ha="center", va="center", fontsize=8.5)
    for i, label in enumerate(DATA):
        (x0, y0), (x1, y1) = pos[i], pos[i + 1]
        if y0 == y1 and x1 > x0:                     # top row, left to right
            a, b = (x0 + w + 0.05, y0 + h / 2), (x1 - 0.05, y1 + h / 2)
            t = ((a[0] + b[0]) / 2, y0 + h + 0.45)
        elif y0 == y1:                               # bottom row, right to left
            a, b = (x0 - 0.05, y0 + h / 2), (x1 + w + 0.05, y1 + h / 2)
            t = ((a[0] + b[0]) / 2, y0 - 0.45)
        else:                                        # down the right-hand side
            a, b = (x0 + w / 2, y0 - 0.05), (x1 + w / 2, y1 + h + 0.05)
            t = (x0 + w / 2 - 1.05, (y0 + y1 + h) / 2)
        ax.add_patch(FancyArrowPatch(a, b, arrowstyle="-|>", mutation_scale=16, lw=1.6,
                                     color="#34495e"))
        ax.text(*t, label, ha="center", va="center", fontsize=8.5, style="italic", color="#7b241c")
    # the model tree enters at the alignment
    mx, my = pos[4][0] + w / 2, pos[4][1]
    ax.add_patch(FancyBboxPatch((mx + 0.35, 2.75), 1.7, 0.5, boxstyle="round,pad=0.04",
                                fc="#fdf2e9", ec="#7b241c", ls="--"))
    ax.text(mx + 1.2, 3.0, "Model tree (TOML)\npose/models/", ha="center", va="center", fontsize=8)
    ax.add_patch(FancyArrowPatch((mx + 0.9, 2.72), (mx + 0.5, my + h + 0.05), arrowstyle="-|>",
                                 mutation_scale=14, lw=1.2, color="#7b241c"))
    ax.text(7.5, 6.4, "topopose: the stages in data-flow order and the data between them",
            ha="center", fontsize=13, weight="bold")
    ax.text(7.5, -0.3, "per frame: blue  ·  over the sequence: green  ·  a stage imports only the "
            "stages before it", ha="center", fontsize=9, color="#555555")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    print(f"wrote {out}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).with_name("design_stages.png")))
    draw(Path(ap.parse_args().out))
