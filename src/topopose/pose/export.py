"""Exports of the matched poses: TRC (OpenSim), wide CSV, C3D (optional extra), BVH (Blender).

Only matched frames carry positions in the exports; rejected and failed frames are rows
with empty values (TRC, CSV) or invalid points (C3D), so frame numbers and times stay aligned
with the capture. Markers are every part and every fitted joint (:attr:`Pose.joints`); with
``labels=OPENSIM_LABELS`` they carry the OpenSim / Pose2Sim marker names where one exists
(``left_elbow`` → ``LElbow``, ``neck`` → ``Neck``, ``pelvis`` → ``Hip``...; without a fitted
skeleton ``torso`` → ``Neck`` and ``crotch`` → ``Hip``), other names are kept as they are.
"""
from __future__ import annotations

import csv as _csv
from pathlib import Path

import numpy as np

from topopose.errors import InputError
from topopose.frames import sort_poses

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


# OpenSim / Pose2Sim marker names (Pose2Sim's HALPE_26 / BODY_25 keypoints) of our part and
# joint names. Hands and feet have no Pose2Sim keypoint at their tip: LHand / LFoot.
OPENSIM_LABELS = {
    "head": "Head", "torso": "Neck", "neck": "Neck", "crotch": "Hip", "pelvis": "Hip",
    "left_shoulder": "LShoulder", "right_shoulder": "RShoulder",
    "left_elbow": "LElbow", "right_elbow": "RElbow",
    "left_wrist": "LWrist", "right_wrist": "RWrist",
    "left_hand": "LHand", "right_hand": "RHand",
    "left_hip": "LHip", "right_hip": "RHip",
    "left_knee": "LKnee", "right_knee": "RKnee",
    "left_ankle": "LAnkle", "right_ankle": "RAnkle",
    "left_foot": "LFoot", "right_foot": "RFoot",
}


def marker_names(poses, parts=()) -> list:
    """Every part and joint name met in ``poses`` (``parts`` first, in their order)."""
    names = dict.fromkeys(parts)
    for p in poses:
        names.update(dict.fromkeys(p.parts))
        names.update(dict.fromkeys(p.joints))
    return list(names)


# parts that give way to the fitted joint of the same marker (Pose2Sim's Neck is the neck base:
# the fitted neck joint, not the skeleton's shoulder-centre junction)
_GIVE_WAY = {"torso": "neck", "crotch": "pelvis"}


def _labels(names, labels):
    if labels is None:
        return list(names)
    present = set(names)
    out, seen = [], set()
    for n in names:
        lab = labels.get(n, n)
        if lab in seen or _GIVE_WAY.get(n) in present:   # two names for one marker: keep ours
            lab = n
        seen.add(lab)
        out.append(lab)
    return out


def _matrix(poses, parts):
    """(n_frames, n_parts, 3) positions, NaN where a part is missing or the frame neither
    matched nor tracked (:mod:`topopose.sequence.follow`).

    Joints (:attr:`Pose.joints`) count as parts; interpolated joints are written too (they are
    flagged in the JSON Lines file).
    """
    a = np.full((len(poses), len(parts), 3), np.nan)
    for i, p in enumerate(poses):
        placed = p.status in ("matched", "tracked")
        if not placed and not p.joints:
            continue
        for j, name in enumerate(parts):
            v = p.parts.get(name) if placed else None
            if v is None:
                v = p.joints.get(name)
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


