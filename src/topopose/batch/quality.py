"""Quality of pose initialization against ground truth (thesis §13.2.2, Fig. 13.4–13.7).

Each output pose falls in one of the thesis' classes (§13.2.2):

1. ``good``: every part at an appropriate location;
2. ``missing limb``: one part without position, the others right;
3. ``partial``: several parts without position, the others right;
4. ``misplaced``: at least one part at a wrong location;
5. ``bad``: almost all (here: more than half of the placed) parts at wrong locations;
6. ``none``: at most one part placed (and every failed frame).

Classes 1–2 are usable (true positives, TP), 4–5 unusable (false positives, FP); classes 3
and 6 are detected and rejected by the method itself. A part is *right* when it lies within
a tolerance of its ground-truth segment (``gt.json``: the last bone of a limb, or the body-axis
stretch where a junction may be detected; junctions get 1.5 × the tolerance, as the skeleton's
junction slides along the body with the limbs meeting there). Parts a tree cannot tell apart (hand_1/hand_2,
the eight spider legs...) are paired with the ground truth optimally (Hungarian method).

For every AHA distance threshold T the study reports (§13.2.2): the ratio of true positives
to frames, of false positives to frames, and of false positives to matchings (TP + FP).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from topopose.errors import InputError
from topopose.frames import sort_poses

CLASSES = ("good", "missing limb", "partial", "misplaced", "bad", "none")
TP_CLASSES = ("good", "missing limb")
FP_CLASSES = ("misplaced", "bad")
DEFAULT_RELATIVE_TOLERANCE = 0.1
JUNCTION_FACTOR = 1.5


def point_segment_distance(p, a, b) -> float:
    """Euclidean distance from point ``p`` to the segment ``[a, b]``."""
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    ab = b - a
    den = float(ab @ ab)
    t = 0.0 if den == 0 else float(np.clip((p - a) @ ab / den, 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def classify(n_parts: int, n_placed: int, n_wrong: int) -> str:
    """Quality class of §13.2.2 from the part counts."""
    if n_placed <= 1:
        return "none"
    if n_wrong == 0:
        missing = n_parts - n_placed
        return "good" if missing == 0 else ("missing limb" if missing == 1 else "partial")
    return "bad" if n_wrong > n_placed / 2 else "misplaced"


@dataclass
class FrameScore:
    frame: str
    status: str
    distance: float | None
    quality: str
    right: dict = field(default_factory=dict)      # part -> True / False / None (not placed)
    errors: dict = field(default_factory=dict)     # part -> distance to its gt segment
    assignment: dict = field(default_factory=dict)  # output part -> gt part (after pairing)
    n_missing: int = 0


def _groups(parts, model=None, extra=()):
    """Interchangeable part groups: from the model, else by numbered stem (hand_1, hand_2);
    ``extra`` groups (e.g. the five fingertips, to score a hand up to finger order) are merged in."""
    if extra:
        base = _groups(parts, model)
        out = [list(g) for g in extra]
        inside = {p for g in out for p in g}
        return out + [g for g in base if not inside & set(g)]
    if model is not None:
        gs = [list(g) for g in model.interchangeable()]
    else:
        by = {}
        for p in parts:
            head, sep, tail = str(p).rpartition("_")
            if sep and tail.isdigit() and head:
                by.setdefault(head, []).append(p)
        gs = [g for g in by.values() if len(g) > 1]
    inside = {p for g in gs for p in g}
    return gs + [[p] for p in parts if p not in inside]


def score_frame(pose, gt_frame: dict, parts, tolerance: float, model=None, groups=(),
                junctions=(), junction_factor=JUNCTION_FACTOR) -> FrameScore:
    """Score one pose against one ``gt.json`` frame (numbered parts paired optimally).

    Junction parts (where limbs meet: torso, crotch, palm...) are right within
    ``junction_factor`` × ``tolerance``: the skeleton's junction slides along the body axis
    with the pose of the limbs that meet there (§7.3), extremities do not.
    """
    segs = gt_frame.get("segments") or {}
    pts = gt_frame.get("parts") or {}
    right, errors, assign = {}, {}, {}
    big = 1e6
    for group in _groups(parts, model, groups):
        pred = [pose.parts.get(p) if pose.status != "failed" else None for p in group]
        cost = np.zeros((len(group), len(group)))
        dmat = np.full((len(group), len(group)), np.inf)
        tol = tolerance * (junction_factor if group[0] in junctions else 1.0)
        for i, x in enumerate(pred):
            for j, g in enumerate(group):
                if x is None:
                    cost[i, j] = 2 * big
                    continue
                if g in segs:
                    a, b = segs[g]
                    d = point_segment_distance(x, a, b)
                elif g in pts:
                    d = float(np.linalg.norm(np.asarray(x) - np.asarray(pts[g])))
                else:
                    raise InputError(f"gt.json: frame {pose.frame}: no segment or position for "
                                     f"part {g!r}")
                dmat[i, j] = d
                cost[i, j] = (big if d > tol else 0.0) + d
        rows, cols = linear_sum_assignment(cost)
        for i, j in zip(rows, cols):
            p = group[i]
            assign[p] = group[j]
            if pred[i] is None:
                right[p] = None
            else:
                errors[p] = float(dmat[i, j])
                right[p] = bool(dmat[i, j] <= tol)
    n_placed = sum(v is not None for v in right.values())
    n_wrong = sum(v is False for v in right.values())
    q = "none" if pose.status == "failed" else classify(len(parts), n_placed, n_wrong)
    return FrameScore(pose.frame, pose.status, pose.distance, q, right, errors, assign,
                      n_missing=len(parts) - n_placed)


@dataclass
class Evaluation:
    """Scores of a run against ground truth, with the threshold study of §13.2.2."""

    frames: list
    parts: list
    tolerance: float
    max_missing: int = 1

    @property
    def counts(self) -> dict:
        return {c: sum(f.quality == c for f in self.frames) for c in CLASSES}

    def _candidates(self):
        """(distance, is TP, is FP) of the frames the method could accept at some threshold."""
        out = []
        for f in self.frames:
            if f.status == "failed" or f.distance is None or f.n_missing > self.max_missing:
                continue
            out.append((f.distance, f.quality in TP_CLASSES, f.quality in FP_CLASSES))
        return out

    def rates(self, threshold: float) -> dict:
        """TP/frames, FP/frames and FP/(TP+FP) when accepting distance ≤ ``threshold``."""
        n = max(len(self.frames), 1)
        c = [x for x in self._candidates() if x[0] <= threshold + 1e-12]
        tp = sum(x[1] for x in c)
        fp = sum(x[2] for x in c)
        return {"threshold": float(threshold), "tp_rate": tp / n, "fp_rate": fp / n,
                "fp_per_match": fp / (tp + fp) if tp + fp else 0.0, "tp": tp, "fp": fp,
                "frames": len(self.frames)}

    def curves(self, thresholds=None) -> dict:
        """Rates for every threshold (default: 0 … 2 by 0.01, T_d = 2 rejects nothing)."""
        if thresholds is None:
            thresholds = np.round(np.arange(0.0, 2.0001, 0.01), 4)
        rs = [self.rates(t) for t in thresholds]
        return {"threshold": np.asarray(thresholds, float),
                "tp_rate": np.array([r["tp_rate"] for r in rs]),
                "fp_rate": np.array([r["fp_rate"] for r in rs]),
                "fp_per_match": np.array([r["fp_per_match"] for r in rs])}

    def at_status(self) -> dict:
        """The same ratios for the frames the run itself matched (its own T_d)."""
        n = max(len(self.frames), 1)
        m = [f for f in self.frames if f.status == "matched"]
        tp = sum(f.quality in TP_CLASSES for f in m)
        fp = sum(f.quality in FP_CLASSES for f in m)
        return {"tp_rate": tp / n, "fp_rate": fp / n,
                "fp_per_match": fp / (tp + fp) if tp + fp else 0.0, "tp": tp, "fp": fp,
                "matched": len(m), "frames": len(self.frames)}

    def best_threshold(self, max_fp_per_match=0.02) -> float | None:
        """The threshold with the most true positives whose FP/match stays ≤ the bound."""
        best, best_tp = None, -1
        for d in sorted({x[0] for x in self._candidates()}):
            r = self.rates(d)
            if r["fp_per_match"] <= max_fp_per_match and r["tp"] > best_tp:
                best, best_tp = d, r["tp"]
        return best

    def plateau_threshold(self) -> float | None:
        """The smallest threshold reaching the largest number of true positives."""
        c = self._candidates()
        tps = sorted(d for d, tp, _ in c if tp)
        return tps[-1] if tps else None

    def part_errors(self) -> dict:
        """Median distance to the gt segment of each part, over matched frames."""
        out = {}
        for p in self.parts:
            e = [f.errors[p] for f in self.frames if f.status == "matched" and p in f.errors]
            out[p] = float(np.median(e)) if e else None
        return out


def evaluate(gt: dict, poses, model=None, tolerance=None, max_missing=1, groups=(),
             junction_factor=JUNCTION_FACTOR) -> Evaluation:
    """Score poses against a ground-truth dict (the content of ``gt.json``).

    Parameters
    ----------
    gt : dict
        ``{"parts": [...], "height": h, "frames": {name: {"segments": ..., "parts": ...}}}``.
    poses : list of Pose
    model : Model, optional
        Gives the interchangeable part groups (default: the built-in model of
        ``gt["subject"]`` if there is one, else numbered name stems).
    tolerance : float, optional
        Distance (capture units) within which a part is right; default 0.1 × ``gt["height"]``.
    groups : list of part lists, optional
        More interchangeable groups, paired optimally too (e.g. the fingertips, to score
        a hand up to finger order).

    junction_factor : float
        Junction parts (degree > 1 in the model) are right within ``junction_factor`` × the
        tolerance (default ``JUNCTION_FACTOR``; 1: the same tolerance for every part).
    """
    if not isinstance(gt, dict) or "frames" not in gt:
        raise InputError("gt.json: expected an object with 'frames'")
    if model is None and gt.get("subject"):
        from topopose.pose.model import BUILTIN, load_model
        name = {"body": "human"}.get(gt["subject"], gt["subject"])   # body: the MakeHuman mesh
        if name in BUILTIN:
            model = load_model(name)
    parts = list(model.parts) if model is not None else list(gt.get("parts") or [])
    if not parts:
        raise InputError("gt.json: field 'parts' is missing (and no model was given)")
    if tolerance is None:
        h = gt.get("height")
        if not h:
            raise InputError("gt.json: field 'height' is missing; give --tolerance")
        tolerance = DEFAULT_RELATIVE_TOLERANCE * float(h)
    if model is not None:
        adj = model.tree.adjacency()
        junctions = {p for p in parts if len(adj[p]) > 1}
    else:
        junctions = set()
    frames = []
    if model is not None and model.mirrors:       # left_hand → hand_1 (gt's left), see chirality
        from topopose.sequence.chirality import numbered
        poses = [numbered(p, model) for p in poses]
    for p in sort_poses(poses):
        g = gt["frames"].get(p.frame)
        if g is None:
            raise InputError(f"gt.json: no ground truth for frame {p.frame!r}")
        frames.append(score_frame(p, g, parts, float(tolerance), model, groups, junctions,
                                  junction_factor))
    return Evaluation(frames, parts, float(tolerance), max_missing)


def evaluation_tolerance(gt: dict, relative=None, absolute=None, junction_factor=None):
    """``(tolerance in capture units, junction factor)`` of ``topopose evaluate``.

    ``relative``: a fraction of the subject height ``gt["height"]`` (e.g. 0.08, so that figures
    compare across subjects and with published ones); ``absolute``: capture units. Either one
    applies to every part alike (junction factor 1 unless given). Neither: the thesis study's
    default, 0.1 × height with junctions at ``JUNCTION_FACTOR`` × that.
    """
    if relative is not None and absolute is not None:
        raise InputError("evaluate: give --tolerance (fraction of the height) or --tolerance-m, "
                         "not both")
    from topopose._paths import check_number

    for name, x in (("--tolerance", relative), ("--tolerance-m", absolute),
                    ("--junction-factor", junction_factor)):
        check_number(x, name, above=0)
    if absolute is not None:
        return float(absolute), 1.0 if junction_factor is None else float(junction_factor)
    h = gt.get("height")
    if not h:
        raise InputError("gt.json: field 'height' is missing; give --tolerance-m")
    if relative is None:
        return (DEFAULT_RELATIVE_TOLERANCE * float(h),
                JUNCTION_FACTOR if junction_factor is None else float(junction_factor))
    return float(relative) * float(h), 1.0 if junction_factor is None else float(junction_factor)


def summary_table(ev: Evaluation, thresholds=(0.1, 0.2, 0.3, 0.4, 0.6, 2.0)) -> str:
    n = len(ev.frames)
    lines = [f"{n} frames, tolerance {ev.tolerance:.3g} (capture units)"]
    lines.append("classes: " + ", ".join(f"{c} {k}" for c, k in ev.counts.items()))
    s = ev.at_status()
    lines.append(f"as run (matched frames): TP rate {s['tp_rate']:.2f}, FP rate {s['fp_rate']:.2f}, "
                 f"FP per match {s['fp_per_match']:.3f} ({s['matched']} matched)")
    lines.append("threshold  TP rate  FP rate  FP/match")
    for t in thresholds:
        r = ev.rates(t)
        lines.append(f"{t:9.2f}  {r['tp_rate']:7.2f}  {r['fp_rate']:7.2f}  {r['fp_per_match']:8.3f}")
    return "\n".join(lines)
