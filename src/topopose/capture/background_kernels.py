"""Numba kernel of the per-pixel foreground probability (:mod:`.background`)."""
from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def colour_probability(img, bg, known, thr, shadow, uncertain, out):
    """uint8 probability (× 255) per pixel from the brightness / chromaticity distortion of
    ``img`` against ``bg`` (both (h, w, 3) uint8; see
    :func:`topopose.capture.background.foreground_probability`)."""
    h, w = out.shape
    width = thr / 4.0
    for i in range(h):
        for j in range(w):
            i0 = float(img[i, j, 0])
            i1 = float(img[i, j, 1])
            i2 = float(img[i, j, 2])
            b0 = float(bg[i, j, 0]) + 1.0
            b1 = float(bg[i, j, 1]) + 1.0
            b2 = float(bg[i, j, 2]) + 1.0
            bb = b0 * b0 + b1 * b1 + b2 * b2
            a = (i0 * b0 + i1 * b1 + i2 * b2) / bb
            c0 = i0 - a * b0
            c1 = i1 - a * b1
            c2 = i2 - a * b2
            cd2 = c0 * c0 + c1 * c1 + c2 * c2
            nb = math.sqrt(bb)
            if a > 1.0:
                bd = (a - 1.0) * nb
            elif a >= shadow:
                bd = 0.0
            else:
                bd = (shadow - a) * nb
            d = math.sqrt(cd2 + bd * bd)
            z = (d - thr) / width
            if z > 30.0:
                z = 30.0
            elif z < -30.0:
                z = -30.0
            p = 1.0 / (1.0 + math.exp(-z))
            if not known[i, j]:
                p = 0.5 + (p - 0.5) * uncertain
            v = p * 255.0 + 0.5
            out[i, j] = 255 if v >= 255.0 else int(v)
