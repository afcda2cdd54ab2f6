"""Numba kernel of the exact silhouette renderer (see :mod:`.synth_geometry` for the maths)."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _cone_hit(o0, o1, o2, d0, d1, d2, p):
    # p: a(3), b(3), ra, rb
    w0 = p[0] - o0
    w1 = p[1] - o1
    w2 = p[2] - o2
    u0 = p[3] - p[0]
    u1 = p[4] - p[1]
    u2 = p[5] - p[2]
    ra = p[6]
    dr = p[7] - p[6]
    dw = d0 * w0 + d1 * w1 + d2 * w2
    du = d0 * u0 + d1 * u1 + d2 * u2
    alpha = u0 * u0 + u1 * u1 + u2 * u2 - du * du
    if alpha < 0.0:
        alpha = 0.0
    beta = w0 * u0 + w1 * u1 + w2 * u2 - dw * du
    gamma = w0 * w0 + w1 * w1 + w2 * w2 - dw * dw
    # h(0), h(1)
    q = gamma
    if q < 0.0:
        q = 0.0
    if np.sqrt(q) - ra <= 0.0:
        return True
    q = alpha + 2.0 * beta + gamma
    if q < 0.0:
        q = 0.0
    if np.sqrt(q) - (ra + dr) <= 0.0:
        return True
    if alpha > dr * dr + 1e-15:
        s0 = -beta / alpha
        delta = gamma - beta * beta / alpha
        if delta < 0.0:
            delta = 0.0
        s = s0 + dr * np.sqrt(delta / (alpha * (alpha - dr * dr)))
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        q = alpha * s * s + 2.0 * beta * s + gamma
        if q < 0.0:
            q = 0.0
        if np.sqrt(q) - (ra + s * dr) <= 0.0:
            return True
    return False


@njit(cache=True)
def render_kernel(xy, Rt, origin, boxes, kinds, params, mask):
    """Set ``mask[v, u]`` for every pixel whose ray meets one of the primitives.

    xy : (h, w, 2) undistorted normalized coordinates of the pixel centres
    Rt : (3, 3) camera → world rotation (Rᵀ)
    boxes : (n, 4) int pixel boxes u0, u1, v0, v1 (exclusive ends)
    kinds : (n,) 0 = round cone, 1 = ellipsoid
    params : (n, 12) cone: a, b, ra, rb; ellipsoid: M (row-major 3×3, world → unit sphere), M (o - c)
    """
    o0, o1, o2 = origin[0], origin[1], origin[2]
    for k in range(boxes.shape[0]):
        p = params[k]
        for v in range(boxes[k, 2], boxes[k, 3]):
            for u in range(boxes[k, 0], boxes[k, 1]):
                if mask[v, u]:
                    continue
                x = xy[v, u, 0]
                y = xy[v, u, 1]
                d0 = Rt[0, 0] * x + Rt[0, 1] * y + Rt[0, 2]
                d1 = Rt[1, 0] * x + Rt[1, 1] * y + Rt[1, 2]
                d2 = Rt[2, 0] * x + Rt[2, 1] * y + Rt[2, 2]
                n = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                d0 /= n
                d1 /= n
                d2 /= n
                if kinds[k] == 0:
                    hit = _cone_hit(o0, o1, o2, d0, d1, d2, p)
                else:
                    e0 = p[0] * d0 + p[1] * d1 + p[2] * d2
                    e1 = p[3] * d0 + p[4] * d1 + p[5] * d2
                    e2 = p[6] * d0 + p[7] * d1 + p[8] * d2
                    od = p[9] * e0 + p[10] * e1 + p[11] * e2
                    oo = p[9] * p[9] + p[10] * p[10] + p[11] * p[11]
                    hit = oo - od * od / (e0 * e0 + e1 * e1 + e2 * e2) <= 1.0
                if hit:
                    mask[v, u] = True
