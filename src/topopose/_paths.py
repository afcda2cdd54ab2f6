"""Checks of command-line arguments and output paths, shared by the sub-commands.

Everything a user can get wrong is checked *before* any work or any write, and raises
:class:`~topopose.InputError` naming the argument or the path (the CLI prints one line and exits
2). One rule for every command: an output never replaces an input or a complete result unless
the command completes. The outputs are checked together (:func:`check_outputs`) against every
file the command reads (:func:`capture_inputs` for a capture folder) and against each other;
devices, FIFOs and folders are refused, and so is a folder that does not exist. Outputs are
written to a temporary file beside the target and renamed over it at the end
(:func:`atomic_output`), so a refused, failed or interrupted command never damages an existing
file.
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


def _real(path) -> Path:
    """``path`` with its folders and links resolved (it need not exist)."""
    return Path(os.path.realpath(Path(path).expanduser()))


def _same(a: Path, b: Path) -> bool:
    if _real(a) == _real(b):
        return True
    try:
        return os.path.samefile(a, b)          # hard links
    except OSError:
        return False


def _inside(p: Path, folder: Path) -> bool:
    r, f = _real(p), _real(folder)
    return r != f and f in r.parents


def capture_inputs(root) -> list:
    """What a capture folder is read from (``(name, path)``): its TOML files, ground truth and
    the folders of masks, frames, videos and backgrounds (everything inside them)."""
    root = Path(root)
    names = ("calibration.toml", "capture.toml", "gt.json", "silhouettes", "images", "videos",
             "backgrounds")
    return [(f"capture {root}", root / n) for n in names if (root / n).exists()]


def file_input(path):
    """``path`` when it names an existing file (an input no output may replace; e.g. a
    ``--model`` that is a TOML file, not a built-in name), else None."""
    return path if isinstance(path, (str, Path)) and str(path) and Path(path).is_file() else None


def _clash(p: Path, inputs) -> str | None:
    """Why writing ``p`` would damage one of ``inputs`` (``(name, path)``), or None."""
    for name, q in inputs:
        if q is None:
            continue
        q = Path(q)
        if _same(p, q):
            return f"{p} is an input ({name})"
        if q.is_dir() and _inside(p, q):
            return f"{p} is inside {q}, an input ({name})"
    return None


def writable_output(path, what: str = "--out", *, suffix=None, inputs=()) -> Path:
    """Check that ``path`` can be written as a file, before any work.

    Refuses (InputError naming ``what`` and the path) an empty path, a folder, a device, FIFO
    or socket (it would be replaced by a file), a path whose folder does not exist (no tree of
    folders is made silently) or is not writable, a read-only file, and a path that is one of
    ``inputs`` (``(name, path)`` pairs: files, or folders whose every file is an input) or
    inside an input folder. Nothing is written. ``suffix``: a required file name ending
    (``".png"``) or a tuple of them.
    """
    if path is None or str(path).strip() == "":
        raise InputError(f"{what}: empty path")
    p = Path(path).expanduser()
    if p.is_dir():
        raise InputError(f"{what}: {p} is a folder, expected a file path")
    if p.exists() and not p.is_file():
        raise InputError(f"{what}: {p} is not a regular file (a device, FIFO or socket); "
                         "give a file path")
    if suffix:
        ends = (suffix,) if isinstance(suffix, str) else tuple(suffix)
        if p.suffix.lower() not in ends:
            raise InputError(f"{what}: {p} must end with {' or '.join(ends)}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise InputError(f"{what}: folder {parent} does not exist (create it first)")
    if not parent.is_dir():
        raise InputError(f"{what}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{what}: folder {parent} is not writable")
    if p.exists() and not os.access(p, os.W_OK):
        raise InputError(f"{what}: {p} is not writable")
    why = _clash(p, inputs)
    if why:
        raise InputError(f"{what}: {why}; give another path")
    return p


def check_outputs(outputs: dict, inputs=(), *, suffixes: dict | None = None) -> dict:
    """Every output of a command checked together before any work: each one
    :func:`writable_output` against ``inputs``, and no two the same file.

    Parameters
    ----------
    outputs : dict option -> path (None: not asked for)
    inputs : ``(name, path)`` pairs the command reads (files, or folders read whole)
    suffixes : dict option -> required file name ending(s)

    Returns
    -------
    dict option -> Path, for the outputs given.
    """
    out = {}
    for what, path in outputs.items():
        if path is None:
            continue
        p = writable_output(path, what, suffix=(suffixes or {}).get(what), inputs=inputs)
        for other, q in out.items():
            if _same(p, q):
                raise InputError(f"{what}: {p} is also the file of {other}; give each output "
                                 "its own file")
        out[what] = p
    return out


def writable_folder(path, what: str = "--out", *, inputs=()) -> Path:
    """Check that ``path`` is (or can be created as) a writable folder and is not an input
    folder nor inside one; create it (its parent must exist: no tree is made silently)."""
    if path is None or str(path).strip() == "":
        raise InputError(f"{what}: empty path")
    p = Path(path).expanduser()
    if p.exists() and not p.is_dir():
        raise InputError(f"{what}: {p} exists and is not a folder")
    why = _clash(p, inputs)
    if why:
        raise InputError(f"{what}: {why}; give another folder")
    parent = p.parent if str(p.parent) else Path(".")
    if not p.exists() and not parent.is_dir():
        raise InputError(f"{what}: folder {parent} does not exist (create it first)")
    try:
        p.mkdir(exist_ok=True)
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
def atomic_output(path, what: str | None = None):
    """``with atomic_output(path) as tmp: write(tmp)``: ``tmp`` replaces ``path`` only when the
    block finishes; on any error (or Ctrl-C) it is deleted and ``path`` is left as it was.

    ``what``: the option that named ``path``; a failure to write the temporary file then
    raises InputError naming the option and ``path`` (not the temporary file)."""
    p = Path(path)
    real = _real(p) if p.is_symlink() else p      # a link keeps pointing at the new file
    tmp = temp_path(real)
    try:
        yield tmp
        os.replace(tmp, real)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if what is not None and isinstance(exc, OSError):
            raise InputError(f"{what}: cannot write {p} ({exc.strerror or exc})") from None
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


def check_number(value, what: str, *, low=None, high=None, above=None, integer=False):
    """A number given by the user: finite, ``>= low``, ``> above``, ``<= high`` (None: no
    bound), an integer with ``integer``; None passes through."""
    if value is None:
        return None
    try:
        if isinstance(value, bool):
            raise TypeError
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected a number, got {value!r}") from None
    if not math.isfinite(x):
        raise InputError(f"{what}: must be a finite number, got {value!r}")
    if integer and not x.is_integer():
        raise InputError(f"{what}: expected an integer, got {value!r}")
    if (low is not None and x < low) or (above is not None and x <= above) \
            or (high is not None and x > high):
        rng = " and ".join(s for s in (f"≥ {low:g}" if low is not None else "",
                                       f"> {above:g}" if above is not None else "",
                                       f"≤ {high:g}" if high is not None else "") if s)
        raise InputError(f"{what}: must be {rng}, got {value!r}")
    return int(x) if integer else x
