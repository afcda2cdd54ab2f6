"""Silhouettes when there is no empty scene: a background learned from the sequence itself, and
a per-pixel foreground probability (``[silhouettes] method = "sequence"``, ``"selfie"`` or
``"sequence+selfie"`` in ``capture.toml``).

The subject of a real recording often never leaves its place (a temporal median then holds the
torso) and other people move behind it. The background model of each camera is built once per
capture from ``samples`` frames spread over the sequence, at ``scale`` of the image size:

1. **Temporal median** ``M`` of the samples and *motion masks* (samples whose largest channel
   difference from ``M`` exceeds ``threshold``).
2. **Where the subject is, in 3D** (multi-view reasoning): the motion masks of each sample are
   carved into a coarse grid around the point the optical axes converge to (all cameras must
   agree, so people moving behind the subject in one view do not count); the union over the
   samples, largest 26-component, dilated, is the region the subject sweeps. Its projection
   into each camera (holes filled) is the *subject zone* — the pixels whose ray passes through
   the subject's 3D region; its box, grown by 2 × ``zone_margin``, is the capture volume.
3. Outside the zone the background is ``M``. Inside, the median may hold the subject, so the
   background there is first *guessed* by inpainting ``M`` from the zone's surroundings
   (OpenCV's Telea inpainting); then, per pixel, the sample closest to that guess is taken when
   it is within ``reveal`` grey levels of it (the frame where that pixel showed the background
   — the subject had moved away); otherwise the pixel was never revealed and keeps the guess,
   marked *uncertain*.

The foreground probability of a pixel (:func:`foreground_probability`) compares it with the
background by brightness and chromaticity distortion (Horprasert et al., ICCV FRAME-RATE 1999):
with α = (I·B)/(B·B), the chromaticity distortion ‖I − αB‖ and the brightness distortion
(α − 1)‖B‖ above α = 1, (``shadow`` − α)‖B‖ below ``shadow``, zero between (a *shadow*:
darker, same colour); their norm d gives
p = 1 / (1 + exp(−(d − threshold) / (threshold / 4))). Pixels that were never revealed get
``p = 0.5 + (p − 0.5) · uncertain`` (a weaker vote either way). Probabilities are uint8
(0-255), at ``scale`` of the image size, and fused into the hull by
:func:`topopose.hull.soft.soft_carve` (Franco & Boyer's occupancy grid).

``"person"`` learns no background (the network alone, :mod:`.segment`). Without
``[capture.volume]`` its grid follows the subject, one voxel size for the capture
(:func:`topopose.hull.visual_hull`).

``"selfie"`` uses MediaPipe's selfie-segmentation network (an optional dependency whose model
ships inside the wheel, see :mod:`.segment`) on the zone's bounding rectangle;
``"sequence+selfie"`` takes the network's probability, raised to the background model's where
that one is sure of the subject (p > 0.8) on a background it has seen (the network misses
caps), lowered where it is sure of the background (p < 0.05).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry.camera import Camera
from topopose.capture.options import UNITS
from topopose.capture.sources import SKIPPED



def scaled_camera(cam: Camera, scale: float) -> Camera:
    """The camera of the image resized by ``scale`` (``cv2.INTER_AREA``, pixel centres kept).

    u' = s·u + (s − 1)/2: pixel i' of the small image covers source pixels [i'/s, (i' + 1)/s).
    """
    s = float(scale)
    w, h = (max(1, int(round(x * s))) for x in cam.size)
    S = np.array([[s, 0.0, (s - 1) / 2], [0.0, s, (s - 1) / 2], [0.0, 0.0, 1.0]])
    return Camera(cam.name, (w, h), S @ cam.matrix, cam.distortions, cam.rotation,
                  cam.translation, cam.fisheye)


def small_size(cam: Camera, scale: float) -> tuple:
    return tuple(max(1, int(round(x * scale))) for x in cam.size)


def downscale(img: np.ndarray, cam: Camera, scale: float) -> np.ndarray:
    """Resize a colour image of ``cam`` to ``scale`` (area averaging)."""
    if scale == 1.0:
        return np.ascontiguousarray(img[:, :, :3])
    return cv2.resize(img[:, :, :3], small_size(cam, scale), interpolation=cv2.INTER_AREA)


def axes_convergence(cameras) -> np.ndarray:
    """The point nearest (least squares) to every camera's optical axis."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in cameras:
        d = cam.R[2]                       # optical axis in world coordinates
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ cam.center
    return np.linalg.lstsq(A, b, rcond=None)[0]


