"""Numba kernel of the soft visual hull (:mod:`.soft`)."""
from __future__ import annotations

from numba import njit

from topopose.geometry.carver_kernels import _pixel


@njit(cache=True)
def fuse(pix, maps, offsets, llr, llr_out, bias, out, stats):
    """Occupancy of every voxel from the log-likelihood ratios of its pixels.

    ``pix`` (n, C) int32: flat pixel index of voxel n's centre in camera c's map (-1: not seen);
    ``maps`` uint8 (all cameras' maps, flattened, camera c from ``offsets[c]``); ``llr`` (256,)
    log P(q | occupied) / P(q | empty) of a probability byte q, ``llr_out`` for an unseen voxel;
    a voxel is occupied when the sum over cameras exceeds ``bias``. ``out`` (n,) uint8;
    ``stats``: [voxels set].
    """
    n, C = pix.shape
    cnt = 0
    for i in range(n):
        s = 0.0
        for c in range(C):
            p = pix[i, c]
            if p < 0:
                s += llr_out
            else:
                s += llr[maps[offsets[c] + p]]
        if s > bias:
            out[i] = 1
            cnt += 1
        else:
            out[i] = 0
    stats[0] = cnt


@njit(cache=True)
def grid_pixels(geo, intr, nx, ny, nz, out):
    """``out`` (nx·ny·nz, C) int32: flat pixel index of every voxel centre (C order) in each
    camera (``geo``, ``intr`` packed as for :mod:`topopose.geometry.carver_kernels`, row stride ``intr[c, 14]``),
    -1 when not in the image (:func:`topopose.geometry.carver_kernels._pixel`)."""
    C = geo.shape[0]
    n = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                for c in range(C):
                    out[n, c] = _pixel(geo, intr, c, float(i), float(j), float(k))
                n += 1
