"""Silhouette support of a placed frame: analysis by synthesis in 2D.

The frame's result — the skeleton curve of each matched model arc (``diagnostics["curves"]``,
:mod:`.curves`), swept by the hull's inscribed ball along it (the hull is the union of its
maximal balls, thesis §4.3) — is rendered into each camera and compared with that camera's
silhouette, in the silhouette's bounding box resized to a fixed height (the figures do not
depend on the image size):

- **unexplained** (:func:`support_features`, the one used): the largest share, over the
  cameras, of the silhouette farther than ``dilation`` × the silhouette's largest inscribed
  radius (about half the trunk's width) from the rendered model: a limb the model did not use
  (an arm visible in some views whose hand the alignment put elsewhere), a part of the body it
  placed wrong;
- *outside*: the largest share of the rendered model outside the silhouette;
- *tip depth*: each placed extremity's depth inside the silhouette (distance to the contour
  over the largest), median over the cameras, mean over the extremities;
- *beyond*: the share of cameras in which the point 0.1 × height beyond each extremity (along
  its curve's last tenth) still lies in the silhouette, mean over the extremities.

Measured (``studies/trust_features.py``; AUC, the
probability that a right frame scores lower than a wrong one): *unexplained* 0.70–0.76 on
synthetic 4-camera walks and 0.82 on the real recording (where the fitted confidence is at
chance, 0.46); the others stay at 0.44–0.74 and not on both. It is one condition of
:func:`topopose.sequence.consistency.judge_sequence` (:data:`~.consistency.MAX_UNEXPLAINED`),
recorded by :class:`~.estimate.FrameEstimator` with ``support=True`` (``run --consistency``).
"""
from __future__ import annotations

import numpy as np

#: the model is dilated by this × the silhouette's largest inscribed radius before comparing
#: (0.25, 0.5, 0.75, 1 compared by AUC on the development seeds of
#: studies/trust_features.py: 0.25 best on both 4-camera set-ups)
DILATION = 0.25
#: height (pixels) of the silhouette's bounding box when compared
WORK_HEIGHT = 96
EXTREMITIES = ("head", "hand_1", "hand_2", "foot_1", "foot_2")


def compared_views(cameras, masks) -> tuple:
    """``(cameras, silhouettes)`` as the frame's result is compared with them: a silhouette
    upsampled from a small probability map (``person``, ``sequence``: its ``small`` attribute)
    is taken small, with its camera scaled to it; the others as they are, boolean."""
    from topopose.capture.background import scaled_camera

    cams, sils = [], []
    for cam, m in zip(cameras, masks):
        small = getattr(m, "small", None)
        cams.append(cam if small is None else scaled_camera(cam, small.shape[1] / cam.size[0]))
        # a boolean mask kept as it is (its bounding box, when it carries one, goes with it)
        sils.append(m if small is None and getattr(m, "dtype", None) == bool
                    else np.asarray(m if small is None else small, bool))
    return cams, sils


