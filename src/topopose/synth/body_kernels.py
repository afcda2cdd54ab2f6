"""Numba kernel of the triangle-mesh silhouette rasterizer (see :mod:`.synth_body`)."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _distort(x, y, K, dist):
    """Pixel (u, v) of the undistorted normalized point (x, y): OpenCV's k1, k2, p1, p2, k3 model."""
    r2 = x * x + y * y
    rad = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]))
    xd = x * rad + 2.0 * dist[2] * x * y + dist[3] * (r2 + 2.0 * x * x)
    yd = y * rad + dist[2] * (r2 + 2.0 * y * y) + 2.0 * dist[3] * x * y
    return K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]


@njit(cache=True)
def _straddling(xc, a, b, c, xy, mask):
    """A triangle crossing the camera plane: ray/triangle test (line through the triangle, hit in
    front of the camera) at every pixel."""
    h, w = mask.shape
    v0 = xc[a]
    v1 = xc[b]
    v2 = xc[c]
    e1 = v1 - v0
    e2 = v2 - v0
    n0 = e1[1] * e2[2] - e1[2] * e2[1]
    n1 = e1[2] * e2[0] - e1[0] * e2[2]
    n2 = e1[0] * e2[1] - e1[1] * e2[0]
    nv = n0 * v0[0] + n1 * v0[1] + n2 * v0[2]
    for v in range(h):
        for u in range(w):
            if mask[v, u]:
                continue
            d0 = xy[v, u, 0]
            d1 = xy[v, u, 1]
            nd = n0 * d0 + n1 * d1 + n2
            if nd == 0.0 or nv / nd <= 0.0:
                continue
            s = np.empty(3)
            for k in range(3):
                p = xc[(a, b, c)[k]]
                q = xc[(b, c, a)[k]]
                s[k] = (d0 * (p[1] * q[2] - p[2] * q[1]) + d1 * (p[2] * q[0] - p[0] * q[2])
                        + (p[0] * q[1] - p[1] * q[0]))
            if (s[0] >= 0 and s[1] >= 0 and s[2] >= 0) or (s[0] <= 0 and s[1] <= 0 and s[2] <= 0):
                mask[v, u] = True


@njit(cache=True)
def raster_kernel(xc, faces, K, dist, full, xy, mask):
    """Set ``mask[v, u]`` for every pixel whose viewing ray meets a triangle.

    ``xc``: vertices in camera coordinates (n, 3); ``xy``: undistorted normalized coordinates of
    every pixel centre (h, w, 2); ``dist``: k1, k2, p1, p2, k3. A triangle in front of the camera
    is a straight-edged triangle in normalized coordinates: a pixel is inside when its three
    edge functions share the triangle's orientation (closed test). Only the pixels of its
    distorted bounding box (vertices and edge midpoints, padded by one pixel) are tested, or the
    whole image when ``full`` (a lens model without a closed form here).
    """
    h, w = mask.shape
    eps = 1e-9
    px = np.empty(6)
    py = np.empty(6)
    for f in range(faces.shape[0]):
        a = faces[f, 0]
        b = faces[f, 1]
        c = faces[f, 2]
        za = xc[a, 2]
        zb = xc[b, 2]
        zc = xc[c, 2]
        if za <= eps and zb <= eps and zc <= eps:
            continue
        if za <= eps or zb <= eps or zc <= eps:
            _straddling(xc, a, b, c, xy, mask)
            continue
        x0 = xc[a, 0] / za
        y0 = xc[a, 1] / za
        x1 = xc[b, 0] / zb
        y1 = xc[b, 1] / zb
        x2 = xc[c, 0] / zc
        y2 = xc[c, 1] / zc
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        if area == 0.0:
            continue
        sg = 1.0 if area > 0 else -1.0
        if full:
            u0, u1, v0, v1 = 0, w - 1, 0, h - 1
        else:
            px[0], py[0] = x0, y0
            px[1], py[1] = x1, y1
            px[2], py[2] = x2, y2
            px[3], py[3] = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
            px[4], py[4] = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
            px[5], py[5] = 0.5 * (x2 + x0), 0.5 * (y2 + y0)
            umin = np.inf
            umax = -np.inf
            vmin = np.inf
            vmax = -np.inf
            for k in range(6):
                uu, vv = _distort(px[k], py[k], K, dist)
                umin = min(umin, uu)
                umax = max(umax, uu)
                vmin = min(vmin, vv)
                vmax = max(vmax, vv)
            if umax < -1.0 or vmax < -1.0 or umin > w or vmin > h:
                continue
            u0 = max(int(np.floor(umin)) - 1, 0)
            u1 = min(int(np.ceil(umax)) + 1, w - 1)
            v0 = max(int(np.floor(vmin)) - 1, 0)
            v1 = min(int(np.ceil(vmax)) + 1, h - 1)
        for v in range(v0, v1 + 1):
            for u in range(u0, u1 + 1):
                if mask[v, u]:
                    continue
                qx = xy[v, u, 0]
                qy = xy[v, u, 1]
                if (sg * ((x1 - x0) * (qy - y0) - (y1 - y0) * (qx - x0)) >= 0.0
                        and sg * ((x2 - x1) * (qy - y1) - (y2 - y1) * (qx - x1)) >= 0.0
                        and sg * ((x0 - x2) * (qy - y2) - (y0 - y2) * (qx - x2)) >= 0.0):
                    mask[v, u] = True
