"""Motion on every frame: the subject's capsule body tracked through the sequence.

The per-frame alignment places a skeleton only where the limbs stand apart in the hull; the
thesis takes that result as the *initialization* of a model-based capture (§13.3.1). Here the
subject's own body (:mod:`.body`) is fitted to every frame's visual hull by articulated ICP
(Mündermann, Corazza & Andriacchi, CVPR 2007; Corazza et al., IJCV 2010), starting from the
previous frame's pose moved on at constant velocity:

* **data**: hull surface points, each to the surface of its nearest capsule (robust, Huber);
* **inside**: points along each bone's axis at least ``depth`` × its radius inside the hull
  (a limb's capsule where the hull is, also where no surface point pulls at it);
* **alignment**: where the frame's alignment is confident, each of its fitted joints that the
  prediction has within ``agree`` of it;
* **prediction**: the constant-velocity pose (a weak prior, also the joint limits' stand-in
  for the bones the data leave free);
* **twist**: the trunk's axial rotation, the hips' line turned against the shoulders', held
  within a joint limit (:func:`.joint_limits.twist_term`): the hull of the hips and thighs
  says little of their turn about the vertical.

Parameters are the root position and one direction per bone (2 degrees of freedom in the
plane normal to it; the bone lengths are the subject's, constant), solved by Gauss–Newton
with the analytic Jacobian (:func:`fit_frame`). Over a sequence (:func:`track_sequence`) the
confident alignments initialize the tracker, and re-initialize it where the fit and the
alignment disagree by more than ``agree`` and the alignment's own fit explains the frame as
well; it runs forwards from the first confident frame and backwards from it and from every
re-initialization, each frame keeping the better fit; a frame whose fit falls well below its
run's is fitted again from the run's last good frame and from its limbs' other starts
(:func:`.limbs.limb_starts`); each run of frames that follow from one initialization is then
smoothed in time (:func:`.smoothing.smooth_track`). Every frame gets a quality (the silhouette
IoU of the fitted body where the silhouettes are known, :mod:`.silhouette`, else
:func:`agreement`) and a status: ``matched`` (alignment confident and the fit agrees)
or ``tracked`` (fit only; :func:`.follow.lost_frames` then tells the ``lost`` ones by the
run's own fits).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from topopose.sequence.body import CapsuleBody, bounding_box, joint_positions, kabsch, snap
from topopose.sequence.joint_limits import twist_term
from topopose.sequence.limbs import limb_pairs, limb_starts, mirror_groups
from topopose.sequence.smoothing import SMOOTH, SMOOTH_RATE, odd_window, smooth_track


@dataclass(frozen=True)
class TrackOptions:
    """Settings of the tracker (development seeds: ``benchmarks/tracking.py --tracker --dev``).

    Attributes
    ----------
    iterations : Gauss–Newton iterations per frame
    points : hull surface points sampled per frame for the data term
    huber : robust scale of the data term, in voxels
    depth : a bone's axis at least this × its radius inside the hull
    deep : weight (against a bone axis too shallow) of a bone axis deeper than that: 0, the
        inside term is one-sided; 1, the axis as deep as the radius (the capsule's surface
        on the hull's), robust (Huber) beyond ``huber``
    samples : positions along each bone of the inside term's points
    inside : weight of the inside term (per point, against the data term's mean)
    rays : weight of the silhouette term (its mean against the data term's): a silhouette
        pixel's ray farther than its nearest capsule's radius from it pulls the capsule
    n_rays : silhouette pixels sampled per camera and frame
    align : weight of the confident alignment's joints (per joint), each where the prediction
        has it within ``agree`` (elsewhere the alignment can only re-initialize the track)
    prior : weight of the constant-velocity prediction (per bone, its end's displacement)
    velocity : share of the last frame's velocity carried into the prediction
    agree : m, the largest joint distance within which the fit agrees with the alignment
    max_step : radians, the largest turn of a bone in one iteration
    seeds : confident frames (spread over the sequence) whose starts compete to begin the track
    smooth : seconds, the Savitzky–Golay window (order 2) over each run of frames the track
        follows from one initialization (:func:`.smoothing.smooth_track`; default: the sequence
        stage's, :func:`.smoothing.smooth_window`); 0: the fits as they are
    recover : a frame whose quality falls below this share of the median quality of the
        frames its run fitted before it is fitted again from the last of them at or above that
        share and from its limbs' other starts (:func:`.limbs.limb_starts`), the best fit
        kept (0: never)
    twist : (degrees, weight) or None: the joint limit on the trunk's axial rotation
        (:func:`.joint_limits.twist_term`): the turn of one rigid group's mirror pair against
        another's (the hips against the shoulders) about the line between their middles,
        beyond the degrees, costs weight × its excess² (radians; the data term's units, m²)
    """

    iterations: int = 8
    points: int = 400
    huber: float = 1.5
    depth: float = 0.5
    deep: float = 0.0
    samples: tuple = (0.15, 0.5, 0.85)
    inside: float = 1.0
    rays: float = 10.0
    n_rays: int = 150
    align: float = 1.0
    prior: float = 0.002
    velocity: float = 0.5
    agree: float = 0.10
    max_step: float = 0.35
    seeds: int = 8
    smooth: float = SMOOTH / SMOOTH_RATE
    twist: tuple | None = (30.0, 0.01)
    recover: float = 0.9


# --------------------------------------------------------------------------- a frame's data
@dataclass
class FrameData:
    """One frame's hull as the fit reads it: sampled surface points, and the signed distance
    to the hull's surface from all its surface voxels (the inside term:
    :func:`.tracker_kernels.inside_rows`).
    ``occupancy``: the grid's voxels from index ``lo`` on (the hull's bounding box); ``kd``:
    the surface voxels' nearest-point search (``query(x)`` → distances, rows of ``surface``:
    :class:`SurfaceGrid`, or a ``scipy.spatial.cKDTree``), None without a surface."""

    points: np.ndarray
    surface: np.ndarray
    occupancy: np.ndarray
    origin: np.ndarray
    voxel_size: float
    kd: object = field(repr=False, default=None)
    rays: tuple = None          # (origins (R, 3), unit directions (R, 3)) of silhouette pixels
    lo: np.ndarray = field(default_factory=lambda: np.zeros(3, np.int64))
    #: the capsule each point and each ray was paired with at the last fit, tried first at
    #: the next (:func:`.tracker_kernels.capsule_normal_equations`: less work, the same result)
    nearest: tuple = field(repr=False, default=None)

    def inside(self, x) -> np.ndarray:
        """Whether each point of ``x`` (N, 3) lies in a hull voxel."""
        idx = np.rint((np.asarray(x) - self.origin) / self.voxel_size).astype(np.int64) - self.lo
        ok = ((idx >= 0) & (idx < np.array(self.occupancy.shape))).all(axis=1)
        out = np.zeros(len(idx), dtype=bool)
        out[ok] = self.occupancy[tuple(idx[ok].T)]
        return out


def silhouette_rays(cameras, silhouettes, n, rng) -> tuple:
    """Rays (origins, unit directions) through ``n`` pixels sampled in each silhouette
    (lens distortion undone). A silhouette is a boolean image, or ``(y0, x0, crop)``: the
    image's set pixels all in ``crop`` (boolean), whose first pixel is the image's (y0, x0)
    (:class:`~.kept.CroppedViews`)."""
    import cv2

    O, U = [], []
    for cam, m in zip(cameras, silhouettes):
        if isinstance(m, tuple):
            yx = np.argwhere(m[2])
            yx += np.array([m[0], m[1]], dtype=yx.dtype)
        else:
            yx = np.argwhere(np.asarray(m, bool))
        if not len(yx):
            continue
        yx = yx if len(yx) <= n else yx[rng.choice(len(yx), n, replace=False)]
        px = yx[:, ::-1].astype(np.float64).reshape(-1, 1, 2)
        if cam.fisheye:
            uv = cv2.fisheye.undistortPoints(px, cam.matrix, cam.distortions).reshape(-1, 2)
        else:
            uv = cv2.undistortPoints(px, cam.matrix, cam.distortions).reshape(-1, 2)
        d = np.c_[uv, np.ones(len(uv))] @ cam.R        # camera → world (R.T applied on the right)
        U.append(d / np.linalg.norm(d, axis=1)[:, None])
        O.append(np.repeat(cam.center[None], len(uv), axis=0))
    if not O:
        return None
    return np.concatenate(O), np.concatenate(U)


def frame_data(volume, n_points, rng=None, views=None, n_rays=0) -> FrameData:
    """The fit's view of a hull (:class:`FrameData`): its surface voxels (object voxels with a
    6-neighbour outside), ``n_points`` of them sampled for the data term; with ``views``
    (cameras, silhouettes), ``n_rays`` pixel rays per camera (:func:`silhouette_rays`).
    ``volume``: a Volume, or the :class:`~.kept.PackedVolume` of one."""
    lo, occ_box = _object_box(volume)
    surf = occ_box & ~_eroded(occ_box)
    at = np.argwhere(surf)                      # in the box
    ijk = at + lo
    X = volume.origin + ijk * float(volume.voxel_size)
    rng = np.random.default_rng(0) if rng is None else rng
    pts = X if len(X) <= n_points else X[rng.choice(len(X), n_points, replace=False)]
    rays = silhouette_rays(*views, n_rays, rng) if views is not None and n_rays else None
    kd = SurfaceGrid(X, at, volume.origin + lo * float(volume.voxel_size),
                     float(volume.voxel_size)) if len(X) else None
    return FrameData(pts, X, occ_box, np.asarray(volume.origin, float),
                     float(volume.voxel_size), kd, rays, lo)


class SurfaceGrid:
    """The nearest surface voxel of points, as ``scipy.spatial.cKDTree(X).query`` finds it
    (:func:`.tracker_kernels.nearest_voxels`), from the voxels bucketed on their grid.

    Parameters
    ----------
    X : ndarray (M, 3), the voxels' centres
    ijk : ndarray (M, 3) of int ≥ 0, their indices on the grid, ``X ≈ corner + ijk × size``
    corner : ndarray (3,), size : float
    bucket : voxels a bucket's side
    """

    def __init__(self, X, ijk, corner, size, bucket=4):
        self.X = np.ascontiguousarray(X, dtype=float)
        self.corner, self.size, self.bucket = np.asarray(corner, float), float(size), bucket
        b = np.asarray(ijk, np.int64) // bucket
        self.shape = b.max(axis=0) + 1
        cell = (b[:, 0] * self.shape[1] + b[:, 1]) * self.shape[2] + b[:, 2]
        self.items = np.argsort(cell, kind="stable")
        self.start = np.zeros(int(np.prod(self.shape)) + 1, np.int64)
        np.cumsum(np.bincount(cell, minlength=len(self.start) - 1), out=self.start[1:])

    def query(self, x):
        """(distances (N,), rows of X (N,)) of the points ``x`` (N, 3)."""
        from topopose.sequence.tracker_kernels import nearest_voxels

        return nearest_voxels(np.ascontiguousarray(x, dtype=float), self.X, self.corner,
                              self.size, self.start, self.items, self.shape, self.bucket)


def _eroded(occ) -> np.ndarray:
    """``scipy.ndimage.binary_erosion(occ)`` (3-D, 6-neighbours, outside the array empty):
    the voxels set with their 6 neighbours."""
    out = occ.copy()
    if not out.size:
        return out
    for a in range(3):
        def at(s):
            return tuple(s if b == a else slice(None) for b in range(3))
        out[at(slice(1, None))] &= occ[at(slice(None, -1))]
        out[at(slice(None, -1))] &= occ[at(slice(1, None))]
        out[at(0)] = False
        out[at(-1)] = False
    return out


def _object_box(volume) -> tuple:
    """The lower corner and the voxels of the hull's bounding box grown by one voxel
    (:func:`.body.bounding_box`) of a Volume, or of a :class:`~.kept.PackedVolume` unpacked
    into that box alone."""
    if not hasattr(volume, "bits"):
        occ = np.asarray(volume.data, dtype=bool)
        lo, box = bounding_box(occ)
        return lo, occ[box]
    size = int(np.prod(volume.box))
    if not size:
        return np.zeros(3, dtype=np.int64), np.zeros((0, 0, 0), bool)
    lo = np.array([max(a - 1, 0) for a in volume.lo])
    hi = [min(a + b + 1, n) for a, b, n in zip(volume.lo, volume.box, volume.shape)]
    occ = np.zeros([b - a for a, b in zip(lo, hi)], bool)
    at = tuple(slice(a - c, a - c + b) for a, c, b in zip(volume.lo, lo, volume.box))
    occ[at] = np.unpackbits(volume.bits, count=size).reshape(volume.box).view(bool)
    return lo, occ


# --------------------------------------------------------------------------- one frame's fit
def twist_pairs(body: CapsuleBody) -> list:
    """The trunk's axial rotations that :func:`.joint_limits.twist_term` limits:
    ``(a1, b1, a2, b2)`` for every two rigid groups (:func:`~topopose.sequence.body.rigid_groups`)
    that each hold a mirror pair (``a``, ``b``: joints ``_1`` and ``_2``), e.g. the shoulders
    and the hips."""
    pairs = mirror_groups(body.names)
    held = [next((p for p in pairs if set(p) <= set(g)), None) for g in body.groups]
    held = [p for p in held if p is not None]
    return [(*held[i], *held[k]) for i in range(len(held)) for k in range(i + 1, len(held))]


def _basis(D):
    """Two unit vectors normal to each direction (J, 3) and to each other: (J, 3, 2)
    (:func:`.tracker_kernels.bone_bases`)."""
    from topopose.sequence.tracker_kernels import bone_bases

    return bone_bases(np.ascontiguousarray(D, dtype=float))


def _dots(V):
    """Each row's dot product with itself, (N, M) → (N,), as ``V[i].dot(V[i])`` sums it
    (NumPy's matmul of stacked vectors is its dot)."""
    return (V[:, None, :] @ V[:, :, None])[:, 0, 0]


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rotation(w):
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    t = math.sqrt(w.dot(w))                       # np.linalg.norm's own sum
    if t < 1e-12:
        return np.eye(3)
    K = _skew(np.asarray(w) / t)
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


class _Fitter:
    """The Gauss–Newton fit of one body (its structure precomputed once per sequence).

    Parameters θ: the root's translation (3), a rotation (3) per rigid group of bones, and a
    turn (2, in the plane normal to the bone) per other bone."""

    def __init__(self, body: CapsuleBody, opts: TrackOptions):
        self.body, self.opts = body, opts
        self.bones = body.bones
        self.par = body.parents[self.bones]
        self.anc = body.ancestry()
        grouped = {int(j): g for g, members in enumerate(body.groups) for j in members}
        self.blocks, self.col, c = [], {}, 3          # (members, column, width)
        for g, members in enumerate(body.groups):
            self.blocks.append((list(members), c, 3))
            for j in members:
                self.col[int(j)] = (c, 3)
            c += 3
        for j in self.bones:
            if int(j) not in grouped:
                self.blocks.append(([int(j)], c, 2))
                self.col[int(j)] = (c, 2)
                c += 2
        self.n = c
        # the capsules: the bones', then the extra ones between virtual joints (rows J + 2e,
        # J + 2e + 1 of the extended joints, :meth:`extend`)
        self.W = body.virtual()
        nj, ne = len(body.names), body.n_extra
        self.cpar = np.r_[self.par, nj + 2 * np.arange(ne)].astype(np.int64)
        self.cbone = np.r_[self.bones, nj + 2 * np.arange(ne) + 1].astype(np.int64)
        self.r = np.r_[body.radii[self.bones], body.extra_radii] if ne else body.radii[self.bones]
        deps = [[0, 1, 2] + sorted({self.col[int(j)][0] + q for j in np.flatnonzero(self.anc[k])
                                    for q in range(self.col[int(j)][1])})
                for k in range(nj)]
        for e in range(ne):                 # both ends: every parameter either end moves with
            d = sorted({i for k in np.flatnonzero(self.W[2 * e:2 * e + 2].any(axis=0))
                        for i in deps[k]})
            deps += [d, d]
        self.cols = np.full((len(deps), max(len(d) for d in deps)), -1, dtype=np.int64)
        for k, d in enumerate(deps):
            self.cols[k, :len(d)] = d
        self.s = np.asarray(opts.samples, float)
        # fixed per fitter: the kernels' arrays, the inside term's points' bones and depths,
        # the prediction term's rows and columns of each bone's block
        self._chain = (np.asarray(body.parents, dtype=np.int64),
                       np.array(body.order, dtype=np.int64), body.root,
                       np.asarray(body.lengths, dtype=float))
        b = np.asarray(self.bones, dtype=np.int64)
        self._blocks = (b, np.array([self.col[int(j)][0] for j in b], dtype=np.int64),
                        np.array([self.col[int(j)][1] for j in b], dtype=np.int64))
        ns, nk = len(self.s), len(self.cpar)
        self._need = np.repeat(opts.depth * self.r, ns)
        self._sk = np.tile(self.s, nk)
        bk = np.repeat(np.arange(nk), ns)
        self._ends_in = (self.cpar[bk], self.cbone[bk])
        # the prediction term's entries: row 3 + 3k + r, column c + q of bone k's block ←
        # M[k, r, q] (q below the block's width)
        self._pred_at = tuple(np.array(v, dtype=np.int64) for v in zip(*[
            (3 + 3 * k + r, self.col[int(j)][0] + q, k, r, q) for k, j in enumerate(self.bones)
            for r in range(3) for q in range(self.col[int(j)][1])]))
        # the step's blocks: the rigid groups, and the other bones with their two columns
        self.rigid = [blk for blk in self.blocks if blk[2] == 3]
        turned = [(m[0], c) for m, c, w in self.blocks if w == 2]
        self.turns = (np.array([j for j, _c in turned], dtype=np.int64),
                      np.array([[c, c + 1] for _j, c in turned], dtype=np.int64).reshape(-1, 2))
        self.twists = twist_pairs(body) if opts.twist else []

    def extend(self, P, G):
        """Joint positions and derivatives (J, 3[, n]) with the extra capsules' ends appended."""
        if not len(self.W):
            return P, G
        return np.r_[P, self.W @ P], np.concatenate([G, np.einsum("vj,jcn->vcn", self.W, G)])

    def jacobian(self, D):
        """dP/dθ (J, 3, n) at directions D, and per bone d(bone end − bone start)/d(its
        block's parameters), (3, width) (:func:`.tracker_kernels.joint_jacobian`)."""
        G, M = self._jacobian(D)
        bones, _col, width = self._blocks
        return G, {int(j): M[k, :, :width[k]] for k, j in enumerate(bones)}

    def _jacobian(self, D):
        """:meth:`jacobian` with ``M`` as one array (nb, 3, 3), the bones in :attr:`bones`'
        order, each block's columns first."""
        from topopose.sequence.tracker_kernels import joint_jacobian

        bones, col, width = self._blocks
        G, M, _E = joint_jacobian(np.ascontiguousarray(D, dtype=float), self._chain[3], bones,
                                  col, width, self.anc, self.n)
        return G, M

    def at(self, root, D):
        """Everything the terms read of the pose (root, D), computed once: the joints ``P``,
        their derivatives ``G`` and the bones' ``M`` (:meth:`_jacobian`), the extended joints
        and derivatives ``Pe``, ``Ge`` (:meth:`extend`)."""
        from topopose.sequence.tracker_kernels import chain_positions

        parents, order, r0, lengths = self._chain
        P = chain_positions(np.asarray(root, float), np.ascontiguousarray(D, dtype=float),
                            lengths, parents, order, r0)
        G, M = self._jacobian(D)
        Pe, Ge = self.extend(P, G)
        return P, G, M, Pe, Ge

    def terms(self, root, D, data: FrameData, align, pred, G=None, capsules=True, at=None):
        """Weighted residuals and their Jacobian rows (``G``: dP/d of other parameters, for
        the data and inside terms alone; ``capsules`` False: without the data and silhouette
        terms, which :meth:`fit` adds with :func:`.tracker_kernels.capsule_normal_equations`;
        ``at``: :meth:`at` of (root, D) if already computed)."""
        o, b = self.opts, self.body
        pose_terms = G is None          # else the lengths' Jacobian: the hull's terms alone
        if pose_terms:
            P, G, M, Pe, Ge = self.at(root, D) if at is None else at
        else:
            align = pred = None
            P = joint_positions(b, root, D)
            Pe, Ge = self.extend(P, G)
        rows, res = [], []
        A, B = Pe[self.cpar], Pe[self.cbone]
        seg = B - A
        ll = np.maximum(np.einsum("kc,kc->k", seg, seg), 1e-12)
        # data: hull surface points to their nearest capsule
        Q = data.points
        if len(Q) and capsules:
            t = np.clip(np.einsum("mkc,kc->mk", Q[:, None] - A[None], seg) / ll, 0.0, 1.0)
            X = A[None] + t[..., None] * seg[None]
            dq = np.linalg.norm(Q[:, None] - X, axis=2)
            k = np.argmin(dq - self.r[None], axis=1)
            m = np.arange(len(Q))
            dk, tk = dq[m, k], t[m, k]
            nq = (Q - X[m, k]) / np.maximum(dk, 1e-9)[:, None]
            r = dk - self.r[k]
            h = o.huber * data.voxel_size
            w = np.sqrt(np.where(np.abs(r) <= h, 1.0, h / np.maximum(np.abs(r), 1e-12)) / len(Q))
            Jd = -(np.einsum("mc,mcn->mn", nq * (1 - tk)[:, None], Ge[self.cpar[k]])
                   + np.einsum("mc,mcn->mn", nq * tk[:, None], Ge[self.cbone[k]]))
            rows.append(Jd * w[:, None])
            res.append(r * w)
        # silhouettes: every sampled silhouette pixel's ray meets a capsule (one-sided)
        if data.rays is not None and o.rays > 0 and capsules:
            C, U = data.rays
            w0 = A[None] - C[:, None]                                   # (R, nb, 3)
            bb = np.einsum("kc,rc->rk", seg, U)
            dd = np.einsum("rkc,kc->rk", w0, seg)
            ee = np.einsum("rkc,rc->rk", w0, U)
            den = np.maximum(ll[None] - bb ** 2, 1e-12)
            t = np.clip((bb * ee - dd) / den, 0.0, 1.0)
            lam = np.maximum(bb * t + ee, 0.0)
            Y = C[:, None] + lam[..., None] * U[:, None]                # on the ray
            X = A[None] + t[..., None] * seg[None]
            dq = np.linalg.norm(Y - X, axis=2)
            k = np.argmin(dq - self.r[None], axis=1)
            m = np.arange(len(C))
            dk, tk = dq[m, k], t[m, k]
            r = dk - self.r[k]
            act = r > 0
            if act.any():
                nq = (Y[m, k] - X[m, k]) / np.maximum(dk, 1e-9)[:, None]
                h = o.huber * data.voxel_size
                w = np.sqrt(np.where(r <= h, 1.0, h / np.maximum(r, 1e-12)) * o.rays / len(C))
                w = w * act
                Jr = -(np.einsum("mc,mcn->mn", nq * (1 - tk)[:, None], Ge[self.cpar[k]])
                       + np.einsum("mc,mcn->mn", nq * tk[:, None], Ge[self.cbone[k]]))
                rows.append(Jr * w[:, None])
                res.append(np.where(act, r, 0.0) * w)
        # inside: bone axis points at least depth × radius inside the hull
        if data.kd is not None:
            from topopose.sequence.tracker_kernels import inside_rows

            S = (A[:, None] + self.s[None, :, None] * seg[:, None]).reshape(-1, 3)
            dist, near = data.kd.query(S)
            start, end = self._ends_in              # each point's bone's ends
            Ji, ri = inside_rows(S, dist, np.asarray(near, np.int64), data.surface,
                                 data.origin, data.voxel_size, data.lo, data.occupancy,
                                 self._need, self._sk, start, end, Ge,
                                 o.huber * data.voxel_size, o.deep,
                                 math.sqrt(o.inside / len(S)))
            rows.append(Ji)
            res.append(ri)
        # the confident alignment's joints
        if align is not None:
            ok = ~np.isnan(align).any(axis=1)
            if ok.any():
                wa = np.sqrt(o.align / ok.sum())
                rows.append(G[ok].reshape(-1, self.n) * wa)
                res.append((P[ok] - align[ok]).ravel() * wa)
        # the trunk's axial rotation within its limit
        if pose_terms:
            for quad in self.twists:
                r, row, _phi = twist_term(P, G, quad, math.radians(o.twist[0]), o.twist[1])
                if r:
                    rows.append(row[None])
                    res.append(np.array([r]))
        # the prediction: the root, and each bone's end displaced from its predicted direction
        if pred is not None:
            proot, pD = pred
            wp = np.sqrt(o.prior)
            Jp = np.zeros((3 + 3 * len(self.bones), self.n))
            Jp[:3, :3] = np.eye(3) * wp
            row, col, k, r, q = self._pred_at       # each bone's end, by its block
            Jp[row, col] = M[k, r, q] * wp
            bo = self.bones
            rp = (b.lengths[bo] * wp)[:, None] * (D[bo] - pD[bo])
            rows.append(Jp)
            res.append(np.concatenate([(root - proot) * wp, rp.ravel()]))
        n = G.shape[2]
        return (np.concatenate(rows) if rows else np.zeros((0, n)),
                np.concatenate(res) if res else np.zeros(0))

    def step(self, root, D, x):
        """The pose moved by the parameter step ``x``: each rigid group turned by its
        rotation vector, each other bone by its turn in the plane normal to it, each block's
        step at most ``max_step`` long."""
        root = root + x[:3]
        D = D.copy()
        top = self.opts.max_step
        for members, c, w in self.rigid:
            a = x[c:c + w]
            na = math.sqrt(a.dot(a))                # np.linalg.norm's own sum, less its cost
            if na > top:
                a = a * (top / na)
            D[members] = D[members] @ _rotation(a).T
        j, c = self.turns
        if len(j):                                  # the other bones, all at once
            E = _basis(D)
            a = x[c]                                # (bones, 2)
            na = np.sqrt(_dots(a))
            far = na > top
            a[far] *= (top / na[far])[:, None]
            d = D[j] + (E[j] @ a[:, :, None])[:, :, 0]
            D[j] = d / np.sqrt(_dots(d))[:, None]
        return root, D

    def fit(self, root, D, data, align=None, pred=None):
        """Gauss–Newton from (root, D); returns the fitted root, directions and joints."""
        from topopose.sequence.tracker_kernels import capsule_normal_equations as cne
        from topopose.sequence.tracker_kernels import normal_equations

        o = self.opts
        root, D = np.array(root, float), np.array(D, float)
        none = np.zeros((0, 3))
        h = o.huber * data.voxel_size
        if data.nearest is None:
            data.nearest = (np.zeros(len(data.points), np.int64),
                            np.zeros(0 if data.rays is None else len(data.rays[0]), np.int64))
        for _ in range(o.iterations):
            at = self.at(root, D)
            J, r = self.terms(root, D, data, align, pred, capsules=False, at=at)
            H, g = normal_equations(J, r)          # JᵀJ, Jᵀr (not BLAS: its threads cost more)
            _P, _G, _M, P, G = at
            A, B = P[self.cpar], P[self.cbone]
            if len(data.points):
                cne(data.points, none, A, B, self.r, self.cpar, self.cbone, G, self.cols, h,
                    1.0 / len(data.points), False, H, g, data.nearest[0])
            if data.rays is not None and o.rays > 0:
                cne(data.rays[0], data.rays[1], A, B, self.r, self.cpar, self.cbone, G,
                    self.cols, h, o.rays / len(data.rays[0]), True, H, g, data.nearest[1])
            H[np.diag_indices_from(H)] += 1e-6 + 1e-3 * np.diag(H)
            root, D = self.step(root, D, -np.linalg.solve(H, g))
        return root, D, joint_positions(self.body, root, D)


def calibrate(body: CapsuleBody, frames, opts: TrackOptions | None = None, rounds=3,
              prior=0.05, bounds=(0.75, 1.4)) -> CapsuleBody:
    """The body's bone lengths refined on the confident frames' hulls (the subject-specific
    model of Corazza et al., IJCV 2010, from the visual hulls): each round fits every frame
    from its alignment with the current lengths, then takes one Gauss–Newton step of the
    lengths shared by all frames (data and inside terms, a weak ``prior`` pulling each length
    towards the kinematic fit's, bounded to ``bounds`` × it). Mirrored bones (``elbow_1``,
    ``elbow_2``: :func:`mirror_groups`) share one length, as in the kinematic fit: a limb
    misplaced in the confident frames is outvoted by its twin's evidence.

    Parameters
    ----------
    body : CapsuleBody
    frames : list of (FrameData, ndarray (J, 3)): the frames' data and alignment joints
    opts : TrackOptions
    rounds : fits and steps
    prior : weight of the kinematic fit's lengths (per bone, squared metres)
    bounds : (low, high) factors of the kinematic fit's lengths
    """
    from dataclasses import replace

    opts = opts or TrackOptions()
    bones = body.bones
    L0 = body.lengths.copy()
    L = L0.copy()
    share = np.arange(len(bones))          # each bone's shared length (mirrored bones: one)
    col = {int(j): k for k, j in enumerate(bones)}
    for a, b in mirror_groups(body.names):
        if a in col and b in col:
            share[col[b]] = share[col[a]]
    _u, share = np.unique(share, return_inverse=True)
    S = np.zeros((len(bones), int(share.max()) + 1))
    S[np.arange(len(bones)), share] = 1.0
    for _ in range(rounds):
        b = replace(body, lengths=L)
        f = _Fitter(b, opts)
        H = np.zeros((len(bones), len(bones)))
        g = np.zeros(len(bones))
        for data, A in frames:
            if data is None or data.kd is None:
                continue
            root, D, _P = f.fit(*snap(b, A), data, align=A)
            GL = np.zeros((len(L), 3, len(bones)))
            for k, j in enumerate(bones):
                GL[f.anc[:, j], :, k] += D[j]
            J, r = f.terms(root, D, data, None, None, G=GL)
            H += np.einsum("mi,mj->ij", J, J)
            g += np.einsum("mi,m->i", J, r)
        H[np.diag_indices_from(H)] += prior / max(len(frames), 1) + 1e-9
        g += prior / max(len(frames), 1) * (L[bones] - L0[bones])
        H, g = S.T @ H @ S, S.T @ g
        L = L.copy()
        L[bones] = np.clip(L[bones] - S @ np.linalg.solve(H, g), bounds[0] * L0[bones],
                           bounds[1] * L0[bones])
    return replace(body, lengths=L)


def fit_frame(body: CapsuleBody, data: FrameData, P0, opts: TrackOptions | None = None,
              align=None, pred=None) -> np.ndarray:
    """Fit the body to one frame's hull from the joint positions ``P0`` (J, 3); returns the
    fitted joint positions (bone lengths the body's).

    Parameters
    ----------
    body : CapsuleBody
    data : FrameData (:func:`frame_data`)
    P0 : ndarray (J, 3), the start (only its root and bone directions are used)
    opts : TrackOptions
    align : ndarray (J, 3), optional; the alignment's joints (NaN rows: none)
    pred : ndarray (J, 3), optional; the predicted pose the fit is weakly held to
    """
    f = _Fitter(body, opts or TrackOptions())
    pr = None if pred is None else snap(body, np.asarray(pred, float))
    return f.fit(*snap(body, np.asarray(P0, float)), data, align, pr)[2]


def agreement(body: CapsuleBody, data: FrameData, P, samples=(0.15, 0.5, 0.85),
              tolerance=2.0) -> float:
    """Voxel agreement of a fitted pose: the harmonic mean of the share of the hull's sampled
    surface points within ``tolerance`` voxels of a capsule's surface (the hull explained)
    and the share of the bones' axis points inside the hull (the body where the hull is)."""
    from topopose.sequence.tracker_kernels import near_surface

    A, B, radii = body.capsules(P)
    seg = B - A
    Q = data.points
    if not len(Q):
        return 0.0
    # the share of points within the tolerance of a capsule's surface: the point's distance
    # to the nearest point of each bone's segment, less its radius
    #   t = clip((Q − A)·seg / |seg|², 0, 1), d = | |Q − (A + t seg)| − r |
    # (:func:`.tracker_kernels.near_surface`)
    near = near_surface(np.ascontiguousarray(Q, dtype=float), A, B, radii,
                        tolerance * data.voxel_size)
    explained = near / len(Q)
    s = np.asarray(samples, float)
    S = (A[:, None] + s[None, :, None] * seg[:, None]).reshape(-1, 3)
    inside = float(np.mean(data.inside(S)))
    return 0.0 if explained + inside == 0 else 2 * explained * inside / (explained + inside)


# --------------------------------------------------------------------------- the sequence
def _swap(P, pairs):
    Q = P.copy()
    for a, b in pairs:
        Q[[a, b]] = P[[b, a]]
    return Q


@dataclass
class Track:
    """The tracker's result over a sequence of F frames with J joints.

    Attributes
    ----------
    joints : ndarray (F, J, 3), NaN where no frame could be fitted
    quality : ndarray (F,), the fit's quality (``track_sequence``'s ``quality``), NaN where
        none
    status : list of str, ``matched`` / ``tracked`` / "" (no fit)
    segment : ndarray (F,) int, the initialization each frame's fit follows from (-1: none)
    swapped : ndarray (F, G) bool, per mirror group: the confident frame's alignment had the
        pair the other way round than the track (its identity carried through)
    reinitialized : list of frame indices where the track was re-initialized
    """

    joints: np.ndarray
    quality: np.ndarray
    status: list
    segment: np.ndarray
    swapped: np.ndarray
    reinitialized: list


def _identity(align_i, P, groups):
    """The alignment's joints with each mirror group's pair ordered as the track's ``P``
    (the permutation nearest to it), and which groups were swapped."""
    A = align_i.copy()
    sw = np.zeros(len(groups), dtype=bool)
    for g, pairs in enumerate(groups):
        idx = [i for p in pairs for i in p]
        if np.isnan(A[idx]).any():
            continue
        B = _swap(A, pairs)
        if np.linalg.norm(B[idx] - P[idx], axis=1).sum() < \
                np.linalg.norm(A[idx] - P[idx], axis=1).sum():
            A, sw[g] = B, True
    return A, sw


def _predict(body, fitter, state, v, max_move):
    """The constant-velocity pose from the last two (root, directions): ``v`` of the last
    step again — a free bone turned on, a rigid group rotated on as a whole; none after a
    root's step longer than ``max_move``."""
    root, D, proot, pD = state
    if np.linalg.norm(root - proot) > max_move:        # a jump: no velocity to go on with
        return root, D
    rp = root + v * (root - proot)
    Dp = D.copy()
    for members, _c, w in fitter.blocks:
        if w == 3:
            R = kabsch(pD[members], D[members])
            from scipy.spatial.transform import Rotation

            Dp[members] = D[members] @ Rotation.from_rotvec(
                v * Rotation.from_matrix(R).as_rotvec()).as_matrix().T
        else:
            j = members[0]
            d = D[j] + v * (D[j] - pD[j])
            Dp[j] = d / max(float(np.linalg.norm(d)), 1e-12)
    return rp, Dp


def track_sequence(body: CapsuleBody, data_of, align, opts: TrackOptions | None = None,
                   groups=None, fps=None, quality=None) -> Track | None:
    """Track the body through a sequence (see the module docstring).

    Up to ``seeds`` confident frames spread over the sequence are first fitted from their
    alignments (their *starts*, with their quality); the track starts at the start of best
    quality and runs forwards to the last frame and
    backwards to the first. At a confident frame whose alignment the track's fit disagrees
    with (a joint farther than ``agree`` from the alignment's pose on the body's bone lengths,
    :func:`~topopose.sequence.body.snap`: lengths are the body's, only the pose is compared)
    and whose start fits the frame better, the track
    is re-initialized there, and also run back the other way from it until the previous
    confident frame; each frame keeps its best fit. Each run of frames that follow from one
    initialization is then smoothed over ``opts.smooth`` seconds
    (:func:`.smoothing.smooth_track`), and its frames' quality and status are taken again.

    Parameters
    ----------
    body : CapsuleBody
    data_of : callable i → FrameData or None (a frame that could not be read: no fit)
    align : ndarray (F, J, 3)
        The confident alignments' joints (their initializations), NaN rows elsewhere.
    opts : TrackOptions
    groups : list of mirror groups (lists of joint index pairs, :func:`mirror_groups` by
        limb); default: one group per mirror pair of joints
    fps : the capture's frame rate, which turns ``opts.smooth`` into frames (None: 25,
        :data:`.smoothing.SMOOTH_RATE`)
    quality : callable (i, FrameData, P) → float, optional
        A fit's quality, higher better, by which the track chooses between fits of a frame
        (default: :func:`agreement`; :func:`.follow.follow`: the silhouette IoU)

    Returns
    -------
    Track, or None when no frame is confident
    """
    opts = opts or TrackOptions()
    align = np.asarray(align, float)
    F, J = align.shape[:2]
    conf = ~np.isnan(align).any(axis=(1, 2))
    if not conf.any():
        return None
    groups = [[p] for p in mirror_groups(body.names)] if groups is None else groups
    fitter = _Fitter(body, opts)
    out = Track(np.full((F, J, 3), np.nan), np.full(F, np.nan), [""] * F, np.full(F, -1),
                np.zeros((F, len(groups)), dtype=bool), [])
    cache = {}
    none = np.zeros(len(groups), dtype=bool)

    def data(i):
        if i not in cache:
            cache[i] = data_of(i)
        return cache[i]

    def keep(i, P, q, status, seg, sw):
        if np.isnan(out.quality[i]) or q > out.quality[i]:
            out.joints[i], out.quality[i], out.status[i], out.segment[i] = P, q, status, seg
            out.swapped[i] = sw

    starts = {}
    if quality is None:
        def quality(_i, d, P):
            return agreement(body, d, P)
    pairs = limb_pairs(body)

    def refit(i, d, fit):
        """The best by quality of ``fit`` (root, D, P, quality) and of the fits from each
        mirrored pair's limb starts (:func:`.limbs.limb_starts`), pair after pair."""
        for pair in pairs:
            fits = [fitter.fit(fit[0], E, d) for E in limb_starts(body, fit[1], fit[2], pair)]
            q, k = max(((quality(i, d, f[2]), k) for k, f in enumerate(fits)), default=(-1, 0))
            if q > fit[3]:
                fit = (*fits[k], q)
        return fit

    def start(i):
        """The fit of confident frame i initialized by its alignment: (root, D, P, quality)."""
        if i not in starts:
            d = data(i)
            if d is None or d.kd is None:
                starts[i] = None
            else:
                root, D, P = fitter.fit(*snap(body, align[i]), d, align=align[i])
                starts[i] = (root, D, P, quality(i, d, P))
        return starts[i]

    def run(i0, state, step, stop, seg):
        """From the fitted frame i0 (state: its and the frame before's root and directions)
        towards ``stop`` (exclusive) by ``step``; returns the frames re-initialized."""
        reinit = []
        i = i0 + step
        seen, good = [], state[:2]         # the run's qualities, its last good frame's pose
        while i != stop:
            d = data(i)
            if d is None or d.kd is None:
                i += step
                continue
            rp, Dp = _predict(body, fitter, state, opts.velocity, opts.agree)
            A, sw, pull = None, none, None
            if conf[i]:
                Pp = joint_positions(body, rp, Dp)
                A, sw = _identity(align[i], Pp, groups)
                pose_of_A = joint_positions(body, *snap(body, A))    # on the body's lengths
                far = np.linalg.norm(Pp - pose_of_A, axis=1) > opts.agree
                pull = np.where(far[:, None], np.nan, A)      # where the prediction has it
            root, D, P = fitter.fit(rp, Dp, d, align=pull, pred=(rp, Dp))
            q = quality(i, d, P)
            # lost below ``recover`` × the median of the run's fits so far (once it has five)
            low = opts.recover * np.median(seen) if len(seen) >= 5 else -np.inf
            if q < low:                     # from the last good pose, and the limbs' starts
                again = fitter.fit(*good, d, align=pull, pred=(rp, Dp))
                fit = max([(root, D, P, q), (*again, quality(i, d, again[2]))],
                          key=lambda f: f[3])
                root, D, P, q = refit(i, d, fit)
            if q >= low:
                good = (root, D)
            seen.append(q)
            status = "tracked"
            if A is not None:
                moved = False
                if float(np.max(np.linalg.norm(P - pose_of_A, axis=1))) <= opts.agree:
                    status = "matched"
                else:
                    st = start(i)
                    if st is not None and st[3] > q:
                        root, D, P, q = st
                        status, seg, sw, moved = "matched", i, none, True
                        reinit.append(i)
            keep(i, P, q, status, seg, sw)
            state = (root, D, root, D) if A is not None and moved else \
                (root, D, state[0], state[1])
            i += step
        return reinit

    confs = np.flatnonzero(conf)                  # the seed: the best of a few spread starts
    spread = confs[np.unique(np.linspace(0, len(confs) - 1, min(opts.seeds, len(confs)))
                             .round().astype(int))]
    cands = [int(i) for i in spread if start(int(i)) is not None] or \
        [int(i) for i in confs if start(int(i)) is not None]
    if not cands:
        return None
    first = max(cands, key=lambda i: starts[i][3])
    root, D, P, q = starts[first]
    keep(first, P, q, "matched", first, none)
    todo = [(first, +1, F), (first, -1, -1)]
    while todo:                 # a run goes on from each frame it re-initializes at; the
        i0, step, stop = todo.pop(0)         # frames back to the confident frame before
        root, D = snap(body, out.joints[i0])  # it are then run the other way from there
        for r in run(i0, (root, D, root, D), step, stop, i0):
            out.reinitialized.append(r)
            back = confs[confs < r] if step > 0 else confs[confs > r]
            end = (int(back[-1]) if len(back) else -1) if step > 0 else \
                (int(back[0]) if len(back) else F)
            todo.append((r, -step, end))
    window = odd_window(opts.smooth, fps or SMOOTH_RATE)
    if window:                  # the smoothed joints' quality
        out.joints = smooth_track(body, out.joints, out.segment, window)
        for i in np.flatnonzero(out.segment >= 0):
            out.quality[i] = quality(i, data(i), out.joints[i])
    return out
