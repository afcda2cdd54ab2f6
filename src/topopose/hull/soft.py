"""The soft visual hull: multi-view fusion of foreground probabilities in a space occupancy grid
(Franco & Boyer, "Fusion of multi-view silhouette cues using a space occupancy grid", ICCV 2005).

Each pixel is a sensor. For a voxel X and a camera i, let S be "the pixel of X's projection
shows the subject" and q = P(S | I) the pixel's foreground probability (from the background
model, :mod:`topopose.capture.background`). The sensor model: P(S | X occupied) = ``p_detect``
(P_D), P(S | X empty) = ``p_false`` (P_FA: another object on the line of sight, or a false
detection). With P(I | S) ∝ q and P(I | ¬S) ∝ 1 − q (equal priors),

    P(I | X occupied) ∝ P_D q + (1 − P_D)(1 − q),   P(I | X empty) ∝ P_FA q + (1 − P_FA)(1 − q),

views are independent given X, and with a uniform prior the posterior occupancy is
Π P(I_i | occ) / (Π P(I_i | occ) + Π P(I_i | empty)). A voxel is in the hull when it exceeds
``occupancy``, i.e. when Σ_i log-likelihood ratio > log(occupancy / (1 − occupancy)).

Unlike the intersection of hard silhouettes, a camera whose pixel is *uncertain* (q ≈ ½: the
background there was never seen, or the subject's colour is close to it) barely votes, so one
camera's hole no longer cuts a limb, while a camera *sure* the pixel is background (q ≈ 0)
still carves. A voxel whose centre projects outside an image is treated as seen as background
(q = 0), as in the hard hull.

Per grid, the pixel of every voxel centre in every camera's probability map is computed once
(the maps are downscaled, so the table is small: 4 bytes per voxel and camera) and cached on the
capture; a frame costs one pass over it (:func:`.soft_kernels.fuse`).
"""
from __future__ import annotations

import math

import numpy as np

from topopose.hull import soft_kernels as K
from topopose.geometry.carver import camera_geometry, camera_intrinsics


def log_ratios(p_detect: float, p_false: float) -> np.ndarray:
    """(256,) log P(q | occupied) / P(q | empty) of a probability byte q = 0 … 255."""
    q = np.arange(256) / 255.0
    l1 = p_detect * q + (1 - p_detect) * (1 - q)
    l0 = p_false * q + (1 - p_false) * (1 - q)
    return np.log(l1 / l0)


def voxel_pixels(cameras_small, origin, voxel_size, shape) -> np.ndarray:
    """(n, C) int32 flat index (row · w + column) of every voxel centre (C order) in each
    downscaled camera's map, -1 when outside the image or not validly in front of the lens
    (the carver's projection, :func:`topopose.geometry.carver_kernels._pixel`, in one kernel pass: 30× faster
    than projecting the voxel centres with NumPy, which took 3.7 s at 100³ on the Pose2Sim
    recording's first frame)."""
    geo = camera_geometry(cameras_small, origin, voxel_size)
    intr = np.stack([camera_intrinsics(c) for c in cameras_small])
    intr[:, 14] = intr[:, 12]                  # rows of the map: its width
    out = np.empty((int(np.prod(shape)), len(cameras_small)), dtype=np.int32)
    K.grid_pixels(geo, intr, *(int(s) for s in shape), out)
    return out


def soft_carve(pix, maps, shape, p_detect=0.9, p_false=0.4, occupancy=0.5) -> tuple:
    """Occupancy (uint8, ``shape``) of the soft hull of one frame and its number of voxels.

    ``pix`` from :func:`voxel_pixels`; ``maps`` the cameras' uint8 probability maps.
    """
    flat = np.concatenate([np.ascontiguousarray(m).ravel() for m in maps])
    offsets = np.cumsum([0] + [m.size for m in maps[:-1]]).astype(np.int64)
    llr = log_ratios(p_detect, p_false)
    bias = math.log(occupancy / (1 - occupancy))
    out = np.empty(pix.shape[0], dtype=np.uint8)
    stats = np.zeros(1, dtype=np.int64)
    K.fuse(pix, flat, offsets, llr, float(llr[0]), bias, out, stats)
    return out.reshape(shape), int(stats[0])


def posterior(qs, p_detect=0.9, p_false=0.4) -> float:
    """Posterior occupancy of one voxel from its pixels' probabilities (0 … 1) — the formula
    itself, for checks."""
    a = b = 1.0
    for q in qs:
        a *= p_detect * q + (1 - p_detect) * (1 - q)
        b *= p_false * q + (1 - p_false) * (1 - q)
    return a / (a + b)
