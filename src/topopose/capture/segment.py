"""Optional person segmentation by a network shipped inside a pip wheel (``[silhouettes]
method = "person"``, ``"selfie"`` or ``"sequence+selfie"``).

``"person"``: MediaPipe's legacy *pose* solution (``mediapipe.solutions.pose``, BlazePose
GHUM "full" model, inside the ``mediapipe`` wheel up to 0.10.14) with its segmentation output:
the network finds the person, crops a region of interest around the whole body and returns a
full-body person probability. Only that probability is used (its landmarks are not): the
pose still comes from the hull's geometry. When it finds no one in a camera's image, that
camera's probability is 0.5 everywhere (no vote).

The network's input is fixed-size (BlazePose: the detector sees 224 × 224, the landmark and
segmentation network a 256 × 256 crop around the person): its compute does not depend on the
image's size, so segmenting a crop around the subject would not cut it (26 / 26 / 29 ms of
CPU per image at 0.125 / 0.25 / 0.5 of 1088 × 1920, ``benchmarks/real.py`` times it). What can
be skipped is the *detector*: ``[silhouettes] person_track = true`` runs MediaPipe in
tracking mode (the region of interest comes from the previous frame's landmarks; the detector
runs only when the person is lost), without mask smoothing: 138 instead of 171 ms of CPU per
4-camera frame of the Pose2Sim recording, the whole process (``benchmarks/results/real.md``).
Off by default, so that a frame's mask never depends on the frames before it: on that
recording tracking is right in as many frames per frame (66 %), fewer as ``topopose run``
writes them (69 against 72 %), and its gate passed one wrong frame where the static mode
passed none. A graph is kept per camera and per run of consecutive
frames: a frame that does not follow the camera's previous one (asked again, out of order)
starts a new graph, which runs the detector as static mode does, so a frame's mask depends
only on the consecutive frames before it in that run. ``false`` (default): every image
segmented alone (``static_image_mode``).

``[silhouettes] person_every = n`` (default 1) segments each camera every n-th frame only, the
cameras staggered (frame i: the cameras c with (i + c) % n = 0; the others keep their map of
the frame before, at most n - 1 frames old; :func:`.background._person_maps`): 1/n of the
network's CPU. Like tracking, a frame's masks then depend on the frames before it in its run.
BlazePose's *lite* model (``model_complexity=0``) is not inside the 0.10.14 wheel: MediaPipe
downloads it on first use (``solutions/pose.py``, ``download_oss_model``), so it is not offered.

MediaPipe's legacy *selfie segmentation* model (``mediapipe.solutions.selfie_segmentation``,
the general 256 × 256 model, ~250 kB, inside the ``mediapipe`` wheel up to 0.10.14: nothing is
downloaded at run time) gives a per-pixel person probability. It is run on the bounding
rectangle of the camera's subject zone (:mod:`.background`), so the person fills the network's
input. Install with ``pip install "topopose[segment]"`` (MediaPipe 0.10.14 requires
``opencv-contrib-python``; the extra keeps it below 5, where it and ``opencv-python-headless``
install the same ``cv2``).
"""
from __future__ import annotations

import threading

import cv2
import numpy as np

from topopose._quiet import native_stderr_silenced
from topopose.errors import InputError

_MODEL = {}
_LOCKS = {}                  # one camera's network is fed by one thread at a time
_LOCK = threading.Lock()     # guards _LOCKS and _POOL
_POOL = []                   # the threads that run several cameras' networks at once


def _process(make, key, rgb, fresh=False):
    """Run the network ``_MODEL[key]`` (made by ``make()`` on first use, or anew when
    ``fresh``) on an RGB image. MediaPipe's graph wants increasing timestamps: calls are
    serialized, and a graph that failed (e.g. a frame asked again out of order) is rebuilt once."""
    with _LOCK:
        lock = _LOCKS.setdefault(key, threading.Lock())
    with lock:
        if fresh or key not in _MODEL:
            with native_stderr_silenced():      # MediaPipe's C++ start-up log lines
                _MODEL[key] = make()
                return _MODEL[key].process(rgb)
        try:
            return _MODEL[key].process(rgb)
        except (RuntimeError, ValueError):
            with native_stderr_silenced():
                _MODEL[key] = make()
                return _MODEL[key].process(rgb)


