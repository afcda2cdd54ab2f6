"""What the tracker reads of a frame, kept by the run's frame loop so the tracking stage carves
and decodes nothing again: the frame's visual hull, packed in bits over its bounding box, and
its silhouettes at the scale the tracker compares them (:func:`~.silhouette.scaled_views`),
cropped to the subject.

A frame of the child recording (10 cameras, 100³ grid) keeps 44 kB (median; 13 kB of hull,
31 kB of silhouettes; 18 MB for its 410 frames); :attr:`KeptFrame.nbytes` counts them.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from topopose.sequence.silhouette import MAX_SIDE

EPS = np.finfo(float).eps      # OpenCV: an integer reduction within DBL_EPSILON


# --------------------------------------------------------------------------- the hull
@dataclass(frozen=True)
class PackedVolume:
    """A boolean voxel grid as ``np.packbits`` of its object's bounding box.

    Attributes
    ----------
    bits : ndarray of uint8, the box's voxels packed (C order)
    lo : tuple of int, the box's lower corner in the grid
    box : tuple of int, the box's shape
    shape : tuple of int, the grid's shape
    origin : ndarray (3,), voxel_size : float, diagnostics : dict
        As the :class:`~topopose.hull.volume.Volume`'s.
    """

    bits: np.ndarray
    lo: tuple
    box: tuple
    shape: tuple
    origin: np.ndarray
    voxel_size: float
    diagnostics: dict

    @classmethod
    def pack(cls, volume) -> "PackedVolume":
        from topopose.sequence.body import bounding_box

        occ = np.asarray(volume.data, bool)
        lo, box = bounding_box(occ, margin=0)
        part = occ[box]
        return cls(np.packbits(part, axis=None), tuple(int(v) for v in lo), part.shape,
                   occ.shape, np.asarray(volume.origin, float).copy(), float(volume.voxel_size),
                   dict(volume.diagnostics))

    def volume(self):
        """The :class:`~topopose.hull.volume.Volume` again, voxel for voxel."""
        from topopose.hull.volume import Volume

        data = np.zeros(self.shape, bool)
        n = int(np.prod(self.box))
        if n:
            sl = tuple(slice(a, a + b) for a, b in zip(self.lo, self.box))
            data[sl] = np.unpackbits(self.bits, count=n).reshape(self.box).view(bool)
        return Volume(data, self.origin.copy(), self.voxel_size, dict(self.diagnostics))

    @property
    def nbytes(self) -> int:
        return int(self.bits.nbytes)


# --------------------------------------------------------------------------- the silhouettes
@functools.lru_cache(maxsize=32)
def _area_table(ssize: int, dsize: int) -> tuple:
    """OpenCV's ``INTER_AREA`` weights from ``ssize`` source to ``dsize`` output pixels along
    one axis (``computeResizeAreaTab``): per entry the output pixel, the source pixel and its
    weight (float32, as OpenCV keeps it), in OpenCV's order."""
    scale = 1.0 / (dsize / ssize)
    di, si, al = [], [], []
    for d in range(dsize):
        f1 = d * scale
        f2 = f1 + scale
        cell = min(scale, ssize - f1)
        s1, s2 = math.ceil(f1), math.floor(f2)
        s2 = min(s2, ssize - 1)
        s1 = min(s1, s2)
        if s1 - f1 > 1e-3:
            di.append(d), si.append(s1 - 1), al.append((s1 - f1) / cell)
        for s in range(s1, s2):
            di.append(d), si.append(s), al.append(1.0 / cell)
        if f2 - s2 > 1e-3:
            di.append(d), si.append(s2), al.append(min(min(f2 - s2, 1.0), cell) / cell)
    return (np.array(di, np.int64), np.array(si, np.int64),
            np.array(al, np.float64).astype(np.float32))


@njit(cache=True, nogil=True)
def _area_crop(src, xd, xs, xa, yd, ys, ya, x0, x1, y0, y1, out):
    """``out`` = rows ``y0:y1``, columns ``x0:x1`` of ``cv2.resize(src * 255, INTER_AREA) >
    127`` from the axes' :func:`_area_table` — the same float32 sums in OpenCV's order
    (``ResizeArea_Invoker``), so the same pixels, reading only the crop's source pixels."""
    nx = x1 - x0
    buf = np.zeros(nx, np.float32)
    acc = np.zeros(nx, np.float32)
    k0, k1 = np.searchsorted(xd, x0), np.searchsorted(xd, x1)
    j0, j1 = np.searchsorted(yd, y0), np.searchsorted(yd, y1)
    if j0 >= j1:
        return
    prev = yd[j0]
    for j in range(j0, j1):
        beta = ya[j]
        row = src[ys[j]]
        for i in range(nx):
            buf[i] = np.float32(0.0)
        for k in range(k0, k1):
            if row[xs[k]]:
                buf[xd[k] - x0] += np.float32(255.0) * xa[k]
            else:
                buf[xd[k] - x0] += np.float32(0.0) * xa[k]
        if yd[j] != prev:
            for i in range(nx):
                out[prev - y0, i] = np.rint(acc[i]) > 127.0
                acc[i] = beta * buf[i]
            prev = yd[j]
        else:
            for i in range(nx):
                acc[i] += beta * buf[i]
    for i in range(nx):
        out[prev - y0, i] = np.rint(acc[i]) > 127.0


