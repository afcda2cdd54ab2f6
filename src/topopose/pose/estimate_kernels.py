"""Numba kernels of the per-frame estimator (:mod:`.estimate`)."""
import numpy as np
from numba import njit


@njit(cache=True)
def window_max(dt, xs, reach):
    """Per row ``x`` of ``xs`` (n, 3) (voxel indices inside ``dt``): the largest value of ``dt``
    within ``reach`` voxels of ``x`` along each axis (the window cut at the array's sides; at
    ``x`` itself when ``reach`` is 0), or, when that is 0, the largest of the 3 × 3 × 3
    neighbourhood of ``x`` (cut the same way)."""
    n0, n1, n2 = dt.shape
    out = np.empty(xs.shape[0], dt.dtype)
    for m in range(xs.shape[0]):
        a, b, c = xs[m, 0], xs[m, 1], xs[m, 2]
        k = reach
        while True:
            r = dt[a, b, c]
            for i in range(max(a - k, 0), min(a + k + 1, n0)):
                for j in range(max(b - k, 0), min(b + k + 1, n1)):
                    for l in range(max(c - k, 0), min(c + k + 1, n2)):
                        if dt[i, j, l] > r:
                            r = dt[i, j, l]
            if r != 0 or k == 1:
                break
            k = 1               # (reach 1 again: the same window, the same 0)
        out[m] = r
    return out
