"""Capture folders: :func:`load_capture` and per-frame silhouette reading (DESIGN.md, "Capture folder").

Errors about the whole capture (calibration, capture.toml, a missing camera folder or background)
are raised by :func:`load_capture`. Errors about one frame (a frame missing for one camera, an
unreadable image, an image whose size differs from the calibration) are raised by
``Capture.silhouettes(frame)``, so a batch run can record that frame as failed and go on.
Frames are the union of the frame names found over the cameras (natural order); frames missing
for some camera are listed in ``cap.options["incomplete_frames"]``.

Videos (``videos/<camera>.mp4``, see :mod:`~topopose.capture.sources`): frames ``000000`` … up to
the longest video; the frames a shorter (or corrupt) video lacks are in ``incomplete_frames`` and
fail with the reason. Folder, video and background names are matched to the calibration names
(:func:`match_cameras`); an image whose size differs from the calibration follows the
``size_policy`` (:func:`fit_size`).
"""
from __future__ import annotations

import functools
import os
import re
import warnings
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.frames import frame_key
from topopose.capture.calibration import read_calibration, read_capture_options
from topopose.geometry.camera import Camera
from topopose.capture.capture import Capture
from topopose.capture.options import SEQUENCE_METHODS
from topopose.capture.silhouettes import extract_silhouette
from topopose.capture.images import (_background, _frame_source, _sequence_method, _size_message,
                                     _warn_size, fit_size, image_list, read_images, size_policy)
from topopose.capture.sources import (MAX_IMAGE_PIXELS, VIDEO_EXTENSIONS, ImageSource, Prefetcher,
                                      VideoSource, imread, png_size)

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


def _list_files(folder: Path, extensions, what: str) -> dict:
    """``{stem: path}`` of the files of ``folder`` with one of ``extensions``; two files with
    the same stem are an error (``what``: "images for frame", "videos for camera")."""
    out = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in extensions:
            if p.stem in out:
                raise InputError(f"{folder}: two {what} {p.stem!r} ({out[p.stem].name}, {p.name})")
            out[p.stem] = p
    return out


def _list_images(folder: Path) -> dict:
    return _list_files(folder, IMAGE_EXTENSIONS, "images for frame")


def _norm_name(s: str) -> str:
    """``cam_01``, ``cam01``, ``Cam1`` → ``cam1``: lower case, no punctuation, no zero padding."""
    s = re.sub(r"[^0-9a-z]", "", s.lower())
    return re.sub(r"\d+", lambda m: str(int(m.group())), s)


def match_cameras(cameras, entries, table: dict, where: Path) -> dict:
    """Calibration name → entry name (a folder, video or background name in ``where``).

    An entry of the ``[cameras]`` table wins, then the exact name, then the one entry whose
    name differs only by case, punctuation or zero padding. Cameras without a match are left
    out; an ambiguous match or two cameras on one entry raise :class:`InputError`.
    """
    entries = list(entries)
    out = {}
    for cam in cameras:
        want = (table.get(cam.name) or {}).get("folder")
        if want is not None:
            if want in entries:
                out[cam.name] = want
            continue
        if cam.name in entries:
            out[cam.name] = cam.name
            continue
        cands = [e for e in entries if _norm_name(e) == _norm_name(cam.name)]
        if len(cands) > 1:
            raise InputError(f"{where}: camera {cam.name!r} of calibration.toml matches both "
                             f"{cands[0]!r} and {cands[1]!r}; name its folder in capture.toml "
                             f"([cameras] {cam.name} = \"{cands[0]}\")")
        if cands:
            out[cam.name] = cands[0]
    seen = {}
    for c, e in out.items():
        if e in seen:
            raise InputError(f"{where}: cameras {seen[e]!r} and {c!r} of calibration.toml both "
                             f"match {e!r}; name their folders in capture.toml ([cameras])")
        seen[e] = c
    return out


def _missing_entry(where: Path, cam, table, what: str) -> InputError:
    want = (table.get(cam.name) or {}).get("folder")
    if want is not None:
        return InputError(f"{where / want}: {what} of camera {cam.name!r} not found "
                          f"(capture.toml [cameras] maps {cam.name!r} to {want!r})")
    return InputError(f"{where / cam.name}: {what} of camera {cam.name!r} (calibration.toml) not "
                      f"found (nor one whose name differs only by case, punctuation or zero "
                      f"padding; or map it in capture.toml [cameras])")


