"""Hierarchical volumetric visual-hull carving with per-grid projection tables (thesis §2.3.2.2).

A voxel belongs to the visual hull when the projection of its centre lies inside the
silhouette in every camera (§2.3.2.2); with ``tolerance = k`` it suffices that C − k cameras see
it as subject. A voxel centre that projects outside an image (or behind the camera, or beyond
the lens' valid field, see :func:`max_radius2`) counts as *not seen as subject* by that camera.

Design (measured in ``benchmarks/hull.py``):

- **Lens distortion is honoured exactly, on the projected points**: voxel centres are projected
  with the full OpenCV model (radial-tangential or fisheye), the same formula as
  :meth:`Camera.project`, then rounded to the nearest pixel. Masks are never resampled.
- **Per-grid tables, built once** (:class:`HullCarver`): for every block of 2^l × 2^l × 2^l
  voxels (l = ``lmin`` … ``lmax``, an octree over the grid) and every camera, the inclusive
  pixel rectangle that bounds the projection of the block. The finest level's rectangles come
  from projecting the lattice of block corners (distortion included, plus a one-pixel safety
  margin for distorted cameras, whose straight edges project slightly curved); coarser levels
  are unions of their 8 children. They are computed by Numba kernels with the same projection
  formula as the per-voxel test, itself tested against :meth:`Camera.project` and
  ``cv2.projectPoints``. Memory: 16 bytes per block and camera, about 4.7 MB for 128³ voxels
  and 8 cameras at ``lmin = 2`` (no per-voxel tables: those would take 64 MB at 128³ and
  512 MB at 256³).
- **Per frame**: one summed-area table per silhouette (``cv2.integral``); a coarse-to-fine
  traversal classifies each block per camera as all-outside / all-inside / undecided in O(1)
  from its rectangle, drops a camera from a block's descendants once it has decided, stops at
  blocks rejected by more than ``tolerance`` cameras or accepted by all, and tests only the
  voxels of undecided finest blocks by exact projection, with early exit. Empty space and the
  body's interior cost little; work concentrates near the hull's surface. (This is the
  hierarchical carving the thesis cites for real-time volumetric hulls in §2.3.2.2: Caillette
  & Howard, BMVC 2004, its ref. [31].)
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry import carver_kernels as K
from topopose.geometry.masks import mask_box

_CLAMP = 1 << 24


def max_radius2(cam) -> float:
    """Largest squared normalized radius (x/z)² + (y/z)² where the lens model is one-to-one.

    Polynomial distortion models fold back beyond the radius where ``r · radial(r)`` stops
    increasing; a point beyond it could land in the image although it is far outside the field
    of view. Such points are treated as not in the image. Pinhole cameras: infinity.
    (The first positive root of the derivative: 1 + 3 k1 s + 5 k2 s² + 7 k3 s³ with s = r²;
    fisheye: 1 + 3 k1 t + 5 k2 t² + 7 k3 t³ + 9 k4 t⁴ with t = θ², θ < π/2, r = tan θ.)
    """
    d = np.zeros(5)
    d[: min(5, cam.distortions.size)] = cam.distortions[:5]
    if cam.fisheye:
        coef = [9 * d[3], 7 * d[2], 5 * d[1], 3 * d[0], 1.0]
        limit = (math.pi / 2) ** 2
    else:
        coef = [7 * d[4], 5 * d[1], 3 * d[0], 1.0]
        limit = math.inf
    coef = np.trim_zeros(np.array(coef), "f")
    if coef.size <= 1:
        return math.inf
    roots = np.roots(coef)
    real = roots[(np.abs(roots.imag) < 1e-12) & (roots.real > 0)].real
    real = real[real < limit]
    if real.size == 0:
        return math.inf
    s0 = float(real.min())
    return math.tan(math.sqrt(s0)) ** 2 if cam.fisheye else s0


def camera_geometry(cameras, origin, voxel_size) -> np.ndarray:
    """The packed ``geo`` rows (C, 12) of a grid (see :mod:`.carver_kernels`)."""
    geo = np.empty((len(cameras), 12))
    origin = np.asarray(origin, dtype=float)
    for q, cam in enumerate(cameras):
        R = cam.R
        geo[q, 0:3] = R @ origin + cam.translation
        for ax in range(3):
            geo[q, 3 + 3 * ax: 6 + 3 * ax] = voxel_size * R[:, ax]
    return geo


def camera_intrinsics(cam) -> np.ndarray:
    """The packed ``intr`` row of a camera (see :mod:`.carver_kernels`)."""
    row = np.zeros(16)
    Km = cam.matrix
    row[0:5] = Km[0, 0], Km[1, 1], Km[0, 2], Km[1, 2], Km[0, 1]
    d = cam.distortions
    if cam.fisheye:
        row[5:9] = d[:4]
        row[10] = 2.0 if np.any(d[:4] != 0) else 0.0
    else:
        row[5:9] = d[:4]
        row[9] = d[4] if d.size > 4 else 0.0
        row[10] = 1.0 if np.any(row[5:10] != 0) else 0.0
    row[11] = max_radius2(cam)
    row[12], row[13] = cam.size
    return row


def project_valid(cam, points: np.ndarray, r2max: float) -> tuple:
    """Pixel coordinates of world points and whether each is validly in front of the lens."""
    xc = cam.to_camera(points)
    z = xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = (xc[:, 0] ** 2 + xc[:, 1] ** 2) / (z * z)
    valid = (z > 0) & (r2 <= r2max)
    uv = cam.project(points)
    valid &= np.all(np.isfinite(uv), axis=1)
    return uv, valid


def corner_rects(cam, r2max, origin, voxel_size, block, nb, margin) -> np.ndarray:
    """Pixel rectangles (nb0, nb1, nb2, 4) of the blocks of ``block`` voxels of a grid.

    Block (a, b, c) spans voxel indices [a·block − ½, (a + 1)·block − ½] etc. (voxel extents,
    which contain every voxel centre of the block). Rows with a corner behind the camera or
    beyond the lens' valid field get ``x0 = INVALID``.
    """
    axes = [(-0.5 + block * np.arange(n + 1)) for n in nb]
    gi, gj, gk = np.meshgrid(*axes, indexing="ij")
    pts = origin + voxel_size * np.stack([gi, gj, gk], axis=-1).reshape(-1, 3)
    uv, valid = project_valid(cam, pts, r2max)
    shp = tuple(n + 1 for n in nb)
    u = np.where(valid, uv[:, 0], np.nan).reshape(shp)
    v = np.where(valid, uv[:, 1], np.nan).reshape(shp)
    ok = valid.reshape(shp)
    sl = [(slice(0, -1), slice(1, None))] * 3
    umin = np.full(tuple(nb), np.inf)
    umax = np.full(tuple(nb), -np.inf)
    vmin = np.full(tuple(nb), np.inf)
    vmax = np.full(tuple(nb), -np.inf)
    good = np.ones(tuple(nb), dtype=bool)
    for s0 in sl[0]:
        for s1 in sl[1]:
            for s2 in sl[2]:
                idx = (s0, s1, s2)
                good &= ok[idx]
                with np.errstate(invalid="ignore"):
                    umin = np.fmin(umin, u[idx])
                    umax = np.fmax(umax, u[idx])
                    vmin = np.fmin(vmin, v[idx])
                    vmax = np.fmax(vmax, v[idx])
    out = np.empty(tuple(nb) + (4,), dtype=np.int64)
    with np.errstate(invalid="ignore"):
        out[..., 0] = np.floor(np.clip(umin, -_CLAMP, _CLAMP) + 0.5) - margin
        out[..., 1] = np.floor(np.clip(vmin, -_CLAMP, _CLAMP) + 0.5) - margin
        out[..., 2] = np.floor(np.clip(umax, -_CLAMP, _CLAMP) + 0.5) + margin
        out[..., 3] = np.floor(np.clip(vmax, -_CLAMP, _CLAMP) + 0.5) + margin
    out[~good] = [K.INVALID, 0, 0, 0]
    return out


def _union_up(r: np.ndarray) -> np.ndarray:
    """Rectangles of the parent level: union of the (up to) 8 children."""
    n = r.shape[:3]
    m = tuple((x + 1) // 2 for x in n)
    # padding children are neutral: empty rectangles (x0 huge, x1 tiny)
    neutral = np.array([_CLAMP * 4, _CLAMP * 4, -_CLAMP * 4, -_CLAMP * 4])
    rp = np.empty(tuple(2 * mm for mm in m) + r.shape[3:], dtype=np.int64)
    rp[...] = neutral
    rp[: n[0], : n[1], : n[2]] = r
    rp = rp.reshape(m[0], 2, m[1], 2, m[2], 2, *r.shape[3:])
    inv = (rp[..., 0] == K.INVALID).any(axis=(1, 3, 5))
    lo = np.where(rp[..., :2] == K.INVALID, _CLAMP * 4, rp[..., :2]).min(axis=(1, 3, 5))
    hi = rp[..., 2:].max(axis=(1, 3, 5))
    out = np.concatenate([lo, hi], axis=-1)
    out[inv] = [K.INVALID, 0, 0, 0]
    return out


class HullCarver:
    """Precomputed projection tables of one voxel grid for the cameras of a capture.

    Parameters
    ----------
    cameras : list of Camera
    origin : (3,) array
        World position of voxel (0, 0, 0)'s centre.
    voxel_size : float
    shape : (nx, ny, nz)
    lmin : int
        Finest block level (blocks of 2^lmin voxels per side) whose voxels are tested one by
        one; 2 by default (chosen in ``benchmarks/hull.py``).

    Examples
    --------
    >>> carver = HullCarver(cap.cameras, origin, 0.02, (100, 60, 40))   # doctest: +SKIP
    >>> occ = carver.carve(cap.silhouettes(0))                          # doctest: +SKIP
    """

    def __init__(self, cameras, origin, voxel_size, shape, lmin: int = 2):
        self.cameras = list(cameras)
        C = len(self.cameras)
        if not 1 <= C <= 62:
            raise InputError(f"visual hull: 1 to 62 cameras supported, got {C}")
        self.origin = np.asarray(origin, dtype=float).reshape(3)
        self.voxel_size = float(voxel_size)
        self.shape = tuple(int(s) for s in shape)
        if self.voxel_size <= 0 or min(self.shape) < 1:
            raise InputError(f"visual hull: bad grid (voxel_size {voxel_size}, shape {shape})")
        self.intr = np.stack([camera_intrinsics(c) for c in self.cameras])
        self.geo = camera_geometry(self.cameras, self.origin, self.voxel_size)
        n = max(self.shape)
        self.lmin = int(lmin)
        self.lmax = max(self.lmin, int(math.ceil(math.log2(max(n / 4.0, 1.0)))))
        # finest level from projected block corners, coarser levels by union
        block = 1 << self.lmin
        nb = [-(-s // block) for s in self.shape]
        lev = np.empty((nb[0], nb[1], nb[2], C, 4), dtype=np.int64)
        one = np.empty((nb[0], nb[1], nb[2], 4), dtype=np.int64)
        for q in range(C):
            margin = 0 if self.intr[q, 10] == 0 else 1
            K.block_rects(self.geo, self.intr, q, float(block), nb[0], nb[1], nb[2], margin,
                          float(_CLAMP), one)
            lev[:, :, :, q] = one
        levels, dims = [lev], [lev.shape[:3]]
        for _ in range(self.lmin + 1, self.lmax + 1):
            lev = K.union_up(lev)
            levels.append(lev)
            dims.append(lev.shape[:3])
        self.ldims = np.array(dims, dtype=np.int64)
        sizes = [x.shape[0] * x.shape[1] * x.shape[2] * C for x in levels]
        self.loff = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self.rects = np.concatenate([x.reshape(-1, 4) for x in levels]).astype(np.int32)
        H = max(c.size[1] for c in self.cameras)
        W = max(c.size[0] for c in self.cameras)
        self.intr[:, 14] = W                     # row stride of the mask buffer
        self._masks = np.zeros((C, H, W), dtype=np.uint8)
        self._sats = np.zeros((C, H + 1, W + 1), dtype=np.int32)
        self._mflat = self._masks.reshape(-1)
        self._sflat = self._sats.reshape(-1)
        self.moff = (np.arange(C) * (H * W)).astype(np.int64)
        self.soff = (np.arange(C) * ((H + 1) * (W + 1))).astype(np.int64)
        self.stats = np.zeros(12, dtype=np.int64)
        self.fac = np.ones((C, 2), dtype=np.int64)   # per camera: mask smaller by (fx, fy)
        self.crop = np.zeros((C, 4), dtype=np.int64)  # per camera: the buffers' part of the mask

    @property
    def nbytes(self) -> int:
        """Memory held by the tables and per-frame buffers."""
        return self.rects.nbytes + self._mflat.nbytes + self._sflat.nbytes

    def load_masks(self, masks) -> None:
        """Copy the silhouettes of one frame and build their summed-area tables. A silhouette
        that is an :class:`~topopose.capture.background.UpsampledMask` is read from its small
        mask (the same hull, 1/(fx·fy) of the copying and summing)."""
        if len(masks) != len(self.cameras):
            raise InputError(f"visual hull: {len(masks)} silhouettes for {len(self.cameras)} cameras")
        for q, (cam, m) in enumerate(zip(self.cameras, masks)):
            small = getattr(m, "small", None)
            box = mask_box(m) if small is None else None
            m = np.asarray(m)
            if m.shape != (cam.size[1], cam.size[0]):
                raise InputError(f"visual hull: silhouette of camera {cam.name!r} has shape "
                                 f"{m.shape}, calibration size (h, w) is {(cam.size[1], cam.size[0])}")
            self.fac[q] = 1
            if small is not None:
                fx, fy = m.shape[1] // small.shape[1], m.shape[0] // small.shape[0]
                if small.shape[1] * fx == m.shape[1] and small.shape[0] * fy == m.shape[0]:
                    self.fac[q] = fx, fy
                    m = small
            if m.dtype == bool:
                m = m.view(np.uint8)
            else:
                m = (m != 0).view(np.uint8)
            # the silhouette's bounding box only (outside it the mask is empty): the copy and
            # the summed-area table cost the subject's pixels, not the image's
            x, y, w, h = box if box is not None and self.fac[q, 0] == 1 else mask_box(m)
            if w == 0:
                x = y = 0
                w = h = 1                 # one empty pixel
            self.crop[q] = x, y, w, h
            m = m[y:y + h, x:x + w]
            # packed at the buffers' start, rows of the crop's width: the kernel's reads stay
            # within the subject's few hundred kilobytes
            np.copyto(self._mflat[self.moff[q]:self.moff[q] + h * w].reshape(h, w), m)
            dst = self._sflat[self.soff[q]:self.soff[q] + (h + 1) * (w + 1)].reshape(h + 1, w + 1)
            r = cv2.integral(np.ascontiguousarray(m), dst, cv2.CV_32S)
            if not np.shares_memory(r, dst):
                dst[...] = r

    def carve(self, masks=None, tolerance: int = 0, levels: bool = False) -> np.ndarray:
        """Boolean occupancy (nx, ny, nz) of the visual hull for the given silhouettes.

        ``masks=None`` reuses the silhouettes of the last :meth:`load_masks`. ``self.stats``
        then holds the work counters, the number of set voxels and the bounding box of the
        result (see :func:`.carver_kernels.carve`).

        ``levels=True`` returns uint8 labels instead, from the same single pass: 2 for the
        voxels all C cameras see as subject (the strict hull, tolerance 0), 1 for those seen by
        C − ``tolerance`` … C − 1 cameras, 0 otherwise — so ``labels >= 1`` is the hull of
        ``tolerance`` and ``labels == 2`` the strict one, for the price of one carve (used by
        the consensus hull, :func:`topopose.hull.visual_hull` ``consensus=``).
        """
        if masks is not None:
            self.load_masks(masks)
        C = len(self.cameras)
        tolerance = int(tolerance)
        if not 0 <= tolerance < C:
            raise InputError(f"visual hull: argument tolerance must be in 0..{C - 1}, got {tolerance}")
        out = np.zeros(self.shape, dtype=np.uint8)
        self.stats[:] = 0
        K.carve(tuple(K.Cameras(self.geo, self.intr)),
                tuple(K.Silhouettes(self._mflat, self.moff, self._sflat, self.soff, self.fac, self.crop)),
                tuple(K.Blocks(self.rects, self.loff, self.ldims, self.lmin, self.lmax)),
                tolerance, bool(levels), out, self.stats)
        return out if levels else out.view(bool)

    def project_voxels(self, ijk) -> np.ndarray:
        """Flat pixel index (row · w + column, or -1) of voxel centres ``ijk`` (n, 3) per camera."""
        return K.project_voxels(self.geo, self.intr, np.asarray(ijk, dtype=float).reshape(-1, 3))
