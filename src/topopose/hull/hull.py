"""The volumetric visual hull of one frame (thesis §2.3.2.2) and its voxel grid.

Grid: ``resolution`` voxels along the longest side of the capture volume. The capture volume is

1. the ``volume=`` argument, else ``[capture.volume]`` of ``capture.toml``: the grid covers it
   exactly (voxel centres at the centres of the N cells along the longest side); a subject
   crossing its border is cut there (the border voxels are then part of the hull);
2. else **fitted to the silhouettes** (:func:`fit_box`): the axis-aligned bounding box of the
   intersection of the cameras' silhouette-bounding-rectangle cones (a convex polytope, six
   linear programs), then shrunk by conservative coarse passes (a 32³ grid over the box keeps
   every cell whose projected bounding rectangle meets the silhouette in enough cameras, so no
   part of the hull can be lost however thin). The capture's fitted volume is the union of the
   boxes (:func:`frame_box`) of a few frames sampled evenly across the whole sequence
   (:class:`VolumeFit`), computed once and cached on the capture. A fitted grid keeps one empty
   voxel all round (N − 2 voxels span the fitted box) and reaches a margin further with voxels of
   the same size (:func:`fitted_grid`). A frame whose hull reaches the fitted
   grid's side (the subject jumped between two sampled frames) is carved again on a grid fitted
   to it with the same voxels on the same lattice (``diagnostics["grid"] = "beyond"``): a
   subject inside the cameras' common view never crosses the border.
3. silhouette method ``"person"`` without ``[capture.volume]``: a *zone* grid, the hull box of
   the capture's first frame with a subject grown by :data:`PERSON_ZONE` (1 m) on each side,
   with the voxel size of that box grown by ⅔ ``zone_margin`` (N − 2 voxels along its longest
   side); each frame is carved on it (one carver for the capture: empty blocks cost little)
   and cropped to its hull with a one-voxel empty margin, and a frame whose hull reaches the
   zone's border is carved on a refocused grid of the same lattice (below). A frame's hull is
   thus the same whatever frames are processed, in whatever order.

``refocus=True`` (thesis §13.2.2.1: "refocus the grid on the subject at each frame") fits the
box of each frame (three conservative coarse passes over the capture volume — a fitted one is
enlarged by a quarter on each side) and puts a grid on it with a voxel size fixed for the whole
capture: the largest side of the fitted boxes of the sampled frames divided by N − 2
(``"person"``: the zone's voxel size, the frame's box fitted with no capture volume). Grid
origins are snapped to multiples of the voxel size, so voxel centres lie on one world lattice in
every frame; the grid keeps a one-voxel empty margin (clipped to the capture volume when one is
set). Each new grid builds its carver (tables) in that frame, so refocusing costs the fit and
the setup per frame (see ``benchmarks/hull.py`` for the setup times).

The hull's largest 26-connected component is kept by default; the others are reported in
``Volume.diagnostics``.
"""
from __future__ import annotations

import itertools
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry import carver_kernels as CK
from topopose.geometry.carver import HullCarver, camera_geometry, camera_intrinsics
from topopose.hull.volume import Volume
from topopose.hull.components import consensus_hull_labels, keep_largest_component

_FIT_RES = 32
_SAMPLE = 32
_MAX_CARVERS = 4


# --------------------------------------------------------------------------- fitting
def _upsampled(mask):
    """``(small, fx, fy)`` when ``mask`` is an :class:`~topopose.capture.background.UpsampledMask`
    (its pixel (y, x) is ``small[y // fy, x // fx]``), else None."""
    small = getattr(mask, "small", None)
    if small is None:
        return None
    h, w = mask.shape
    fx, fy = w // small.shape[1], h // small.shape[0]
    return (small, fx, fy) if small.shape[1] * fx == w and small.shape[0] * fy == h else None


def _pixel_box(mask):
    """(x min, x max, y min, y max) of the set pixels of ``mask``, or None when there is none
    (read on the small mask of an upsampled one: the same box)."""
    up = _upsampled(mask)
    m = np.asarray(mask if up is None else up[0])
    m8 = m.view(np.uint8) if m.dtype == bool and m.flags.c_contiguous else (m != 0).astype(np.uint8)
    x, y, w, h = cv2.boundingRect(m8)
    if w == 0:
        return None
    fx, fy = (1, 1) if up is None else up[1:]
    return x * fx, (x + w) * fx - 1, y * fy, (y + h) * fy - 1


