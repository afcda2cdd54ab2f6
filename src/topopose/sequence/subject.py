"""The subject's own limb lengths, learned from its confident frames.

The model's relative lengths (§12.3) are a guess for every subject. A run sees one subject
over many frames: a first pass with the generic model finds the frames it matches confidently
(AHA distance low, every part placed); the median length of each model edge over them — the
data-tree path between the images of its two parts, in normalized weights — is the subject's
own; a second pass matches every frame with the model carrying those lengths
(:func:`two_pass`). Opt-in: twice the time for a small gain (``benchmarks/quality.py --only
body``, *two-pass* rows).
"""
from __future__ import annotations

import math

import numpy as np

from topopose.pose.model import Model, model_from_dict

__all__ = ["edge_lengths", "subject_model", "two_pass"]


def edge_lengths(model: Model, alignment, data) -> dict:
    """Length of every finite model edge in one matched frame: the data-tree path between the
    images of its two parts (normalized weights), or None when a part is unplaced."""
    from topopose.frame.placement import path_length

    adj = data.adjacency()
    out = {}
    m = alignment.mapping
    for u, v, w in model.tree.edges:
        if not math.isfinite(w):
            continue
        a, b = m.get(u), m.get(v)
        out[(u, v)] = None if a is None or b is None else path_length(adj, a, b)
    return out


def _group_key(model, u, v):
    """Edges of interchangeable parts (hand_1, hand_2) share one length."""
    groups = {p: i for i, g in enumerate(model.interchangeable()) for p in g}
    return tuple(sorted((groups.get(u, u), groups.get(v, v)), key=str))


def subject_model(model: Model, samples, min_frames: int = 5) -> Model | None:
    """``model`` with its finite edge lengths replaced by the medians of ``samples`` (a list of
    :func:`edge_lengths` dicts), interchangeable parts pooled; None when fewer than
    ``min_frames`` samples. The lengths keep the model's total (only ratios matter, §12.1.1)."""
    if len(samples) < min_frames:
        return None
    pooled = {}
    for s in samples:
        for (u, v), x in s.items():
            if x is not None and math.isfinite(x):
                pooled.setdefault(_group_key(model, u, v), []).append(x)
    total_old = sum(w for _, _, w in model.tree.edges if math.isfinite(w))
    new = {}
    for u, v, w in model.tree.edges:
        xs = pooled.get(_group_key(model, u, v))
        new[(u, v)] = float(np.median(xs)) if math.isfinite(w) and xs else w
    total_new = sum(w for w in new.values() if math.isfinite(w))
    scale = total_old / total_new if total_new > 0 else 1.0
    d = model.to_dict()
    for e in d["edge"]:
        w = new[tuple(e["parts"])]
        e["length"] = "inf" if math.isinf(w) else float(w) * scale
    return model_from_dict(d, source=f"{model.name} (subject lengths)")


def two_pass(cap, frames, model="human", resolution=100, *, confident=0.25, min_frames=5,
             **options):
    """Pose of ``frames`` in two passes: the generic model, then the subject's own lengths.

    Parameters
    ----------
    confident : float
        A first-pass frame teaches the lengths when it is matched with every part placed and an
        AHA distance ≤ ``confident``.
    min_frames : int
        Fewer confident frames: the first pass is the answer.
    options
        :class:`~topopose.frame.FrameEstimator` options.

    Returns
    -------
    (poses, learned) : list of Pose, and the learned :class:`Model` (None if not learned).
    """
    from topopose.frame.estimate import FrameEstimator

    est = FrameEstimator(cap, model, resolution, **options)
    first, samples = [], []
    for f in frames:
        pose, det = est.estimate(f, detail=True)
        first.append(pose)
        if (pose.status == "matched" and not pose.diagnostics.get("missing")
                and pose.distance is not None and pose.distance <= confident):
            samples.append(edge_lengths(est.model, det.alignment, det.data))
    learned = subject_model(est.model, samples, min_frames)
    if learned is None:
        return first, None
    est2 = FrameEstimator(cap, learned, resolution, **options)
    return [est2.estimate(f) for f in frames], learned
