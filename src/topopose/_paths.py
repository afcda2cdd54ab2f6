"""Checks of command-line arguments and output paths, shared by the sub-commands.

Everything a user can get wrong is checked *before* any work or any write, and raises
:class:`~topopose.InputError` naming the argument or the path (the CLI prints one line and exits
2). Outputs are written to a temporary file beside the target and renamed over it at the end
(:func:`atomic_output`), so a refused, failed or interrupted command never damages an existing file.
"""
from __future__ import annotations

import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from topopose.errors import InputError

#: bytes of memory per voxel of the grid that one frame of the pipeline needs at its peak
#: (hull labels and masks, filled copy, thinning work arrays, skeleton), measured at 200³.
BYTES_PER_VOXEL = 12
RESOLUTION_MIN = 8
RESOLUTION_MAX = 1024


def writable_output(path, what: str = "--out", *, suffix: str | None = None) -> Path:
    """Check that ``path`` can be written as a file; create its missing parent folders.

    Refuses (InputError naming ``what`` and the path) a path that is a folder, whose parent
    cannot be created or is not a folder, or that is not writable. Nothing is written to
    ``path`` itself. ``suffix``: required file name ending (e.g. ``".png"``).
    """
    if path is None or str(path).strip() == "":
        raise InputError(f"{what}: empty path")
    p = Path(path).expanduser()
    if p.is_dir():
        raise InputError(f"{what}: {p} is a folder, expected a file path")
    if suffix and p.suffix.lower() != suffix:
        raise InputError(f"{what}: {p} must end with {suffix}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{what}: cannot create folder {parent} ({exc.strerror or exc})") from None
    if not parent.is_dir():
        raise InputError(f"{what}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{what}: folder {parent} is not writable")
    if p.exists() and not os.access(p, os.W_OK):
        raise InputError(f"{what}: {p} is not writable")
    return p


def writable_folder(path, what: str = "--out") -> Path:
    """Check that ``path`` is (or can be created as) a writable folder; create it."""
    p = Path(path).expanduser()
    if p.exists() and not p.is_dir():
        raise InputError(f"{what}: {p} exists and is not a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{what}: cannot create folder {p} ({exc.strerror or exc})") from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise InputError(f"{what}: folder {p} is not writable")
    return p


def temp_path(path) -> Path:
    """The temporary file beside ``path`` (same folder: the final rename is atomic); it keeps
    the file's suffix, so writers that add one (``np.savez``) or pick a format from it work."""
    p = Path(path)
    return p.with_name(f".{p.stem}.partial-{os.getpid()}{p.suffix}")


@contextmanager
def atomic_output(path):
    """``with atomic_output(path) as tmp: write(tmp)``: ``tmp`` replaces ``path`` only when the
    block finishes; on any error (or Ctrl-C) it is deleted and ``path`` is left as it was."""
    p = Path(path)
    tmp = temp_path(p)
    try:
        yield tmp
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _gb(n: float) -> str:
    return f"{n / 1e9:.1f} GB" if n < 1e12 else f"{n / 1e12:.3g} TB" if n < 1e15 else f"{n / 1e15:.3g} PB"


def check_resolution(resolution, what: str = "--resolution", *, minimum: int = RESOLUTION_MIN,
                     memory: int | None = None, warn=True) -> int:
    """Grid resolution (voxels along the longest side of the capture volume): an integer in
    ``minimum..RESOLUTION_MAX`` whose N³ grid fits in the available memory (refused with the
    size named); a note on stderr when it takes more than 2 GB."""
    if isinstance(resolution, bool) or not hasattr(resolution, "__index__"):
        raise InputError(f"{what}: expected an integer, got {resolution!r}")
    n = int(resolution)
    need = float(n) ** 3 * BYTES_PER_VOXEL
    avail = available_memory() if memory is None else memory
    if n < minimum:
        raise InputError(f"{what}: {n} is too small (at least {minimum} voxels)")
    if avail is not None and need > avail:
        raise InputError(f"{what}: a {n}³ grid needs about {_gb(need)} of memory, "
                         f"{_gb(avail)} available")
    if n > RESOLUTION_MAX:
        raise InputError(f"{what}: {n} is too large (at most {RESOLUTION_MAX}; a {n}³ grid needs "
                         f"about {_gb(need)} of memory)")
    if warn and need > 2e9:
        print(f"topopose: note: a {n}³ grid takes about {_gb(need)} of memory per frame",
              file=sys.stderr)
    return n


def check_tolerance(tolerance, n_cameras: int, what: str = "--tolerance") -> int | None:
    """Visual-hull tolerance k (voxels seen by all cameras but k): None or 0..C-1."""
    if tolerance is None:
        return None
    if isinstance(tolerance, bool) or not float(tolerance).is_integer():
        raise InputError(f"{what}: expected an integer, got {tolerance!r}")
    k = int(tolerance)
    if not 0 <= k < n_cameras:
        raise InputError(f"{what}: {k} must be in 0..{n_cameras - 1} "
                         f"(keep voxels seen by all cameras but k; the capture has {n_cameras})")
    return k


def check_threshold(threshold, what: str = "--threshold") -> float | None:
    """AHA distance threshold T_d: None or a finite number ≥ 0."""
    if threshold is None:
        return None
    t = float(threshold)
    if not math.isfinite(t) or t < 0:
        raise InputError(f"{what}: must be a distance ≥ 0, got {threshold!r}")
    return t