def _silhouette_planes(cam, mask) -> np.ndarray | None:
    """Half-spaces ``A @ X + b >= 0`` (4, 4) bounding camera ``cam``'s silhouette cone."""
    box = _pixel_box(mask)
    if box is None:
        return None
    x0, x1, y0, y1 = box[0] - 0.5, box[1] + 0.5, box[2] - 0.5, box[3] + 0.5
    if np.any(cam.distortions != 0):
        # undistort the silhouette's outline (pixel corners of its boundary pixels)
        m8 = (np.asarray(mask).view(np.uint8) if mask.dtype == bool and mask.flags.c_contiguous
              else np.ascontiguousarray(mask, dtype=np.uint8))
        contours, _ = cv2.findContours(m8, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        pts = np.concatenate([c.reshape(-1, 2) for c in contours]).astype(float)
        pts = np.concatenate([pts + d for d in ([-.5, -.5], [.5, -.5], [-.5, .5], [.5, .5])])
        if cam.fisheye:
            nrm = cv2.fisheye.undistortPoints(pts.reshape(-1, 1, 2), cam.matrix,
                                              cam.distortions[:4]).reshape(-1, 2)
        else:
            nrm = cv2.undistortPointsIter(pts.reshape(-1, 1, 2), cam.matrix, cam.distortions,
                                          None, None, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                                       50, 1e-9)).reshape(-1, 2)
        a0, b0 = nrm.min(axis=0)
        a1, b1 = nrm.max(axis=0)
        # a little slack for the iterative undistortion
        da, db = 1e-3 * (a1 - a0 + 1e-3), 1e-3 * (b1 - b0 + 1e-3)
        a0, a1, b0, b1 = a0 - da, a1 + da, b0 - db, b1 + db
    else:
        Ki = np.linalg.inv(cam.matrix)
        c = Ki @ np.array([[x0, x1, x0, x1], [y0, y0, y1, y1], [1, 1, 1, 1]])
        a0, a1 = c[0].min(), c[0].max()
        b0, b1 = c[1].min(), c[1].max()
    R, t = cam.R, cam.translation
    rows = []
    for coef, k, sign in ((a0, 0, 1), (a1, 0, -1), (b0, 1, 1), (b1, 1, -1)):
        # sign * (x_k - coef * z) >= 0 in camera coordinates
        A = sign * (R[k] - coef * R[2])
        b = sign * (t[k] - coef * t[2])
        rows.append(np.r_[A, b])
    return np.array(rows)


def _lp_box(planes: list, fallback: tuple) -> tuple | None:
    """Bounding box of ``{X : A X + b >= 0 for all planes}`` by six linear programs."""
    from scipy.optimize import linprog

    P = np.concatenate(planes)
    A_ub, b_ub = -P[:, :3], P[:, 3]
    lo, hi = np.empty(3), np.empty(3)
    for ax in range(3):
        for sgn, dst in ((1.0, lo), (-1.0, hi)):
            c = np.zeros(3)
            c[ax] = sgn
            r = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 3, method="highs")
            if r.status == 2:           # infeasible: the cones do not meet
                return None
            if r.status == 0:
                dst[ax] = r.x[ax]
            else:                       # unbounded (or numerical trouble): fall back
                dst[ax] = fallback[0][ax] if sgn > 0 else fallback[1][ax]
    return lo, hi


def _fallback_box(cameras) -> tuple:
    c = np.array([cam.center for cam in cameras])
    lo, hi = c.min(axis=0), c.max(axis=0)
    pad = max(float(np.linalg.norm(hi - lo)), 1e-6)
    return lo - pad, hi + pad


def _coarse_shrink(cameras, masks, lo, hi, tolerance, res=_FIT_RES, intr=None, sats=None):
    """Shrink a box to the cells of a coarse grid that may hold hull points (conservative):
    a cell is dropped when its projected bounding rectangle (one-pixel margin) misses the
    silhouette in more than ``tolerance`` cameras. ``sats``: the masks' integral images
    (:func:`_integral`)."""
    ext = hi - lo
    vs = float(ext.max()) / res
    if not vs > 0:
        return lo, hi
    shape = [max(1, int(math.ceil(e / vs - 1e-9))) for e in ext]
    origin = lo + vs / 2
    if intr is None:
        intr = np.stack([camera_intrinsics(c) for c in cameras])
    geo = camera_geometry(cameras, origin, vs)
    misses = np.zeros(shape, dtype=np.int32)
    r = np.empty(tuple(shape) + (4,), dtype=np.int64)
    for q, m in enumerate(masks):
        CK.block_rects(geo, intr, q, 1.0, shape[0], shape[1], shape[2], 1, float(1 << 24), r)
        sat, fx, fy = _integral(m) if sats is None else sats[q]
        h, w = m.shape
        # an upsampled mask: the pixels of a rectangle are those of the small mask's rectangle
        # of the blocks it meets (a block is set or not as a whole)
        CK.rect_misses(r, sat, w, h, fx, fy, misses)
    keep = misses <= tolerance
    if not keep.any():
        return None
    kmin = np.array([np.flatnonzero(keep.any(axis=tuple(b for b in range(3) if b != a)))[0]
                     for a in range(3)])
    kmax = np.array([np.flatnonzero(keep.any(axis=tuple(b for b in range(3) if b != a)))[-1]
                     for a in range(3)])
    nlo = origin + (kmin - 0.5) * vs
    nhi = origin + (kmax + 0.5) * vs
    return np.maximum(nlo, lo), np.minimum(nhi, hi)


