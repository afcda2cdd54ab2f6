"""Frame sources: colour images per camera and frame, from ``images/`` folders or ``videos/``.

A frame source only delivers colour images (BGR, uint8); how silhouettes are made from them is
the business of :mod:`~topopose.capture.silhouettes` (``[silhouettes]`` of ``capture.toml``).

- :class:`ImageSource`: ``images/<camera>/<frame>.png`` (frame names = file stems).
- :class:`VideoSource`: ``videos/<camera>.<mp4|avi|mov|mkv>`` decoded with OpenCV. Frame ``i``
  is named ``f"{i:06d}"`` (as :func:`~topopose.synth.capture.synthesize` names its frames);
  the frame rate and the frame count come from the files. The capture has as many frames as
  its **longest** video: frames beyond a shorter video's end, or that cannot be decoded (corrupt
  file), fail with the reason, the others are read normally.

Both offer random access (:meth:`read`, e.g. ``topopose hull --frame F``) and a sequential
reader (:meth:`sequential`) used by :class:`Prefetcher` — a thread decoding ahead of the
computation into a bounded queue, so decoding overlaps the pipeline. Video decoders read
forward; they seek only when the requested frame is more than ``SEEK_GAP`` frames ahead or is
behind the decoder (mp4 seeks are slow and land on key frames).
"""
from __future__ import annotations

import queue
import threading
from pathlib import Path

import cv2
import numpy as np

from topopose.errors import InputError

VIDEO_EXTENSIONS = (".mp4", ".avi", ".mov", ".mkv")
#: decode forward (grab) rather than seek when the wanted frame is at most this far ahead
SEEK_GAP = 48


class Skipped:
    """Stands for a camera's image that :meth:`VideoSource.sequential` decoded but did not
    convert to BGR (its ``needed`` left the camera out): ``read`` it when it is wanted after
    all (:func:`topopose.capture.background.foreground_maps` does)."""

    def __repr__(self):
        return "SKIPPED"


#: the one :class:`Skipped` instance
SKIPPED = Skipped()


def video_frame_name(i: int) -> str:
    return f"{int(i):06d}"


#: the most pixels an image may have (OpenCV's own limit, ``CV_IO_MAX_IMAGE_PIXELS``)
MAX_IMAGE_PIXELS = 1 << 30


