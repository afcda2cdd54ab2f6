"""Capture folders: :func:`load_capture` and per-frame silhouette reading (DESIGN.md, "Capture folder").

Errors about the whole capture (calibration, capture.toml, a missing camera folder or background)
are raised by :func:`load_capture`. Errors about one frame (a frame missing for one camera, an
unreadable image, an image whose size differs from the calibration) are raised by
``Capture.silhouettes(frame)``, so a batch run can record that frame as failed and go on.
Frames are the union of the frame names found over the cameras (natural order); frames missing
for some camera are listed in ``cap.options["incomplete_frames"]``.
"""
from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from .calibration import read_calibration, read_capture_options
from .capture import Capture
from .background import SEQUENCE_METHODS
from .silhouettes import extract_silhouette

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


def _natural_key(s: str):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", s)]


def _list_images(folder: Path) -> dict:
    out = {}
    for p in folder.iterdir():
        if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in IMAGE_EXTENSIONS:
            if p.stem in out:
                raise InputError(f"{folder}: two images for frame {p.stem!r} "
                                 f"({out[p.stem].name}, {p.name})")
            out[p.stem] = p
    return out


def load_capture(path) -> Capture:
    """Read a capture folder: calibration, options, frame lists (silhouettes are read lazily).

    Parameters
    ----------
    path : str or Path
        Folder with ``calibration.toml``, optional ``capture.toml``, and either
        ``silhouettes/<camera>/<frame>.png`` or ``images/<camera>/<frame>.png`` plus
        ``backgrounds/<camera>.png``.

    Returns
    -------
    Capture
        ``cap.silhouettes(frame)`` reads (or extracts) the masks of one frame.

    Raises
    ------
    InputError
        Missing folder or calibration, malformed calibration or capture.toml, a camera
        folder or background image absent, no frame at all.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError(f"{root}: capture folder not found")
    cameras = read_calibration(root / "calibration.toml")
    opts = read_capture_options(root / "capture.toml", cameras)
    sil, img = root / "silhouettes", root / "images"
    if sil.is_dir():
        source, base = "silhouettes", sil
    elif img.is_dir():
        source, base = "images", img
    else:
        raise InputError(f"{root}: no silhouettes/ folder (masks) nor images/ folder "
                         f"(colour frames + backgrounds/)")
    files = {}
    for cam in cameras:
        folder = base / cam.name
        if not folder.is_dir():
            raise InputError(f"{folder}: folder of camera {cam.name!r} (calibration.toml) not found")
        files[cam.name] = _list_images(folder)
    backgrounds = {}
    sequence = opts["silhouettes"]["method"] in SEQUENCE_METHODS
    if source == "images" and not sequence:
        bdir = root / "backgrounds"
        for cam in cameras:
            cands = [bdir / f"{cam.name}{e}" for e in IMAGE_EXTENSIONS] if bdir.is_dir() else []
            found = [p for p in cands if p.is_file()]
            if not found:
                raise InputError(f"{bdir / (cam.name + '.png')}: background image of camera "
                                 f"{cam.name!r} not found (needed to extract silhouettes from images/)")
            backgrounds[cam.name] = found[0]
    frames = sorted(set().union(*[set(f) for f in files.values()]), key=_natural_key)
    if not frames:
        raise InputError(f"{base}: no frame images in the camera folders "
                         f"(expected {base}/<camera>/<frame>.png)")
    incomplete = {f: [c.name for c in cameras if f not in files[c.name]] for f in frames}
    incomplete = {f: v for f, v in incomplete.items() if v}
    options = {"source": source, "silhouettes": opts["silhouettes"],
               "incomplete_frames": incomplete, "backgrounds": backgrounds}
    cap = Capture(cameras=cameras, frames=frames, path=root, up=opts["up"], units=opts["units"],
                  fps=opts["fps"], volume=opts["volume"], options=options, files=files)
    for cam in cameras:                      # backgrounds concern every frame: check them now
        if cam.name in backgrounds:
            bg = _imread(backgrounds[cam.name], cv2.IMREAD_COLOR)
            _check_size(backgrounds[cam.name], bg, cam)
            cap.cache[("background", cam.name)] = bg
    return cap


def _imread(path: Path, flags: int) -> np.ndarray:
    try:
        buf = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    img = cv2.imdecode(buf, flags) if buf.size else None
    if img is None:
        raise InputError(f"{path}: unreadable or corrupt image")
    return img


def _check_size(path, img, cam):
    h, w = img.shape[:2]
    if (w, h) != tuple(cam.size):
        raise InputError(f"{path}: image size {w}x{h} differs from the calibration size of camera "
                         f"{cam.name!r} (field 'size' = [{cam.size[0]}, {cam.size[1]}])")


def read_silhouettes(cap: Capture, frame: str) -> list:
    """Boolean masks (h, w) of one frame of a capture folder, one per camera.

    Masks are 8-bit images where > 127 is the subject (colour masks: any channel). Without
    masks, silhouettes are extracted from ``images/`` and ``backgrounds/`` with the
    ``[silhouettes]`` parameters (:func:`~topopose.capture.silhouettes.extract_silhouette`).

    Raises
    ------
    InputError
        The frame is missing for a camera, an image is unreadable, or its size differs from
        the calibration's ``size``.
    """
    if cap.files is None:
        raise InputError(f"{cap.path or 'capture'}: no silhouette files nor in-memory masks")
    out = []
    source = cap.options.get("source", "silhouettes")
    if source == "images" and cap.options["silhouettes"]["method"] in SEQUENCE_METHODS:
        from .background import foreground_maps, masks_from_maps
        return masks_from_maps(cap, foreground_maps(cap, frame))
    for cam in cap.cameras:
        p = cap.files[cam.name].get(frame)
        if p is None:
            raise InputError(f"{Path(cap.path) / source / cam.name}: frame {frame!r} missing for "
                             f"camera {cam.name!r} (other cameras have it)")
        if source == "silhouettes":
            img = _imread(p, cv2.IMREAD_UNCHANGED)
            _check_size(p, img, cam)
            if img.ndim == 3:
                img = img[:, :, :3].max(axis=2)
            if img.dtype != np.uint8:   # 16-bit masks: same rule on the 8-bit scale
                img = (img.astype(np.float64) * (255.0 / np.iinfo(img.dtype).max)
                       if np.issubdtype(img.dtype, np.integer) else img * 255.0)
            out.append(img > 127)
        else:
            bg = cap.cache.get(("background", cam.name))
            if bg is None:
                bp = cap.options["backgrounds"][cam.name]
                bg = _imread(bp, cv2.IMREAD_COLOR)
                _check_size(bp, bg, cam)
                cap.cache[("background", cam.name)] = bg
            img = _imread(p, cv2.IMREAD_COLOR)
            _check_size(p, img, cam)
            out.append(extract_silhouette(img, bg, cap.options.get("silhouettes")))
    return out


def read_images(cap: Capture, frame: str) -> list:
    """Colour images (h, w, 3) uint8 BGR of one frame, one per camera (``images/`` source).

    Raises
    ------
    InputError
        The frame is missing for a camera, an image is unreadable, or its size differs from
        the calibration's ``size``.
    """
    if cap.files is None or cap.options.get("source") != "images":
        raise InputError(f"{cap.path or 'capture'}: no colour images (images/ folder) to read")
    out = []
    for cam in cap.cameras:
        p = cap.files[cam.name].get(frame)
        if p is None:
            raise InputError(f"{Path(cap.path) / 'images' / cam.name}: frame {frame!r} missing for "
                             f"camera {cam.name!r} (other cameras have it)")
        img = _imread(p, cv2.IMREAD_COLOR)
        _check_size(p, img, cam)
        out.append(img)
    return out
