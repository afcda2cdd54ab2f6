"""Numba kernel of :func:`topopose.pose.unseen.hull_remainder`."""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def unexplained(X, S, reach):
    """Mask (n,) of the points ``X`` (n, 3) farther from every sample ``S[j]`` (m, 3) than its
    ``reach[j]``: the same distances, bit for bit, as NumPy's ``norm(X - S, axis=-1)``, each
    point's search stopped at the first sample that explains it."""
    n = X.shape[0]
    m = S.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    for i in range(n):
        x0 = X[i, 0]
        x1 = X[i, 1]
        x2 = X[i, 2]
        for j in range(m):
            d0 = x0 - S[j, 0]
            d1 = x1 - S[j, 1]
            d2 = x2 - S[j, 2]
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) <= reach[j]:
                keep[i] = False
                break
    return keep
