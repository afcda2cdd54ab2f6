"""Reading and checking ``calibration.toml`` and ``capture.toml`` (DESIGN.md, "Capture folder").

``calibration.toml`` follows the Pose2Sim / aniposelib layout: one table per camera with
``name``, ``size = [w, h]``, ``matrix`` (3×3 K), ``distortions`` (``[k1, k2, p1, p2]`` or with
``k3``; fisheye: ``[k1, k2, k3, k4]``), ``rotation`` (Rodrigues vector, world → camera; a 3×3
rotation matrix is also accepted), ``translation`` (world → camera, capture units) and optional
``fisheye``. Tables named ``metadata`` are ignored. Every problem raises :class:`InputError`
naming the file, the camera table and the field.
"""
from __future__ import annotations

import math
import tomllib
import warnings
from pathlib import Path

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry.camera import Camera
from topopose.capture.options import (_CAPTURE_KEYS, _SIL_TYPES, SEQUENCE_METHODS, SILHOUETTE_DEFAULTS,
                                      SIZE_POLICIES, UNITS, check_params)
from topopose.capture.capture import axis_vector

IGNORED_TABLES = {"metadata"}


def _read_toml(path: Path) -> dict:
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file (expected TOML)") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None


def _array(path, where, value, shape, field):
    """A finite float array of the given shape (``None`` in shape = any length)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: [{where}] field '{field}' must be numbers, got {value!r}") from None
    if a.dtype == object or a.ndim != len(shape) or any(
            s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "×".join("n" if s is None else str(s) for s in shape)
        raise InputError(f"{path}: [{where}] field '{field}' must be a {want} array, "
                         f"got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{path}: [{where}] field '{field}' has non-finite values ({value!r})")
    return a


def _camera_from_table(path: Path, key: str, t: dict) -> Camera:
    for field in ("size", "matrix", "distortions", "rotation", "translation"):
        if field not in t:
            raise InputError(f"{path}: [{key}] is missing field '{field}' "
                             f"(expected name, size, matrix, distortions, rotation, translation)")
    name = t.get("name", key)
    if isinstance(name, int) and not isinstance(name, bool):
        name = str(name)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\"):
        raise InputError(f"{path}: [{key}] field 'name' must be a folder name (non-empty text "
                         f"without slashes), got {name!r}")
    size = _array(path, key, t["size"], (2,), "size")
    if np.any(size <= 0) or np.any(size != np.round(size)):
        raise InputError(f"{path}: [{key}] field 'size' must be two positive integers [w, h], "
                         f"got {t['size']!r}")
    K = _array(path, key, t["matrix"], (3, 3), "matrix")
    if abs(np.linalg.det(K)) < 1e-12 or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError(f"{path}: [{key}] field 'matrix' is singular or has non-positive focal "
                         f"lengths (expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0)")
    fisheye = t.get("fisheye", False)
    if not isinstance(fisheye, bool):
        raise InputError(f"{path}: [{key}] field 'fisheye' must be true or false, got {fisheye!r}")
    d = _array(path, key, t["distortions"], (None,), "distortions")
    if fisheye and d.size != 4:
        raise InputError(f"{path}: [{key}] field 'distortions' must be [k1, k2, k3, k4] for a "
                         f"fisheye camera, got {d.size} values")
    if not fisheye and d.size not in (4, 5):
        raise InputError(f"{path}: [{key}] field 'distortions' must be [k1, k2, p1, p2] or "
                         f"[k1, k2, p1, p2, k3], got {d.size} values")
    rot = np.asarray(t["rotation"], dtype=object)
    if rot.shape == (3, 3):
        Rm = _array(path, key, t["rotation"], (3, 3), "rotation")
        if not np.allclose(Rm @ Rm.T, np.eye(3), atol=1e-5) or np.linalg.det(Rm) < 0:
            raise InputError(f"{path}: [{key}] field 'rotation' is a 3×3 matrix but not a rotation "
                             f"(expected a Rodrigues vector or an orthonormal matrix with det +1)")
        r = cv2.Rodrigues(Rm)[0].ravel()
    else:
        r = _array(path, key, t["rotation"], (3,), "rotation")
    tr = _array(path, key, t["translation"], (3,), "translation")
    return Camera(name, (int(size[0]), int(size[1])), K, d, r, tr, fisheye)


def read_calibration(path) -> list:
    """Cameras of a ``calibration.toml`` file, in file order.

    Raises
    ------
    InputError
        Missing file, invalid TOML, no camera table, a camera table with a missing or malformed
        field (named), a singular or non-finite matrix, duplicate camera names.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: calibration file not found (every capture needs calibration.toml)")
    data = _read_toml(path)
    cams = []
    for key, t in data.items():
        if not isinstance(t, dict) or key.lower() in IGNORED_TABLES:
            continue
        cams.append(_camera_from_table(path, key, t))
    if not cams:
        raise InputError(f"{path}: no camera table (expected one table per camera, e.g. [cam_01] "
                         f"with name, size, matrix, distortions, rotation, translation)")
    names = [c.name for c in cams]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"{path}: camera name(s) {dup} used by more than one table (field 'name')")
    return cams


