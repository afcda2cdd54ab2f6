"""A capture's colour images and masks as files give them: the size policy, backgrounds, frame sources."""
from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np

from topopose.capture.capture import Capture
from topopose.capture.options import SEQUENCE_METHODS
from topopose.capture.sources import SKIPPED, ImageSource, imread
from topopose.errors import InputError
from topopose.geometry.camera import Camera


def size_policy(cap: Capture, camera: str) -> str:
    """The size policy of ``camera``: ``[cameras.<name>] size_policy``, else ``[capture]``'s."""
    per = (cap.options.get("cameras") or {}).get(camera) or {}
    return per.get("size_policy") or cap.options.get("size_policy") or "error"


def _size_message(where, size, cam) -> str:
    return (f"{where}: image size {size[0]}x{size[1]} differs from the calibration size of camera "
            f"{cam.name!r} (field 'size' = [{cam.size[0]}, {cam.size[1]}]); set size_policy = "
            f"\"pad\" or \"scale\" in [capture] (or [cameras.{cam.name}]) of capture.toml")


def _warn_size(cap, cam, size, where, pol):
    key = ("size_warned", cam.name)
    if key in cap.cache:
        return
    cap.cache[key] = True
    what = ("padded or cropped at the right/bottom to" if pol == "pad"
            else "used with the intrinsics rescaled from")
    ow, oh = cap.options.get("original_sizes", {}).get(cam.name, cam.size)
    warnings.warn(f"{where}: images of camera {cam.name!r} are {size[0]}x{size[1]}, the "
                  f"calibration says {ow}x{oh}: {what} the calibration size "
                  f"(size_policy = \"{pol}\")", stacklevel=3)


def fit_size(cap: Capture, path, img: np.ndarray, cam: Camera) -> np.ndarray:
    """Apply the camera's size policy to an image (or mask) read from ``path``.

    "error": :class:`InputError` naming the file, the sizes and the option; "pad": zero-padded
    or cropped at the right/bottom to the calibration size; "scale": the cameras were rescaled
    at loading, so the size must match the rescaled one.
    """
    h, w = img.shape[:2]
    if (w, h) == tuple(cam.size):
        return img
    pol = size_policy(cap, cam.name)
    if pol != "pad":
        raise InputError(_size_message(path, (w, h), cam))
    _warn_size(cap, cam, (w, h), path, pol)
    W, H = cam.size
    out = np.empty((H, W) + img.shape[2:], dtype=img.dtype)
    out[:min(h, H), :min(w, W)] = img[:min(h, H), :min(w, W)]
    out[h:] = 0                           # the padding only (each byte written once)
    out[:h, w:] = 0
    return out


def _background(cap: Capture, cam: Camera) -> np.ndarray:
    bg = cap.cache.get(("background", cam.name))
    if bg is None:
        bp = cap.options["backgrounds"][cam.name]
        bg = fit_size(cap, bp, imread(bp, cv2.IMREAD_COLOR), cam)
        cap.cache[("background", cam.name)] = bg
    return bg


def _frame_source(cap: Capture):
    src = cap.options.get("frame_source")
    if src is None and cap.options.get("source") == "images" and cap.files is not None:
        src = ImageSource(cap.files, {c: Path(cap.path) / "images" / c for c in cap.files})
    return src


def read_images(cap: Capture, frame: str) -> list:
    """Colour images (BGR, calibration size after the size policy) of one frame, one per camera.

    Raises
    ------
    InputError
        The frame is missing for a camera (or a video is shorter / corrupt there), an image is
        unreadable, or its size differs from the calibration (``size_policy = "error"``).
    """
    src = _frame_source(cap)
    if src is None:
        raise InputError(f"{cap.path or 'capture'}: no colour frames (images/ or videos/)")
    out = []
    for cam in cap.cameras:
        out.append(fit_size(cap, src.path(cam.name, frame) or cam.name,
                            src.read(cam.name, frame), cam))
    return out


def _sequence_method(cap: Capture) -> bool:
    return (cap.options.get("silhouettes") or {}).get("method") in SEQUENCE_METHODS


def image_list(cap: Capture, frame: str, images) -> list:
    """``images`` in camera order, from a list or the ``{camera: image or InputError}`` of a
    frame source (the size policy applied)."""
    if isinstance(images, dict):
        src = _frame_source(cap)
        imgs = []
        for cam in cap.cameras:
            im = images[cam.name]
            if isinstance(im, Exception):
                raise im
            imgs.append(im if im is SKIPPED else      # decoded, not converted: read if wanted
                        fit_size(cap, src.path(cam.name, frame) or cam.name, im, cam))
        images = imgs
    return images
