"""A voxelized capsule stick figure walking: an independent oracle for the kinematics stage.

The figure is made of capsules (segments with a radius) hung on a joint skeleton whose
positions are known exactly in every frame, so the joints the kinematics stage finds
(Mukasa et al. §3.1) can be scored against them without any other stage (no cameras, no
visual hull). The synthetic captures of :mod:`topopose.synth.capture` are the end-to-end
counterpart.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from topopose.hull.volume import Volume

#: anatomical joints of the walker (the ground truth scored by R_detection / E_dist)
JOINTS = ("head_top", "neck", "shoulder_l", "shoulder_r", "elbow_l", "elbow_r", "wrist_l", "wrist_r",
          "hand_l", "hand_r", "pelvis", "hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r",
          "foot_l", "foot_r")


@dataclass
class WalkerSequence:
    """Voxelized frames of the walker with their ground truth.

    Attributes
    ----------
    volumes : list of Volume
    joints : list of dict name -> (3,) world position (anatomical joints and end points,
        :data:`JOINTS`, named as the synthetic captures' gt.json "joints")
    parts : list of dict name -> (3,) world position (human model parts: head, torso, ...)
    height : float
        Standing height of the figure (world units), for normalizing errors.
    """

    volumes: list
    joints: list
    parts: list
    height: float
    frames: list = field(default_factory=list)


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def walker_pose(t: float, period: float = 16.0, speed: float = 0.0, stride: float = 1.0):
    """Joint positions of the walking figure at time ``t`` (frames); +z up, walking along +x.

    Returns ``(joints, ends, capsules)``: anatomical joints, end points (head top, hand
    ends, toes) and the list of ``(a, b, radius)`` capsules.
    """
    ph = 2 * np.pi * t / period
    lat = np.array([0.0, 1.0, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    pelvis = np.array([speed * t, 0.0, 0.95 + 0.015 * np.cos(2 * ph)])
    neck = pelvis + np.array([0.02, 0.0, 0.52])
    J = {"pelvis": pelvis, "neck": neck}
    caps = [(pelvis, neck, 0.125), (pelvis + 0.1 * up, neck - 0.08 * up, 0.14)]
    ends = {}
    head_c = neck + np.array([0.02, 0, 0.17])
    caps.append((neck, head_c, 0.055))
    caps.append((head_c, head_c + 0.04 * up, 0.1))
    ends["head"] = head_c + 0.14 * up
    for side, s in (("l", 1.0), ("r", -1.0)):
        sgn = 1.0 if side == "l" else -1.0
        swing = stride * np.radians(28) * np.sin(ph + (0 if side == "l" else np.pi))
        # leg: hip flexion about the lateral axis, knee flexes during the swing phase
        hip = pelvis + s * 0.095 * lat
        knee_flex = stride * np.radians(45) * max(0.0, np.sin(ph + (0 if side == "l" else np.pi) + 0.9))
        R_hip = _rot(lat, swing)
        thigh = R_hip @ np.array([0, 0, -0.44])
        knee = hip + thigh
        R_knee = R_hip @ _rot(lat, -knee_flex)
        ankle = knee + R_knee @ np.array([0, 0, -0.42])
        toe = ankle + R_hip @ _rot(lat, -knee_flex + 0.2 * knee_flex) @ np.array([0.16, 0, -0.04])
        J["hip_" + side], J["knee_" + side], J["ankle_" + side] = hip, knee, ankle
        ends["foot_" + side] = toe
        caps += [(hip, knee, 0.07), (knee, ankle, 0.055), (ankle, toe, 0.045)]
        # arm: opposite swing, abducted, elbow flexed
        sh = neck + s * 0.19 * lat - 0.03 * up
        arm_swing = -0.8 * swing
        R_sh = _rot(lat, arm_swing) @ _rot(np.array([1.0, 0, 0]), sgn * np.radians(14))
        elbow = sh + R_sh @ np.array([0, 0, -0.29])
        el_flex = np.radians(20) + stride * np.radians(25) * (1 + np.sin(ph + (np.pi if side == "l" else 0))) / 2
        R_el = R_sh @ _rot(lat, el_flex)
        wrist = elbow + R_el @ np.array([0, 0, -0.26])
        hand = wrist + R_el @ np.array([0, 0, -0.1])
        J["shoulder_" + side], J["elbow_" + side], J["wrist_" + side] = sh, elbow, wrist
        ends["hand_" + side] = hand
        caps += [(sh, elbow, 0.048), (elbow, wrist, 0.042), (wrist, hand, 0.04),
                 (neck - 0.03 * up, sh, 0.06)]
    return J, ends, caps


def voxelize_capsules(capsules, shape, origin, voxel_size, thickness: float = 1.0) -> np.ndarray:
    """Boolean grid of the union of capsules ``(a, b, radius)`` (world units)."""
    shape = tuple(int(s) for s in shape)
    grid = np.zeros(shape, bool)
    origin = np.asarray(origin, float)
    for a, b, r in capsules:
        r = r * thickness
        a = np.asarray(a, float)
        b = np.asarray(b, float)
        lo = np.floor((np.minimum(a, b) - r - origin) / voxel_size).astype(int)
        hi = np.ceil((np.maximum(a, b) + r - origin) / voxel_size).astype(int) + 1
        lo = np.clip(lo, 0, shape)
        hi = np.clip(hi, 0, shape)
        if np.any(hi <= lo):
            continue
        ax = [origin[k] + voxel_size * np.arange(lo[k], hi[k]) for k in range(3)]
        X, Y, Z = np.meshgrid(*ax, indexing="ij")
        P = np.stack([X, Y, Z], -1)
        ab = b - a
        den = float(ab @ ab) or 1.0
        u = np.clip(((P - a) @ ab) / den, 0, 1)
        d = np.linalg.norm(P - (a + u[..., None] * ab), axis=-1)
        grid[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] |= d <= r
    return grid


def walker_sequence(frames: int = 16, resolution: int = 100, period: float = 16.0,
                    speed: float = 0.0, thickness: float = 1.0, stride: float = 1.0,
                    start: float = 0.0) -> WalkerSequence:
    """Voxelize ``frames`` frames of the walking capsule figure.

    The grid is fixed for the whole sequence (like a capture volume); its longest side has
    ``resolution`` voxels.
    """
    poses = [walker_pose(start + t, period, speed, stride) for t in range(frames)]
    pts = np.array([p for J, E, _ in poses for p in (*J.values(), *E.values())])
    lo = pts.min(0) - 0.2
    hi = pts.max(0) + 0.2
    vs = float((hi - lo).max()) / (resolution - 1)
    shape = np.ceil((hi - lo) / vs).astype(int) + 1
    vols, joints, parts = [], [], []
    for J, E, caps in poses:
        vols.append(Volume(voxelize_capsules(caps, shape, lo, vs, thickness), lo, vs))
        jj = {k: np.asarray(v, float) for k, v in J.items()}
        jj.update({"head_top": E["head"], "hand_l": E["hand_l"], "hand_r": E["hand_r"],
                   "foot_l": E["foot_l"], "foot_r": E["foot_r"]})
        joints.append({k: jj[k] for k in JOINTS})
        parts.append({"head": E["head"], "torso": J["neck"], "crotch": J["pelvis"],
                      "hand_1": E["hand_l"], "hand_2": E["hand_r"],
                      "foot_1": E["foot_l"], "foot_2": E["foot_r"]})
    J0, E0, _ = walker_pose(0.0, period, 0.0, 0.0)
    height = float(E0["head"][2] - min(E0["foot_l"][2], E0["foot_r"][2]) + 0.05)
    return WalkerSequence(vols, joints, parts, height, [f"{t:06d}" for t in range(frames)])
