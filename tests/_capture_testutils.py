"""Test helpers for the capture and hull tests: camera rings, analytic silhouettes, capture folders.

Silhouettes are rendered analytically: every pixel centre is undistorted into a viewing ray and
tested against the primitive (sphere or capsule) in closed form.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from topopose.capture import Camera


def look_at(center, target, up=(0, 0, 1)):
    """World → camera rotation for a camera at ``center`` looking at ``target`` (y down)."""
    z = np.asarray(target, float) - np.asarray(center, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def camera_at(centre, name, size=(640, 480), f=500.0):
    """A pinhole camera at ``centre`` looking at the world origin (z up), its principal point
    at the image centre."""
    c = np.asarray(centre, float)
    R = look_at(c, (0.0, 0.0, 0.0))
    K = [[f, 0, size[0] / 2], [0, f, size[1] / 2], [0, 0, 1]]
    return Camera(name, size, K, [0, 0, 0, 0], cv2.Rodrigues(R)[0].ravel(), -R @ c)


def ring(n=8, radius=3.0, height=1.2, target=(0, 0, 0.9), size=(640, 480), f=800.0,
         dist=(0, 0, 0, 0), fisheye=False, tilt_every=2):
    """``n`` cameras on a circle around ``target``; every other one a bit higher."""
    cams = []
    for q in range(n):
        ang = 2 * np.pi * q / n + 0.1
        h = height + (0.6 if tilt_every and q % tilt_every else 0.0)
        c = np.array([radius * np.cos(ang), radius * np.sin(ang), h])
        R = look_at(c, target)
        K = [[f, 0, size[0] / 2 - 0.5 + 3 * (q % 3)], [0, f * 1.001, size[1] / 2 - 0.5], [0, 0, 1]]
        cams.append(Camera(f"cam_{q + 1:02d}", size, K, list(dist), cv2.Rodrigues(R)[0].ravel(),
                           -R @ c, fisheye))
    return cams


_RAYS = {}


def pixel_rays(cam):
    """Unit world directions (h·w, 3) of the rays through every pixel centre (cached)."""
    key = (cam.size, cam.matrix.tobytes(), cam.distortions.tobytes(), cam.rotation.tobytes(),
           cam.fisheye)
    if key not in _RAYS:
        _RAYS[key] = _pixel_rays(cam)
    return _RAYS[key]


def _pixel_rays(cam):
    w, h = cam.size
    uu, vv = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    pts = np.stack([uu.ravel(), vv.ravel()], 1).reshape(-1, 1, 2)
    if not cam.fisheye and not np.any(cam.distortions != 0):
        Ki = np.linalg.inv(cam.matrix)
        d = np.c_[uu.ravel(), vv.ravel(), np.ones(w * h)] @ (cam.R.T @ Ki).T
        return d / np.linalg.norm(d, axis=1, keepdims=True)
    if cam.fisheye:
        nrm = cv2.fisheye.undistortPoints(pts, cam.matrix, cam.distortions[:4]).reshape(-1, 2)
    elif np.any(cam.distortions != 0):
        nrm = cv2.undistortPointsIter(pts, cam.matrix, cam.distortions, None, None,
                                      (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
                                      ).reshape(-1, 2)
    else:
        nrm = cv2.undistortPoints(pts, cam.matrix, cam.distortions).reshape(-1, 2)
    d = np.c_[nrm, np.ones(len(nrm))] @ cam.R
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def line_segment_dist2(C, d, A, B):
    """Squared distance between the lines {C + t d} (d unit, rows) and the segment [A, B]."""
    # point P(s) = A + s (B - A); distance to the line: |(P - C) - ((P - C)·d) d|
    e = B - A
    a0 = A - C                               # (3,)
    # w(s) = a0 + s e projected orthogonally to d: w(s) - (w(s)·d) d
    p0 = a0[None, :] - (d @ a0)[:, None] * d
    p1 = e[None, :] - (d @ e)[:, None] * d
    den = np.einsum("ij,ij->i", p1, p1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 1e-18, -np.einsum("ij,ij->i", p0, p1) / den, 0.0)
    s = np.clip(s, 0.0, 1.0)
    q = p0 + s[:, None] * p1
    return np.einsum("ij,ij->i", q, q)


def capsule_masks(cams, A, B, r, margin_px=0.0):
    """Exact silhouettes (pixel-centre rays) of the capsule [A, B] ⊕ ball(r), one per camera.

    ``margin_px`` > 0 widens the test by that many pixels' angular size (conservative masks).
    A sphere is the capsule with A == B.
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    out = []
    for cam in cams:
        w, h = cam.size
        d = pixel_rays(cam)
        c = cam.center
        d2 = line_segment_dist2(c, d, A, B)
        rr = r
        if margin_px:
            far = max(np.linalg.norm(A - c), np.linalg.norm(B - c)) + r
            rr = r + far * margin_px / min(cam.matrix[0, 0], cam.matrix[1, 1])
        front = (d @ ((A + B) / 2 - c)) > 0
        out.append(((d2 <= rr * rr) & front).reshape(h, w))
    return out


