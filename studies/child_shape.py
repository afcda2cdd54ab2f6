"""Whether the capsule body's shape limits its silhouette IoU on child_rope: the tracked poses
drawn with one radius a bone (as the tracker draws them), with two (the hull's depth over each
half of the bone), and tapered (the least-squares line through the depth along the bone), and
where the mask pixels the body leaves out lie.

    python studies/child_shape.py CHILD_ROPE_DIR [--work DIR] [--every 4] [--out studies/results]

``CHILD_ROPE_DIR``: the recording (``../shared/data/real/child_rope``; its masks are read in
place, never copied). The sequence is run as ``topopose run`` does; the body's confident frames'
hulls give the radius profiles (:func:`~topopose.sequence.body.radius_profile` at 0.1–0.9 of
each bone, median over the frames); every ``--every``-th frame's last fit is drawn again in
each camera at the tracker's scale (:func:`~topopose.sequence.silhouette.scaled_views`). A bone
of varying radius is drawn as 4 pieces, each with its own radius (OpenCV thick lines, round
caps), as :func:`~topopose.sequence.silhouette.body_masks` draws a capsule.

Per variant: the IoU per camera (median over the frames) and its mean. Then the mask pixels
the tracker's body leaves out and the body's pixels outside the mask, each given to the
capsule whose outline is nearest, as shares of the mask's pixels.

Writes ``child_shape.md``.
"""
import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import machine, machine_line  # noqa: E402
from _tracker import child_rope_capture  # noqa: E402

import topopose.sequence.body as body_module  # noqa: E402
import topopose.sequence.silhouette as silhouette_module  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.capture import load_capture  # noqa: E402
from topopose.sequence.body import RADIUS_RANGE, hull_depth, radius_profile  # noqa: E402
from topopose.sequence.follow import FollowOptions  # noqa: E402

SAMPLES = np.linspace(0.1, 0.9, 9)
PIECES = 4


def recorded(capture):
    """Run the sequence; return the learned body's inputs and each frame's last fit drawn."""
    learned, fits = {}, {}
    learn_body, silhouette_iou = body_module.learn_body, silhouette_module.silhouette_iou

    def learning(tree, lengths, frames, voxel_size, **kw):
        learned.update(frames=frames, voxel_size=voxel_size)
        return learn_body(tree, lengths, frames, voxel_size, **kw)

    def judged(body, P, cameras, silhouettes, shapes=None):
        fits[id(silhouettes)] = (body, np.array(P), cameras, silhouettes, shapes)
        return silhouette_iou(body, P, cameras, silhouettes, shapes)

    body_module.learn_body, silhouette_module.silhouette_iou = learning, judged
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run(load_capture(capture), progress=False, follow=FollowOptions())
    finally:
        body_module.learn_body, silhouette_module.silhouette_iou = learn_body, silhouette_iou
    return learned, list(fits.values())


def profiles(body, learned):
    """(K, S): each capsule's radius at ``SAMPLES`` along it, median over the confident frames."""
    rows = [radius_profile(v, *body.capsules(np.asarray(P, float))[:2], samples=SAMPLES,
                           depth=hull_depth(v)) for v, P in learned["frames"]]
    R = np.stack(rows, axis=1)                                   # (K, frames, S)
    with np.errstate(all="ignore"):
        med = np.nanmedian(np.where(R > 0, R, np.nan), axis=1)
    lo, hi = RADIUS_RANGE[0] * float(learned["voxel_size"]), RADIUS_RANGE[1]
    return np.clip(med, lo, hi)


def radius_along(kind, prof, r):
    """(K, PIECES) radii of each capsule's pieces: ``one`` (the body's), ``halves``, ``taper``."""
    mid = (np.arange(PIECES) + 0.5) / PIECES
    if kind == "one":
        return np.repeat(r[:, None], PIECES, axis=1)
    if kind == "halves":
        first = np.nanmedian(prof[:, SAMPLES <= 0.5], axis=1)
        second = np.nanmedian(prof[:, SAMPLES >= 0.5], axis=1)
        return np.where(mid[None] < 0.5, first[:, None], second[:, None])
    out = np.empty((len(r), PIECES))
    for k in range(len(r)):
        ok = np.isfinite(prof[k])
        slope, cut = np.polyfit(SAMPLES[ok], prof[k, ok], 1) if ok.sum() > 2 else (0.0, r[k])
        out[k] = cut + slope * mid
    return np.clip(out, np.nanmin(prof), np.nanmax(prof))


