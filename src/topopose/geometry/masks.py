"""Silhouette masks as the hull carver, the silhouette support and the trim read them: their
bounding box, computed once."""
from __future__ import annotations

import cv2
import numpy as np


class BoxedMask(np.ndarray):
    """A boolean silhouette that carries its bounding box ``box`` = ``cv2.boundingRect`` (x, y,
    w, h; w = 0 when empty), computed once — by the thread that decoded it — for the hull
    carver, the silhouette support and the trim, which look at the box only. Arrays derived
    from it (slices, copies, results of operations) do not carry ``box``."""

    box = None


def boxed(mask) -> np.ndarray:
    """``mask`` (boolean, 2-D) as a :class:`BoxedMask` with its bounding box; a mask that
    already has one, or carries a reduced ``small`` mask, is returned as it is."""
    if getattr(mask, "box", None) is not None or getattr(mask, "small", None) is not None:
        return mask
    m = np.ascontiguousarray(mask, dtype=bool)
    out = m.view(BoxedMask)
    out.box = tuple(int(v) for v in cv2.boundingRect(m.view(np.uint8)))
    return out


def mask_box(mask) -> tuple:
    """The bounding box (x, y, w, h) of a silhouette's set pixels (``w`` 0: none): its
    :class:`BoxedMask` box, else ``cv2.boundingRect``."""
    box = getattr(mask, "box", None)
    if box is not None:
        return box
    m = np.asarray(mask)
    m8 = (m.view(np.uint8) if m.dtype == bool and m.flags.c_contiguous
          else np.ascontiguousarray(m != 0, dtype=np.uint8))
    return tuple(int(v) for v in cv2.boundingRect(m8))
