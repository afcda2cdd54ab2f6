"""Silhouettes from colour images and one empty-scene background image per camera.

Methods (``[silhouettes] method`` in ``capture.toml``):

- ``"diff"`` (default): both images are smoothed by a median filter of size ``median`` (removes
  sensor noise while keeping edges in place; a Gaussian blur would dilate the silhouette by
  about its sigma) and optionally a Gaussian of sigma ``blur``; a pixel is subject when the
  largest absolute difference over the colour channels exceeds ``threshold`` (0-255 scale).
- ``"mog2"`` / ``"knn"``: OpenCV's ``BackgroundSubtractorMOG2`` / ``KNN`` trained on the
  (median-filtered) background image; ``threshold`` is the Euclidean colour distance at which a
  pixel becomes foreground (MOG2: fixed variance (threshold/4)², ``varThreshold`` 16; KNN:
  ``dist2Threshold`` = threshold²); shadow detection is off.

Then a morphological clean-up: opening by an elliptical kernel of size ``open`` (removes specks),
closing by size ``close`` (fills cracks), removal of blobs of fewer than ``min_area`` pixels, and
filling of holes of fewer than ``fill_holes`` pixels (0: none).
"""
from __future__ import annotations

import cv2
import numpy as np

from topopose.capture.options import SILHOUETTE_DEFAULTS


def _kernel(size: int):
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (int(size), int(size)))


def _as_bgr(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        return img[:, :, None]
    return img[:, :, :3]


def _smooth_median(img: np.ndarray, k: int) -> np.ndarray:
    if k <= 1:
        return img
    img = np.ascontiguousarray(img)
    if img.dtype != np.uint8 and k > 5:
        img = np.clip(img, 0, 255).astype(np.uint8)
    return cv2.medianBlur(img, int(k) | 1)


def clean_mask(mask: np.ndarray, params: dict | None = None) -> np.ndarray:
    """Morphological clean-up of a boolean mask (opening, closing, small blobs, small holes)."""
    p = dict(SILHOUETTE_DEFAULTS, **(params or {}))
    m = mask.astype(np.uint8)
    if p["open"] > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, _kernel(p["open"]))
    if p["close"] > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, _kernel(p["close"]))
    if p["min_area"] > 0:
        n, lab, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        keep = np.zeros(n, dtype=np.uint8)
        keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= p["min_area"]
        m = keep[lab]
    if p["fill_holes"] > 0:
        inv = (1 - m).astype(np.uint8)
        n, lab, stats, _ = cv2.connectedComponentsWithStats(inv, connectivity=4)
        h, w = m.shape
        border = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
        fill = stats[:, cv2.CC_STAT_AREA] < p["fill_holes"]
        fill[0] = False               # label 0 of ``inv`` is the subject itself
        fill[border] = False          # background touching the image border is not a hole
        m = np.where(fill[lab], 1, m).astype(np.uint8)
    return m.astype(bool)


def extract_silhouette(image: np.ndarray, background: np.ndarray, params: dict | None = None
                       ) -> np.ndarray:
    """Boolean silhouette of ``image`` (h, w[, 3] uint8) against ``background`` (same size).

    Parameters are those of the ``[silhouettes]`` table (see the module docstring);
    missing ones take :data:`~topopose.capture.options.SILHOUETTE_DEFAULTS`.
    """
    p = dict(SILHOUETTE_DEFAULTS, **(params or {}))
    img, bg = _as_bgr(np.asarray(image)), _as_bgr(np.asarray(background))
    if img.shape[:2] != bg.shape[:2]:
        raise ValueError(f"image {img.shape[:2]} and background {bg.shape[:2]} differ in size")
    img, bg = _smooth_median(img, p["median"]), _smooth_median(bg, p["median"])
    if p["method"] == "diff":
        a = img.astype(np.float32)
        b = bg.astype(np.float32)
        if p["blur"] > 0:
            a = cv2.GaussianBlur(a, (0, 0), float(p["blur"]))
            b = cv2.GaussianBlur(b, (0, 0), float(p["blur"]))
        if a.ndim == 2:
            a, b = a[:, :, None], b[:, :, None]
        d = np.abs(a - b).max(axis=2)
        raw = d > float(p["threshold"])
    else:
        if p["method"] == "mog2":
            # a fixed per-pixel variance (threshold / 4)² and varThreshold 16: a pixel is
            # foreground when its colour distance to every background mode exceeds ``threshold``
            sub = cv2.createBackgroundSubtractorMOG2(history=10, varThreshold=16.0,
                                                     detectShadows=False)
            var = (float(p["threshold"]) / 4.0) ** 2
            sub.setVarInit(var)
            sub.setVarMin(var)
            sub.setVarMax(var)
        else:
            sub = cv2.createBackgroundSubtractorKNN(history=10, dist2Threshold=float(p["threshold"]) ** 2,
                                                    detectShadows=False)
        a, b = np.ascontiguousarray(img), np.ascontiguousarray(bg)
        if p["blur"] > 0:
            a = cv2.GaussianBlur(a, (0, 0), float(p["blur"]))
            b = cv2.GaussianBlur(b, (0, 0), float(p["blur"]))
        for _ in range(5):
            sub.apply(b, learningRate=1.0 if _ == 0 else 0.5)
        raw = sub.apply(a, learningRate=0.0) > 127
    return clean_mask(raw, p)
