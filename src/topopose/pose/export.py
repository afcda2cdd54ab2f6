"""Exports of the matched poses: TRC (OpenSim), wide CSV, C3D (optional extra).

Only matched frames carry positions in the exports; rejected and failed frames are rows
with empty values (TRC, CSV) or invalid points (C3D), so frame numbers and times stay aligned
with the capture.
"""
from __future__ import annotations

import csv as _csv
from pathlib import Path

import numpy as np

from ..errors import InputError

_TO_METRES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "dm": 0.1, "km": 1000.0, "in": 0.0254,
              "ft": 0.3048}


def metres_per_unit(units: str) -> float:
    """Scale from capture units to metres."""
    u = str(units or "m").strip().lower()
    if u not in _TO_METRES:
        raise InputError(f"capture.toml: units {units!r} unknown for export (one of "
                         f"{', '.join(_TO_METRES)})")
    return _TO_METRES[u]


def y_up_rotation(up: str = "+z") -> np.ndarray:
    """Rotation taking the capture's up axis to +Y (OpenSim's convention), right-handed.

    For ``+z`` up: (x, y, z) → (y, z, x).
    """
    s = str(up).strip().lower()
    sign = -1.0 if s.startswith("-") else 1.0
    k = "xyz".index(s.lstrip("+-"))
    e = np.eye(3)
    new_y = sign * e[k]
    new_x = e[(k + 2) % 3]
    new_z = np.cross(new_x, new_y)
    return np.stack([new_x, new_y, new_z])


def _matrix(poses, parts):
    """(n_frames, n_parts, 3) positions, NaN where a part is missing or the frame not matched."""
    a = np.full((len(poses), len(parts), 3), np.nan)
    for i, p in enumerate(poses):
        if p.status != "matched":
            continue
        for j, name in enumerate(parts):
            v = p.parts.get(name)
            if v is not None:
                a[i, j] = v
    return a


def _frame_numbers(poses):
    nums = []
    for i, p in enumerate(poses):
        try:
            nums.append(int(p.frame))
        except ValueError:
            nums.append(i)
    return nums


def write_trc(path, poses, parts, fps=25.0, units="m", up="+z", y_up=True) -> Path:
    """Write an OpenSim ``.trc`` marker file, in metres.

    Parameters
    ----------
    poses : list of Pose (sorted by frame)
    parts : part names (markers)
    fps : capture frame rate
    units : capture units (converted to metres)
    up : the capture's up axis; with ``y_up`` the positions are rotated so that up is +Y,
        OpenSim's convention.
    """
    path = Path(path)
    poses = sorted(poses, key=lambda p: p.frame)
    a = _matrix(poses, parts) * metres_per_unit(units)
    if y_up:
        a = a @ y_up_rotation(up).T
    nums = _frame_numbers(poses)
    n, m = len(poses), len(parts)
    fps = float(fps or 25.0)
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
             "OrigDataStartFrame\tOrigNumFrames",
             f"{fps:.2f}\t{fps:.2f}\t{n}\t{m}\tm\t{fps:.2f}\t{(nums[0] + 1) if nums else 1}\t{n}",
             "Frame#\tTime\t" + "\t".join(f"{p}\t\t" for p in parts).rstrip("\t"),
             "\t\t" + "\t".join(f"X{j + 1}\tY{j + 1}\tZ{j + 1}" for j in range(m)),
             ""]
    for i in range(n):
        vals = []
        for j in range(m):
            for c in range(3):
                x = a[i, j, c]
                vals.append("" if np.isnan(x) else f"{x:.6f}")
        lines.append(f"{i + 1}\t{(nums[i] - nums[0]) / fps:.6f}\t" + "\t".join(vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def read_trc(path):
    """Read a ``.trc`` written by :func:`write_trc`: (marker names, times, (n, m, 3) array)."""
    lines = Path(path).read_text().splitlines()
    names = [x for x in lines[3].split("\t")[2:] if x]
    rows = [ln.split("\t") for ln in lines[6:] if ln.strip()]
    times = np.array([float(r[1]) for r in rows])
    a = np.full((len(rows), len(names), 3), np.nan)
    for i, r in enumerate(rows):
        for k, x in enumerate(r[2:2 + 3 * len(names)]):
            if x != "":
                a[i, k // 3, k % 3] = float(x)
    return names, times, a


def write_csv(path, poses, parts) -> Path:
    """Wide CSV: ``frame, status, distance, <part>_x, <part>_y, <part>_z, ...`` (capture units).

    Positions are written for matched frames only.
    """
    path = Path(path)
    poses = sorted(poses, key=lambda p: p.frame)
    a = _matrix(poses, parts)
    with open(path, "w", newline="") as fh:
        w = _csv.writer(fh)
        w.writerow(["frame", "status", "distance"] + [f"{p}_{c}" for p in parts for c in "xyz"])
        for i, p in enumerate(poses):
            row = [p.frame, p.status, "" if p.distance is None else f"{p.distance:.6f}"]
            row += ["" if np.isnan(x) else f"{x:.6f}" for x in a[i].ravel()]
            w.writerow(row)
    return path


def require_c3d():
    """Import the optional ``c3d`` package or raise a clear :class:`InputError`."""
    try:
        import c3d  # noqa: F401
    except ImportError:
        raise InputError("--c3d: C3D export needs the optional package 'c3d'; install it with "
                         "`pip install topopose[c3d]` (or use --trc / --csv)") from None
    return c3d


def write_c3d(path, poses, parts, fps=25.0, units="m") -> Path:
    """Write a C3D file (points in millimetres; missing points flagged invalid)."""
    c3d = require_c3d()
    poses = sorted(poses, key=lambda p: p.frame)
    a = _matrix(poses, parts) * metres_per_unit(units) * 1000.0
    w = c3d.Writer(point_rate=float(fps or 25.0), point_units="mm")
    try:
        w.set_point_labels(list(parts))
    except AttributeError:
        pass
    frames = []
    for i in range(len(poses)):
        pts = np.zeros((len(parts), 5), dtype=np.float32)
        ok = ~np.isnan(a[i]).any(axis=1)
        pts[ok, :3] = a[i][ok]
        pts[~ok, 3] = -1.0                  # residual -1: invalid point
        frames.append((pts, np.zeros((0, 0), dtype=np.float32)))
    w.add_frames(frames)
    with open(path, "wb") as fh:
        w.write(fh)
    return Path(path)