def scaled_crop(mask, size) -> tuple:
    """``(y0, x0, crop)``: the pixels of ``cv2.resize(mask, size, INTER_AREA) > 127`` (the
    boolean ``mask`` as 0 / 255) over the bounding box of those that can be set, computed from
    the mask's bounding box alone (an integer reduction on both axes, which OpenCV computes
    another way, resizes the whole mask)."""
    import cv2

    from topopose.geometry.masks import mask_box

    m = np.ascontiguousarray(mask, dtype=bool)
    h, w = m.shape
    x, y, bw, bh = mask_box(mask)
    if not bw:
        return 0, 0, np.zeros((0, 0), bool)
    sx, sy = 1.0 / (size[0] / w), 1.0 / (size[1] / h)       # OpenCV's scales
    if abs(sx - round(sx)) < EPS and abs(sy - round(sy)) < EPS:
        full = cv2.resize(m.view(np.uint8) * np.uint8(255), size, interpolation=cv2.INTER_AREA)
        return _cropped(full > 127)
    # the output pixels whose area meets the box (one more each side: the tables' ends)
    x0, x1 = max(int(x / sx) - 1, 0), min(int(math.ceil((x + bw) / sx)) + 1, size[0])
    y0, y1 = max(int(y / sy) - 1, 0), min(int(math.ceil((y + bh) / sy)) + 1, size[1])
    out = np.zeros((y1 - y0, x1 - x0), bool)
    _area_crop(m, *_area_table(w, size[0]), *_area_table(h, size[1]), x0, x1, y0, y1, out)
    y2, x2, c = _cropped(out)
    return y0 + y2, x0 + x2, c


def _cropped(m) -> tuple:
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    if not len(rows):
        return 0, 0, np.zeros((0, 0), bool)
    return (int(rows[0]), int(cols[0]),
            np.ascontiguousarray(m[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]))


@dataclass(frozen=True)
class CroppedViews:
    """Cameras and silhouettes as :func:`~.silhouette.scaled_views` gives them, each
    silhouette kept as its set pixels' bounding box.

    Attributes
    ----------
    cameras : list of Camera (scaled)
    crops : list of (y0, x0, ndarray of bool)
    shapes : list of (h, w), the scaled silhouettes' shapes
    """

    cameras: list
    crops: list
    shapes: list

    @classmethod
    def scaled(cls, cameras, silhouettes, max_side=MAX_SIDE) -> "CroppedViews":
        """:func:`~.silhouette.scaled_views` of ``(cameras, silhouettes)``, pixel for pixel,
        resizing only around each silhouette's bounding box."""
        from topopose.capture.background import scaled_camera

        cams, crops, shapes = [], [], []
        for cam, m in zip(cameras, silhouettes):
            m = m if getattr(m, "dtype", None) == bool else np.asarray(m, bool)
            s = min(1.0, max_side / max(m.shape))
            if s < 1.0:
                size = (max(1, int(round(m.shape[1] * s))), max(1, int(round(m.shape[0] * s))))
                crops.append(scaled_crop(m, size))
                cam = scaled_camera(cam, size[0] / cam.size[0])
                shapes.append((size[1], size[0]))
            else:
                crops.append(_cropped(np.asarray(m, bool)))
                shapes.append(m.shape)
            cams.append(cam)
        return cls(cams, crops, shapes)

    def views(self) -> tuple:
        """``(cameras, silhouettes)``, the silhouettes whole."""
        sils = []
        for (y0, x0, c), shape in zip(self.crops, self.shapes):
            m = np.zeros(shape, bool)
            m[y0:y0 + c.shape[0], x0:x0 + c.shape[1]] = c
            sils.append(m)
        return list(self.cameras), sils

    @property
    def nbytes(self) -> int:
        return int(sum(c.nbytes for _, _, c in self.crops))


@dataclass(frozen=True)
class KeptFrame:
    """A frame as the tracker reads it: its hull (:class:`PackedVolume`) and its silhouettes
    (:class:`CroppedViews`, None where the hull has none to compare)."""

    hull: PackedVolume
    views: CroppedViews | None

    @classmethod
    def keep(cls, volume, views=None) -> "KeptFrame":
        """Keep ``volume`` and ``views`` = (cameras, silhouettes) as the hull was carved from."""
        return cls(PackedVolume.pack(volume),
                   None if views is None else CroppedViews.scaled(*views))

    def read(self) -> tuple:
        """``(Volume, (cameras, silhouettes) or None)``."""
        return self.hull.volume(), None if self.views is None else self.views.views()

    @property
    def nbytes(self) -> int:
        return self.hull.nbytes + (self.views.nbytes if self.views is not None else 0)
