"""A frame as a picture a person can read: visual hull (light), curve skeleton, data tree,
labelled parts, and the model tree beside it; optionally the silhouettes with the parts
reprojected (thesis Fig. 12.8 outputs, Fig. 13.8)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy import ndimage

from topopose.geometry.axes import up_rotation


def part_colours(parts) -> dict:
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if len(parts) <= 10 else "tab20"]
    return {p: cmap(i % cmap.N) for i, p in enumerate(parts)}


def _surface(a: np.ndarray) -> np.ndarray:
    return a & ~ndimage.binary_erosion(a, border_value=0)


def draw_model_tree(ax, model, colours):
    """The model tree as a graph (layout by networkx), edges labelled with relative lengths."""
    import networkx as nx

    g = model.tree.to_networkx()
    fin = [w for _, _, w in model.tree.edges if math.isfinite(w)]
    total = sum(fin) or 1.0
    for u, v, d in g.edges(data=True):
        d["len"] = 1.0 if not math.isfinite(d["weight"]) else 0.5 + 3 * d["weight"] / total
    try:
        pos = nx.kamada_kawai_layout(g, weight="len")
    except Exception:
        pos = nx.spring_layout(g, seed=0)
    for u, v, d in g.edges(data=True):
        (x0, y0), (x1, y1) = pos[u], pos[v]
        inf = not math.isfinite(d["weight"])
        ax.plot([x0, x1], [y0, y1], color="0.4", ls=":" if inf else "-", lw=1.5, zorder=1)
        lab = "∞" if inf else f"{d['weight'] / total:.2f}"
        ax.text((x0 + x1) / 2, (y0 + y1) / 2, lab, fontsize=7, color="0.3", ha="center",
                va="center", bbox=dict(fc="white", ec="none", alpha=0.7, pad=0.5))
    for p, (x, y) in pos.items():
        ax.scatter([x], [y], s=160 if p == model.root else 90, color=colours[p],
                   edgecolors="k", linewidths=1.5 if p == model.root else 0.5, zorder=2)
        ax.text(x, y + 0.09, str(p), fontsize=8, ha="center", va="bottom", zorder=3)
    cons = []
    for c in model.constraints:
        if c.kind == "between":
            cons.append(f"between (R_{c.relation or 'b'}): " + ", ".join(c.parts))
        else:
            cons.append(f"{c.parts[0]} {c.kind} {c.parts[1]}" + (f" ({c.axis})" if c.axis else ""))
    ax.set_title(f"model '{model.name}' ({'complete' if model.complete else 'incomplete'}, "
                 f"root {model.root})", fontsize=9, pad=14)
    if cons:
        ax.text(0.5, -0.02, "\n".join(cons), transform=ax.transAxes, fontsize=7, ha="center",
                va="top")
    ax.set_aspect("equal")
    ax.margins(0.18)
    ax.axis("off")


def _label_positions(points: dict):
    """Label anchors pushed outwards from the parts' centre (so neighbouring parts' labels do
    not sit on each other), then spread vertically where two still come close."""
    if not points:
        return []
    P = np.array(list(points.values()), dtype=float)
    c = P.mean(0)
    ext = max(float(np.ptp(P, axis=0).max()), 1e-6)
    out = []
    for (name, w) in points.items():
        d = w - c
        d[2] *= 0.3                                  # mostly sideways
        n = np.linalg.norm(d)
        d = d / n if n > 1e-9 else np.array([1.0, 0, 0])
        out.append([name, w + d * 0.12 * ext, "left" if d[0] >= 0 else "right"])
    gap = 0.06 * ext                                 # spread labels closer than this
    out.sort(key=lambda t: t[1][2])
    for i in range(1, len(out)):
        for j in range(i):
            a, b = out[j][1], out[i][1]
            if np.linalg.norm((a - b)[:2]) < 2 * gap and abs(a[2] - b[2]) < gap:
                b[2] = a[2] + gap
    return [tuple(t) for t in out]


def render_frame(path, model, pose, detail=None, cap=None, silhouettes=False, up=(0, 0, 1),
                 title=None, max_hull_points=12000):
    """Draw one frame to ``path`` (PNG).

    Parameters
    ----------
    model : Model
    pose : Pose
    detail : FrameDetail, optional
        Hull, skeleton, data tree of the frame (from ``FrameEstimator.estimate(f, detail=True)``).
    cap : Capture, optional
        Needed for ``silhouettes=True`` (silhouettes with the parts reprojected).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from topopose.sequence.chirality import numbered
    pose = numbered(pose, model)           # left_hand → hand_1: the model's part names
    colours = part_colours(model.parts)
    R = up_rotation(up)
    ncam = len(cap.cameras) if (silhouettes and cap is not None) else 0
    srows = math.ceil(ncam / 4) if ncam else 0
    fig = plt.figure(figsize=(13, 7 + 2.6 * srows), dpi=100)
    gs = fig.add_gridspec(1 + srows, 4, height_ratios=[7] + [2.6] * srows, left=0.03,
                          right=0.97, bottom=0.02, top=0.95, wspace=0.15, hspace=0.2)
    ax = fig.add_subplot(gs[0, :3], projection="3d")
    axm = fig.add_subplot(gs[0, 3])

    pts_all = []
    if detail is not None and detail.volume is not None:
        vol = detail.volume
        surf = np.argwhere(_surface(vol.data))
        if len(surf) > max_hull_points:
            surf = surf[np.random.default_rng(0).choice(len(surf), max_hull_points, replace=False)]
        if len(surf):
            w = vol.world(surf) @ R.T
            ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=4, color="#4292c6", alpha=0.22,
                       depthshade=False, label="visual hull", rasterized=True)
            pts_all.append(w)
        if detail.skeleton is not None:
            sk = np.argwhere(detail.skeleton)
            if len(sk):
                w = vol.world(sk) @ R.T
                ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=3, color="0.25", depthshade=False,
                           label="skeleton (D6I1D)")
    if detail is not None and detail.data is not None:
        t = detail.data
        adj = t.adjacency()
        first = True
        for u, v, _ in t.edges:
            pu, pv = t.positions.get(u), t.positions.get(v)
            if pu is None or pv is None:
                continue
            seg = np.stack([pu, pv]) @ R.T
            ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="#6a3d9a", lw=2.0, alpha=0.9,
                    label="data tree" if first else None)
            first = False
        vs = [v for v in t.vertices if t.positions.get(v) is not None]
        if vs:
            w = np.stack([t.positions[v] for v in vs]) @ R.T
            deg = np.array([len(adj[v]) for v in vs])
            ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=np.where(deg == 1, 14, 24),
                       color="#756bb1", marker="s", depthshade=False)
    placed = {p: x for p, x in pose.parts.items() if x is not None}
    for a, b, _ in model.tree.edges:
        if a in placed and b in placed:
            seg = np.stack([placed[a], placed[b]]) @ R.T
            ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="k", lw=1.2, alpha=0.45, ls="--")
    for p, x in placed.items():
        w = np.asarray(x) @ R.T
        ax.scatter([w[0]], [w[1]], [w[2]], s=90, color=colours.get(p, "k"), edgecolors="k",
                   depthshade=False, zorder=5)
        pts_all.append(w[None])
    for p, w, ha in _label_positions({p: np.asarray(x) @ R.T for p, x in placed.items()}):
        ax.text(w[0], w[1], w[2], str(p), fontsize=9, fontweight="bold", zorder=6, ha=ha,
                va="center", bbox=dict(fc="white", ec="none", alpha=0.75, pad=0.8))
    if pts_all:
        allp = np.concatenate(pts_all)
        lo, hi = allp.min(0), allp.max(0)
        c, r = (lo + hi) / 2, max((hi - lo).max() / 2, 1e-6) * 1.05
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(c[2] - r, c[2] + r)
        ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=12, azim=-60)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("up")
    ax.tick_params(labelsize=6)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", fontsize=8, markerscale=3)
    dist = "—" if pose.distance is None else f"{pose.distance:.3f}"
    head = title or f"frame {pose.frame}: {pose.status}, AHA distance {dist}"
    if pose.error:
        head += f"\n{pose.error}"
    ax.set_title(head, fontsize=10)
    draw_model_tree(axm, model, colours)

    if ncam:
        sils = cap.silhouettes(pose.frame)
        for i, (camera, sil) in enumerate(zip(cap.cameras, sils)):
            a = fig.add_subplot(gs[1 + i // 4, i % 4])
            uv = None
            a.imshow(sil, cmap="gray", vmin=0, vmax=1.6)
            ys, xs = np.nonzero(sil)
            if placed:
                names = list(placed)
                uv = camera.project(np.stack([placed[p] for p in names]))
                for a_, b_, _ in model.tree.edges:
                    if a_ in placed and b_ in placed:
                        i0, i1 = names.index(a_), names.index(b_)
                        a.plot(uv[[i0, i1], 0], uv[[i0, i1], 1], color="w", lw=1)
                for p, (x, y) in zip(names, uv):
                    a.scatter([x], [y], s=20, color=colours[p], edgecolors="k", linewidths=0.5)
            if len(xs):                    # crop to the subject (largest blob ± margin)
                x0, x1 = np.percentile(xs, [0.5, 99.5])
                y0, y1 = np.percentile(ys, [0.5, 99.5])
                if placed:
                    ok = np.isfinite(uv).all(axis=1)
                    x0, x1 = min(x0, uv[ok, 0].min()), max(x1, uv[ok, 0].max())
                    y0, y1 = min(y0, uv[ok, 1].min()), max(y1, uv[ok, 1].max())
                r = max(x1 - x0, y1 - y0) * 0.6 + 10
                cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
                a.set_xlim(cx - r, cx + r)
                a.set_ylim(cy + r, cy - r)
            a.set_title(camera.name, fontsize=8)
            a.axis("off")
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
