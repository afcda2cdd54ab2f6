"""The fitted body seen by the cameras: its silhouettes and their agreement with the frame's.

A capsule projects (nearly) to a 2-D capsule: the segment between its end points' images,
as wide as the radius seen at the bone's depth. :func:`body_masks` draws them (OpenCV thick
lines have round caps); :func:`silhouette_iou` compares them with the frame's silhouettes per
camera (intersection over union), on images scaled so their longest side is at most
``max_side`` pixels.
"""
from __future__ import annotations

import numpy as np

MAX_SIDE = 320   # pixels: the longest image side the silhouettes are compared at


def body_masks(body, P, cameras, shapes) -> list:
    """Boolean (h, w) silhouettes of the capsule body at joint positions ``P`` in each camera
    (``shapes``: the (h, w) of each image)."""
    import cv2

    A, B, radii = body.capsules(P)
    mid = 0.5 * (A + B)
    out = []
    for cam, (h, w) in zip(cameras, shapes):
        img = np.zeros((h, w), np.uint8)
        a, b = cam.project(A), cam.project(B)
        z = cam.to_camera(mid)[:, 2]
        ok = np.flatnonzero(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1) & (z > 0))
        if len(ok):
            f = float(cam.matrix[0, 0])
            t = np.maximum(1, np.rint(2 * f * radii[ok] / z[ok])).astype(np.int64).tolist()
            p, q = (np.rint(np.clip(x[ok], -1e5, 1e5)).astype(np.int64).tolist() for x in (a, b))
            for k in range(len(ok)):
                cv2.line(img, p[k], q[k], 1, thickness=t[k])
        out.append(img.view(bool))
    return out


def scaled_views(cameras, silhouettes, max_side=MAX_SIDE) -> tuple:
    """The cameras and silhouettes scaled down so the longest side is at most ``max_side``."""
    import cv2

    from topopose.capture.background import scaled_camera

    cams, sils = [], []
    for cam, m in zip(cameras, silhouettes):
        m = np.asarray(m, bool)
        s = min(1.0, max_side / max(m.shape))
        if s < 1.0:
            size = (max(1, int(round(m.shape[1] * s))), max(1, int(round(m.shape[0] * s))))
            m = cv2.resize(m.astype(np.uint8) * 255, size, interpolation=cv2.INTER_AREA) > 127
            cam = scaled_camera(cam, size[0] / cam.size[0])
        cams.append(cam)
        sils.append(m)
    return cams, sils


def silhouette_iou(body, P, cameras, silhouettes, shapes=None) -> np.ndarray:
    """Intersection over union of the body's and the frame's silhouette, per camera (NaN for
    a camera where both are empty). With ``shapes`` (the images' (h, w)), each silhouette is
    ``(y0, x0, crop)``: its set pixels all in ``crop``, whose first pixel is the image's
    (y0, x0) (:class:`~.kept.CroppedViews`)."""
    if shapes is None:
        shapes = [m.shape for m in silhouettes]
        silhouettes = [(0, 0, m) for m in silhouettes]
    drawn = body_masks(body, P, cameras, shapes)
    out = np.full(len(silhouettes), np.nan)
    for c, (d, (y0, x0, m)) in enumerate(zip(drawn, silhouettes)):
        both = np.count_nonzero(d[y0:y0 + m.shape[0], x0:x0 + m.shape[1]] & m)
        u = np.count_nonzero(d) + np.count_nonzero(m) - both
        if u:
            out[c] = both / u
    return out


def radius_scale(body, frames, scales):
    """The body with its trunk's radii (the rigid groups' bones) scaled by the factor of
    ``scales`` whose projected body agrees
    best with the silhouettes of ``frames`` (list of ((cameras, silhouettes), joints (J, 3)):
    mean IoU over frames and cameras). The distance transform gives a bone's inscribed radius,
    narrower than the limb seen across its wider side (the trunk's width against its depth)."""
    from dataclasses import replace

    views = [(scaled_views(*v), P) for v, P in frames]
    trunk = np.zeros(len(body.radii), bool)
    trunk[[j for g in body.groups for j in g]] = True
    best, out = -1.0, body
    for s in scales:
        b = replace(body, radii=np.where(trunk, body.radii * float(s), body.radii))
        iou = np.nanmean([np.nanmean(silhouette_iou(b, P, *v)) for v, P in views])
        if iou > best:
            best, out = iou, b
    return out
