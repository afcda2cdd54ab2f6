"""The subject's own articulated body: one capsule per bone of the kinematic tree.

The pose initialization (thesis §13.3.1) places a skeleton in the frames whose limbs stand
apart; a model-based capture then follows the subject through the others. Its model is the
subject's own (Corazza et al., IJCV 2010: a subject-specific model from the visual hulls):

* the **bone lengths** are the kinematic fit's (:func:`topopose.sequence.kinematic_fit.fit_sequence`,
  constant over the sequence);
* the **rigid groups** (the upper trunk, the pelvis: :func:`rigid_groups`) keep the shape
  the confident frames give them (:func:`group_shape`);
* each bone's **radius** is the profile of the hull's distance transform along the bone, in the
  confident frames (the matched frames, where the fitted skeleton lies inside the limbs), its
  median taken over the profile and the frames.

A body is a :class:`CapsuleBody`: joint positions come from a root position and one unit
direction per bone (:func:`joint_positions`), and the capsule of bone ``j`` joins the joint's
parent to joint ``j`` with radius ``radii[j]``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: positions along a bone (0 at the parent joint, 1 at the child) where its radius is sampled
PROFILE = (0.2, 0.35, 0.5, 0.65, 0.8)
#: the radius of a bone: at least this many voxels (a thin limb at a coarse grid), at most
#: this many metres (a bone inside the trunk, whose distance transform is the trunk's)
RADIUS_RANGE = (0.75, 0.25)


@dataclass(frozen=True)
class CapsuleBody:
    """An articulated body of capsules.

    Attributes
    ----------
    names : tuple of str
        Joint names (the kinematic tree's, e.g. ``elbow_1``).
    parents : ndarray of int
        Parent joint of each joint, -1 for the root.
    lengths : ndarray
        Length of the bone from each joint's parent to the joint (NaN for the root).
    radii : ndarray
        Radius of that bone's capsule (NaN for the root).
    order : tuple of int
        Joint indices, parents before children.
    groups : tuple of tuples of int
        Bones (by the joint they end at) that move as one rigid body (:func:`rigid_groups`).
    shapes : tuple of ndarray
        Each group's bone directions (m, 3) in the group's own frame (any rotation of them is
        the group in some pose).
    """

    names: tuple
    parents: np.ndarray
    lengths: np.ndarray
    radii: np.ndarray
    order: tuple
    groups: tuple = ()
    shapes: tuple = ()

    @property
    def root(self) -> int:
        return int(np.flatnonzero(self.parents < 0)[0])

    @property
    def bones(self) -> np.ndarray:
        """Joint indices that end a bone (every joint but the root), in :attr:`order`."""
        return np.array([j for j in self.order if self.parents[j] >= 0], dtype=np.int64)

    def ancestry(self) -> np.ndarray:
        """(J, J) bool: ``A[k, j]`` when bone ``j`` lies on the path from the root to joint
        ``k`` (``j`` is ``k`` or one of its ancestors, not the root)."""
        n = len(self.names)
        A = np.zeros((n, n), dtype=bool)
        for k in range(n):
            j = k
            while self.parents[j] >= 0:
                A[k, j] = True
                j = self.parents[j]
        return A


def joint_positions(body: CapsuleBody, root, dirs) -> np.ndarray:
    """Joint positions (J, 3) from the root position and the bones' unit directions (J, 3)."""
    P = np.zeros((len(body.names), 3))
    P[body.root] = root
    for j in body.order:
        p = body.parents[j]
        if p >= 0:
            P[j] = P[p] + body.lengths[j] * dirs[j]
    return P


def bone_directions(body: CapsuleBody, P) -> np.ndarray:
    """Unit direction of each bone (J, 3; the root's row is zero) of joint positions ``P``."""
    return bone_directions_of(P, body.parents)


def rigid_groups(tree) -> tuple:
    """The bones that move as one rigid body: at each junction of the kinematic tree (a joint
    with two or more bones leaving it) its bones off the model's trunk arc, with the bone
    entering it when that one lies on the trunk arc — for the human the upper trunk (chest →
    neck, chest → shoulders) and the pelvis (chest → pelvis, pelvis → hips). Groups of a single
    bone are left out."""
    trunk = set(tree.trunk)
    on_trunk = [len(trunk) == 2 and set(a) == trunk for a in tree.arc]
    out = []
    for p in range(len(tree.names)):
        kids = [j for j, q in enumerate(tree.parents) if q == p]
        if len(kids) < 2:
            continue
        g = [j for j in kids if not on_trunk[j]]
        if tree.parents[p] >= 0 and on_trunk[p]:
            g.insert(0, p)
        if len(g) >= 2:
            out.append(tuple(g))
    return tuple(out)


def kabsch(V, T) -> np.ndarray:
    """The rotation R taking the rows of ``V`` nearest to those of ``T`` (``T ≈ V @ R.T``)."""
    U, _, Wt = np.linalg.svd(np.asarray(V).T @ np.asarray(T))
    d = np.sign(np.linalg.det(Wt.T @ U.T)) or 1.0
    return Wt.T @ np.diag([1.0, 1.0, d]) @ U.T


def group_shape(dirs_frames) -> np.ndarray:
    """A rigid group's bone directions (m, 3) from several frames' (list of (m, 3)): each
    frame turned onto the first (:func:`kabsch`), averaged, normalized."""
    ref = np.asarray(dirs_frames[0], float)
    acc = np.zeros_like(ref)
    for D in dirs_frames:
        D = np.asarray(D, float)
        acc += D @ kabsch(D, ref).T
    return acc / np.maximum(np.linalg.norm(acc, axis=1), 1e-12)[:, None]


def snap(body: CapsuleBody, P):
    """Root and bone directions of joint positions ``P`` with each rigid group turned to
    them as a whole (its shape kept)."""
    D = bone_directions(body, P)
    for g, S in zip(body.groups, body.shapes):
        R = kabsch(S * body.lengths[list(g)][:, None], D[list(g)] * body.lengths[list(g)][:, None])
        D[list(g)] = S @ R.T
    return np.asarray(P[body.root], float).copy(), D


def radius_profile(volume, P, parents, samples=PROFILE) -> np.ndarray:
    """The hull's depth (distance transform of its voxels, world units) at ``samples`` along
    each bone of the joint positions ``P``: (J, len(samples)), NaN for the root.

    Parameters
    ----------
    volume : Volume
        The frame's visual hull.
    P : ndarray (J, 3)
    parents : sequence of int
    samples : positions along a bone, 0 at the parent joint, 1 at the child
    """
    from scipy import ndimage

    lo, box = bounding_box(np.asarray(volume.data, dtype=bool), margin=2)
    depth = ndimage.distance_transform_edt(volume.data[box]) * float(volume.voxel_size)
    s = np.asarray(samples, float)
    out = np.full((len(P), len(s)), np.nan)
    for j, p in enumerate(parents):
        if p < 0:
            continue
        x = P[p][None] + s[:, None] * (P[j] - P[p])[None]
        idx = (x - volume.origin) / volume.voxel_size - lo
        out[j] = ndimage.map_coordinates(depth, idx.T, order=1, mode="constant", cval=0.0)
    return out


def learn_body(tree, lengths, frames, voxel_size, radius_range=RADIUS_RANGE) -> CapsuleBody:
    """The subject's capsule body from the confident frames.

    Parameters
    ----------
    tree : KinematicTree
        The model's joints (:func:`topopose.sequence.kinematic_fit.kinematic_tree`).
    lengths : ndarray
        Bone lengths (the kinematic fit's, :func:`~topopose.sequence.kinematic_fit.fit_sequence`).
    frames : list of (Volume, ndarray (J, 3))
        The confident frames' hulls and fitted joint positions.
    voxel_size : float
        The grid's voxel size (the smallest radius is ``radius_range[0]`` voxels).
    radius_range : (voxels, metres)
        Bounds of a radius: at least that many voxels, at most that many world units.

    Returns
    -------
    CapsuleBody
    """
    parents = np.asarray(tree.parents, dtype=np.int64)
    profiles = [radius_profile(vol, np.asarray(P, float), parents) for vol, P in frames]
    lo, hi = radius_range[0] * float(voxel_size), float(radius_range[1])
    radii = np.full(len(parents), np.nan)
    if profiles:
        stack = np.concatenate(profiles, axis=1)
        stack = np.where(stack > 0, stack, np.nan)
        stack[parents < 0] = lo                        # the root has no bone
        with np.errstate(all="ignore"):
            med = np.nanmedian(stack, axis=1)
        radii = np.where(parents >= 0, np.clip(np.nan_to_num(med, nan=lo), lo, hi), np.nan)
    groups = rigid_groups(tree)
    shapes = tuple(group_shape([bone_directions_of(P, parents)[list(g)] for _v, P in frames])
                   if frames else np.zeros((len(g), 3)) for g in groups)
    return CapsuleBody(tuple(tree.names), parents, np.asarray(lengths, float).copy(), radii,
                       tuple(tree.order()), groups, shapes)


def bone_directions_of(P, parents) -> np.ndarray:
    """Unit direction of each bone of joint positions ``P`` (root row zero)."""
    P = np.asarray(P, float)
    D = np.zeros_like(P)
    for j, p in enumerate(parents):
        if p >= 0:
            d = P[j] - P[p]
            D[j] = d / max(float(np.linalg.norm(d)), 1e-12)
    return D


def bounding_box(occ, margin=1):
    """The lower corner and the slices of the object's bounding box grown by ``margin``."""
    nz = [np.flatnonzero(occ.any(axis=tuple(b for b in range(3) if b != a))) for a in range(3)]
    if any(len(z) == 0 for z in nz):
        return np.zeros(3, dtype=np.int64), tuple(slice(0, 0) for _ in range(3))
    lo = np.array([max(int(z[0]) - margin, 0) for z in nz])
    hi = [min(int(z[-1]) + margin + 1, n) for z, n in zip(nz, occ.shape)]
    return lo, tuple(slice(a, b) for a, b in zip(lo, hi))