def _integral(mask) -> tuple:
    """``(summed-area table, fx, fy)`` of a silhouette: of its small mask when it is upsampled
    by (fx, fy) (:func:`_upsampled`; 1/(fx·fy) of the work), else of itself (1, 1)."""
    up = _upsampled(mask)
    if up is not None:
        return cv2.integral(np.ascontiguousarray(up[0], dtype=np.uint8)), up[1], up[2]
    return cv2.integral(np.ascontiguousarray(mask, dtype=np.uint8)), 1, 1


def fit_box(cameras, masks, tolerance: int = 0, within=None) -> tuple | None:
    """World box (lo, hi) that contains the visual hull of one frame, or None when it is empty.

    The box of the intersection of the silhouette-bounding-rectangle cones (exact, by linear
    programming; with ``tolerance = k``, the union over every choice of k cameras left out),
    shrunk by two conservative coarse passes (see the module docstring). With ``within`` (a box
    known to contain the part of the hull of interest, e.g. the capture volume) the linear
    programs are skipped and the coarse passes start from that box (``refocus`` does this).
    """
    if within is not None:
        lo, hi = (np.asarray(v, dtype=float) for v in within)
        passes = 3
    else:
        b = _cone_box(cameras, masks, tolerance)
        if b is None:
            return None
        lo, hi = b
        passes = 2
    intr = np.stack([camera_intrinsics(c) for c in cameras])
    sats = [_integral(m) for m in masks]
    for _ in range(passes):
        r = _coarse_shrink(cameras, masks, lo, hi, tolerance, intr=intr, sats=sats)
        if r is None:
            return None
        lo, hi = r
    return lo, hi


def _cone_box(cameras, masks, tolerance):
    planes = [_silhouette_planes(c, m) for c, m in zip(cameras, masks)]
    C = len(cameras)
    fb = _fallback_box(cameras)
    boxes = []
    for drop in itertools.combinations(range(C), tolerance):
        pl = [p for q, p in enumerate(planes) if q not in drop]
        if any(p is None for p in pl):
            continue
        b = _lp_box(pl, fb) if pl else fb
        if b is not None:
            boxes.append(b)
    if not boxes:
        return None
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    pad = 1e-6 * max(float((hi - lo).max()), 1e-9)
    return lo - pad, hi + pad


@dataclass(frozen=True)
class VolumeFit:
    """How a capture volume is fitted to the silhouettes (no ``[capture.volume]``).

    Parameters
    ----------
    samples : int
        Frames sampled evenly across the whole sequence, first and last included (all frames
        when there are fewer). Each gives its hull's box (:func:`frame_box`); the volume is
        their union grown by ``margin``. A frame whose subject reaches beyond it (it moved or
        jumped between two samples) is carved on a grid of its own, with the same voxels
        (:func:`visual_hull`).
    margin : float
        The grid reaches beyond the union on each side by this fraction of its longest side,
        with the voxels the union alone gives (``resolution`` voxels along its longest side,
        :func:`fitted_grid`): room for the subject between samples at no loss of resolution.
    """

    samples: int = 12
    margin: float = 0.05


#: the default fit (``docs/decisions.md``: first frame and frames beyond the volume on the
#: child recording, ``benchmarks/real.py --child``)
VOLUME_FIT = VolumeFit()


@dataclass(frozen=True)
class MaskResolution:
    """The resolution a grid's silhouette test needs: each camera's mask is read reduced by an
    integer factor (:func:`topopose.capture.io.reduce_mask`, block majority) while a voxel at
    the grid's centre still spans ``pixels_per_voxel`` reduced pixels.

    Parameters
    ----------
    pixels_per_voxel : float
        Reduced pixels across a voxel at the grid's centre (at least).
    max_factor : int
        The largest reduction.
    """

    pixels_per_voxel: float = 1.25
    max_factor: int = 8


#: the reduction ``FrameEstimator(mask_resolution=True)`` uses (off by default:
#: ``docs/decisions.md``)
MASK_RESOLUTION = MaskResolution()


def mask_factors(cameras, origin, voxel_size, shape, res: MaskResolution = MASK_RESOLUTION) -> list:
    """Per camera, the reduction of its masks for a grid (``origin``, ``voxel_size``,
    ``shape``): the largest integer ≤ ``max_factor`` that divides the image's width and height
    and leaves a voxel at the grid's centre ``pixels_per_voxel`` reduced pixels wide (1: full
    resolution)."""
    centre = np.asarray(origin, float) + (np.asarray(shape) - 1) / 2 * float(voxel_size)
    out = []
    for cam in cameras:
        depth = float((cam.R @ centre + cam.translation)[2])
        f = float(min(cam.matrix[0, 0], cam.matrix[1, 1]))
        k = int(min(res.max_factor, f * float(voxel_size) / max(depth, 1e-9)
                    / float(res.pixels_per_voxel))) if depth > 0 else 1
        w, h = cam.size
        while k > 1 and (w % k or h % k):
            k -= 1
        out.append(max(1, k))
    return out


