"""A capture: calibrated cameras, frame names, and silhouettes per camera and frame."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from topopose.errors import InputError
from topopose.geometry.camera import Camera

_AXES = {"x": 0, "y": 1, "z": 2}


def axis_vector(axis: str, where: str = "up") -> np.ndarray:
    """``"+z"`` → (0, 0, 1), ``"-y"`` → (0, -1, 0)."""
    s = str(axis).strip().lower()
    sign = -1.0 if s.startswith("-") else 1.0
    name = s.lstrip("+-")
    if name not in _AXES:
        raise InputError(f"{where}: axis {axis!r} must be one of +x, -x, +y, -y, +z, -z")
    v = np.zeros(3)
    v[_AXES[name]] = sign
    return v


@dataclass
class Capture:
    """Calibrated cameras and their silhouettes.

    A capture is read from a folder by :func:`topopose.load_capture`, or built in
    memory (``masks``: frame name → list of boolean (h, w) arrays, one per camera).

    ``options`` (from :func:`~topopose.capture.load_capture`): ``source`` ("silhouettes",
    "images" or "videos"), ``silhouettes`` (background-subtraction parameters),
    ``incomplete_frames`` (frame → cameras lacking it; loading such a frame raises
    :class:`InputError`), ``frame_source`` (the :mod:`~topopose.capture.sources` object giving
    colour frames), ``names`` (calibration name → folder / video name), ``size_policy`` and
    ``cameras`` (the ``[cameras]`` table of ``capture.toml``).
    """

    cameras: list
    frames: list
    path: Path | None = None
    up: str = "+z"
    units: str = "m"
    fps: float | None = None
    volume: tuple | None = None          # (min xyz, max xyz) or None: fitted to the silhouettes
    options: dict = field(default_factory=dict)
    masks: dict | None = None
    #: camera name → frame name → image file (set by :func:`topopose.load_capture`)
    files: dict | None = field(default=None, repr=False)
    #: per-capture caches (hull carvers per grid, backgrounds, fitted volumes); never saved
    cache: dict = field(default_factory=dict, repr=False, compare=False)
    #: ``reader(capture, frame) -> masks`` for captures read from files (set by
    #: :func:`topopose.load_capture`); unused when ``masks`` is given
    reader: object = field(default=None, repr=False, compare=False)

    @property
    def up_vector(self) -> np.ndarray:
        return axis_vector(self.up, where=f"{self.path or 'capture'}: capture.up")

    def camera(self, name: str) -> Camera:
        for c in self.cameras:
            if c.name == name:
                return c
        raise InputError(f"{self.path or 'capture'}: no camera named {name!r}")

    def silhouettes(self, frame) -> list:
        """Boolean silhouettes (h, w) of ``frame``, one per camera, in camera order."""
        frame = self.frame_name(frame)
        if self.masks is not None:
            if frame not in self.masks:
                raise InputError(f"capture: no masks for frame {frame!r}")
            ms = self.masks[frame]
            if len(ms) != len(self.cameras):
                raise InputError(f"capture: frame {frame!r} has {len(ms)} masks for "
                                 f"{len(self.cameras)} cameras")
            from topopose.geometry.masks import BoxedMask

            out = []
            for cam, m in zip(self.cameras, ms):
                if not (isinstance(m, BoxedMask) and m.dtype == bool):
                    m = np.asarray(m, dtype=bool)      # (a decoded mask keeps its box)
                if m.shape != (cam.size[1], cam.size[0]):
                    raise InputError(f"capture: frame {frame!r} camera {cam.name!r}: mask shape "
                                     f"{m.shape} differs from the calibration size "
                                     f"(h, w) = {(cam.size[1], cam.size[0])}")
                out.append(m)
            return out
        if self.reader is None:
            raise InputError(f"{self.path or 'capture'}: frame {frame!r}: no masks and no files to read them from")
        return self.reader(self, frame)

    def frame_name(self, frame) -> str:
        """Accept a frame name or an index into :attr:`frames` (also as digits, e.g. ``"3"``,
        when no frame has that name)."""
        if isinstance(frame, (int, np.integer)) and str(frame) not in self.frames:
            if not -len(self.frames) <= frame < len(self.frames):
                raise InputError(f"{self.path or 'capture'}: frame index {frame} out of range "
                                 f"({len(self.frames)} frames)")
            return self.frames[frame]
        frame = str(frame)
        if frame not in self.frames and frame.isdigit() and int(frame) < len(self.frames):
            return self.frames[int(frame)]          # "3" on the command line: an index
        if frame not in self.frames:
            raise InputError(f"{self.path or 'capture'}: no frame {frame!r} "
                             f"(frames {self.frames[0] if self.frames else ''}…)")
        return frame

    @property
    def gt(self) -> dict | None:
        """Ground truth from ``gt.json`` (synthetic captures), or None."""
        if self.path is None:
            return self.options.get("gt")
        p = Path(self.path) / "gt.json"
        if not p.exists():
            return None
        try:
            return json.loads(p.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"{p}: not valid JSON ({exc})") from None