def drawn(body, P, cameras, shapes, radii):
    """Each camera's mask of the body with ``radii`` (K, PIECES) per capsule piece."""
    import cv2

    A, B, _r = body.capsules(P)
    cut = np.linspace(0, 1, PIECES + 1)
    out = []
    for cam, (h, w) in zip(cameras, shapes):
        img = np.zeros((h, w), np.uint8)
        f = float(cam.matrix[0, 0])
        for q in range(PIECES):
            a3 = A + cut[q] * (B - A)
            b3 = A + cut[q + 1] * (B - A)
            a, b = cam.project(a3), cam.project(b3)
            z = cam.to_camera(0.5 * (a3 + b3))[:, 2]
            for k in np.flatnonzero(np.isfinite(a).all(1) & np.isfinite(b).all(1) & (z > 0)):
                t = max(1, int(np.rint(2 * f * radii[k, q] / z[k])))
                cv2.line(img, tuple(np.rint(a[k]).astype(int).tolist()),
                         tuple(np.rint(b[k]).astype(int).tolist()), 1, thickness=t)
        out.append(img.view(bool))
    return out


def iou(masks, silhouettes):
    out = []
    for d, (y0, x0, m) in zip(masks, silhouettes):
        both = np.count_nonzero(d[y0:y0 + m.shape[0], x0:x0 + m.shape[1]] & m)
        u = np.count_nonzero(d) + np.count_nonzero(m) - both
        out.append(both / u if u else np.nan)
    return out


def nearest_capsule(body, P, cam, ys, xs):
    """The capsule whose projected outline is nearest each pixel (ys, xs)."""
    A, B, r = body.capsules(P)
    a, b = cam.project(A), cam.project(B)
    rr = float(cam.matrix[0, 0]) * r / cam.to_camera(0.5 * (A + B))[:, 2]
    X = np.c_[xs, ys].astype(float)
    s = b - a
    t = np.clip(((X[:, None] - a[None]) * s[None]).sum(2) / np.maximum((s ** 2).sum(1), 1e-9),
                0, 1)
    d = np.linalg.norm(X[:, None] - (a[None] + t[..., None] * s[None]), axis=2) - rr[None]
    return np.argmin(d, axis=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("child_rope")
    ap.add_argument("--work", default=None)
    ap.add_argument("--every", type=int, default=4)
    ap.add_argument("--out", default="studies/results")
    a = ap.parse_args()
    if not (Path(a.child_rope) / "cam00").exists():
        sys.exit(f"child_shape: {a.child_rope} is not the child_rope recording (no cam00)")
    work = Path(a.work or tempfile.mkdtemp(prefix="child_shape_"))
    learned, fits = recorded(child_rope_capture(Path(a.child_rope), work / "child_rope_capture"))
    fits = fits[::a.every]
    body = fits[0][0]
    prof = profiles(body, learned)
    r = body.capsules(np.zeros((len(body.names), 3)))[2]
    lines = ["# child_rope: the body's shape against its silhouette IoU", "",
             machine_line(machine()), "",
             f"{len(fits)} frames (every {a.every}th fit), {len(fits[0][2])} cameras, longest "
             "side 320 pixels.", "", "| body drawn | IoU per camera (median over frames) | mean |",
             "| --- | --- | --- |"]
    for kind in ("one", "halves", "taper"):
        radii = radius_along(kind, prof, r)
        rows = np.array([iou(drawn(b, P, cams, shapes, radii), sils)
                         for b, P, cams, sils, shapes in fits])
        lines.append(f"| {kind} | {np.round(np.nanmedian(rows, axis=0), 3).tolist()} | "
                     f"{np.nanmean(rows):.4f} |")
        print(lines[-1], flush=True)
    names = [body.names[j] for j in body.bones] + [f"extra {e}" for e in range(body.n_extra)]
    out_px, over_px, total = np.zeros(len(names)), np.zeros(len(names)), 0
    for b, P, cams, sils, shapes in fits:
        for cam, d, (y0, x0, m) in zip(cams, silhouette_module.body_masks(b, P, cams, shapes),
                                       sils):
            total += np.count_nonzero(m)
            ys, xs = np.nonzero(m & ~d[y0:y0 + m.shape[0], x0:x0 + m.shape[1]])
            if len(ys):
                np.add.at(out_px, nearest_capsule(b, P, cam, ys + y0, xs + x0), 1)
            over = d.copy()
            over[y0:y0 + m.shape[0], x0:x0 + m.shape[1]] &= ~m
            ys, xs = np.nonzero(over)
            if len(ys):
                np.add.at(over_px, nearest_capsule(b, P, cam, ys, xs), 1)
    for label, px in (("mask pixels left out", out_px), ("body pixels outside the mask", over_px)):
        top = np.argsort(-px)[:8]
        lines.append(f"\n{label}: {px.sum() / total:.3f} of the masks' pixels; by nearest "
                     "capsule: " + ", ".join(f"{names[k]} {px[k] / total:.3f}" for k in top))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "child_shape.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-2:]))


if __name__ == "__main__":
    main()
