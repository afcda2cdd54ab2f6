"""Connectivity numbers, simple points and isthmuses of one voxel (thesis §4.1–4.2).

Every function takes either a 26-bit configuration index (see
:mod:`topopose.topology.neighbourhood`), a 3×3×3 boolean cube (its centre is the
voxel tested and is ignored), or a 3D boolean volume plus a point ``(x, y, z)``
(voxels outside the array count as background).  They compute the numbers exactly
(no table), with the bit-parallel flood fills of :mod:`.tables_kernels`.
"""
from __future__ import annotations

import numpy as np

from topopose.errors import InputError
from topopose.topology.neighbourhood import config_index


def config_of(volume, point=None) -> int:
    """26-bit configuration index of ``point`` in ``volume`` (or of a cube / an index)."""
    if point is None:
        if isinstance(volume, (int, np.integer)):
            idx = int(volume)
            if not 0 <= idx < (1 << 26):
                raise InputError(f"configuration index {idx} is outside [0, 2^26)")
            return idx
        cube = np.asarray(volume)
        if cube.shape != (3, 3, 3):
            raise InputError(f"neighbourhood: expected a 3x3x3 cube or an index, got shape {cube.shape}")
        return config_index(cube.astype(bool))
    vol = np.asarray(volume, dtype=bool)
    if vol.ndim != 3:
        raise InputError(f"volume: expected a 3D array, got shape {vol.shape}")
    p = np.asarray(point, dtype=np.int64).reshape(3)
    cube = np.zeros((3, 3, 3), dtype=bool)
    for dx in range(3):
        for dy in range(3):
            for dz in range(3):
                q = p + (dx - 1, dy - 1, dz - 1)
                if np.all(q >= 0) and np.all(q < vol.shape):
                    cube[dx, dy, dz] = vol[tuple(q)]
    return config_index(cube)


def t26(volume, point=None) -> int:
    """T26(p, X): number of 26-components of X ∩ N26*(p) (thesis §4.1.1.3)."""
    from topopose.topology.tables_kernels import expand26, t26_word

    return int(t26_word(expand26(np.int64(config_of(volume, point)))))


def t6bar(volume, point=None) -> int:
    """T6(p, X̄): number of 6-components of G6(p, X̄) = N6²(p, X̄) (thesis §4.1.1.3)."""
    from topopose.topology.tables_kernels import expand26, t6bar_word

    return int(t6bar_word(expand26(np.int64(config_of(volume, point)))))


def is_simple(volume, point=None) -> bool:
    """Simple point (26/6): T26 = 1 and T̄6 = 1 (Bertrand–Malandain, thesis Prop. 2)."""
    return t26(volume, point) == 1 and t6bar(volume, point) == 1


def is_isthmus_1d(volume, point=None) -> bool:
    """1D isthmus: T26 ≥ 2 (thesis §4.2.2.2)."""
    return t26(volume, point) >= 2


def is_isthmus_2d(volume, point=None) -> bool:
    """2D isthmus: T̄6 ≥ 2 (thesis §4.2.2.2)."""
    return t6bar(volume, point) >= 2