def _sample_frames(frames: list, samples: int = _SAMPLE) -> list:
    if len(frames) <= samples:
        return list(frames)
    idx = np.unique(np.round(np.linspace(0, len(frames) - 1, samples)).astype(int))
    return [frames[i] for i in idx]


def frame_box(cameras, masks, tolerance: int = 0) -> tuple | None:
    """A box (lo, hi) holding one frame's hull, cheaply: the box of the intersection of all
    the silhouettes' bounding-rectangle cones (six linear programs, :func:`fit_box`'s first
    step at tolerance 0) grown by half its size on each side, shrunk by :func:`fit_box`'s
    conservative coarse passes at ``tolerance``. A camera that misses the subject (no cone
    to intersect): :func:`fit_box` itself. None: no subject."""
    b = _cone_box(cameras, masks, 0)
    if b is None:
        return fit_box(cameras, masks, tolerance)
    grow = 0.5 * (b[1] - b[0])
    return fit_box(cameras, masks, tolerance, within=(b[0] - grow, b[1] + grow))


def _sampled_boxes(cap, tolerance, fit: VolumeFit = VOLUME_FIT) -> list:
    key = ("fitted_boxes", tolerance, fit)
    if key not in cap.cache:
        from topopose.capture.io import read_direct

        boxes = []
        frames = _sample_frames(cap.frames, fit.samples)
        # masks read reduced by at most 4, a reduced pixel set when any of its block is: the
        # boxes hold the full masks' hulls, for a sixteenth of the summing
        factors = []
        for cam in cap.cameras:
            k = 4
            while k > 1 and (cam.size[0] % k or cam.size[1] % k):
                k -= 1
            factors.append(k)
        # the next frame read (not through a prefetch: it would skip frames) during this one's box
        with ThreadPoolExecutor(max_workers=1) as reader:
            nxt = reader.submit(read_direct, cap, frames[0], factors, "any") if frames else None
            for i in range(len(frames)):
                fut = nxt
                if i + 1 < len(frames):
                    nxt = reader.submit(read_direct, cap, frames[i + 1], factors, "any")
                try:
                    masks = fut.result()
                except InputError:      # a broken frame is reported when it is processed
                    continue
                b = frame_box(cap.cameras, masks, tolerance)
                if b is not None:
                    boxes.append(b)
        cap.cache[key] = boxes
    return cap.cache[key]


def uses_soft_fusion(cap) -> bool:
    """Whether the capture's silhouettes are probabilities fused by the soft hull (:mod:`.soft`,
    Franco & Boyer's occupancy grid) rather than hard masks carved by :func:`visual_hull`."""
    from topopose.capture.options import SEQUENCE_METHODS

    p = cap.options.get("silhouettes") or {}
    return (cap.masks is None and cap.options.get("source") in ("images", "videos")
            and p.get("method") in SEQUENCE_METHODS
            and (p.get("fusion") == "soft" or (p.get("fusion") == "auto" and p.get("method") != "person")))


def _soft_table(cap, origin, vs, shape):
    from topopose.capture.background import scaled_camera
    from topopose.hull.soft import voxel_pixels

    key = ("soft_pix", tuple(np.round(np.asarray(origin) / vs, 6)), round(vs, 12), tuple(shape))
    if key not in cap.cache:
        s = float(cap.options["silhouettes"]["scale"])
        cap.cache[key] = voxel_pixels([scaled_camera(c, s) for c in cap.cameras], origin, vs, shape)
    return cap.cache[key]


def _bbox(occ) -> np.ndarray:
    """Carver-style stats of an occupancy: [6:9] inclusive min, [9:12] max (-1: empty)."""
    st = np.zeros(12, dtype=np.int64)
    st[9:12] = -1
    for ax in range(3):
        other = tuple(a for a in range(3) if a != ax)
        nz = np.flatnonzero(occ.any(axis=other))
        if nz.size == 0:
            return st
        st[6 + ax], st[9 + ax] = nz[0], nz[-1]
    return st


def _soft_carve(cap, pix, maps, shape):
    """Soft hull of one frame (:mod:`.soft`), opened by ``open3d``, and its bounding box."""
    from scipy import ndimage

    from topopose.hull.soft import soft_carve

    p = cap.options["silhouettes"]
    occ, n = soft_carve(pix, maps, shape, float(p["p_detect"]), float(p["p_false"]),
                        float(p["occupancy"]))
    st = _bbox(occ)
    k = int(p.get("open3d", 0))
    if k > 0 and n:
        # opening by a (2k + 1)³ cube (minimum then maximum filter, separable, on the bounding
        # box): removes the hairs a noisy surface gives the skeleton as spurious branches
        bb = tuple(slice(int(a), int(b) + 1) for a, b in zip(st[6:9], st[9:12]))
        sub = np.pad(occ[bb], k)
        sub = ndimage.maximum_filter(ndimage.minimum_filter(sub, 2 * k + 1, mode="constant"),
                                     2 * k + 1, mode="constant")[k:-k, k:-k, k:-k]
        occ[bb] = sub
        st = _bbox(occ)
    return occ.view(bool), st


