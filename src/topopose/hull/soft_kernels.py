"""Numba kernel of the soft visual hull (:mod:`.soft`)."""
from __future__ import annotations

import numpy as np
from numba import njit


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
