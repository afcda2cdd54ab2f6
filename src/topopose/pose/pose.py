"""The per-frame result of pose initialization and its JSON Lines file (DESIGN.md "Poses")."""
from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from topopose.match.tree import _jsonable

from topopose.errors import InputError
from topopose.frames import sort_frames, sort_poses

STATUSES = ("matched", "tracked", "rejected", "lost", "failed")


@dataclass
class Pose:
    """Pose of one frame.

    Attributes
    ----------
    frame : str
    status : str
        ``"matched"`` (distance ≤ T_d and enough parts), ``"rejected"`` (distance above T_d,
        or too few parts placed: the partial / no-matching classes of §13.2.2 that the method
        detects itself) or ``"failed"`` (the frame could not be processed; see ``error``);
        after the tracker (:mod:`topopose.sequence.follow`) also ``"tracked"`` (the subject's
        body followed into this frame fits it, ``fit`` says how well) and ``"lost"``.
    distance : float or None
        AHA distance between the normalized model and data trees (§12.1.1).
    parts : dict part -> ndarray (3,) or None
        World position of each model part; None when the alignment left it unmatched. Rejected
        frames keep the positions the alignment proposed (for the quality study), flagged by
        their status: use only matched frames.
    error : str or None
        Why a frame failed (or was rejected).
    timings_ms : dict
        Per-stage times: hull, thinning, tree, alignment, total.
    diagnostics : dict
        Small JSON-able facts (data tree size, hull voxels, ...).
    joints : dict name -> ndarray (3,)
        The full kinematic skeleton of the frame (:mod:`.kinematic_fit`): neck, shoulders,
        elbows, ... with bone lengths constant over the sequence; empty when not fitted.
        ``diagnostics["interpolated"]`` is true when they were filled in across a short
        rejected stretch rather than fitted to this frame (also when this frame's own fit
        was off the motion around it: ``diagnostics["temporal_outlier"]``; its parts listed
        in ``diagnostics["interpolated_parts"]`` were then interpolated too). A joint listed
        in ``diagnostics["despiked_joints"]`` had its bone's direction, far off the frames
        around it, replaced by theirs before the smoothing.
    fit : float or None
        How well the tracked body fits the frame (:mod:`topopose.sequence.follow`: the
        silhouette IoU of the projected body, or the voxel agreement); None: not tracked.
    """

    frame: str
    status: str
    distance: float | None = None
    parts: dict = field(default_factory=dict)
    error: str | None = None
    timings_ms: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    fit: float | None = None

    @property
    def matched(self) -> bool:
        return self.status == "matched"

    def to_dict(self) -> dict:
        d = {"frame": str(self.frame), "status": self.status,
             "distance": None if self.distance is None or not math.isfinite(self.distance)
             else float(self.distance),
             "parts": {str(k): (None if v is None or not np.all(np.isfinite(v))   # unplaced
                                else [float(x) for x in np.asarray(v).ravel()])
                       for k, v in self.parts.items()},
             "error": self.error,
             **({} if self.fit is None else {"fit": float(self.fit)}),
             "timings_ms": {k: round(float(v), 3) for k, v in self.timings_ms.items()}}
        if self.diagnostics:
            d["diagnostics"] = _jsonable(self.diagnostics)
        if self.joints:
            d["joints"] = {str(k): [float(x) for x in np.asarray(v).ravel()]
                           for k, v in self.joints.items() if np.all(np.isfinite(v))}
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))

    @classmethod
    def from_dict(cls, d: dict, source: str = "poses") -> "Pose":
        """A pose from its JSON object; every field checked (positions: three finite numbers
        within :data:`MAX_COORDINATE`), InputError naming ``source`` and the field."""
        if not isinstance(d, dict) or "frame" not in d or "status" not in d:
            raise InputError(f"{source}: expected an object with 'frame' and 'status'")
        if not isinstance(d["frame"], (str, int)) or isinstance(d["frame"], bool):
            raise InputError(f"{source}: field 'frame' must be a frame name, got {d['frame']!r}"[:300])
        if not isinstance(d["status"], str) or d["status"] not in STATUSES:
            raise InputError(f"{source}: status {d['status']!r} must be one of {STATUSES}"[:300])
        for key in ("parts", "joints", "timings_ms", "diagnostics"):
            if d.get(key) is not None and not isinstance(d[key], dict):
                raise InputError(f"{source}: field '{key}' must be an object")
        parts = {k: None if v is None else _point(v, f"{source}: parts.{k}")
                 for k, v in (d.get("parts") or {}).items()}
        joints = {k: _point(v, f"{source}: joints.{k}") for k, v in (d.get("joints") or {}).items()}
        dist = d.get("distance")
        if dist is not None and not _number(dist, finite=True):
            raise InputError(f"{source}: field 'distance' must be a finite number or null, "
                             f"got {dist!r}"[:300])
        if d.get("error") is not None and not isinstance(d["error"], str):
            raise InputError(f"{source}: field 'error' must be a text or null")
        return cls(frame=str(d["frame"]), status=d["status"],
                   distance=None if dist is None else float(dist), parts=parts,
                   error=d.get("error"), timings_ms=dict(d.get("timings_ms") or {}),
                   diagnostics=dict(d.get("diagnostics") or {}), joints=joints,
                   fit=None if d.get("fit") is None else float(d["fit"]))