def _person_grid(cap) -> bool:
    """Silhouette method ``"person"`` without ``[capture.volume]`` (see the module docstring)."""
    return cap.volume is None and (cap.options.get("silhouettes") or {}).get("method") == "person"


#: ``"person"``: how far (metres) the zone grid reaches beyond the first frame's box
PERSON_ZONE = 1.0


def _person_zone(cap, resolution, tolerance, name=None, masks=None) -> tuple:
    """``"person"``: ``(voxel size, zone grid (origin, shape))``, cached. The voxel size is
    the longest side of the hull box of the capture's first frame with a subject
    (:func:`fit_box`), grown by ⅔ ``zone_margin`` on each side (10 cm by default), divided by
    ``resolution`` − 2; the zone is that box grown by :data:`PERSON_ZONE` on each side, on the
    lattice of multiples of the voxel size. One frame segmented, not 32 sampled ones (on the
    Pose2Sim recording 8–44 s; none more when the frame processed, ``name`` with its
    silhouettes ``masks``, is that frame), and the same whatever frames are processed, in
    whatever order."""
    from topopose.capture.options import UNITS

    key = ("person_zone", resolution, tolerance)
    if key not in cap.cache:
        unit = UNITS.get(cap.units, 1.0)
        m = float(cap.options["silhouettes"]["zone_margin"]) / unit * 2 / 3
        for f in cap.frames:
            try:
                sil = masks if f == name and masks is not None else cap.silhouettes(f)
                b = fit_box(cap.cameras, sil, tolerance)
            except InputError:          # a broken frame is reported when it is processed
                continue
            if b is not None:
                break
        else:
            raise InputError(f"{cap.path or 'capture'}: cannot size the voxel grid: no frame "
                             f"has a subject seen by the cameras (set [capture.volume] in "
                             f"capture.toml)")
        vs = (float((b[1] - b[0]).max()) + 2 * m) / (resolution - 2)
        z = PERSON_ZONE / unit
        ilo = np.floor((b[0] - z) / vs).astype(int)
        ihi = np.ceil((b[1] + z) / vs).astype(int)
        cap.cache[key] = vs, (ilo * vs, tuple(int(x) for x in ihi - ilo + 1))
    return cap.cache[key]


def capture_box(cap, tolerance: int = 0, fit: VolumeFit = VOLUME_FIT) -> tuple:
    """The capture volume (lo, hi): ``cap.volume``, the box the subject sweeps (silhouettes
    learned from the sequence, :mod:`topopose.capture.background`), or fitted to frames
    sampled across the sequence (``fit``, :class:`VolumeFit`; cached).

    Silhouette method ``"person"`` does not use it: its grid follows the subject
    (:func:`visual_hull`).
    """
    return _capture_volume(cap, tolerance, fit)[:2]


def _capture_volume(cap, tolerance, fit) -> tuple:
    """(lo, hi, sampled): :func:`capture_box`, and whether it was fitted to sampled frames."""
    if cap.volume is not None:
        lo, hi = (np.asarray(v, dtype=float) for v in cap.volume)
        return lo, hi, False
    if (cap.options.get("silhouettes") or {}).get("method") in (
            "sequence", "selfie", "sequence+selfie"):
        from topopose.capture.background import subject_box

        box = subject_box(cap)
        if box is not None:
            return box[0], box[1], False
    boxes = _sampled_boxes(cap, tolerance, fit)
    if not boxes:
        raise InputError(f"{cap.path or 'capture'}: cannot fit a capture volume: no sampled frame "
                         f"has a subject seen by the cameras (set [capture.volume] in capture.toml)")
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0), True


def fitted_grid(cap, tolerance: int, resolution: int, fit: VolumeFit = VOLUME_FIT) -> tuple:
    """(origin, voxel_size, shape) of the grid on the capture volume (:func:`capture_box`, no
    ``[capture.volume]``): :func:`grid_for_box` with its one-voxel margin, and, when fitted to
    sampled frames, grown on each side by ``fit.margin`` × the volume's longest side in voxels
    of the same size."""
    lo, hi, sampled = _capture_volume(cap, tolerance, fit)
    origin, vs, shape = grid_for_box(lo, hi, resolution, margin=True)
    k = int(math.ceil(fit.margin * (max(shape) - 2) - 1e-9)) if sampled else 0
    return origin - k * vs, vs, tuple(int(s) + 2 * k for s in shape)


