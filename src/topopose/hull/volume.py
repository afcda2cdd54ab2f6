"""Volumes between stages: a boolean voxel grid placed in the world."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from topopose.errors import InputError


@dataclass
class Volume:
    """A boolean voxel grid with its place in the world.

    Parameters
    ----------
    data : ndarray of bool, shape (nx, ny, nz)
        Object voxels, axes x, y, z.
    origin : ndarray, shape (3,)
        World position of the centre of voxel (0, 0, 0).
    voxel_size : float
        Edge length of a voxel, in world units.
    diagnostics : dict
        Free-form facts about how the volume was made (e.g. dropped components).
    """

    data: np.ndarray
    origin: np.ndarray
    voxel_size: float
    diagnostics: dict = field(default_factory=dict)

    def __post_init__(self):
        self.data = np.asarray(self.data, dtype=bool)
        self.origin = np.asarray(self.origin, dtype=float).reshape(3)
        self.voxel_size = float(self.voxel_size)

    def world(self, ijk) -> np.ndarray:
        """World coordinates of voxel indices ``ijk`` (shape (..., 3))."""
        return self.origin + np.asarray(ijk, dtype=float) * self.voxel_size

    def save(self, path) -> None:
        """Write the volume as ``.npz`` with keys ``volume``, ``origin``, ``voxel_size``."""
        np.savez_compressed(path, volume=self.data, origin=self.origin,
                            voxel_size=np.float64(self.voxel_size))

    @classmethod
    def load(cls, path) -> "Volume":
        """Read a volume ``.npz``; ``origin`` and ``voxel_size`` default to 0 and 1."""
        path = Path(path)
        try:
            with np.load(path) as f:
                if "volume" not in f:
                    raise InputError(f"{path}: no array 'volume' in the .npz (keys: {sorted(f.keys())})")
                data = f["volume"]
                origin = np.asarray(f["origin"] if "origin" in f else np.zeros(3), dtype=float)
                vs = float(f["voxel_size"]) if "voxel_size" in f else 1.0
        except InputError:
            raise
        except Exception as exc:  # unreadable file
            raise InputError(f"{path}: cannot read volume .npz ({exc})") from None
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise InputError(f"{path}: field 'origin' must be 3 finite numbers, got "
                             f"{origin.ravel().tolist()}"[:300])
        if not (np.isfinite(vs) and vs > 0):
            raise InputError(f"{path}: field 'voxel_size' must be a finite number > 0, got {vs!r}")
        if data.ndim != 3:
            raise InputError(f"{path}: field 'volume' must be a 3D array, got shape {data.shape}")
        if data.dtype != bool:
            raise InputError(f"{path}: field 'volume' must be boolean, got {data.dtype}")
        return cls(data, origin, vs)


def add_rod(vol, start, direction, length):
    """``vol`` (changed in place) with a rod from ``start`` along the unit ``direction`` for
    ``length`` world units — at each half-voxel step a 3 × 3 square of voxels in the grid's first
    two axes, one voxel along the third — stopped 2 voxels from the grid's border: a limb the subject does not have, to check that the confidence gate
    rejects it (``benchmarks/confidence.py``, ``tests/test_pose_confidence.py``)."""
    vs = vol.voxel_size
    for s in np.arange(0.0, length, vs / 2):
        i = np.round((start + s * direction - vol.origin) / vs).astype(int)
        if np.any(i < 2) or np.any(i > np.array(vol.data.shape) - 3):
            break
        vol.data[i[0] - 1:i[0] + 2, i[1] - 1:i[1] + 2, i[2]] = True
    vol.diagnostics.pop("bbox", None)
    vol.diagnostics["voxels"] = int(vol.data.sum())
    return vol
