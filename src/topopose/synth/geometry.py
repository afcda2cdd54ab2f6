"""Geometry of the synthetic subjects: round cones, ellipsoids, exact silhouettes, clearances.

A synthetic subject is a union of two kinds of convex primitives:

* a *round cone* — the union of the spheres centred on a segment ``a → b`` whose radius varies
  linearly from ``ra`` to ``rb`` (the convex hull of the two end spheres); with ``ra == rb`` it is a
  capsule;
* an *ellipsoid* — centre ``c``, orthonormal axes (columns of ``axes``) and semi-axes ``semi``.

Silhouettes are rendered exactly: every pixel centre is undistorted once per camera into a viewing
ray (``cv2.undistortPointsIter``), and a pixel belongs to the silhouette when its ray meets one of
the primitives.  The ray tests are closed forms:

* ellipsoid: map the ray into the ellipsoid's unit-sphere frame and compare the ray's distance to
  the origin with 1;
* round cone: the distance from the ray's line to the point ``q(s) = a + s (b - a)`` is the norm of
  an affine function of ``s`` (a convex function), minus the linear radius ``r(s)``; the minimum of
  this convex function over ``[0, 1]`` is at its clipped stationary point, which has a closed form
  (:func:`ray_hits_cone`).  The ray meets the primitive iff that minimum is ≤ 0.

The camera lies outside every primitive, so "the line meets it in front of the camera" is the same
as "the ray meets it" for primitives in front of the camera, which is always the case here.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class Prim:
    """One convex primitive of a synthetic body.

    Parameters
    ----------
    kind : "cone" | "ellipsoid"
    link : str
        The kinematic link (bone) the primitive belongs to.
    a, b, ra, rb : round cone axis end points and radii.
    c, axes, semi : ellipsoid centre, axes (3×3, columns) and semi-axes.
    """

    kind: str
    link: str
    a: np.ndarray | None = None
    b: np.ndarray | None = None
    ra: float = 0.0
    rb: float = 0.0
    c: np.ndarray | None = None
    axes: np.ndarray | None = None
    semi: np.ndarray | None = None

    def bounding_sphere(self):
        """(centre, radius) of a sphere containing the primitive."""
        if self.kind == "cone":
            c = 0.5 * (self.a + self.b)
            return c, 0.5 * float(np.linalg.norm(self.b - self.a)) + max(self.ra, self.rb)
        return self.c, float(np.max(self.semi))

    def transformed(self, R, t):
        """The primitive moved by ``x → R x + t``."""
        if self.kind == "cone":
            return Prim("cone", self.link, R @ self.a + t, R @ self.b + t, self.ra, self.rb)
        return Prim("ellipsoid", self.link, c=R @ self.c + t, axes=R @ self.axes, semi=self.semi.copy())

    def surface_points(self, n=64):
        """Points on the surface (used for tests and extents)."""
        k = np.arange(n) + 0.5
        phi = np.arccos(1 - 2 * k / n)
        th = np.pi * (1 + 5 ** 0.5) * k
        sph = np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], 1)
        if self.kind == "ellipsoid":
            return self.c + (sph * self.semi) @ self.axes.T
        # round cone: spheres along the axis (their union is the primitive; the points of each
        # sphere lying inside a neighbour are inside the solid, harmless for extents)
        s = np.linspace(0, 1, 9)
        centres = self.a + s[:, None] * (self.b - self.a)
        radii = self.ra + s * (self.rb - self.ra)
        return (centres[:, None, :] + radii[:, None, None] * sph[None]).reshape(-1, 3)


# ----------------------------------------------------------------------------- ray tests
def ray_hits_cone(o, d, a, b, ra, rb):
    """Exact test: do the lines ``o + t d`` (d: (N, 3) unit directions) meet the round cone?

    Minimises ``h(s) = |P⊥(w + s u)| - (ra + s (rb - ra))`` over ``s ∈ [0, 1]`` where
    ``w = a - o``, ``u = b - a`` and ``P⊥`` removes the component along ``d``.  With
    ``q(s) = α s² + 2 β s + γ = α (s - s0)² + δ`` the stationary point of the convex ``h`` is
    ``s0 + x`` with ``x = dr sqrt(δ / (α (α - dr²)))`` when ``α > dr²``; otherwise ``h`` is
    monotone and the minimum is at an end.  Returns a bool array (N,).
    """
    w = a - o
    u = b - a
    dr = rb - ra
    dw = d @ w
    du = d @ u
    uu = float(u @ u)
    wu = float(w @ u)
    ww = float(w @ w)
    alpha = uu - du * du
    beta = wu - dw * du
    gamma = ww - dw * dw
    alpha = np.maximum(alpha, 0.0)

    def h(s):
        q = np.maximum(alpha * s * s + 2 * beta * s + gamma, 0.0)
        return np.sqrt(q) - (ra + s * dr)

    best = np.minimum(h(np.zeros_like(alpha)), h(np.ones_like(alpha)))
    ok = alpha > dr * dr + 1e-15
    with np.errstate(divide="ignore", invalid="ignore"):
        s0 = np.where(ok, -beta / np.where(ok, alpha, 1.0), 0.0)
        delta = np.maximum(gamma - np.where(ok, beta * beta / np.where(ok, alpha, 1.0), 0.0), 0.0)
        x = np.where(ok, dr * np.sqrt(delta / np.where(ok, alpha * (alpha - dr * dr), 1.0)), 0.0)
    s = np.clip(s0 + x, 0.0, 1.0)
    best = np.minimum(best, np.where(ok, h(s), np.inf))
    return best <= 0.0


def ray_hits_ellipsoid(o, d, c, axes, semi):
    """Exact test: do the lines ``o + t d`` meet the ellipsoid?  Returns bool (N,)."""
    M = axes.T / semi[:, None]                  # world → unit-sphere frame (linear part)
    oo = M @ (o - c)
    dd = d @ M.T
    dd2 = np.einsum("ij,ij->i", dd, dd)
    od = dd @ oo
    return float(oo @ oo) - od * od / dd2 <= 1.0


# ----------------------------------------------------------------------------- rendering
@dataclass
class RayTable:
    """Undistorted normalized coordinates of every pixel centre of one camera.

    ``xy[v, u]`` is the point (x, y) of the plane z = 1 (camera frame) whose image is the pixel
    centre (u, v); the viewing ray in the world is ``origin + t Rt (x, y, 1)``.
    """

    origin: np.ndarray
    Rt: np.ndarray
    xy: np.ndarray              # (h, w, 2)

    def directions(self, v0=0, v1=None, u0=0, u1=None) -> np.ndarray:
        """Unit world ray directions (h', w', 3) of a block of pixels."""
        xy = self.xy[v0:v1, u0:u1]
        dc = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=2)
        dw = dc @ self.Rt.T
        return dw / np.linalg.norm(dw, axis=2, keepdims=True)


def ray_table(cam) -> RayTable:
    """Viewing rays of every pixel centre of ``cam`` (pixel (u, v) centre at integer u, v).

    The distorted pixel grid is undistorted with ``cv2.undistortPointsIter`` (iterated to
    1e-12), the inverse of :meth:`Camera.project`.
    """
    w, h = cam.size
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.stack([uu.ravel(), vv.ravel()], 1).reshape(-1, 1, 2)
    if cam.fisheye:
        xy = cv2.fisheye.undistortPoints(pts, cam.matrix, cam.distortions[:4]).reshape(-1, 2)
    elif np.any(cam.distortions != 0):
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        xy = cv2.undistortPointsIter(pts, cam.matrix, cam.distortions, None, None, crit).reshape(-1, 2)
    else:
        K = cam.matrix
        y = (pts[:, 0, 1] - K[1, 2]) / K[1, 1]
        x = (pts[:, 0, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        xy = np.stack([x, y], 1)
    return RayTable(cam.center, cam.R.T.copy(), np.ascontiguousarray(xy.reshape(h, w, 2)))


def _pixel_boxes(cam, centres, radii, pad=3):
    """Pixel bounding boxes (n, 4: u0, u1, v0, v1) of the images of spheres, clipped to the image.

    The cone of rays tangent to each sphere touches it along a circle; a 48-gon circumscribing
    that circle is projected with :meth:`Camera.project` (distortion included) and its pixel box
    padded by ``pad`` pixels. Boxes with u0 ≥ u1 or v0 ≥ v1 are empty.
    """
    w, h = cam.size
    centres = np.asarray(centres, float).reshape(-1, 3)
    radii = np.asarray(radii, float).ravel()
    C = cam.center
    v = centres - C
    D = np.linalg.norm(v, axis=1)
    n = v / D[:, None]
    inside = D <= radii * 1.0001
    Ds = np.where(inside, 2 * radii, D)
    cc = C + v * (1 - radii ** 2 / Ds ** 2)[:, None]
    rho = radii * np.sqrt(np.maximum(Ds ** 2 - radii ** 2, 0)) / Ds
    ref = np.where(np.abs(n[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(n, ref)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    th = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    rr = rho / np.cos(np.pi / 48)
    ring = (cc[:, None, :] + rr[:, None, None] * (np.cos(th)[None, :, None] * e1[:, None, :]
                                                  + np.sin(th)[None, :, None] * e2[:, None, :]))
    px = cam.project(ring.reshape(-1, 3)).reshape(len(radii), 48, 2)
    bad = inside | ~np.all(np.isfinite(px), axis=(1, 2))
    with np.errstate(invalid="ignore"):
        u0 = np.floor(np.nanmin(px[..., 0], axis=1)) - pad
        u1 = np.ceil(np.nanmax(px[..., 0], axis=1)) + pad + 1
        v0 = np.floor(np.nanmin(px[..., 1], axis=1)) - pad
        v1 = np.ceil(np.nanmax(px[..., 1], axis=1)) + pad + 1
    boxes = np.stack([u0, u1, v0, v1], 1)
    boxes[bad] = [0, w, 0, h]
    boxes[:, 0:2] = np.clip(boxes[:, 0:2], 0, w)
    boxes[:, 2:4] = np.clip(boxes[:, 2:4], 0, h)
    return boxes.astype(np.int64)


def _kernel_inputs(cam, prims, origin):
    spheres = [p.bounding_sphere() for p in prims]
    allboxes = _pixel_boxes(cam, [c for c, _ in spheres], [r for _, r in spheres])
    boxes, kinds, params = [], [], []
    for p, box in zip(prims, allboxes):
        if box[0] >= box[1] or box[2] >= box[3]:
            continue
        boxes.append(box)
        if p.kind == "cone":
            kinds.append(0)
            params.append(np.concatenate([p.a, p.b, [p.ra, p.rb], np.zeros(4)]))
        else:
            M = p.axes.T / p.semi[:, None]
            kinds.append(1)
            params.append(np.concatenate([M.ravel(), M @ (origin - p.c)]))
    return (np.array(boxes, dtype=np.int64).reshape(-1, 4), np.array(kinds, dtype=np.int64),
            np.array(params, dtype=np.float64).reshape(-1, 12))


def render(cam, table: RayTable, prims) -> np.ndarray:
    """Exact silhouette (bool (h, w)) of the union of ``prims`` seen by ``cam``.

    Only the pixels inside each primitive's projected bounding-sphere box are tested (Numba
    kernel :func:`.synth_kernels.render_kernel`, same closed forms as :func:`ray_hits_cone` and
    :func:`ray_hits_ellipsoid`).
    """
    from topopose.synth.kernels import render_kernel

    w, h = cam.size
    mask = np.zeros((h, w), dtype=np.bool_)
    boxes, kinds, params = _kernel_inputs(cam, prims, table.origin)
    if len(boxes):
        render_kernel(table.xy, table.Rt, np.asarray(table.origin, np.float64), boxes, kinds, params, mask)
    return mask


def render_numpy(cam, table: RayTable, prims) -> np.ndarray:
    """Reference implementation of :func:`render` with the vectorized NumPy ray tests."""
    w, h = cam.size
    mask = np.zeros((h, w), dtype=bool)
    o = table.origin
    spheres = [p.bounding_sphere() for p in prims]
    allboxes = _pixel_boxes(cam, [c for c, _ in spheres], [r for _, r in spheres])
    for p, box in zip(prims, allboxes):
        u0, u1, v0, v1 = (int(x) for x in box)
        if u0 >= u1 or v0 >= v1:
            continue
        d = table.directions(v0, v1, u0, u1).reshape(-1, 3)
        if p.kind == "cone":
            hit = ray_hits_cone(o, d, p.a, p.b, p.ra, p.rb)
        else:
            hit = ray_hits_ellipsoid(o, d, p.c, p.axes, p.semi)
        mask[v0:v1, u0:u1] |= hit.reshape(v1 - v0, u1 - u0)
    return mask


# ----------------------------------------------------------------------------- clearances
def sdf(p: Prim, x: np.ndarray) -> np.ndarray:
    """Signed distance (approximate for ellipsoids and tapered cones) from points x (N, 3)."""
    if p.kind == "cone":
        u = p.b - p.a
        uu = float(u @ u)
        t = np.clip(((x - p.a) @ u) / uu, 0.0, 1.0) if uu > 0 else np.zeros(len(x))
        q = p.a + t[:, None] * u
        return np.linalg.norm(x - q, axis=1) - (p.ra + t * (p.rb - p.ra))
    y = (x - p.c) @ p.axes                       # local coordinates
    k0 = np.linalg.norm(y / p.semi, axis=1)
    k1 = np.linalg.norm(y / (p.semi * p.semi), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(k1 > 0, k0 * (k0 - 1.0) / k1, -float(np.min(p.semi)))
    return d


def _samples(p: Prim, n=33):
    """Points and radii whose swept spheres make up ``p`` (axis for cones, surface for ellipsoids)."""
    if p.kind == "cone":
        s = np.linspace(0, 1, n)
        return p.a + s[:, None] * (p.b - p.a), p.ra + s * (p.rb - p.ra)
    pts = p.surface_points(160)
    return pts, np.zeros(len(pts))


def clearance(pa: Prim, pb: Prim, exclude_a=(), exclude_b=(), rho=0.0) -> float:
    """Smallest surface gap between two primitives (negative: they overlap).

    Sample points of ``pa`` within ``rho`` of a point of ``exclude_a`` (and of ``pb`` near
    ``exclude_b``) are ignored: adjacent limbs always touch near the joint that connects them.
    """
    best = np.inf
    for p, q, exclude in ((pa, pb, exclude_a), (pb, pa, exclude_b)):
        x, r = _samples(p)
        if len(exclude):
            ex = np.asarray(exclude, dtype=float).reshape(-1, 3)
            far = np.min(np.linalg.norm(x[:, None, :] - ex[None], axis=2), axis=1) > rho
            x, r = x[far], r[far]
        if len(x):
            best = min(best, float(np.min(sdf(q, x) - r)))
    return best