def read_capture_options(path, cameras=()) -> dict:
    """Settings of an optional ``capture.toml`` (defaults when it is absent).

    Returns a dict with ``up``, ``units``, ``fps``, ``volume`` ((min, max) or None),
    ``size_policy`` (:data:`SIZE_POLICIES`, default "error"), ``cameras`` (the ``[cameras]``
    table: calibration name → ``{"folder", "size_policy"}``, see :func:`_camera_table`) and
    ``silhouettes`` (the background-subtraction parameters, :data:`SILHOUETTE_DEFAULTS` updated).
    Warns (``warnings.warn``) when the camera centres are more than 100 units from the origin
    while ``units = "m"`` (probably millimetre translations).
    """
    path = Path(path)
    out = {"up": "+z", "units": "m", "fps": None, "volume": None, "size_policy": "error",
           "cameras": {}, "silhouettes": dict(SILHOUETTE_DEFAULTS)}
    data = _read_toml(path) if path.is_file() else {}
    c = data.get("capture", {})
    if not isinstance(c, dict):
        raise InputError(f"{path}: 'capture' must be a table ([capture])")
    unknown = set(c) - _CAPTURE_KEYS
    if unknown:
        warnings.warn(f"{path}: [capture] ignores unknown field(s) {sorted(unknown)}", stacklevel=3)
    if "up" in c:
        if not isinstance(c["up"], str):
            raise InputError(f"{path}: [capture] field 'up' must be text like \"+z\", got {c['up']!r}")
        axis_vector(c["up"], where=f"{path}: [capture] field 'up'")
        out["up"] = c["up"].strip()
    if "units" in c:
        u = c["units"]
        if not isinstance(u, str) or u.strip().lower() not in UNITS:
            raise InputError(f"{path}: [capture] field 'units' must be one of {sorted(UNITS)}, got {u!r}")
        out["units"] = u.strip().lower()
    if "fps" in c:
        f = c["fps"]
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or f <= 0:
            raise InputError(f"{path}: [capture] field 'fps' must be a positive number, got {f!r}")
        out["fps"] = float(f)
    if "volume" in c:
        v = c["volume"]
        if not isinstance(v, dict) or "min" not in v or "max" not in v:
            raise InputError(f"{path}: [capture.volume] needs fields 'min' and 'max' ([x, y, z] each)")
        lo = _array(path, "capture.volume", v["min"], (3,), "min")
        hi = _array(path, "capture.volume", v["max"], (3,), "max")
        if np.any(lo >= hi):
            raise InputError(f"{path}: [capture.volume] field 'min' must be < 'max' on every axis, "
                             f"got min={lo.tolist()} max={hi.tolist()}")
        out["volume"] = (lo, hi)
    if "size_policy" in c:
        out["size_policy"] = _size_policy(path, "capture", c["size_policy"])
    out["cameras"] = _camera_table(path, data.get("cameras", {}), cameras)
    s = data.get("silhouettes", {})
    if not isinstance(s, dict):
        raise InputError(f"{path}: 'silhouettes' must be a table ([silhouettes])")
    for k, v in s.items():
        if k not in _SIL_TYPES:
            raise InputError(f"{path}: [silhouettes] unknown field '{k}' "
                             f"(known: {', '.join(sorted(_SIL_TYPES))})")
        if (isinstance(v, bool) != (_SIL_TYPES[k] is bool)) or not isinstance(v, _SIL_TYPES[k]):
            raise InputError(f"{path}: [silhouettes] field '{k}' has the wrong type ({v!r})")
        if k not in ("method", "fusion") and v < 0:
            raise InputError(f"{path}: [silhouettes] field '{k}' must be ≥ 0, got {v!r}")
        out["silhouettes"][k] = v
    if out["silhouettes"]["median"] > 1 and out["silhouettes"]["median"] % 2 == 0:
        raise InputError(f"{path}: [silhouettes] field 'median' must be an odd size (or 0), "
                         f"got {out['silhouettes']['median']}")
    if out["silhouettes"]["method"] not in ("diff", "mog2", "knn", *SEQUENCE_METHODS):
        raise InputError(f"{path}: [silhouettes] field 'method' must be \"diff\", \"mog2\", \"knn\", "
                         f"\"sequence\", \"selfie\", \"sequence+selfie\" or \"person\", "
                         f"got {out['silhouettes']['method']!r}")
    if out["silhouettes"]["fusion"] not in ("auto", "soft", "hard"):
        raise InputError(f"{path}: [silhouettes] field 'fusion' must be \"auto\", \"soft\" or \"hard\", "
                         f"got {out['silhouettes']['fusion']!r}")
    check_params(path, out["silhouettes"])
    if not 1 <= out["silhouettes"]["person_every"] <= 64:
        raise InputError(f"{path}: [silhouettes] field 'person_every' must be an integer in 1..64, "
                         f"got {out['silhouettes']['person_every']!r}")
    for k, hi in (("decode_threads", 64), ("decode_ahead", 64)):
        if out["silhouettes"][k] > hi:
            raise InputError(f"{path}: [silhouettes] field '{k}' must be an integer in 0..{hi}, "
                             f"got {out['silhouettes'][k]!r}")
    if cameras:
        far = max(float(np.linalg.norm(cam.center)) for cam in cameras)
        if out["units"] == "m" and far > 100:
            warnings.warn(f"{path}: units = \"m\" but a camera centre is {far:.0f} units from the "
                          f"origin: are the calibration translations in millimetres? "
                          f"(set [capture] units = \"mm\")", stacklevel=3)
    return out