def subject_region(cameras_small, motion, unit: float):
    """The 3D region the moving subject sweeps (module docstring, step 2), or None.

    The motion masks of each sample are carved (all cameras must agree) into a 48³ grid of
    3.2 m around the point the optical axes converge to; the union over the samples of the
    voxels carved in at least two samples, its largest 26-component, dilated by one voxel.

    Parameters
    ----------
    cameras_small : cameras of the downscaled images
    motion : list over samples of lists over cameras of bool masks
    unit : capture units per metre

    Returns
    -------
    (centres (n, 3), voxel_size) or None
    """
    from topopose.geometry.carver import HullCarver

    import cc3d
    from scipy import ndimage

    c = axes_convergence(cameras_small)
    half = 1.6 * unit
    n = 48
    vs = 2 * half / n
    origin = c - half + vs / 2
    carver = HullCarver(cameras_small, origin, vs, (n, n, n))
    acc = np.zeros((n, n, n), dtype=np.uint16)
    for masks in motion:
        acc += carver.carve(masks, 0).view(np.uint8)
    occ = acc >= 2
    if not occ.any():
        return None
    lab = cc3d.connected_components(occ, connectivity=26)
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    occ = ndimage.binary_dilation(lab == int(np.argmax(sizes)), np.ones((3, 3, 3), bool))
    return origin + np.argwhere(occ) * vs, vs


def region_zone(cam: Camera, centres, voxel_size) -> np.ndarray:
    """Boolean mask of the projection of a voxel region into ``cam``, holes filled."""
    w, h = cam.size
    zone = np.zeros((h, w), dtype=np.uint8)
    uv = cam.project(centres)
    ok = np.all(np.isfinite(uv), axis=1)
    if not ok.any():
        return zone.astype(bool)
    depth = cam.to_camera(centres[ok])[:, 2]
    rad = np.maximum(1, np.ceil(0.75 * voxel_size * cam.matrix[0, 0] / np.maximum(depth, 1e-9)))
    for (u, v), r in zip(np.round(uv[ok]).astype(int), rad.astype(int)):
        if -r <= u < w + r and -r <= v < h + r:
            cv2.circle(zone, (int(u), int(v)), int(r), 1, -1)
    # fill holes: what the border's background cannot reach
    from scipy import ndimage
    return ndimage.binary_fill_holes(zone.astype(bool))


class SequenceBackground:
    """Background model of one camera learned from the sequence (module docstring).

    Attributes: ``image`` (h, w, 3) uint8 background, ``known`` (h, w) bool (False where the
    background was never revealed and is a guess), ``zone`` (h, w) bool subject zone,
    ``camera`` (the downscaled camera).
    """

    def __init__(self, image, known, zone, camera):
        self.image = image
        self.known = known
        self.zone = zone
        self.camera = camera


def _zone_background(stack, guess, zone, reveal):
    """Background of the zone's pixels (module docstring, step 3): per pixel the sample nearest
    the inpainted ``guess`` when within ``reveal`` of it (known), else the guess (unknown)."""
    ii, jj = np.nonzero(zone)
    x = stack[:, ii, jj].astype(np.float32)                  # (N, m, 3)
    g = guess[ii, jj].astype(np.float32)
    dg = np.sqrt(((x - g[None]) ** 2).sum(-1))               # (N, m)
    k = np.argmin(dg, axis=0)
    r = np.arange(k.size)
    known = dg[k, r] <= reveal
    bg = guess.copy()
    bg[ii, jj] = np.where(known[:, None], x[k, r], g).astype(np.uint8)
    kn = np.zeros(zone.shape, dtype=bool)
    kn[ii, jj] = known
    return bg, kn


def learn_backgrounds(samples, cameras, params, unit) -> tuple:
    """Background models of every camera from ``samples`` (list over cameras of (N, h, w, 3)
    uint8 stacks of downscaled frames) and the downscaled ``cameras`` (module docstring), and
    the subject's region (:func:`subject_region`)."""
    thr = float(params["threshold"])
    meds, motion = [], []
    for stack in samples:
        med = np.median(stack, axis=0).astype(np.uint8)
        meds.append(med)
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        # largest channel difference (as method "diff"), cheaper than the Euclidean one
        motion.append([cv2.morphologyEx((cv2.absdiff(x, med).max(axis=2) > thr).astype(np.uint8),
                                        cv2.MORPH_OPEN, k).astype(bool) for x in stack])
    per_sample = [[motion[c][i] for c in range(len(cameras))] for i in range(len(samples[0]))]
    region = subject_region(cameras, per_sample, unit)
    out = []
    for c, (stack, med, cam) in enumerate(zip(samples, meds, cameras)):
        if region is None:
            zone = np.zeros(med.shape[:2], dtype=bool)
        else:
            zone = region_zone(cam, *region)
        if zone.any():
            guess = cv2.inpaint(med, zone.astype(np.uint8), 5, cv2.INPAINT_TELEA)
            bg, known = _zone_background(stack, guess, zone, float(params["reveal"]))
            bg = np.where(zone[:, :, None], bg, med)
            known |= ~zone
        else:
            bg, known = med, np.ones(med.shape[:2], dtype=bool)
        out.append(SequenceBackground(np.ascontiguousarray(bg), known, zone, cam))
    return out, region