def _list_videos(folder: Path) -> dict:
    return _list_files(folder, VIDEO_EXTENSIONS, "videos for camera")


def _scaled_camera(cam: Camera, size) -> Camera:
    """``cam`` for images of ``size`` (w, h): fx, cx (and the skew) scale by w'/w, fy, cy by h'/h."""
    sx, sy = size[0] / cam.size[0], size[1] / cam.size[1]
    K = cam.matrix.copy()
    K[0, :] *= sx
    K[1, :] *= sy
    K[2] = [0.0, 0.0, 1.0]
    return Camera(cam.name, size, K, cam.distortions, cam.rotation, cam.translation, cam.fisheye)


def _first_size(src, camera, frames) -> tuple:
    """((w, h), path) of the camera's first readable frame ((None, None) when there is none):
    a PNG's header, else the decoded image."""
    for f in frames:
        p = src.path(camera, f)
        if p is None:
            continue
        size = png_size(p)
        if size is not None and 0 < size[0] * size[1] <= MAX_IMAGE_PIXELS:
            return size, p
        try:
            img = imread(p, cv2.IMREAD_UNCHANGED, camera)
        except InputError:                   # that frame fails on its own, with its reason
            continue
        return (img.shape[1], img.shape[0]), p
    return None, None


def load_capture(path) -> Capture:
    """Read a capture folder: calibration, options, frame lists (silhouettes are read lazily).

    Parameters
    ----------
    path : str or Path
        Folder with ``calibration.toml``, optional ``capture.toml``, and one of
        ``silhouettes/<camera>/<frame>.png`` (masks), ``images/<camera>/<frame>.png`` or
        ``videos/<camera>.<mp4|avi|mov|mkv>`` (colour frames, with ``backgrounds/<camera>.png``).
        Folder, video and background names may differ from the calibration names by case,
        punctuation or zero padding (``cam_01`` ↔ ``cam01`` ↔ ``Cam1``), or be mapped by the
        ``[cameras]`` table of ``capture.toml``.

    Returns
    -------
    Capture
        ``cap.silhouettes(frame)`` reads (or extracts) the masks of one frame. With
        ``size_policy = "scale"``, ``cap.cameras`` holds the rescaled cameras.

    Raises
    ------
    InputError
        Missing folder or calibration, malformed calibration or capture.toml, a camera
        folder, video or background image absent, an ambiguous name, no frame at all, a video or
        background whose size differs from the calibration with ``size_policy = "error"``.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError(f"{root}: capture folder not found")
    cameras = read_calibration(root / "calibration.toml")
    opts = read_capture_options(root / "capture.toml", cameras)
    table = opts["cameras"]
    sil, img, vid = root / "silhouettes", root / "images", root / "videos"
    if sil.is_dir():
        source, base = "silhouettes", sil
    elif img.is_dir():
        source, base = "images", img
    elif vid.is_dir():
        source, base = "videos", vid
    else:
        raise InputError(f"{root}: no silhouettes/ folder (masks), images/ folder nor videos/ "
                         f"folder (colour frames + backgrounds/)")
    files, names = {}, {}
    if source == "videos":
        videos = _list_videos(vid)
        names = match_cameras(cameras, videos, table, vid)
        for cam in cameras:
            if cam.name not in names:
                raise _missing_entry(vid, cam, table, "video")
        src = VideoSource({c.name: videos[names[c.name]] for c in cameras},
                          threads=opts["silhouettes"]["decode_threads"])
        frames = list(src.frames)
        if not frames:
            raise InputError(f"{vid}: no readable frame in the videos "
                             f"({'; '.join(src.errors.values()) or 'all are empty'})")
        incomplete = {}
        for i, f in enumerate(frames):
            miss = [c.name for c in cameras if src.missing(c.name, i) is not None]
            if miss:
                incomplete[f] = miss
    else:
        folders = [p.name for p in base.iterdir() if p.is_dir()]
        names = match_cameras(cameras, folders, table, base)
        for cam in cameras:
            if cam.name not in names:
                raise _missing_entry(base, cam, table, "folder")
            files[cam.name] = _list_images(base / names[cam.name])
        src = ImageSource(files, {c.name: base / names[c.name] for c in cameras})
        frames = sorted(set().union(*[set(f) for f in files.values()]), key=frame_key)
        if not frames:
            raise InputError(f"{base}: no frame images in the camera folders "
                             f"(expected {base}/<camera>/<frame>.png)")
        incomplete = {f: [c.name for c in cameras if f not in files[c.name]] for f in frames}
        incomplete = {f: v for f, v in incomplete.items() if v}
    backgrounds = {}
    sequence = opts["silhouettes"]["method"] in SEQUENCE_METHODS   # no empty scene needed
    if source != "silhouettes" and not sequence:
        bdir = root / "backgrounds"
        stems = {}
        if bdir.is_dir():
            for p in sorted(bdir.iterdir()):
                if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS:
                    stems.setdefault(p.stem, p)
        bnames = match_cameras(cameras, stems, table, bdir)
        for cam in cameras:
            if cam.name not in bnames:
                raise InputError(f"{bdir / (cam.name + '.png')}: background image of camera "
                                 f"{cam.name!r} not found (needed to extract silhouettes from "
                                 f"{source}/)")
            backgrounds[cam.name] = stems[bnames[cam.name]]
    fps = opts["fps"]
    if source == "videos" and fps is None:
        rates = [r for r in src.fps.values() if r]
        if rates:
            fps = rates[0]
            if max(rates) > 1.01 * min(rates):
                warnings.warn(f"{vid}: the videos have different frame rates "
                              f"({', '.join(f'{r:g}' for r in rates)}); using {fps:g} "
                              f"(set [capture] fps)", stacklevel=2)
    options = {"source": source, "silhouettes": opts["silhouettes"],
               "incomplete_frames": incomplete, "backgrounds": backgrounds,
               "size_policy": opts["size_policy"], "cameras": table,
               "names": names, "frame_source": src if source != "silhouettes" else None,
               "original_sizes": {c.name: c.size for c in cameras}}
    cap = Capture(cameras=cameras, frames=frames, path=root, up=opts["up"], units=opts["units"],
                  fps=fps, volume=opts["volume"], options=options, files=files or None,
                  reader=read_silhouettes)
    # sizes known now (videos; first image of each folder, a PNG's header): "scale" rescales
    # the cameras, "pad" warns once, "error" stops at once (every frame would fail)
    for k, cam in enumerate(cameras):
        if source == "videos":
            size, where = src.sizes.get(cam.name), src.videos[cam.name]
        else:
            size, where = _first_size(src, cam.name, frames)
        if size is None or tuple(size) == tuple(cam.size):
            continue
        pol = size_policy(cap, cam.name)
        if pol == "error":
            raise InputError(_size_message(where, size, cam))
        _warn_size(cap, cam, size, where, pol)
        if pol == "scale":
            cameras[k] = _scaled_camera(cam, size)
    for cam in cameras:                      # backgrounds concern every frame: check them now
        if cam.name in backgrounds:
            bg = imread(backgrounds[cam.name], cv2.IMREAD_COLOR)
            cap.cache[("background", cam.name)] = fit_size(cap, backgrounds[cam.name], bg, cam)
    return cap


def silhouettes_from_images(cap: Capture, frame: str, images) -> list:
    """Silhouettes of one frame from its colour ``images`` (a list in camera order, or the
    ``{camera: image or InputError}`` of a frame source), with the capture's method."""
    images = image_list(cap, frame, images)
    if _sequence_method(cap):
        from topopose.capture.background import foreground_maps, masks_from_maps
        return masks_from_maps(cap, foreground_maps(cap, frame, images))
    return [extract_silhouette(im, _background(cap, cam), cap.options.get("silhouettes"))
            for cam, im in zip(cap.cameras, images)]


