"""Rotations between a capture's up axis and a viewer's."""
from __future__ import annotations

import numpy as np


def up_rotation(up) -> np.ndarray:
    """Rotation taking the capture's up vector to +z (matplotlib's vertical)."""
    u = np.asarray(up, float)
    u = u / np.linalg.norm(u)
    z = np.array([0.0, 0.0, 1.0])
    if np.allclose(u, z):
        return np.eye(3)
    if np.allclose(u, -z):
        return np.diag([1.0, -1.0, -1.0])
    v = np.cross(u, z)
    s, c = np.linalg.norm(v), float(u @ z)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k * ((1 - c) / s ** 2)