def write_trc(path, poses, parts, fps=25.0, units="m", up="+z", y_up=True, labels=None,
              name=None) -> Path:
    """Write an OpenSim ``.trc`` marker file, in metres.

    Parameters
    ----------
    poses : list of Pose (sorted by frame)
    parts : part names (markers)
    fps : capture frame rate
    units : capture units (converted to metres)
    up : the capture's up axis; with ``y_up`` the positions are rotated so that up is +Y,
        OpenSim's convention.
    labels : dict, optional
        Marker label of each name (e.g. :data:`OPENSIM_LABELS`); unlisted names are kept.
    name : str, optional
        The file name the header records (default ``path``'s): the final name when ``path``
        is a temporary file renamed at the end.
    """
    path = Path(path)
    poses = sort_poses(poses)
    a = _matrix(poses, parts) * metres_per_unit(units)
    if y_up:
        a = a @ y_up_rotation(up).T
    nums = _frame_numbers(poses)
    n, m = len(poses), len(parts)
    fps = float(fps or 25.0)
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{name or path.name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
             "OrigDataStartFrame\tOrigNumFrames",
             f"{fps:.2f}\t{fps:.2f}\t{n}\t{m}\tm\t{fps:.2f}\t{(nums[0] + 1) if nums else 1}\t{n}",
             "Frame#\tTime\t" + "\t".join(f"{p}\t\t" for p in _labels(parts, labels)).rstrip("\t"),
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
    """Read a ``.trc`` (ours or Pose2Sim's): (marker names, times, (n, m, 3) array)."""
    lines = Path(path).read_text().splitlines()
    names = [x.strip() for x in lines[3].split("\t")[2:] if x.strip()]
    # data from line 6 (ours, after an empty line) or line 5 (Pose2Sim / OpenSim files)
    rows = [ln.split("\t") for ln in lines[5:] if ln.strip() and ln.split("\t")[0].strip()
            and ln.split("\t")[0].strip()[0].isdigit()]
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
    poses = sort_poses(poses)
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


def write_c3d(path, poses, parts, fps=25.0, units="m", labels=None) -> Path:
    """Write a C3D file (points in millimetres, capture axes; missing points flagged invalid).

    ``labels`` as for :func:`write_trc`.
    """
    c3d = require_c3d()
    poses = sort_poses(poses)
    a = _matrix(poses, parts) * metres_per_unit(units) * 1000.0
    w = c3d.Writer(point_rate=float(fps or 25.0), point_units="mm")
    try:
        w.set_point_labels(_labels(parts, labels))
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


def _min_rotation(a, b) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0.0, 0.0])          # half turn about any axis ⟂ a
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def write_bvh(path, names, parents, positions, fps=25.0, units="m", up="+z", y_up=True) -> Path:
    """Write a skeleton sequence as BVH (Biovision hierarchy) for Blender and other animation tools.

    Parameters
    ----------
    names : list of str
        Joint names (spaces are replaced by ``_``).
    parents : list of int
        Parent index of each joint, -1 for the root (exactly one).
    positions : ndarray (n_frames, n_joints, 3)
        World positions (capture units); a frame with any NaN repeats the previous complete
        frame (BVH has no missing values; the JSON Lines file says which frames were fitted).
    fps, units, up, y_up : as for :func:`write_trc` (BVH in metres, +Y up by default, which
        Blender's importer expects).

    Notes
    -----
    Offsets are constant: each bone's length is its median over the complete frames and its
    rest direction the normalized mean of its directions. Each joint rotates its one outgoing
    bone by the smallest rotation from the rest direction (twist-free); a joint with several
    children (the pelvis, the shoulder centre) gets one zero-offset helper joint
    ``<joint>.<child>`` per child. Channels: the root has
    ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``, the others
    ``Zrotation Xrotation Yrotation`` (ZXY order, degrees): local matrix ``Rz·Rx·Ry``, global
    rotation the product of the locals from the root down, joint position
    ``parent position + parent global rotation · offset``. When the bone lengths of
    ``positions`` are constant (the kinematic fit makes them so), re-reading the file gives
    the same joint positions.
    """
    import warnings

    from scipy.spatial.transform import Rotation

    path = Path(path)
    names = [str(n).replace(" ", "_") for n in names]
    parents = [int(x) for x in parents]
    n = len(names)
    roots = [i for i, q in enumerate(parents) if q < 0]
    if len(roots) != 1 or len(parents) != n:
        raise InputError(f"{path}: a BVH skeleton needs exactly one root (parent -1), got {roots}")
    P = np.asarray(positions, dtype=float) * metres_per_unit(units)
    if y_up:
        P = P @ y_up_rotation(up).T
    ok = ~np.isnan(P).any(axis=(1, 2))
    if not ok.any():
        raise InputError(f"{path}: no complete frame to write")
    first = int(np.argmax(ok))
    for i in range(len(P)):                       # hold the last complete frame
        if not ok[i]:
            P[i] = P[i - 1] if i > first else P[first]
    root = roots[0]
    children = {i: [c for c in range(n) if parents[c] == i] for i in range(n)}
    good = P[ok]
    offset = np.zeros((n, 3))
    for c in range(n):
        if parents[c] >= 0:
            v = good[:, c] - good[:, parents[c]]
            length = float(np.median(np.linalg.norm(v, axis=1)))
            d = (v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)).mean(axis=0)
            nd = np.linalg.norm(d)
            offset[c] = length * (d / nd if nd > 1e-9 else np.array([0.0, 1.0, 0.0]))

    # BVH nodes: (name, joint index or None, offset, child joint it orients or None, children)
    nodes = []

    def build(j, off):
        k = len(nodes)
        nodes.append([names[j], j, off, None, []])
        kids = children[j]
        if len(kids) == 1:
            nodes[k][3] = kids[0]
            nodes[k][4].append(build(kids[0], offset[kids[0]]))
        else:
            for c in kids:
                h = len(nodes)
                nodes.append([f"{names[j]}.{names[c]}", None, np.zeros(3), c, []])
                nodes[h][4].append(build(c, offset[c]))
                nodes[k][4].append(h)
        return k

    build(root, np.zeros(3))
    parent_node = {c: k for k, nd in enumerate(nodes) for c in nd[4]}

    lines = ["HIERARCHY"]

    def emit(k, depth):
        name, j, off, _, kids = nodes[k]
        ind = "\t" * depth
        head = "ROOT" if k == 0 else "JOINT"
        lines.append(f"{ind}{head} {name}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {off[0]:.9f} {off[1]:.9f} {off[2]:.9f}")
        ch = ("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" if k == 0
              else "CHANNELS 3 Zrotation Xrotation Yrotation")
        lines.append(f"{ind}\t{ch}")
        for c in kids:
            emit(c, depth + 1)
        if not kids:
            o = offset[j] if j is not None else np.zeros(3)
            o = 0.1 * o if np.linalg.norm(o) > 0 else np.array([0.0, 0.01, 0.0])
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {o[0]:.9f} {o[1]:.9f} {o[2]:.9f}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(0, 0)
    fps = float(fps or 25.0)
    lines += ["MOTION", f"Frames: {len(P)}", f"Frame Time: {1.0 / fps:.9f}"]
    for f in range(len(P)):
        G = [None] * len(nodes)
        vals = [*P[f, root]]
        for k, nd in enumerate(nodes):             # parents come before children
            _, j, _, target, _ = nd
            Gp = G[parent_node[k]] if k in parent_node else np.eye(3)
            if target is None:
                G[k] = Gp
            else:
                src = nodes[k][1] if nodes[k][1] is not None else parents[target]
                d = P[f, target] - P[f, src]
                d0 = offset[target]
                if np.linalg.norm(d) < 1e-12 or np.linalg.norm(d0) < 1e-12:
                    G[k] = Gp
                else:
                    G[k] = _min_rotation(d0 / np.linalg.norm(d0), d / np.linalg.norm(d))
            with warnings.catch_warnings():       # gimbal lock: still an exact decomposition
                warnings.simplefilter("ignore", UserWarning)
                vals += list(Rotation.from_matrix(Gp.T @ G[k]).as_euler("ZXY", degrees=True))
        lines.append(" ".join(f"{x:.9f}" for x in vals))
    path.write_text("\n".join(lines) + "\n")
    return path