def foreground_probability(img: np.ndarray, bg: SequenceBackground, params) -> np.ndarray:
    """uint8 (h, w) foreground probability (× 255) of a downscaled image (module docstring)."""
    from topopose.capture.background_kernels import colour_probability

    q = np.empty(img.shape[:2], dtype=np.uint8)
    colour_probability(np.ascontiguousarray(img[:, :, :3]), bg.image, bg.known,
                       float(params["threshold"]), float(params["shadow"]),
                       float(params["uncertain"]), q)
    k = int(params["median"])
    if k > 1:
        q = cv2.medianBlur(q, k | 1)
    return q


def sample_frames(frames, n: int) -> list:
    """``n`` frames evenly spaced over the sequence (all when fewer)."""
    if len(frames) <= n:
        return list(frames)
    idx = np.unique(np.round(np.linspace(0, len(frames) - 1, n)).astype(int))
    return [frames[i] for i in idx]


def capture_backgrounds(cap) -> list:
    """The capture's background models (learned once, cached on the capture)."""
    key = ("sequence_backgrounds",)
    if key in cap.cache:
        return cap.cache[key]
    from topopose.capture.images import _frame_source, fit_size

    p = cap.options["silhouettes"]
    s = float(p["scale"])
    cams = [scaled_camera(c, s) for c in cap.cameras]
    names = sample_frames(cap.frames, int(p["samples"]))
    src = _frame_source(cap)
    if src is None:
        raise InputError(f"{cap.path or 'capture'}: no colour frames (images/ or videos/) to "
                         f"learn the background from")

    def read(cam):         # one camera's samples, downscaled (videos: decoded forward)
        out = {}
        for f, images in src.sequential(names, [cam.name]):
            im = images[cam.name]
            if isinstance(im, InputError):
                continue                   # an unreadable frame is not needed here
            try:
                out[f] = downscale(fit_size(cap, src.path(cam.name, f) or cam.name, im, cam),
                                   cam, s)
            except InputError:
                continue
        return out

    t0 = time.perf_counter()
    with ThreadPoolExecutor(len(cap.cameras)) as ex:   # OpenCV decodes without the GIL
        got = list(ex.map(read, cap.cameras))
    ok = [f for f in names if all(f in g for g in got)]
    stacks = [[g[f] for f in ok] for g in got]
    if not ok:
        raise InputError(f"{cap.path}: no readable frame to learn the background from")
    unit = 1.0 / UNITS.get(cap.units, 1.0)
    stacks = [np.stack(x) for x in stacks]
    times = {"decode": time.perf_counter() - t0}
    models, region = learn_backgrounds(stacks, cams, p, unit)
    times["background"] = time.perf_counter() - t0 - sum(times.values())
    cap.cache[key] = models
    box = None
    if region is not None:
        pts, vs = region
        m = 2 * float(p["zone_margin"]) * unit      # the hull may reach beyond the motion
        box = (pts.min(axis=0) - vs / 2 - m, pts.max(axis=0) + vs / 2 + m)
    cap.cache[("setup_seconds",)] = times     # where the set-up's time went (benchmarks)
    cap.cache[("subject_box",)] = box
    return models


def subject_box(cap):
    """(lo, hi) of the 3D region the subject sweeps, grown by 2 × ``zone_margin`` (or None)."""
    capture_backgrounds(cap)
    return cap.cache[("subject_box",)]