#: the largest position coordinate a poses file may hold (capture units): far beyond any
#: capture volume, small enough that distances and squares stay finite
MAX_COORDINATE = 1e9


def _number(x, finite=False) -> bool:
    """A JSON number (not a boolean); with ``finite``, one that is a finite float."""
    if not isinstance(x, numbers.Real) or isinstance(x, (bool, np.bool_)):
        return False
    try:
        return not finite or math.isfinite(float(x))
    except OverflowError:                        # an integer beyond any float
        return False


def _point(v, where) -> np.ndarray:
    """``[x, y, z]`` of finite numbers within :data:`MAX_COORDINATE`, else InputError."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not (isinstance(v, (list, tuple)) and len(v) == 3 and all(_number(x) for x in v)):
        raise InputError(f"{where} must be [x, y, z] (three numbers)"[:300])
    a = np.asarray(v, dtype=float) if all(_number(x, finite=True) for x in v) else np.full(3, np.inf)
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > MAX_COORDINATE):
        raise InputError(f"{where} must be finite coordinates within ±{MAX_COORDINATE:g}, "
                         f"got {list(v)}"[:300])
    return a


def is_header(d) -> bool:
    """The optional first line of a poses file: ``{"topopose": version, "model": ...}`` (what
    made the file: model, model_hash, resolution, capture, settings; see ``run``). Any JSON
    object without ``"frame"`` counts (another tool's header); every pose line has one."""
    return isinstance(d, dict) and "frame" not in d


def read_header(path) -> dict | None:
    """The header line of a poses file (None for a file without one, or an empty file)."""
    try:
        with open(path) as fh:
            first = fh.readline()
    except FileNotFoundError:
        raise InputError(f"{path}: no such poses file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read poses ({exc})") from None
    try:
        d = json.loads(first)
    except (ValueError, RecursionError):         # not JSON (or nested beyond reading)
        return None
    return d if is_header(d) else None


def read_poses(path, strict: bool = True) -> list:
    """Read a poses ``.jsonl`` file (one :class:`Pose` per line), sorted by frame.

    A header line (:func:`is_header`) is skipped (files with and without one are read).
    ``strict=False`` skips an unreadable *last* line (a run interrupted mid-write).
    Later lines win when a frame appears twice.
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise InputError(f"{path}: no such poses file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read poses ({exc})") from None
    poses = {}
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
        except (ValueError, RecursionError) as exc:   # also numbers too long, nesting too deep
            if not strict and i == len(lines) - 1:
                break
            raise InputError(f"{path}: line {i + 1} is not JSON "
                             f"({str(exc)[:200] or type(exc).__name__})") from None
        if is_header(d):
            continue
        p = Pose.from_dict(d, source=f"{path}: line {i + 1}")
        poses[p.frame] = p
    return [poses[k] for k in sort_frames(poses)]


def write_poses(path, poses, header: dict | None = None) -> None:
    """Write poses as JSON Lines, sorted by frame, after the optional ``header`` line
    (written to a temporary file renamed over ``path``: an existing file is never half-written)."""
    from topopose._paths import atomic_output

    with atomic_output(path) as tmp, open(tmp, "w") as fh:
        if header is not None:
            fh.write(json.dumps(header, separators=(",", ":")) + "\n")
        for p in sort_poses(poses):
            fh.write(p.to_json() + "\n")
