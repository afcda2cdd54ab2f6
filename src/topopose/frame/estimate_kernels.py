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


@njit(cache=True)
def taxicab_distances(a):
    """Taxicab (L1) distance of every voxel of ``a`` (3D, nonzero = object) to the nearest
    zero voxel of ``a`` (int32; 0 on the background, -1 everywhere when ``a`` has no zero
    voxel): :func:`scipy.ndimage.distance_transform_cdt` with ``metric="taxicab"``, by the
    separable form of the L1 distance (a forward and a backward pass along each axis, 6 passes
    over the array instead of two chamfer passes over 26-neighbourhoods)."""
    nx, ny, nz = a.shape
    big = nx + ny + nz + 1               # beyond any distance inside the array
    d = np.empty((nx, ny, nz), np.int32)
    for i in range(nx):
        for j in range(ny):
            prev = big
            for k in range(nz):
                prev = 0 if a[i, j, k] == 0 else min(prev + 1, big)
                d[i, j, k] = prev
            prev = big
            for k in range(nz - 1, -1, -1):
                prev = min(prev + 1, d[i, j, k])
                d[i, j, k] = prev
    for i in range(nx):
        for j in range(1, ny):
            for k in range(nz):
                d[i, j, k] = min(d[i, j, k], d[i, j - 1, k] + 1)
        for j in range(ny - 2, -1, -1):
            for k in range(nz):
                d[i, j, k] = min(d[i, j, k], d[i, j + 1, k] + 1)
    for i in range(1, nx):
        for j in range(ny):
            for k in range(nz):
                d[i, j, k] = min(d[i, j, k], d[i - 1, j, k] + 1)
    for i in range(nx - 2, -1, -1):
        for j in range(ny):
            for k in range(nz):
                d[i, j, k] = min(d[i, j, k], d[i + 1, j, k] + 1)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if d[i, j, k] >= big:
                    d[i, j, k] = -1
    return d