def analytic_hull(cams, pts, A, B, r):
    """Per point (n, 3): inside the intersection of the capsule's silhouette cones.

    The line from the camera centre C through X meets the capsule iff
    min over s in [0, 1] of |(A + s (B - A) - C) × (X - C)|² / |X - C|² ≤ r².
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    inside = np.ones(len(pts), bool)
    for cam in cams:
        C = cam.center
        idx = np.nonzero(inside)[0]
        if np.array_equal(A, B):             # sphere: |(A - C) × d|² ≤ r² |d|²
            d = pts[idx] - C
            ac = A - C
            t = d @ ac
            ok = (ac @ ac) * np.einsum("ij,ij->i", d, d) - t * t <= r * r * np.einsum("ij,ij->i", d, d)
            inside[idx[~ok]] = False
            continue
        d = (pts[idx] - C).astype(np.float64)
        u0 = np.cross(A - C, d)
        u1 = np.cross(B - A, d)
        a = np.einsum("ij,ij->i", u1, u1)
        b = np.einsum("ij,ij->i", u0, u1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.clip(np.where(a > 0, -b / a, 0.0), 0.0, 1.0)
        q = u0 + s[:, None] * u1
        ok = np.einsum("ij,ij->i", q, q) <= r * r * np.einsum("ij,ij->i", d, d)
        inside[idx[~ok]] = False
    return inside


def in_capsule(pts, A, B, r):
    A, B = np.asarray(A, float), np.asarray(B, float)
    e = B - A
    den = max(float(e @ e), 1e-18)
    s = np.clip((pts - A) @ e / den, 0, 1)
    q = A + s[:, None] * e
    return np.linalg.norm(pts - q, axis=1) <= r


def calibration_toml(cams) -> str:
    """Pose2Sim-layout calibration text for ``cams``."""
    lines = []
    for c in cams:
        lines += [f"[{c.name}]", f'name = "{c.name}"', f"size = [{c.size[0]}, {c.size[1]}]",
                  "matrix = [" + ", ".join("[" + ", ".join(repr(float(x)) for x in row) + "]"
                                           for row in c.matrix) + "]",
                  "distortions = [" + ", ".join(repr(float(x)) for x in c.distortions) + "]",
                  "rotation = [" + ", ".join(repr(float(x)) for x in c.rotation) + "]",
                  "translation = [" + ", ".join(repr(float(x)) for x in c.translation) + "]",
                  f"fisheye = {'true' if c.fisheye else 'false'}", ""]
    lines += ["[metadata]", 'adjusted = false', 'error = 0.0', ""]
    return "\n".join(lines)


def write_capture(root, cams, frames: dict, capture_toml: str | None = None,
                  images: dict | None = None, backgrounds: list | None = None) -> Path:
    """Write a capture folder: masks ``frames`` (name → list of bool masks), or colour
    ``images`` (name → list of images) plus ``backgrounds``."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    (root / "calibration.toml").write_text(calibration_toml(cams))
    if capture_toml is not None:
        (root / "capture.toml").write_text(capture_toml)
    for f, ms in (frames or {}).items():
        for c, m in zip(cams, ms):
            d = root / "silhouettes" / c.name
            d.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(d / f"{f}.png"), np.where(m, 255, 0).astype(np.uint8))
    for f, ims in (images or {}).items():
        for c, im in zip(cams, ims):
            d = root / "images" / c.name
            d.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(d / f"{f}.png"), im)
    if backgrounds is not None:
        d = root / "backgrounds"
        d.mkdir(parents=True, exist_ok=True)
        for c, im in zip(cams, backgrounds):
            cv2.imwrite(str(d / f"{c.name}.png"), im)
    return root
