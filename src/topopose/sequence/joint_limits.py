"""Joint limits of the tracked body (:mod:`.tracker`): soft costs on the pose beyond the angles
a body reaches, each a residual and its row of the Gauss–Newton Jacobian.
"""
from __future__ import annotations

import math

import numpy as np


def twist_term(P, G, quad, limit, weight) -> tuple:
    """The axial rotation of two mirror pairs' lines about the line between their middles
    (within ±90°: which joint of a pair is which side is not known here), held within
    ``limit`` (a joint limit, soft): residual ``√weight × (φ − clip(φ, ±limit))``
    and its row ``dr/dθ`` (``G``: dP/dθ, (J, 3, n)).

    Parameters
    ----------
    P : ndarray (J, 3), joints
    quad : (a1, b1, a2, b2), joint indices (:func:`.tracker.twist_pairs`)
    limit : radians; weight : float

    Returns
    -------
    r : float, the residual (0 within the limit)
    row : ndarray (n,), its derivative
    phi : float, the angle (radians)

    Examples
    --------
    >>> P = np.array([[-1., 0, 1], [1, 0, 1], [0, -1, 0], [0, 1, 0]])   # lines 90° apart
    >>> r, row, phi = twist_term(P, np.zeros((4, 3, 1)), (0, 1, 2, 3), np.radians(30), 1.0)
    >>> round(float(np.degrees(phi)), 1), round(float(r), 4)
    (90.0, 1.0472)
    """
    a1, b1, a2, b2 = quad
    pa1, pb1, pa2, pb2 = P[a1].tolist(), P[b1].tolist(), P[a2].tolist(), P[b2].tolist()
    l1 = [y - x for x, y in zip(pa1, pb1)]
    l2 = [y - x for x, y in zip(pa2, pb2)]
    m = [(x1 + y1 - x2 - y2) / 2 for x1, y1, x2, y2 in zip(pa1, pb1, pa2, pb2)]
    nm = max(math.sqrt(_dot(m, m)), 1e-12)
    n = [x / nm for x in m]
    c12 = _cross(l1, l2)
    s = _dot(c12, n)                        # φ = atan2(s, c): l1, l2 projected normal to n
    c = _dot(l1, l2) - _dot(l1, n) * _dot(l2, n)
    phi = math.atan2(s, c)
    if abs(phi) > math.pi / 2:              # lines, not directions: a pair's numbering is no side
        phi -= math.copysign(math.pi, phi)
    over = phi - min(max(phi, -limit), limit)
    w = math.sqrt(weight)
    if over == 0.0:
        return 0.0, np.zeros(G.shape[2]), phi
    q = max(s * s + c * c, 1e-24)
    n1, n2 = _dot(l1, n), _dot(l2, n)
    x2, x1 = _cross(l2, n), _cross(n, l1)
    d1 = [(c * x - s * (y - n2 * z)) / q for x, y, z in zip(x2, l2, n)]     # dφ/dl1
    d2 = [(c * x - s * (y - n1 * z)) / q for x, y, z in zip(x1, l1, n)]     # dφ/dl2
    dn = [(c * x + s * (n2 * y + n1 * z)) / q for x, y, z in zip(c12, l1, l2)]
    dnn = _dot(dn, n)
    dm = [(x - dnn * z) / nm / 2 for x, z in zip(dn, n)]                    # dφ/dP, from m
    C = np.array([[y - x for x, y in zip(d1, dm)], [x + y for x, y in zip(d1, dm)],
                  [-x - y for x, y in zip(d2, dm)], [x - y for x, y in zip(d2, dm)]])
    row = np.tensordot(C, G[[a1, b1, a2, b2]], axes=([0, 1], [0, 1]))
    return w * over, w * row, phi


def _dot(u, v) -> float:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _cross(u, v) -> list:
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
