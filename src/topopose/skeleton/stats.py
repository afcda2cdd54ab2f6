"""Statistics on data trees over a capture (thesis §11.4.1, Fig. 11.8–11.11).

For each grid resolution, every frame goes through visual hull → D6I1D
thinning → data tree, and the distributions of the tree sizes (vertex counts)
and maximal degrees are tabulated and drawn.  These sizes bound the cost of
the alignment (its complexity depends on the data tree's size and degree).
"""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from time import perf_counter

import numpy as np

from topopose.errors import InputError
from topopose.skeleton.tree import data_tree


def tree_stats(capture, resolutions=(50, 100, 150), method="d6i1d", frames=None,
               incomplete=False, progress=False) -> dict:
    """Data-tree sizes and maximal degrees of every frame at each resolution.

    Parameters
    ----------
    capture : Capture or path
        A capture (see :func:`topopose.load_capture`).
    resolutions : sequence of int
        Grid resolutions (voxels along the longest side of the capture volume).
    method : str
        Thinning method (:func:`topopose.thin`).
    frames : list of str, optional
        Frame names; all frames by default.
    incomplete : bool
        Incomplete model (§7.3.3.1, §12.1): thin with the border constraint and
        build trees with ``border="grid"``.
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        ``{resolution: {"frames": [...], "n_vertices": [...], "max_degree": [...],
        "cycles": [...], "time_ms": {"hull": [...], "thin": [...], "tree": [...]},
        "failed": {frame: reason}}}``.
    """
    from topopose.capture import Capture
    from topopose.hull import visual_hull
    from topopose.topology import border_constraint, thin

    if not isinstance(capture, Capture):
        from topopose.capture import load_capture

        capture = load_capture(capture)
    frames = list(capture.frames if frames is None else frames)
    try:
        resolutions = [int(r) for r in resolutions]
    except (TypeError, ValueError):
        raise InputError(f"resolutions: expected integers, got {resolutions!r}") from None
    if not resolutions or min(resolutions) < 8:
        raise InputError(f"resolutions: expected integers >= 8, got {resolutions}")
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(frames) * len(resolutions), unit="frame", desc="tree stats")
    out = {}
    for res in resolutions:
        rec = {"frames": [], "n_vertices": [], "max_degree": [], "cycles": [],
               "time_ms": {"hull": [], "thin": [], "tree": []}, "failed": {}}
        for f in frames:
            try:
                t0 = perf_counter()
                vol = visual_hull(capture, f, resolution=res)
                t1 = perf_counter()
                keep = border_constraint(vol.data) if incomplete else None
                skel = thin(vol.data, method=method, keep=keep)
                t2 = perf_counter()
                tree = data_tree(skel, origin=vol.origin, voxel_size=vol.voxel_size,
                                 border="grid" if incomplete else None)
                t3 = perf_counter()
            except InputError as exc:
                rec["failed"][str(f)] = str(exc)
            else:
                d = tree.diagnostics
                rec["frames"].append(str(f))
                rec["n_vertices"].append(tree.n_vertices)
                rec["max_degree"].append(tree.max_degree())
                rec["cycles"].append(d["cycles_broken"] + d["loops"])
                rec["time_ms"]["hull"].append((t1 - t0) * 1e3)
                rec["time_ms"]["thin"].append((t2 - t1) * 1e3)
                rec["time_ms"]["tree"].append((t3 - t2) * 1e3)
            if bar is not None:
                bar.update()
        out[res] = rec
    if bar is not None:
        bar.close()
    return out


def stats_table(stats: dict) -> str:
    """A Markdown table of :func:`tree_stats` results."""
    lines = ["| resolution | frames | failed | vertices: min / median / mean / max | "
             "max degree: distribution | frames with cycles | tree ms (median) |",
             "|---|---|---|---|---|---|---|"]
    for res, r in stats.items():
        nv = np.asarray(r["n_vertices"])
        if nv.size == 0:
            lines.append(f"| {res} | 0 | {len(r['failed'])} | – | – | – | – |")
            continue
        deg = Counter(r["max_degree"])
        dist = ", ".join(f"{k}: {deg[k]}" for k in sorted(deg))
        cyc = sum(c > 0 for c in r["cycles"])
        lines.append(f"| {res} | {nv.size} | {len(r['failed'])} | {nv.min()} / {np.median(nv):g} / "
                     f"{nv.mean():.1f} / {nv.max()} | {dist} | {cyc} | "
                     f"{np.median(r['time_ms']['tree']):.2f} |")
    return "\n".join(lines)


def stats_figure(stats: dict, path, title="") -> None:
    """Histograms of data-tree sizes and maximal degrees per resolution (Fig. 11.8–11.11)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    ress = [r for r in stats if stats[r]["n_vertices"]]
    width = 0.8 / max(len(ress), 1)
    for ax, key, label in ((axes[0], "n_vertices", "data tree size (vertices)"),
                           (axes[1], "max_degree", "maximal degree")):
        allv = [v for r in ress for v in stats[r][key]]
        if not allv:
            continue
        xs = np.arange(min(allv), max(allv) + 1)
        for i, r in enumerate(ress):
            vals = np.asarray(stats[r][key])
            freq = np.array([(vals == x).mean() for x in xs])
            ax.bar(xs + (i - (len(ress) - 1) / 2) * width, freq, width, label=f"{r}³ grid")
        ax.set_xlabel(label)
        ax.set_ylabel("fraction of frames")
        ax.set_xticks(xs)
        ax.legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def tree_stats_cli(capture_path, out=None, resolutions=(50, 100, 150), incomplete=False) -> int:
    """``topopose tree --stats CAPTURE [--out STATS.png]``: table, PNG and JSON.

    Prints the Markdown table; writes the histogram PNG to ``out`` (default
    ``<capture name>_tree_stats.png`` in the current directory) and, beside it,
    the table (``.md``) and the per-frame numbers (``.json``).  Returns the exit
    status: 0, or 1 when some frames failed (empty hull...).
    """
    path = Path(capture_path)
    stats = tree_stats(path, resolutions=resolutions, incomplete=incomplete, progress=True)
    png = Path(out) if out is not None else Path(f"{path.resolve().name}_tree_stats.png")
    if png.suffix.lower() != ".png":
        png = png.with_suffix(".png")
    table = stats_table(stats)
    print(table)
    from topopose._paths import atomic_output

    with atomic_output(png, "--out") as tmp:
        stats_figure(stats, tmp, title=f"data trees of {path.name}")
    with atomic_output(png.with_suffix(".md"), "--out") as tmp:
        tmp.write_text(f"# Data-tree statistics: {path}\n\n{table}\n")
    with atomic_output(png.with_suffix(".json"), "--out") as tmp:
        tmp.write_text(json.dumps({str(k): v for k, v in stats.items()}, indent=1))
    print(f"wrote {png}, {png.with_suffix('.md')}, {png.with_suffix('.json')}")
    failed = sum(len(r["failed"]) for r in stats.values())
    for res, r in stats.items():
        for f, why in r["failed"].items():
            print(f"resolution {res}, frame {f}: failed: {why}")
    return 1 if failed else 0