def foreground_maps(cap, frame, images=None) -> list:
    """uint8 foreground probabilities of one frame (one per camera, downscaled by
    ``[silhouettes] scale``), cached on the capture for the frame last asked."""
    ck = ("foreground", frame)
    hit = cap.cache.get("foreground_last")
    if hit is not None and hit[0] == ck:
        return hit[1]
    pf = cap.cache.get("prefetch")
    if images is None and pf is not None:       # computed ahead by the reader thread
        ok, maps = pf.take(frame)
        if ok:
            cap.cache["foreground_last"] = (ck, maps)
            return maps
    p = cap.options["silhouettes"]
    method = p["method"]
    s = float(p["scale"])
    if images is None:
        from topopose.capture.images import read_images
        images = read_images(cap, frame)
    if method == "person":       # the network alone needs no background model
        out = _person_maps(cap, frame, images, p)
        cap.cache["foreground_last"] = (ck, out)
        return out
    small = [downscale(img, cam, s) for img, cam in zip(images, cap.cameras)]
    bgs = capture_backgrounds(cap)
    out = []
    for c, (img, bg) in enumerate(zip(small, bgs)):
        q = None
        if method in ("sequence", "sequence+selfie"):
            q = foreground_probability(img, bg, p)
        if method in ("selfie", "sequence+selfie"):
            from topopose.capture.segment import selfie_probability
            q2 = selfie_probability(img, bg.zone, stream=(id(cap), c))
            # the network misses limbs: its "background" is a weak vote (floor), so that the
            # other cameras decide there
            fl = int(round(255 * float(p["selfie_floor"])))
            if fl > 0:
                q2 = np.maximum(q2, fl).astype(np.uint8)
            if q is not None:
                # where the background model has seen the background: raised to its probability
                # where it is sure of the subject (the network misses caps, held objects),
                # lowered where it is sure of the background
                q = np.where(bg.known & (q > 204), np.maximum(q, q2),
                             np.where(bg.known & (q < 13), np.minimum(q, q2), q2))
            else:
                q = q2
        out.append(q)
    cap.cache["foreground_last"] = (ck, out)
    return out


def _person_maps(cap, frame, images, p) -> list:
    """The ``person`` network's probabilities of one frame (:mod:`.segment`). ``person_every
    = n`` > 1: when the frame follows the one segmented last, only the cameras ``c`` with
    ``(index + c) % n == 0`` are segmented (a share 1/n of them, staggered so that every
    camera is segmented every n-th frame); the others keep their map of the frame before,
    at most n - 1 frames old. Otherwise (the first frame, a jump) every camera is segmented
    (and, with ``person_track``, starts a new tracking graph)."""
    from topopose.capture.segment import person_probabilities
    i = cap.frames.index(frame)
    n = int(p.get("person_every", 1))
    last = cap.cache.get("person_last")          # (index, maps) of the frame segmented last
    follows = last is not None and last[0] == i - 1
    cams = [c for c in range(len(cap.cameras)) if not follows or (i + c) % n == 0]
    s = float(p["scale"])
    images = list(images)
    for c in cams:
        if images[c] is SKIPPED:      # not converted by the reader (io._person_needed)
            from topopose.capture.images import _frame_source, fit_size
            cam = cap.cameras[c]
            src = _frame_source(cap)
            images[c] = fit_size(cap, src.path(cam.name, frame) or cam.name,
                                 src.read(cam.name, frame), cam)
    got = person_probabilities([downscale(images[c], cap.cameras[c], s) for c in cams],
                               [(id(cap), c) for c in cams],
                               i if p.get("person_track") else None, n if follows else 0)
    out = list(last[1]) if follows else [None] * len(cap.cameras)
    for c, q in zip(cams, got):
        out[c] = q
    cap.cache["person_last"] = (i, out)
    return out


class UpsampledMask(np.ndarray):
    """A boolean silhouette at the calibration size that is the nearest-neighbour upsampling of
    ``small`` (uint8 0/1, an integer factor smaller on each axis): the hull carver reads
    ``small`` instead (:meth:`topopose.geometry.carver.HullCarver.load_masks`). Arrays derived from
    it (slices, copies, results of operations) do not carry ``small``."""

    small = None


def masks_from_maps(cap, maps) -> list:
    """Boolean silhouettes at the calibration size from probability maps (p > ``[silhouettes]
    cut``, default 0.5). A map an integer factor smaller than its image gives an
    :class:`UpsampledMask`. A camera whose map is the very array of the call before (``person_every``
    keeps a camera's map between its segmentations) gets the mask made then again. ``[silhouettes]
    upsampled = false``: plain full-size masks (the hull then reads every pixel of them)."""
    cut = int(255 * float(cap.options["silhouettes"].get("cut", 0.5)))
    upsampled = bool(cap.options["silhouettes"].get("upsampled", True))
    last = cap.cache.get("masks_last") or []
    out = []
    for c, (q, cam) in enumerate(zip(maps, cap.cameras)):
        if c < len(last) and last[c][0] is q and last[c][1] == (cut, upsampled):
            out.append(last[c][2])
            continue
        m = q > cut
        small = None
        if m.shape != (cam.size[1], cam.size[0]):
            small = m.view(np.uint8)              # 0/1 (views: no copies)
            m = cv2.resize(small, tuple(cam.size), interpolation=cv2.INTER_NEAREST).view(bool)
        h, w = small.shape if small is not None else (0, 0)
        if upsampled and small is not None and cam.size[0] % w == 0 and cam.size[1] % h == 0:
            m = m.view(UpsampledMask)
            m.small = small
        out.append(m)
    cap.cache["masks_last"] = [(q, (cut, upsampled), m) for q, m in zip(maps, out)]
    return out
