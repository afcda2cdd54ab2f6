"""The subject's own articulated body: one capsule per bone of the kinematic tree.

The pose initialization (thesis §13.3.1) places a skeleton in the frames whose limbs stand
apart; a model-based capture then follows the subject through the others. Its model is the
subject's own (Corazza et al., IJCV 2010: a subject-specific model from the visual hulls):

* the **bone lengths** are the kinematic fit's (:func:`topopose.sequence.kinematic_fit.fit_sequence`,
  constant over the sequence), refined on the confident frames' hulls jointly, mirrored
  bones sharing one length (:func:`topopose.sequence.tracker.calibrate`);
* the **rigid groups** (the upper trunk, the pelvis: :func:`rigid_groups`) keep the shape
  the confident frames give them (:func:`group_shape`);
* each bone's **radius** is the profile of the hull's distance transform along the bone, in the
  confident frames (the matched frames, where the fitted skeleton lies inside the limbs), its
  median taken over the profile and the frames.

* the **trunk's sides** (:func:`trunk_sides`): one bone's capsule is a poor trunk, round where
  the trunk is flat and wide; a capsule down each side of it (from between the chest and a
  shoulder to between the pelvis and a hip) gives it its width, its radius the hull's depth
  along it like a bone's.

* the body **past a joint** (:func:`reach_beyond`): where the model says the body goes on past
  a joint along its bone (``extends``: the top of the head past the skull, the heel behind the
  ankle, whose child leaves it at a right angle), a capsule on along the bone to where the
  hull ends there covers the rest, so that the end of the hull does not pull the joint
  towards it.

A body is a :class:`CapsuleBody`: joint positions come from a root position and one unit
direction per bone (:func:`joint_positions`); the capsule of bone ``j`` joins the joint's
parent to joint ``j`` with radius ``radii[j]``, and each extra capsule joins two fixed
weightings of the joints (:attr:`CapsuleBody.ends`), moving with them.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

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
    ends : ndarray (E, 2, J), optional
        Extra capsules (:func:`trunk_sides`): the weights of the joints giving each one's two
        ends (rows summing to 1).
    extra_radii : ndarray (E,), optional
        Their radii.
    trunk : int
        The joint at the trunk's far end from the root (the human's pelvis): a limb hangs
        along the trunk from the root towards it (:func:`.limbs.limb_starts`); -1: none.
    """

    names: tuple
    parents: np.ndarray
    lengths: np.ndarray
    radii: np.ndarray
    order: tuple
    groups: tuple = ()
    shapes: tuple = ()
    ends: np.ndarray | None = None
    extra_radii: np.ndarray | None = None
    trunk: int = -1

    @property
    def root(self) -> int:
        return int(np.flatnonzero(self.parents < 0)[0])

    @property
    def bones(self) -> np.ndarray:
        """Joint indices that end a bone (every joint but the root), in :attr:`order`."""
        return np.array([j for j in self.order if self.parents[j] >= 0], dtype=np.int64)

    @property
    def n_extra(self) -> int:
        return 0 if self.ends is None else len(self.ends)

    def virtual(self) -> np.ndarray:
        """(2E, J): the weights of the joints giving the extra capsules' ends (first end,
        second end, per capsule)."""
        return np.zeros((0, len(self.names))) if self.ends is None else \
            np.asarray(self.ends, float).reshape(-1, len(self.names))

    def capsules(self, P) -> tuple:
        """Every capsule at joint positions ``P``: its ends ``A``, ``B`` (K, 3) and radii (K,),
        the bones' (in :attr:`bones`' order) then the extra ones."""
        b = self.bones
        V = self.virtual() @ P
        r = self.radii[b] if not self.n_extra else np.r_[self.radii[b], self.extra_radii]
        return np.r_[P[self.parents[b]], V[0::2]], np.r_[P[b], V[1::2]], r

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


def hull_depth(volume) -> tuple:
    """The hull's depth: the distance transform of its voxels (world units) on its bounding
    box grown by 2 voxels, and the box's lower corner: ``(lo, depth)``."""
    from scipy import ndimage

    lo, box = bounding_box(np.asarray(volume.data, dtype=bool), margin=2)
    return lo, ndimage.distance_transform_edt(volume.data[box]) * float(volume.voxel_size)