@functools.cache
def decode_pool() -> ThreadPoolExecutor:
    """The threads that decode mask files (one per core; OpenCV decodes without the GIL)."""
    return ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1),
                              thread_name_prefix="topopose-decode")


def reduce_mask(mask, factor: int, rule: str = "majority"):
    """``mask`` read ``factor`` times smaller on each axis: a reduced pixel is set when its
    block of factor × factor pixels is mostly set (``cv2.INTER_AREA``, rounded). Returned as an
    :class:`~topopose.capture.background.UpsampledMask` (the reduced mask upsampled back, its
    ``small`` attribute the reduced one, which the hull carver and the silhouette comparisons
    read). A voxel centre falling in a block is then inside the reduced silhouette only if the
    full one holds a pixel of that block, and outside only if it misses one: the hull lies
    between those of the full silhouettes eroded and dilated by a (2·factor − 1)² square.
    ``factor`` 1 (or a mask already reduced by it): ``mask`` as it is. ``rule="any"``: a
    reduced pixel is set when any pixel of its block is (a hull that holds the full one, for
    fitting boxes)."""
    from topopose.capture.background import UpsampledMask

    k = int(factor)
    if k <= 1:
        return mask
    small = getattr(mask, "small", None)
    h, w = mask.shape
    if small is not None and small.shape == (h // k, w // k):
        return mask
    m8 = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
    if rule == "any":            # the maximum over the block at its top-left pixel
        small = np.ascontiguousarray(
            cv2.dilate(m8, np.ones((k, k), np.uint8), anchor=(0, 0))[: h // k * k:k, : w // k * k:k])
    else:
        small = cv2.resize(m8, (w // k, h // k), interpolation=cv2.INTER_AREA)
    full = cv2.resize(small, (w, h), interpolation=cv2.INTER_NEAREST).view(bool).view(UpsampledMask)
    full.small = small
    return full


def reduce_masks(masks, factors) -> list:
    """:func:`reduce_mask` of each camera's mask by its factor (None: ``masks`` unchanged)."""
    if factors is None:
        return masks
    return [reduce_mask(m, k) for m, k in zip(masks, factors)]


def _read_mask(cap: Capture, cam, p, factor: int = 1, rule: str = "majority"):
    img = fit_size(cap, p, imread(p, cv2.IMREAD_UNCHANGED, cam.name), cam)
    if img.ndim == 3:
        img = img[:, :, :3].max(axis=2)
    if img.dtype != np.uint8:   # 16-bit masks: same rule on the 8-bit scale
        img = (img.astype(np.float64) * (255.0 / np.iinfo(img.dtype).max)
               if np.issubdtype(img.dtype, np.integer) else img * 255.0)
    from topopose.geometry.masks import boxed

    m = img > 127
    return reduce_mask(m, factor, rule) if factor > 1 else boxed(m)


def _read_masks(cap: Capture, frame: str, factors=None, rule: str = "majority") -> list:
    """The masks of one frame, decoded by :func:`decode_pool` (reduced by ``factors`` with
    ``rule``, :func:`reduce_mask`)."""
    base = Path(cap.path) / "silhouettes"
    names = cap.options.get("names") or {}
    paths = []
    for cam in cap.cameras:
        p = cap.files[cam.name].get(frame)
        if p is None:
            raise InputError(f"{base / names.get(cam.name, cam.name)}: frame {frame!r} missing for "
                             f"camera {cam.name!r} (other cameras have it)")
        paths.append(p)
    factors = factors or [1] * len(paths)
    return list(decode_pool().map(lambda a: _read_mask(cap, *a, rule),
                                  zip(cap.cameras, paths, factors)))


def read_silhouettes(cap: Capture, frame: str) -> list:
    """Boolean masks (h, w) of one frame of a capture folder, one per camera.

    Masks are 8-bit images where > 127 is the subject (colour masks: any channel). Without
    masks, silhouettes are extracted from the colour frames (``images/`` or ``videos/``) and
    ``backgrounds/`` with the ``[silhouettes]`` parameters
    (:func:`~topopose.capture.silhouettes.extract_silhouette`). Inside :func:`prefetch` the
    frames come from the reader thread.

    Raises
    ------
    InputError
        The frame is missing for a camera, an image is unreadable, or its size differs from
        the calibration's ``size`` (with ``size_policy = "error"``).
    """
    pf = cap.cache.get("prefetch")
    if pf is not None:
        ok, masks = pf.take(frame)
        if ok:
            if _sequence_method(cap):        # the reader computed probability maps
                from topopose.capture.background import masks_from_maps
                return masks_from_maps(cap, masks)
            return masks
    return _silhouettes_now(cap, frame)


def read_direct(cap: Capture, frame, factors=None, rule: str = "majority") -> list:
    """The silhouettes of ``frame`` read now, never taken from a running :func:`prefetch` (which
    would drop the frames queued before it): for looking at a few frames out of order, e.g.
    fitting the capture volume. ``factors``, ``rule``: reduced as :func:`reduce_mask` says."""
    frame = cap.frame_name(frame)
    if cap.masks is None and cap.options.get("source", "silhouettes") == "silhouettes":
        return _read_masks(cap, frame, factors, rule)      # reduced by the decoding threads
    masks = cap.silhouettes(frame) if cap.masks is not None else _silhouettes_now(cap, frame)
    return masks if factors is None else [reduce_mask(m, k, rule) for m, k in zip(masks, factors)]


def _silhouettes_now(cap: Capture, frame: str, images=None, factors=None) -> list:
    if cap.files is None and cap.options.get("frame_source") is None:
        raise InputError(f"{cap.path or 'capture'}: no silhouette files nor in-memory masks")
    if cap.options.get("source", "silhouettes") == "silhouettes":
        return _read_masks(cap, frame, factors)
    if images is None:
        images = read_images(cap, frame)
    return silhouettes_from_images(cap, frame, images)


def _person_needed(cap: Capture, names: list):
    """For :class:`~.sources.Prefetcher`: ``needed(position, frame)``, the cameras whose images
    the ``person`` method segments in that frame when ``person_every = n`` > 1 (a frame that
    follows the one before it in ``names``: the cameras c with (index + c) % n = 0, as
    :func:`.background._person_maps` picks them; None: all), so that the others are not
    converted from the video; None when every camera is always segmented. A camera that
    :func:`.background._person_maps` wants after all (the frame before failed) is read again."""
    p = cap.options.get("silhouettes") or {}
    n = int(p.get("person_every", 1))
    if p.get("method") != "person" or n <= 1:
        return None
    index = {f: i for i, f in enumerate(cap.frames)}
    pos = [index.get(f) for f in names]

    def needed(k, frame):
        i = pos[k]
        if k == 0 or i is None or pos[k - 1] != i - 1:
            return None
        return {cam.name for c, cam in enumerate(cap.cameras) if (i + c) % n == 0}
    return needed


@contextmanager
def prefetch(cap: Capture, frames, depth: int = 4, factors=None):
    """Within the block, ``cap.silhouettes(f)`` for ``frames`` (in that order) comes from a reader
    thread that decodes the frames sequentially (masks: each frame's cameras in parallel,
    :func:`decode_pool`) and extracts their silhouettes ahead of the computation, at most
    ``depth`` frames ahead; masks are reduced by ``factors`` (per camera, :func:`reduce_mask`)
    as they are decoded. Other frames are read directly. In-memory captures: no effect."""
    if cap.masks is not None or cap.path is None or "prefetch" in cap.cache:
        yield cap
        return
    names = [cap.frame_name(f) for f in frames]
    src = None if cap.options.get("source") == "silhouettes" else _frame_source(cap)
    if _sequence_method(cap):
        # the reader computes the foreground probabilities (the soft hull's input); the
        # background model is learned first, here
        from topopose.capture.background import capture_backgrounds, foreground_maps
        if cap.options["silhouettes"]["method"] != "person":
            capture_backgrounds(cap)

        def work(f, images):
            return foreground_maps(cap, f, image_list(cap, f, images) if images is not None
                                   else None)
    else:
        def work(f, images):
            return _silhouettes_now(cap, f, images, factors)
    pf = Prefetcher(names, work, src, depth,
                    (cap.options.get("silhouettes") or {}).get("decode_ahead", 2),
                    needed=_person_needed(cap, names))
    cap.cache["prefetch"] = pf
    try:
        yield cap
    finally:
        cap.cache.pop("prefetch", None)
        pf.close()
