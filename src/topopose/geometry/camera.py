"""Calibrated pinhole cameras (Pose2Sim / aniposelib conventions).

World → camera: ``x_cam = R @ X + t`` with ``R`` from the Rodrigues vector ``rotation``;
pixels: ``u = K @ distort(x_cam / z)`` with OpenCV's distortion model
``[k1, k2, p1, p2(, k3)]`` (or the fisheye model when ``fisheye`` is true).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class Camera:
    """One calibrated camera.

    Parameters
    ----------
    name : str
        Also the name of the camera's folder in a capture.
    size : (int, int)
        Image width and height in pixels.
    matrix : ndarray (3, 3)
        Intrinsic matrix K.
    distortions : ndarray (4,) or (5,)
        ``[k1, k2, p1, p2(, k3)]``; fisheye cameras: ``[k1, k2, k3, k4]``.
    rotation : ndarray (3,)
        Rodrigues vector, world → camera.
    translation : ndarray (3,)
        World → camera translation, in capture units.
    fisheye : bool
    """

    name: str
    size: tuple
    matrix: np.ndarray
    distortions: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    fisheye: bool = False

    def __post_init__(self):
        self.size = (int(self.size[0]), int(self.size[1]))
        self.matrix = np.asarray(self.matrix, dtype=float).reshape(3, 3)
        self.distortions = np.asarray(self.distortions, dtype=float).ravel()
        self.rotation = np.asarray(self.rotation, dtype=float).reshape(3)
        self.translation = np.asarray(self.translation, dtype=float).reshape(3)

    @property
    def R(self) -> np.ndarray:
        """World → camera rotation matrix (a copy; computed once per ``rotation``)."""
        key = self.rotation.tobytes()
        got = self.__dict__.get("_R")
        if got is None or got[0] != key:
            got = self.__dict__["_R"] = (key, cv2.Rodrigues(self.rotation)[0])
        return got[1].copy()

    @property
    def center(self) -> np.ndarray:
        """Optical centre in world coordinates."""
        return -self.R.T @ self.translation

    def to_camera(self, points) -> np.ndarray:
        """World points (N, 3) → camera coordinates (N, 3)."""
        return np.asarray(points, dtype=float).reshape(-1, 3) @ self.R.T + self.translation

    def project(self, points) -> np.ndarray:
        """World points (N, 3) → pixel coordinates (N, 2), lens distortion applied.

        Points behind the camera (z ≤ 0) give NaN.

        Examples
        --------
        >>> cam = Camera("c", (640, 480), [[500, 0, 320], [0, 500, 240], [0, 0, 1]],
        ...              [0, 0, 0, 0], [0, 0, 0], [0, 0, 5])
        >>> cam.project([[0.1, 0.0, 0.0]]).round(3).tolist()
        [[330.0, 240.0]]
        """
        xc = self.to_camera(points)
        z = xc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            a = xc[:, 0] / z
            b = xc[:, 1] / z
        d = self.distortions
        if self.fisheye:
            k = np.zeros(4)
            k[: min(4, d.size)] = d[:4]
            r = np.hypot(a, b)
            th = np.arctan(r)
            th2 = th * th
            thd = th * (1 + k[0] * th2 + k[1] * th2**2 + k[2] * th2**3 + k[3] * th2**4)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(r > 1e-12, thd / r, 1.0)
            ad, bd = a * s, b * s
        else:
            k = np.zeros(5)
            k[: min(5, d.size)] = d[:5]
            r2 = a * a + b * b
            if k.any():
                radial = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2**3
                ad = a * radial + 2 * k[2] * a * b + k[3] * (r2 + 2 * a * a)
                bd = b * radial + k[2] * (r2 + 2 * b * b) + 2 * k[3] * a * b
            else:       # zero coefficients: those terms add +0, or NaN where r2³ overflows
                zero = 0.0 * r2**3
                ad, bd = a + zero, b + zero
        K = self.matrix
        u = K[0, 0] * ad + K[0, 1] * bd + K[0, 2]
        v = K[1, 1] * bd + K[1, 2]
        out = np.stack([u, v], axis=1)
        out[~(z > 0)] = np.nan
        return out