def _size_policy(path, where, v) -> str:
    if not isinstance(v, str) or v.strip().lower() not in SIZE_POLICIES:
        raise InputError(f"{path}: [{where}] field 'size_policy' must be one of "
                         f"{', '.join(repr(p) for p in SIZE_POLICIES)}, got {v!r}")
    return v.strip().lower()


def _camera_table(path, table, cameras) -> dict:
    """The ``[cameras]`` table: calibration name → ``{"folder": name or None, "size_policy":
    policy or None}``. Entries are ``cam_01 = "cam01"`` or ``[cameras.cam_01]`` with fields
    ``folder`` (folder / video / background name) and ``size_policy``."""
    if not isinstance(table, dict):
        raise InputError(f"{path}: 'cameras' must be a table ([cameras]: calibration name = "
                         f"folder name)")
    known = [c.name for c in cameras]
    out = {}
    for name, v in table.items():
        if known and name not in known:
            raise InputError(f"{path}: [cameras] names camera {name!r}, which calibration.toml "
                             f"does not have (cameras: {', '.join(known)})")
        if isinstance(v, str):
            v = {"folder": v}
        if not isinstance(v, dict):
            raise InputError(f"{path}: [cameras] field '{name}' must be a folder name (text) or a "
                             f"table with 'folder' and/or 'size_policy', got {v!r}")
        bad = set(v) - {"folder", "size_policy"}
        if bad:
            raise InputError(f"{path}: [cameras.{name}] unknown field(s) {sorted(bad)} "
                             f"(known: folder, size_policy)")
        folder = v.get("folder")
        if folder is not None and (not isinstance(folder, str) or not folder.strip()):
            raise InputError(f"{path}: [cameras.{name}] field 'folder' must be a non-empty text, "
                             f"got {folder!r}")
        pol = _size_policy(path, f"cameras.{name}", v["size_policy"]) if "size_policy" in v else None
        out[name] = {"folder": folder, "size_policy": pol}
    return out
