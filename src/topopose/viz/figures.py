"""Figures of a run: AHA distance per frame with the quality classes, and the threshold study
of thesis §13.2.2 (Fig. 13.4–13.7: TP rate, FP rate and FP per match against T_d)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from topopose.frames import sort_poses

CLASS_COLOURS = {"good": "#2ca02c", "missing limb": "#98df8a", "partial": "#ffbb78",
                 "misplaced": "#ff7f0e", "bad": "#d62728", "none": "#7f7f7f"}
STATUS_COLOURS = {"matched": "#2ca02c", "rejected": "#ff7f0e", "failed": "#d62728"}


def _mpl():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _frame_axis(frames):
    x = []
    for i, f in enumerate(frames):
        try:
            x.append(int(f))
        except ValueError:
            x.append(i)
    return np.asarray(x)


def _history(ax, frames, distances, colours, labels, threshold=None, title=""):
    x = _frame_axis(frames)
    d = np.array([np.nan if v is None else v for v in distances], dtype=float)
    top = np.nanmax(d) if np.isfinite(d).any() else 1.0
    if threshold is not None and threshold < 2:
        top = max(top, threshold)
    ax.plot(x, d, color="0.75", lw=0.8, zorder=1)
    nan = np.isnan(d)
    for lab in dict.fromkeys(labels):
        sel = np.array([l_ == lab for l_ in labels]) & ~nan
        if sel.any():
            ax.scatter(x[sel], d[sel], s=18, color=colours[lab], label=lab, zorder=2)
    if nan.any():       # frames without a distance (failed): a band at the bottom, not a height
        ax.scatter(x[nan], np.full(int(nan.sum()), 0.03), transform=ax.get_xaxis_transform(),
                   marker="x", s=30, color="#d62728", zorder=3, clip_on=False,
                   label=f"failed (no distance): {int(nan.sum())}")
        for xi in x[nan]:
            ax.axvline(xi, color="#d62728", alpha=0.12, lw=3, zorder=0)
    if threshold is not None:
        ax.axhline(threshold, color="k", ls="--", lw=1, label=f"T_d = {threshold:g}")
    ax.set_xlabel("frame")
    ax.set_ylabel("AHA distance")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
    if np.isfinite(top):
        ax.set_ylim(top=top * 1.15 + 1e-3)
    ax.grid(alpha=0.3)


def plot_distances(poses, path, evaluation=None, threshold=None, title=None):
    """AHA distance per frame, coloured by quality class (with ground truth) or status."""
    plt = _mpl()
    poses = sort_poses(poses)
    fig, ax = plt.subplots(figsize=(9, 3.6), dpi=110)
    if evaluation is not None:
        q = {f.frame: f.quality for f in evaluation.frames}
        labels = [q.get(p.frame, "none") for p in poses]
        colours = CLASS_COLOURS
    else:
        labels = [p.status for p in poses]
        colours = STATUS_COLOURS
    _history(ax, [p.frame for p in poses], [p.distance for p in poses], colours, labels,
             threshold, title or "AHA distance per frame (missing = failed)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def plot_quality(rows, path, thresholds=None, suptitle=None, threshold=None):
    """One row per (label, Evaluation): distance history with classes | rates vs threshold.

    The layout of the thesis' Fig. 13.4–13.7 (rows: e.g. resolutions 50³, 100³, 150³).
    ``threshold``: the model's T_d, marked on both plots (the threshold axis includes it).
    """
    plt = _mpl()
    n = len(rows)
    fig, axes = plt.subplots(n, 2, figsize=(12, 3.4 * n), dpi=100, squeeze=False,
                             gridspec_kw={"width_ratios": [1.5, 1]})
    for (label, ev), (a0, a1) in zip(rows, axes):
        fr = [f.frame for f in ev.frames]
        _history(a0, fr, [f.distance for f in ev.frames], CLASS_COLOURS,
                 [f.quality for f in ev.frames], threshold, f"{label}: distance and quality per frame")
        c = ev.curves(thresholds)
        a1.plot(c["threshold"], c["tp_rate"], color="#2ca02c", label="TP / frames")
        a1.plot(c["threshold"], c["fp_rate"], color="#d62728", label="FP / frames")
        a1.plot(c["threshold"], c["fp_per_match"], color="#ff7f0e", ls="--", label="FP / matches")
        dmax = max([f.distance for f in ev.frames if f.distance is not None] or [1.0])
        right = min(2.0, dmax * 1.1 + 0.05)
        if threshold is not None and threshold < 2:
            right = max(right, threshold * 1.15)
            a1.axvline(threshold, color="k", ls="--", lw=1, label=f"model T_d = {threshold:g}")
        a1.set_xlim(0, right)
        a1.set_ylim(-0.02, 1.02)
        a1.set_xlabel("AHA distance threshold T_d")
        a1.set_title(f"{label}: ratios against T_d")
        a1.legend(fontsize=7)
        a1.grid(alpha=0.3)
    if suptitle:
        fig.suptitle(suptitle)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
