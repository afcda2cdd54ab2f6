"""Numba kernels of the limbs' centre lines (:mod:`.centre`)."""
import numpy as np
from numba import njit


@njit(cache=True)
def scan_runs(mask, uv, normal, half, step, steps, lo, hi):
    """:func:`topopose.frame.centre.scan_widths` into ``lo`` and ``hi`` (NaN-filled by the
    caller): per point, samples ``s·step`` (s = 0 … ``steps``) along ±``normal`` from ``uv``,
    each read at the nearest pixel (``np.rint``) of ``mask`` (2-D uint8, nonzero = inside; the
    image's outside is outside); a crossing at the first outside sample s is ``(s − ½)·step``,
    kept when the point itself is inside and the crossing within ``half``. Each scan stops at
    its crossing, or once a crossing could no longer lie within ``half``."""
    H, W = mask.shape
    for i in range(uv.shape[0]):
        for side in range(2):
            sign = 1.0 if side == 0 else -1.0
            for s in range(steps + 1):
                d = (s - 0.5) * step
                if s > 0 and not d <= half[i]:
                    break                      # a crossing from here on lies beyond half
                t = sign * (s * step)
                x = np.rint(uv[i, 0] + t * normal[i, 0])
                y = np.rint(uv[i, 1] + t * normal[i, 1])
                inside = (np.isfinite(x) and np.isfinite(y) and x >= 0 and y >= 0
                          and x < W and y < H and mask[int(y), int(x)] != 0)
                if not inside:
                    if s > 0:
                        if side == 0:
                            hi[i] = d
                        else:
                            lo[i] = -d
                    break