def grid_for_box(lo, hi, resolution: int, margin: bool) -> tuple:
    """(origin, voxel_size, shape) of a grid with ``resolution`` voxels along the box's longest side.

    ``margin=True``: the box spans N − 2 voxels and one empty voxel is added on each side.
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    ext = hi - lo
    n = resolution - 2 if margin else resolution
    vs = float(ext.max()) / n
    shape = np.maximum(1, np.ceil(ext / vs - 1e-6).astype(int))
    if margin:
        shape = shape + 2
    centre = (lo + hi) / 2
    origin = centre - (shape - 1) / 2 * vs
    return origin, vs, tuple(int(s) for s in shape)


def _check_volume_arg(volume) -> tuple:
    try:
        lo, hi = (np.asarray(v, dtype=float).reshape(3) for v in volume)
    except (TypeError, ValueError):
        raise InputError(f"visual_hull: argument volume must be (min xyz, max xyz), got {volume!r}") from None
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(lo >= hi):
        raise InputError(f"visual_hull: argument volume needs finite min < max on every axis, "
                         f"got {volume!r}")
    return lo, hi


def get_carver(cap, origin, voxel_size, shape) -> HullCarver:
    """The :class:`HullCarver` of a grid, cached on the capture (a few grids at most)."""
    key = ("carver", tuple(np.round(np.asarray(origin) / voxel_size, 6)), round(voxel_size, 12),
           tuple(shape))
    store = cap.cache.setdefault("carvers", {})
    if key in store:
        store[key] = store.pop(key)         # most recently used last
        return store[key]
    carver = HullCarver(cap.cameras, origin, voxel_size, shape)
    store[key] = carver
    while len(store) > _MAX_CARVERS:
        store.pop(next(iter(store)))
    return carver


# --------------------------------------------------------------------------- main entry
def _refocus_grid(cap, resolution, tolerance, name, masks, user_box, person, lattice=None):
    """The grid refocused on the subject (thesis §13.2.2.1): ``(voxel size, origin, shape,
    empty)``, empty when no box holds the subject. ``lattice`` ``(voxel size, origin)``: a
    frame beyond the fitted volume, on that grid's voxels and lattice, its box fitted whole
    (:func:`frame_box`)."""
    empty = False
    base = np.zeros(3)
    # the subject's box: coarse passes over the capture volume (given, or fitted to the
    # sampled frames and enlarged by a quarter on each side for frames outside the sample;
    # "person": the frame's own cone box, on the zone grid's lattice)
    if lattice is not None:
        vs, base = lattice
    elif person:
        vs, within = _person_zone(cap, resolution, tolerance, name, masks)[0], None
    else:
        vs = _refocus_voxel_size(cap, resolution, tolerance, user_box)
        if user_box is not None:
            within = user_box
        else:
            glo, ghi = capture_box(cap, tolerance)
            grow = 0.25 * (ghi - glo)
            within = (glo - grow, ghi + grow)
    box = (frame_box(cap.cameras, masks, tolerance) if lattice is not None
           else fit_box(cap.cameras, masks, tolerance, within=within))
    if box is not None and user_box is not None:
        box = (np.maximum(box[0], user_box[0]), np.minimum(box[1], user_box[1]))
        if np.any(box[0] >= box[1]):
            box = None
    if box is None:
        empty = True
        c = np.mean(user_box, axis=0) if user_box is not None else np.mean(
            [cam.center for cam in cap.cameras], axis=0)
        box = (c - vs, c + vs)
    ilo = np.floor((box[0] - base) / vs + 0.5).astype(int) - 1
    ihi = np.ceil((box[1] - base) / vs - 0.5).astype(int) + 1
    if user_box is not None:            # no margin beyond the capture volume
        ulo = np.ceil(user_box[0] / vs - 0.5 - 1e-9).astype(int)
        uhi = np.floor(user_box[1] / vs - 0.5 + 1e-9).astype(int)
        ilo, ihi = np.maximum(ilo, ulo), np.minimum(ihi, np.maximum(uhi, ulo))
    shape = tuple(int(s) for s in np.maximum(ihi - ilo + 1, 1))
    origin = base + ilo * vs
    return vs, origin, shape, empty


def _kept_components(occ, st, shape, consensus, max_removed, keep_largest):
    """The carved grid's kept voxels: the consensus hull, or the largest 26-component;
    ``(occ, dropped, voxels, lo, hi, touches_border, consensus diagnostics, empty)``."""
    empty = False
    dropped, nvox, touches = [], 0, False
    lo_i = hi_i = None
    cdiag = {}
    if consensus is not None:
        if st[9] >= st[6]:
            dropped, nvox, lo_i, hi_i, cdiag = consensus_hull_labels(
                occ, st[6:9], st[9:12], int(consensus), float(max_removed))
            touches = bool(np.any(lo_i == 0) or np.any(hi_i == np.array(shape) - 1))
        else:
            empty = True
            cdiag = {"consensus": {"repair": int(consensus), "strict_voxels": 0,
                                   "tolerant_voxels": 0, "path": "one-pass"}}
        occ = occ.view(bool)
    elif st[9] >= st[6]:
        lo_i, hi_i = st[6:9].astype(int), st[9:12].astype(int)
        bb = tuple(slice(int(a), int(b) + 1) for a, b in zip(lo_i, hi_i))
        if keep_largest:
            dropped = keep_largest_component(occ, bb)
        sub = occ[bb]
        nvox = int(np.count_nonzero(sub))
        if dropped:                     # the kept component's own bounding box
            for ax in range(3):
                other = tuple(a for a in range(3) if a != ax)
                nz = np.flatnonzero(sub.any(axis=other))
                lo_i[ax], hi_i[ax] = lo_i[ax] + nz[0], lo_i[ax] + nz[-1]
        touches = bool(np.any(lo_i == 0) or np.any(hi_i == np.array(shape) - 1))
    else:
        empty = True
    return occ, dropped, nvox, lo_i, hi_i, touches, cdiag, empty


def _checked_args(C, resolution, tolerance, consensus, max_removed) -> tuple:
    """:func:`visual_hull`'s ``resolution``, ``tolerance`` (``C`` cameras) and ``consensus``
    checked (:class:`InputError`); ``consensus`` None with tolerance 0 (the strict hull is its
    own consensus)."""
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 4:
        raise InputError(f"visual_hull: argument resolution must be an integer ≥ 4, got {resolution!r}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, np.integer)) or not 0 <= tolerance < C:
        raise InputError(f"visual_hull: argument tolerance must be an integer in 0..{C - 1}, "
                         f"got {tolerance!r}")
    resolution, tolerance = int(resolution), int(tolerance)
    if consensus is not None:
        if isinstance(consensus, bool) or not isinstance(consensus, (int, np.integer)) or consensus < 0:
            raise InputError(f"visual_hull: argument consensus must be None or an integer ≥ 0, "
                             f"got {consensus!r}")
        if not 0.0 <= float(max_removed) <= 1.0:
            raise InputError(f"visual_hull: argument max_removed must be in [0, 1], got {max_removed!r}")
        if tolerance == 0:
            consensus = None            # the strict hull is its own consensus
    return resolution, tolerance, consensus


def visual_hull(cap, frame, resolution: int = 100, tolerance: int = 0, refocus: bool = False,
                keep_largest: bool = True, volume=None, masks=None, consensus: int | None = None,
                max_removed: float = 0.2, _lattice=None) -> Volume:
    """Volumetric visual hull of one frame (thesis §2.3.2.2).

    Parameters
    ----------
    cap : Capture
    frame : str or int
        Frame name or index.
    resolution : int
        Voxels along the longest side of the capture volume (or of the subject with ``refocus``).
    tolerance : int
        Keep a voxel seen as subject by at least C − ``tolerance`` cameras (robustness to bad
        masks). A voxel whose centre projects outside an image is not seen as subject there.
    refocus : bool
        Grid refocused on the subject every frame, fixed voxel size (thesis §13.2.2.1).
    keep_largest : bool
        Keep only the largest 26-connected component (the others are listed in diagnostics).
    volume : (min xyz, max xyz), optional
        Capture volume overriding ``cap.volume`` / the fitted one.
    masks : list of bool arrays, optional
        Silhouettes to use instead of ``cap.silhouettes(frame)``.
    consensus : int, optional
        The *consensus hull* (with ``tolerance`` > 0; ignored at 0): keep a tolerant voxel
        only within ``consensus`` voxels (steps in the 26-neighbourhood; 0: the strict hull
        itself) of the strict hull (tolerance 0) of the same grid, then the largest
        26-component. See :func:`consensus_hull_labels` for the reason and the algorithm (one
        carve gives both hulls). None: off.
    max_removed : float
        With ``consensus``: when the restriction would remove more than this fraction of the
        tolerant hull's largest component, that component is kept as it is (one camera lost the
        subject or much of it — what the tolerance is for; ``consensus_skipped`` in the
        diagnostics).

    Returns
    -------
    Volume
        ``diagnostics``: ``components_dropped`` (sizes of the dropped components of the
        (tolerant) hull, largest first), ``voxels``, ``bbox`` (inclusive voxel index box
        ``([imin, jmin, kmin], [imax, jmax, kmax])`` holding every voxel of ``data``, or None
        when empty), ``touches_border``, ``grid`` ("fixed",
        "refocus", "zone" or "beyond"), ``timings_ms`` (silhouettes, fit, setup, carve, components — the latter
        includes the consensus), ``work`` (kernel counters); with ``consensus``:
        ``consensus_removed`` (voxels the restriction removed) or ``consensus_skipped``
        (voxels it would have removed), and ``consensus`` (``repair``, ``strict_voxels``,
        ``tolerant_voxels`` of the whole grid, ``path``: "one-pass" or "labelled").

    Raises
    ------
    InputError
        Bad arguments, or a frame that cannot be read (see ``Capture.silhouettes``).
    """
    resolution, tolerance, consensus = _checked_args(len(cap.cameras), resolution, tolerance,
                                                     consensus, max_removed)
    t = {}
    t0 = time.perf_counter()
    name = cap.frame_name(frame)
    soft = masks is None and uses_soft_fusion(cap)
    maps = None
    if soft:
        from topopose.capture.background import foreground_maps
        maps = foreground_maps(cap, name)
        if refocus:
            masks = cap.silhouettes(name)
    elif masks is None:
        masks = cap.silhouettes(name)
    t["silhouettes"] = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    user_box = _check_volume_arg(volume) if volume is not None else None
    if user_box is None and cap.volume is not None:
        user_box = _check_volume_arg(cap.volume)
    empty = False
    fitted = False                      # on the volume fitted to sampled frames
    person = user_box is None and _person_grid(cap)
    if refocus:
        vs, origin, shape, empty = _refocus_grid(cap, resolution, tolerance, name, masks,
                                                 user_box, person, _lattice)
    elif person:
        vs, (origin, shape) = _person_zone(cap, resolution, tolerance, name, masks)
    else:
        if user_box is not None:
            origin, vs, shape = grid_for_box(*user_box, resolution, margin=False)
        else:
            origin, vs, shape = fitted_grid(cap, tolerance, resolution)
            fitted = not soft
    t["fit"] = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    if soft:
        pix = _soft_table(cap, origin, vs, shape)
        t["setup"] = (time.perf_counter() - t0) * 1e3
        t0 = time.perf_counter()
        occ, st = _soft_carve(cap, pix, maps, shape)
        consensus = None
        t["carve"] = (time.perf_counter() - t0) * 1e3
    else:
        carver = get_carver(cap, origin, vs, shape)
        t["setup"] = (time.perf_counter() - t0) * 1e3
        t0 = time.perf_counter()
        occ = carver.carve(masks, tolerance, levels=consensus is not None)
        st = carver.stats.copy()
        t["carve"] = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    occ, dropped, nvox, lo_i, hi_i, touches, cdiag, none = _kept_components(
        occ, st, shape, consensus, max_removed, keep_largest)
    empty = empty or none
    t["components"] = (time.perf_counter() - t0) * 1e3
    bbox = None if lo_i is None or nvox == 0 else ([int(x) for x in lo_i], [int(x) for x in hi_i])
    total = nvox + sum(dropped)
    diag = {"frame": name, "voxels": nvox, "bbox": bbox,
            "components_dropped": dropped, "touches_border": touches,
            # what was lost: each dropped component's share of all hull voxels, and the kept one's
            "components_share": [round(d / total, 4) for d in dropped] if total else [],
            "largest_share": round(nvox / total, 4) if total else 0.0,
            "fusion": "soft" if soft else "hard",
            "grid": "refocus" if refocus else "zone" if person else "fixed",
            "tolerance": tolerance,
            "empty": empty, "timings_ms": t,
            "work": {"blocks": int(st[0]), "voxel_tests": int(st[1]), "projections": int(st[2]),
                     "full_blocks": int(st[3]), "empty_blocks": int(st[4])}, **cdiag}
    if fitted and touches:
        # the subject reaches beyond the volume fitted to the sampled frames (it jumped between
        # two of them): carved on a grid of its own, with the same voxels on the same lattice
        vol = visual_hull(cap, name, resolution, tolerance, True, keep_largest, volume, masks,
                          consensus, max_removed, _lattice=(vs, origin))
        vol.diagnostics["grid"] = "beyond"
        vol.diagnostics["timings_ms"]["silhouettes"] = t["silhouettes"]
        return vol
    if person and not refocus:
        if touches:                     # the subject left the zone: a grid of its own
            vol = visual_hull(cap, name, resolution, tolerance, True, keep_largest, volume,
                              masks, consensus, max_removed)
            vol.diagnostics["timings_ms"]["silhouettes"] = t["silhouettes"]
            return vol
        # cropped to the hull's box and a one-voxel empty margin (the refocused grid's)
        lo = np.zeros(3, int) if bbox is None else np.array(bbox[0]) - 1
        hi = np.zeros(3, int) if bbox is None else np.array(bbox[1]) + 1
        occ = np.ascontiguousarray(occ[tuple(slice(a, b + 1) for a, b in zip(lo, hi))])
        origin = origin + lo * vs
        if bbox is not None:
            diag["bbox"] = ([1, 1, 1], [int(x) for x in hi - lo - 1])
    return Volume(occ, origin, vs, diag)


def _refocus_voxel_size(cap, resolution, tolerance, user_box) -> float:
    key = ("refocus_voxel", resolution, tolerance)
    if key not in cap.cache:
        boxes = _sampled_boxes(cap, tolerance)
        if user_box is not None:
            boxes = [(np.maximum(b[0], user_box[0]), np.minimum(b[1], user_box[1])) for b in boxes]
            boxes = [b for b in boxes if np.all(b[0] < b[1])]
        if boxes:
            ext = max(float((b[1] - b[0]).max()) for b in boxes)
        elif user_box is not None:
            ext = float((user_box[1] - user_box[0]).max())
        else:
            raise InputError(f"{cap.path or 'capture'}: cannot size the refocused grid: no sampled "
                             f"frame has a subject seen by the cameras")
        cap.cache[key] = ext / (resolution - 2)
    return cap.cache[key]