def depth_at(volume, x, depth=None) -> np.ndarray:
    """The hull's depth at points ``x`` (N, 3), interpolated; 0 outside it (``depth``:
    :func:`hull_depth` of ``volume`` if already computed)."""
    from scipy import ndimage

    lo, d = hull_depth(volume) if depth is None else depth
    idx = (np.asarray(x, float) - volume.origin) / float(volume.voxel_size) - lo
    return ndimage.map_coordinates(d, idx.T, order=1, mode="constant", cval=0.0)


def radius_profile(volume, A, B, samples=PROFILE, depth=None) -> np.ndarray:
    """The hull's depth (distance transform of its voxels, world units) at ``samples`` along
    each segment from ``A`` to ``B``: (K, len(samples)).

    Parameters
    ----------
    volume : Volume
        The frame's visual hull.
    A, B : ndarray (K, 3)
        The segments' ends (a bone: its parent joint and its joint).
    samples : positions along a segment, 0 at ``A``, 1 at ``B``
    depth : :func:`hull_depth` of ``volume`` if already computed
    """
    s = np.asarray(samples, float)
    A, B = np.asarray(A, float), np.asarray(B, float)
    x = A[:, None] + s[None, :, None] * (B - A)[:, None]             # (K, S, 3)
    return depth_at(volume, x.reshape(-1, 3), depth).reshape(len(A), len(s))


def trunk_junctions(names, parents):
    """The trunk's two junctions with their mirrored pair of children: ``((root, (a_1,
    a_2)), (low, (b_1, b_2)))`` — the root (e.g. the chest, with the shoulders) and its child
    that has such a pair (the pelvis, with the hips) — or None."""
    parents = np.asarray(parents)

    def pair(u):
        kids = {str(names[j]).rpartition("_")[::2]: j for j in np.flatnonzero(parents == u)}
        bases = [b for (b, k) in kids if k == "1" and (b, "2") in kids]
        return (kids[(bases[0], "1")], kids[(bases[0], "2")]) if bases else None

    root = int(np.flatnonzero(parents < 0)[0])
    up = pair(root)
    low = next(((int(j), pair(j)) for j in np.flatnonzero(parents == root) if pair(j)), None)
    return None if up is None or low is None else ((root, up), low)


def trunk_sides(names, parents, reach=(0.6, 1.0)) -> np.ndarray:
    """The ends of a capsule down each side of the trunk, (2, 2, J) weights of the joints:
    from ``reach[0]`` of the way from the upper trunk's junction (the root, e.g. the chest)
    to its side's mirrored child (``shoulder_1``) to ``reach[1]`` of the way from the lower
    junction (the root's child that has a mirrored pair of children, e.g. the pelvis) to its
    side's child (``hip_1``). None when the tree has no such pair of junctions.

    Parameters
    ----------
    names : sequence of str
        Joint names; mirrored joints end ``_1`` and ``_2`` on the same base name.
    parents : sequence of int
    reach : (upper, lower) fractions along the junctions' side bones
    """
    junctions = trunk_junctions(names, parents)
    if junctions is None:
        return None
    (root, up), low = junctions
    W = np.zeros((2, 2, len(names)))
    for k in range(2):
        W[k, 0, root] += 1.0 - reach[0]
        W[k, 0, up[k]] += reach[0]
        W[k, 1, low[0]] += 1.0 - reach[1]
        W[k, 1, low[1][k]] += reach[1]
    return W


def reach_beyond(volume, P, parents, joints, step=0.5, longest=0.4, depth=None) -> np.ndarray:
    """How far the hull goes on beyond each of ``joints`` along the bone into it, less its
    depth half-way there (the radius of a capsule covering it): (J,), NaN for the other
    joints and where the joint lies outside the hull.

    Parameters
    ----------
    volume : Volume
    P : ndarray (J, 3)
    parents : sequence of int
    joints : sequence of int
        The joints looked beyond (the skull, the ankles: ``KinematicTree.extends``).
    step : voxels between the samples along the bone
    longest : m, the farthest looked
    depth : :func:`hull_depth` of ``volume`` if already computed
    """
    parents = np.asarray(parents)
    depth = hull_depth(volume) if depth is None else depth
    vs = float(volume.voxel_size)
    t = np.arange(0.0, longest, step * vs)
    out = np.full(len(P), np.nan)
    for j in joints:
        p = parents[j]
        if p < 0:
            continue
        d = P[j] - P[p]
        d = d / max(float(np.linalg.norm(d)), 1e-12)
        dep = depth_at(volume, P[j][None] + t[:, None] * d[None], depth)
        if dep[0] <= 0:
            continue
        end = t[np.argmax(dep <= 0)] if (dep <= 0).any() else t[-1]
        half = float(np.interp(0.5 * end, t, dep))
        out[j] = max(end - half, 0.0)
    return out


