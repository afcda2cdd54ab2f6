"""Optional person segmentation by a network shipped inside a pip wheel (``[silhouettes]
method = "selfie"`` or ``"sequence+selfie"``).

MediaPipe's legacy *selfie segmentation* model (``mediapipe.solutions.selfie_segmentation``,
the general 256 × 256 model, ~250 kB, inside the ``mediapipe`` wheel up to 0.10.14: nothing is
downloaded at run time) gives a per-pixel person probability. It is run on the bounding
rectangle of the camera's subject zone (:mod:`.background`), so the person fills the network's
input. Install with ``pip install "topopose[segment]"`` (MediaPipe 0.10.14 requires
``opencv-contrib-python``, which conflicts with ``opencv-python-headless`` when both are
installed: keep one).
"""
from __future__ import annotations

import cv2
import numpy as np

from ..errors import InputError

_MODEL = {}


def _segmenter(stream):
    """One segmenter per camera: MediaPipe's solution smooths its masks over the images it is
    given in turn, which must then be one camera's frames, not several cameras'."""
    if stream not in _MODEL:
        try:
            from mediapipe.python.solutions import selfie_segmentation
        except ImportError:
            raise InputError("[silhouettes] method \"selfie\" needs MediaPipe ≤ 0.10.14 "
                             "(pip install \"topopose[segment]\")") from None
        _MODEL[stream] = selfie_segmentation.SelfieSegmentation(model_selection=0)
    return _MODEL[stream]


def selfie_probability(img: np.ndarray, zone: np.ndarray | None = None, stream="") -> np.ndarray:
    """uint8 (h, w) person probability (× 255) of a BGR image; outside the bounding rectangle
    of ``zone`` (when given and not empty) it is 0. ``stream``: the camera (one segmenter each)."""
    h, w = img.shape[:2]
    y0, y1, x0, x1 = 0, h, 0, w
    if zone is not None and zone.any():
        ys, xs = np.nonzero(zone)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    crop = np.ascontiguousarray(img[y0:y1, x0:x1, ::-1])
    res = _segmenter(stream).process(crop)
    out = np.zeros((h, w), dtype=np.uint8)
    if res.segmentation_mask is not None:
        out[y0:y1, x0:x1] = np.clip(res.segmentation_mask * 255 + 0.5, 0, 255).astype(np.uint8)
    return out