def png_size(path) -> tuple | None:
    """(w, h) from a PNG file's header (its first 24 bytes), or None for another file."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def imread(path: Path, flags: int = cv2.IMREAD_COLOR, camera: str | None = None) -> np.ndarray:
    """``cv2.imread`` that accepts any path and raises :class:`InputError` naming the file (and
    ``camera``) on failure, also for an image whose header claims more than
    :data:`MAX_IMAGE_PIXELS`."""
    who = f" of camera {camera!r}" if camera else ""
    size = png_size(path)
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise InputError(f"{path}: the image{who} claims {size[0]}x{size[1]} pixels in its "
                         f"header (at most {MAX_IMAGE_PIXELS} pixels): a corrupt file")
    try:
        buf = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the image{who} ({exc.strerror or exc})") from None
    try:
        img = cv2.imdecode(buf, flags) if buf.size else None
    except cv2.error as exc:                 # OpenCV refuses the header (size, format)
        why = str(exc).strip().splitlines()[-1][:200]
        raise InputError(f"{path}: cannot decode the image{who} ({why})") from None
    if img is None:
        raise InputError(f"{path}: unreadable or corrupt image{who}")
    return img


class ImageSource:
    """Colour frames from image files: ``files`` maps camera → frame name → path."""

    kind = "images"

    def __init__(self, files: dict, folders: dict | None = None):
        self.files = files
        self.folders = folders or {}

    def read(self, camera: str, frame: str) -> np.ndarray:
        p = self.files[camera].get(frame)
        if p is None:
            where = self.folders.get(camera, camera)
            raise InputError(f"{where}: frame {frame!r} missing for camera {camera!r} "
                             f"(other cameras have it)")
        return imread(p, cv2.IMREAD_COLOR, camera)

    def path(self, camera: str, frame: str):
        return self.files[camera].get(frame)

    def sequential(self, frames, cameras=None, needed=None):
        """Yield ``(frame, {camera: image or InputError})`` for ``frames`` in order (of
        ``cameras`` only when given). ``needed``: ignored (every image is read: a missing
        file is reported)."""
        for f in frames:
            out = {}
            for cam in (self.files if cameras is None else cameras):
                try:
                    out[cam] = self.read(cam, f)
                except InputError as exc:
                    out[cam] = exc
            yield f, out


class _Decoder:
    """One ``cv2.VideoCapture`` that knows which frame it decodes next."""

    def __init__(self, path: Path, threads: int = 1):
        self.path = path
        self.threads = int(threads)
        self.vc = None
        self.pos = 0
        self.failed_at = None                # frame at which decoding failed (then reopened)

    def _open(self):
        # ``threads`` FFmpeg threads (0: its own choice, one per core). One by default: the
        # decoding thread already runs beside the silhouettes and the pipeline, and FFmpeg's
        # own threads add CPU (benchmarks/real.py, "Where the time goes")
        self.vc = None
        if self.threads > 0:
            self.vc = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG,
                                       [cv2.CAP_PROP_N_THREADS, self.threads])
        if self.vc is None or not self.vc.isOpened():
            self.vc = cv2.VideoCapture(str(self.path))
        self.pos = 0
        if not self.vc.isOpened():
            self.vc = None
            raise InputError(f"{self.path}: cannot open the video (corrupt file or unsupported codec)")

    def close(self):
        if self.vc is not None:
            self.vc.release()
        self.vc = None

    def get(self, i: int, retrieve: bool = True) -> np.ndarray | None:
        """Frame ``i`` (BGR); ``retrieve=False``: decoded (errors raised the same) but not
        converted to BGR, None returned (the colour conversion is about a third of the CPU of
        a 1088 × 1920 H.264 frame)."""
        if self.vc is None:
            self._open()
        if not self.pos <= i < self.pos + SEEK_GAP:
            if i < SEEK_GAP:                 # near the start: reopen and decode forward (exact)
                self.close()
                self._open()
            else:
                self.vc.set(cv2.CAP_PROP_POS_FRAMES, float(i))
                got = int(round(self.vc.get(cv2.CAP_PROP_POS_FRAMES)))
                self.pos = got if got >= 0 else i
                if self.pos > i:             # the seek overshot: start again from the beginning
                    self.close()
                    self._open()
        while self.pos < i:
            if not self.vc.grab():
                self.failed_at = self.pos
                self.close()
                raise InputError(f"{self.path}: frame {i} cannot be decoded (the video ends or is "
                                 f"corrupt at frame {self.pos})")
            self.pos += 1
        if not retrieve:
            if not self.vc.grab():
                self.failed_at = i
                self.close()
                raise InputError(f"{self.path}: frame {i} cannot be decoded (corrupt or truncated video)")
            self.pos += 1
            return None
        ok, img = self.vc.read()
        if not ok or img is None:
            self.failed_at = i
            self.close()
            raise InputError(f"{self.path}: frame {i} cannot be decoded (corrupt or truncated video)")
        self.pos += 1
        if img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        return img


class VideoSource:
    """Colour frames decoded from one video per camera (``videos``: camera → path).

    Attributes
    ----------
    counts, fps, sizes : dict
        Per camera: frame count, frame rate and (w, h) read from the file (0 / None when the
        file cannot be opened; ``errors`` then holds the reason).
    frames : list of str
        ``"000000"`` … up to the longest video.
    """

    kind = "videos"

    def __init__(self, videos: dict, threads: int = 1):
        self.videos = {c: Path(p) for c, p in videos.items()}
        self.threads = int(threads)          # FFmpeg threads per decoder (0: its choice)
        self.counts, self.fps, self.sizes, self.errors = {}, {}, {}, {}
        for cam, p in self.videos.items():
            vc = cv2.VideoCapture(str(p))
            if not vc.isOpened():
                self.counts[cam], self.fps[cam], self.sizes[cam] = 0, None, None
                self.errors[cam] = f"{p}: cannot open the video (corrupt file or unsupported codec)"
                continue
            n = int(vc.get(cv2.CAP_PROP_FRAME_COUNT))
            fps = float(vc.get(cv2.CAP_PROP_FPS))
            size = (int(vc.get(cv2.CAP_PROP_FRAME_WIDTH)), int(vc.get(cv2.CAP_PROP_FRAME_HEIGHT)))
            if n <= 0:                       # no count in the header: count by decoding
                n = 0
                while vc.grab():
                    n += 1
            vc.release()
            self.counts[cam] = n
            self.fps[cam] = fps if fps > 0 else None
            self.sizes[cam] = size
        self.count = max(self.counts.values(), default=0)
        self.frames = [video_frame_name(i) for i in range(self.count)]
        self._index = {f: i for i, f in enumerate(self.frames)}
        self._bad = {}                       # camera → first frame that failed to decode
        self._random = {}
        self._lock = threading.Lock()

    def frame_index(self, frame: str) -> int:
        i = self._index.get(frame)
        if i is None:
            raise InputError(f"videos: no frame {frame!r} ({self.count} frames)")
        return i

    def missing(self, camera: str, i: int) -> str | None:
        """Why camera ``camera`` has no frame ``i`` (None when it should have it)."""
        if camera in self.errors:
            return self.errors[camera]
        if i >= self.counts[camera]:
            return (f"{self.videos[camera]}: frame {i} missing for camera {camera!r}: its video has "
                    f"{self.counts[camera]} frames, the longest {self.count}")
        return None

    def _get(self, decoders: dict, camera: str, i: int, retrieve: bool = True) -> np.ndarray:
        why = self.missing(camera, i)
        if why is not None:
            raise InputError(why)
        bad = self._bad.get(camera)
        if bad is not None and i >= bad[0]:  # fail fast: do not decode up to the damage again
            raise InputError(bad[1])
        dec = decoders.get(camera)
        if dec is None:
            dec = decoders[camera] = _Decoder(self.videos[camera], self.threads)
        try:
            return dec.get(i, retrieve)
        except InputError as exc:
            at = dec.failed_at
            if at is not None and (bad is None or at < bad[0]):
                self._bad[camera] = (at, f"{self.videos[camera]}: frame {i} cannot be decoded "
                                         f"(the video is corrupt or truncated from frame {at} on)")
            raise exc from None

    def read(self, camera: str, frame: str) -> np.ndarray:
        """Random access (seeks only when far from the decoder's position)."""
        i = self.frame_index(frame)
        with self._lock:
            return self._get(self._random, camera, i)

    def path(self, camera: str, frame: str):
        return self.videos[camera]

    def sequential(self, frames, cameras=None, needed=None):
        """Yield ``(frame, {camera: image or InputError})`` for ``frames`` in order (of
        ``cameras`` only when given), with decoders of its own (decoding forward).
        ``needed(position, frame)``: the cameras whose images are wanted (None: all); the
        others are decoded (a decoding error is reported the same) but not converted, and
        given as :data:`SKIPPED`."""
        decoders = {}
        try:
            for k, f in enumerate(frames):
                i = self.frame_index(f)
                want = None if needed is None else needed(k, f)
                out = {}
                for cam in (self.videos if cameras is None else cameras):
                    try:
                        got = self._get(decoders, cam, i, want is None or cam in want)
                        out[cam] = SKIPPED if got is None else got
                    except InputError as exc:
                        out[cam] = exc
                yield f, out
        finally:
            for d in decoders.values():
                d.close()

    def close(self):
        with self._lock:
            for d in self._random.values():
                d.close()
            self._random.clear()

    def __getstate__(self):                  # picklable (Dask workers): no open decoders
        d = dict(self.__dict__)
        d["_random"], d["_lock"] = {}, None
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._lock = threading.Lock()


def read_ahead(items, depth: int = 2, stop: threading.Event | None = None):
    """Yield the items of the iterable ``items`` in order, pulled by a thread of their own at
    most ``depth`` ahead (decoding overlaps the work done on the previous items; OpenCV's
    decoders release the GIL). An exception raised by ``items`` is raised here, at its place.
    Closing this generator (or setting ``stop``) stops the thread, which closes ``items``."""
    q = queue.Queue(maxsize=max(1, int(depth)))
    stop = stop if stop is not None else threading.Event()
    done = threading.Event()
    end = object()

    def put(x):
        while not (stop.is_set() or done.is_set()):
            try:
                q.put(x, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def pull():
        it = iter(items)
        try:
            for x in it:
                if not put((x, None)):
                    break
            else:
                put((end, None))
        except Exception as exc:         # handed to the consumer at its place
            put((end, exc))
        finally:
            if hasattr(it, "close"):
                it.close()

    t = threading.Thread(target=pull, name="topopose-decode", daemon=True)
    t.start()
    try:
        while True:
            try:
                x, exc = q.get(timeout=0.1)
            except queue.Empty:
                if stop.is_set() or not t.is_alive() and q.empty():
                    return
                continue
            if exc is not None:
                raise exc
            if x is end:
                return
            yield x
    finally:
        done.set()
        t.join()


class Prefetcher:
    """A reader thread that computes ``work(frame, images)`` for ``frames`` in order, ahead of
    the consumer, into a bounded queue of ``depth`` frames.

    ``images`` comes from ``source.sequential(frames)`` (None when ``source`` is None), decoded
    by a thread of its own up to ``ahead`` frames ahead of ``work`` (:func:`read_ahead`; 0:
    decoded in the reader thread). Results
    (or the exception raised) are handed out by :meth:`take` in the same order.
    """

    _END = object()

    def __init__(self, frames, work, source=None, depth: int = 4, ahead: int = 2, needed=None):
        self.frames = list(frames)
        self._pos = 0
        self._q = queue.Queue(maxsize=max(1, int(depth)))
        self._stop = threading.Event()
        self._work = work
        self._source = source
        self._ahead = int(ahead)
        self._needed = needed
        self._thread = threading.Thread(target=self._loop, name="topopose-reader", daemon=True)
        self._thread.start()

    def _loop(self):
        it = ((f, None) for f in self.frames) if self._source is None else \
            self._source.sequential(self.frames, needed=self._needed)
        if self._source is not None and self._ahead > 0:
            it = read_ahead(it, self._ahead, self._stop)
        try:
            for f, images in it:
                if self._stop.is_set():
                    break
                try:
                    item = (f, self._work(f, images), None)
                except Exception as exc:     # handed to the consumer with its frame
                    item = (f, None, exc)
                while not self._stop.is_set():
                    try:
                        self._q.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
        finally:
            if hasattr(it, "close"):
                it.close()
            try:
                self._q.put_nowait(self._END)
            except queue.Full:
                pass

    def take(self, frame):
        """The result for ``frame`` when it is among the frames still ahead (earlier ones are
        discarded); ``(False, None)`` when the prefetcher does not have it."""
        if frame not in self.frames[self._pos:]:
            return False, None
        while True:
            item = self._q.get()
            if item is self._END:
                self._pos = len(self.frames)
                return False, None
            self._pos += 1
            f, res, exc = item
            if f == frame:
                if exc is not None:
                    raise exc
                return True, res

    def close(self):
        self._stop.set()
        while self._thread.is_alive():
            try:
                self._q.get(timeout=0.05)
            except queue.Empty:
                pass
        self._thread.join()