def _selfie():
    """One segmenter per camera: MediaPipe's solution smooths its masks over the images it is
    given in turn, which must then be one camera's frames, not several cameras'."""
    try:
        from mediapipe.python.solutions import selfie_segmentation
    except ImportError:
        raise InputError("[silhouettes] method \"selfie\" needs MediaPipe ≤ 0.10.14 "
                         "(pip install \"topopose[segment]\")") from None
    return selfie_segmentation.SelfieSegmentation(model_selection=0)


def _pose(track=False):
    try:
        from mediapipe.python.solutions import pose
    except ImportError:
        raise InputError("[silhouettes] method \"person\" needs MediaPipe ≤ 0.10.14 "
                         "(pip install \"topopose[segment]\")") from None
    if track:
        return pose.Pose(static_image_mode=False, model_complexity=1, enable_segmentation=True,
                         smooth_landmarks=False, smooth_segmentation=False)
    return pose.Pose(static_image_mode=True, model_complexity=1, enable_segmentation=True)


_LAST = {}                   # tracking: stream → index of the frame it segmented last


def _rgb(img: np.ndarray) -> np.ndarray:
    """The RGB copy of a BGR image (``cv2.cvtColor`` for 8-bit 3-channel ones: the same bytes
    as ``img[:, :, ::-1]`` made contiguous, several times faster)."""
    if img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return np.ascontiguousarray(img[:, :, ::-1])


def person_probability(img: np.ndarray, stream="", index=None, step=1) -> np.ndarray:
    """uint8 (h, w) full-body person probability (× 255) of a BGR image from MediaPipe's pose
    network (module docstring); 128 everywhere when it finds no one. ``stream``: the camera.
    ``index``: the frame's index in its sequence, for tracking mode (None: static mode); a
    frame that does not follow the stream's previous one (by 1 to ``step`` frames: the
    stream's frames may be every ``step``-th, ``person_every``; ``step = 0``: never) starts
    a new graph."""
    key, make, fresh = ("person", stream), _pose, False
    if index is not None:
        key, make = ("person-track", stream), lambda: _pose(track=True)   # noqa: E731
        with _LOCK:
            last = _LAST.get(key)
            fresh = last is None or not 1 <= index - last <= step
            _LAST[key] = index
    res = _process(make, key, _rgb(img), fresh)
    if res.segmentation_mask is None:
        return np.full(img.shape[:2], 128, dtype=np.uint8)
    return np.clip(res.segmentation_mask * 255 + 0.5, 0, 255).astype(np.uint8)


def person_probabilities(images, streams, index=None, step=1) -> list:
    """:func:`person_probability` of several cameras' images at once, one thread per camera
    (MediaPipe releases the GIL while its graph runs: on 2 idle cores the 4 cameras of the
    Pose2Sim recording took 111 ms instead of 174 ms one after the other; ``benchmarks/real.py``
    times both). ``index``, ``step``: tracking mode (:func:`person_probability`)."""
    if len(images) == 1:
        return [person_probability(images[0], streams[0], index, step)]
    with _LOCK:
        if not _POOL:
            from concurrent.futures import ThreadPoolExecutor
            _POOL.append(ThreadPoolExecutor(4, thread_name_prefix="topopose-person"))
    n = len(images)
    return list(_POOL[0].map(person_probability, images, streams, [index] * n, [step] * n))


def selfie_probability(img: np.ndarray, zone: np.ndarray | None = None, stream="") -> np.ndarray:
    """uint8 (h, w) person probability (× 255) of a BGR image; outside the bounding rectangle
    of ``zone`` (when given and not empty) it is 0. ``stream``: the camera (one segmenter each)."""
    h, w = img.shape[:2]
    y0, y1, x0, x1 = 0, h, 0, w
    if zone is not None and zone.any():
        ys, xs = np.nonzero(zone)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    crop = np.ascontiguousarray(img[y0:y1, x0:x1, ::-1])
    res = _process(_selfie, ("selfie", stream), crop)
    out = np.zeros((h, w), dtype=np.uint8)
    if res.segmentation_mask is not None:
        out[y0:y1, x0:x1] = np.clip(res.segmentation_mask * 255 + 0.5, 0, 255).astype(np.uint8)
    return out