def beyond_capsules(parents, lengths, reach, shortest) -> np.ndarray:
    """The ends (E, 2, J) of a capsule from each joint on along its bone by ``reach``
    (joints reaching less than ``shortest`` get none)."""
    parents = np.asarray(parents)
    out = []
    for j in np.flatnonzero(np.isfinite(reach) & (np.nan_to_num(reach) >= shortest)):
        f = reach[j] / max(float(lengths[j]), 1e-9)
        W = np.zeros((2, len(parents)))
        W[0, j] = 1.0
        W[1, j], W[1, parents[j]] = 1.0 + f, -f
        out.append(W)
    return np.array(out).reshape(-1, 2, len(parents))


def learn_body(tree, lengths, frames, voxel_size, radius_range=RADIUS_RANGE,
               sides=(0.6, 1.0), extends=True) -> CapsuleBody:
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
    sides : (upper, lower) reach of the trunk's side capsules (:func:`trunk_sides`), or
        None: none
    extends : a capsule on past each joint the model marks ``extends`` (``tree.extends``:
        the human's skull and ankles) where the hull goes on beyond it (the median of
        :func:`reach_beyond` over the frames and the joints of one base name, mirrored joints
        reaching as far; at least a voxel)

    Returns
    -------
    CapsuleBody
    """
    parents = np.asarray(tree.parents, dtype=np.int64)
    ends = None if sides is None else trunk_sides(tree.names, parents, sides)
    marked = (extends and tree.extends) or [False] * len(parents)
    beyond = [j for j in range(len(parents)) if parents[j] >= 0 and marked[j]]
    depths = [hull_depth(v) for v, _P in frames]
    if beyond and frames:
        R = np.array([reach_beyond(v, np.asarray(P, float), parents, beyond, depth=dep)
                      for (v, P), dep in zip(frames, depths)])
        reach = np.full(len(parents), np.nan)
        for j in beyond:            # mirrored joints (one base name) reach as far
            c = R[:, [k for k in beyond if tree.base[k] == tree.base[j]]]
            c = c[np.isfinite(c)]
            reach[j] = np.median(c) if len(c) else np.nan
        T = beyond_capsules(parents, np.asarray(lengths, float), reach, float(voxel_size))
        ends = T if ends is None else np.concatenate([ends, T])
        ends = ends if len(ends) else None
    groups = rigid_groups(tree)
    shapes = tuple(group_shape([bone_directions_of(P, parents)[list(g)] for _v, P in frames])
                   if frames else np.zeros((len(g), 3)) for g in groups)
    on_trunk = [j for j, a in enumerate(tree.arc) if tree.trunk and set(a) == set(tree.trunk)]
    body = CapsuleBody(tuple(tree.names), parents, np.asarray(lengths, float).copy(),
                       np.full(len(parents), np.nan), tuple(tree.order()), groups, shapes, ends,
                       None if ends is None else np.full(len(ends), np.nan),
                       max(on_trunk, key=lambda j: tree.at[j]) if on_trunk else -1)
    lo, hi = radius_range[0] * float(voxel_size), float(radius_range[1])
    K = len(body.bones) + body.n_extra
    profiles = [radius_profile(vol, *body.capsules(np.asarray(P, float))[:2], depth=dep)
                for (vol, P), dep in zip(frames, depths)]
    med = np.full(K, lo)
    if profiles:
        stack = np.concatenate(profiles, axis=1)
        stack = np.where(stack > 0, stack, np.nan)
        with np.errstate(all="ignore"):
            med = np.clip(np.nan_to_num(np.nanmedian(stack, axis=1), nan=lo), lo, hi)
    radii = np.full(len(parents), np.nan)
    radii[body.bones] = med[:len(body.bones)]
    return replace(body, radii=radii,
                   extra_radii=None if ends is None else med[len(body.bones):])


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