def exact_edt(mask) -> np.ndarray:
    """The Euclidean distance (float64) of each pixel of ``mask`` to the background, equal to
    ``scipy.ndimage.distance_transform_edt``'s bit for bit (the square root of a whole number of
    squared pixels; OpenCV's exact transform in float32 gives that number back, rounded), at a
    fraction of its cost. The image's outside does not count as background (as SciPy's)."""
    import cv2

    m = np.asarray(mask, bool)
    if m.all():                           # no background: SciPy's distances to nothing
        from scipy.ndimage import distance_transform_edt
        return distance_transform_edt(m)
    d = cv2.distanceTransform(m.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.sqrt(np.rint(d.astype(np.float64) ** 2))


def largest_depth(mask) -> float:
    """``exact_edt(mask).max()`` from OpenCV's transform alone: the square root of a rounded
    square does not decrease, so it maps the largest value of the transform to the largest of
    :func:`exact_edt`."""
    import cv2

    m = np.asarray(mask, bool)
    if m.all():
        return float(exact_edt(m).max())
    d = float(cv2.distanceTransform(m.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE).max())
    return float(np.sqrt(np.rint(np.float64(d) ** 2)))


def curve_radii(points, occ, origin, voxel_size, edt=None) -> np.ndarray:
    """The hull's inscribed radius (world units) at ``points`` (N, 3): its distance transform
    at the nearest voxel. ``edt``: :func:`topopose.frame.tips.inscribed_distances` of ``occ``
    if already computed."""
    from topopose.frame.tips import inscribed_distances

    if edt is None:
        edt = inscribed_distances(occ)
    if edt is None or not len(points):
        return np.zeros(len(points))
    dt, lo = edt
    ijk = np.round((np.asarray(points, float) - origin) / voxel_size).astype(int)
    ijk = np.clip(ijk - np.asarray(lo) + 1, 0, np.array(dt.shape) - 1)
    return dt[tuple(ijk.T)] * float(voxel_size)


def support_features(curves, parts, cams, masks, occ, origin, voxel_size, edt=None,
                     dilation=DILATION, work_height=WORK_HEIGHT, beyond=0.1,
                     extras=True) -> dict:
    """The features of the module docstring for one frame.

    Parameters
    ----------
    curves : dict part -> (n, 3) curve from its parent part (``diagnostics["curves"]``)
    parts : dict part -> position or None
    cams : list of Camera, the ones ``masks`` are seen by
    masks : list of bool arrays (the silhouettes)
    occ, origin, voxel_size : the visual hull
    edt : :func:`topopose.frame.tips.inscribed_distances` of ``occ`` if already computed
    extras : bool
        Also the features other than ``unexplained`` (NaN when False).

    Returns
    -------
    dict: ``unexplained``, ``unexplained_mean``, ``outside``, ``tip_depth``, ``beyond``
    (floats; NaN when nothing to measure).
    """
    import cv2

    from topopose.geometry.masks import mask_box

    origin = np.asarray(origin, float)
    from topopose.frame.tips import inscribed_distances

    segs = [np.asarray(c, float) for c in curves.values() if c is not None and len(c) > 1]
    P = np.concatenate(segs) if segs else np.zeros((0, 3))
    if edt is None and len(P):
        edt = inscribed_distances(occ)
    R = curve_radii(P, occ, origin, voxel_size, edt)
    first = np.zeros(len(P), bool)            # the first point of each curve
    first[np.cumsum([0] + [len(c) for c in segs[:-1]])] = len(P) > 0
    height = 0.0
    if extras:
        nz = np.argwhere(occ)
        height = float(np.ptp(nz, axis=0).max() * voxel_size) if len(nz) else 0.0
    unexpl, outside, depth, beyond_in = [], [], {}, {}
    for cam, S in zip(cams, masks):
        S8 = np.asarray(S, bool).view(np.uint8)
        bx, by, bw, bh = mask_box(S)
        if not bw:
            continue
        m = max(2, (bh - 1) // 16)                          # margin around the silhouette
        y0, x0 = max(by - m, 0), max(bx - m, 0)
        crop = S8[y0:by + bh + m, x0:bx + bw + m] * np.uint8(255)
        sc = work_height / crop.shape[0]
        hh, ww = work_height, max(1, round(crop.shape[1] * sc))
        Sw = cv2.resize(crop, (ww, hh), interpolation=cv2.INTER_AREA) >= 128

        def to_work(X):
            return (cam.project(X) - [x0, y0]) * sc

        M = np.zeros((hh, ww), np.uint8)
        f = sc * float(cam.matrix[0, 0])
        if len(P):
            uv = to_work(P)
            z = cam.to_camera(P)[:, 2]
            ok = np.all(np.isfinite(uv), axis=1) & (z > 1e-6)
            uv = np.round(np.where(ok[:, None], uv, 0)).astype(int).tolist()
            rp = np.maximum(1, np.round(f * R / np.where(ok, z, 1.0))).astype(int).tolist()
            okl, firstl = ok.tolist(), first.tolist()
            for i in range(len(uv)):
                if not okl[i]:
                    continue
                cv2.circle(M, uv[i], rp[i], 1, -1)
                if not firstl[i] and okl[i - 1]:
                    cv2.line(M, uv[i], uv[i - 1], 1, rp[i] + rp[i - 1])
        ns = max(int(Sw.sum()), 1)
        dS = exact_edt(Sw) if extras else None        # the tips' depths need the whole map
        dm = max(float(dS.max()) if extras else largest_depth(Sw), 1.0)
        d = 2 * max(1, int(round(dilation * dm))) + 1
        Md = cv2.dilate(M, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (d, d))) > 0
        unexpl.append(float((Sw & ~Md).sum()) / ns)
        if not extras:
            continue
        Mb = M > 0
        outside.append(float((Mb & ~Sw).sum()) / max(int(Mb.sum()), 1))
        for p in EXTREMITIES:
            E, c = parts.get(p), curves.get(p)
            if E is None:
                continue
            E = np.asarray(E, float)
            u, v = to_work(E[None])[0]
            if not (np.isfinite(u) and 0 <= u < ww and 0 <= v < hh):
                continue
            depth.setdefault(p, []).append(float(dS[int(v), int(u)]) / dm)
            if c is None or len(c) < 2:
                continue
            t = E - np.asarray(c[-max(2, len(c) // 10)], float)
            n = np.linalg.norm(t)
            if n < 1e-9:
                continue
            uq, vq = to_work((E + beyond * height * t / n)[None])[0]
            beyond_in.setdefault(p, []).append(bool(np.isfinite(uq) and 0 <= uq < ww
                                                    and 0 <= vq < hh and Sw[int(vq), int(uq)]))
    nan = float("nan")
    dmed = [float(np.median(v)) for v in depth.values()]
    return {"unexplained": max(unexpl) if unexpl else nan,
            "unexplained_mean": float(np.mean(unexpl)) if unexpl else nan,
            "outside": max(outside) if outside else nan,
            "tip_depth": float(np.mean(dmed)) if dmed else nan,
            "beyond": (float(np.mean([np.mean(v) for v in beyond_in.values()]))
                       if beyond_in else nan)}
