"""The ``body`` subject: the MakeHuman base mesh, posed by linear blend skinning.

An anatomically real human for :mod:`.synth` (real shoulders, neck, hands, feet), unlike the
capsule ``human`` of :mod:`.synth_subjects`. Data: ``data/makehuman_body.npz`` (CC0 MakeHuman
base mesh, 13,380 vertices, 26,756 triangles, a closed surface, with the 31-bone ``cmu_mb`` rig
and 4 skinning weights per vertex; see ``data/README.md``), converted to the body frame of the
other subjects (x forward, y left, z up).

Posing. Every bone ``b`` gets an affine map ``x → A_b x + t_b`` of the rest mesh,
``A_b = Q_b S_b``: ``S_b`` the *build* (proportions: scaling along the bone axis for lengths and
radially about it for girth; trunk bones scale horizontally for girth), ``Q_b`` its world
rotation, ``Q_b = F_b N_b``, where ``F_b`` is the joint-angle frame of the capsule human (the same
pose dict and angle conventions: :func:`.synth_subjects.human`, so :func:`.synth_subjects.human_walk`
drives the body too) and ``N_b`` the constant rotation from the rest A-pose to the capsule's
zero pose (arms hanging, elbows and knees straight, with the elbow/knee hinge un-bent about its
own axis). Joint positions follow by forward kinematics, ``P_c = P_p + A_p (H_c - H_p)``, and the
vertices by linear blend skinning ``x' = Σ_k w_k (A_{b_k} x + t_{b_k})``. A final uniform scale
gives the build's standing height (1.1–2.0 m).

Ground truth (``gt.json``, parts of the built-in ``human`` model; hand_1 / foot_1 are the left
ones, as for the capsule human):

* head: segment neck base (``Neck`` head) → crown (the head vertex farthest along the head
  bone); part: the crown minus the head's radius along that segment.
* hand_k: wrist (``Hand`` head) → fingertip (the hand vertex farthest along wrist → finger
  bone tip); part: the fingertip minus the hand's radius.
* foot_k: ankle (``Foot`` head) → toe tip (the foot vertex farthest along ankle → toe bone tip);
  part: the toe tip minus the foot's radius.
* torso: the chest segment, neck base → ``Spine1`` head (mid-chest); part: the neck base.
* crotch: the pelvis, hip centre − 4 cm → + 7 cm along the pelvis axis (``Hips`` bone, scaled
  with the height); part: the hip centre (mean of the two ``UpLeg`` heads).
* joints: every rig bone's ``<name>_head`` and ``<name>_tail``, and ``crown``, ``fingertip_l``,
  ``fingertip_r``, ``toe_l``, ``toe_r``.

Crown, fingertips and toe tips are mesh vertices (on the surface); every other point of the
segments lies inside the mesh (tests). ``separated`` is measured on the mesh: vertex-to-vertex
distances (an over-estimate of the surface gap by up to half an edge: median edge 6 mm, 95 % of
the edges under 3 cm, at the rest scale) between the distal arm (forearm, hand and the lower half of the upper arm) and the
trunk, the legs and the other arm, and between the lower legs (lower half of the thigh, shin,
foot) and each other and the trunk.

Re-posing: ``gt.json`` keeps ``synth.build`` and per frame ``pose`` (the joint angles) and
``placement`` (``R``, ``t``: body frame → world, full precision), so :func:`body_mesh` returns
the exact posed mesh of any frame; :func:`dominant_bones` gives each vertex's bone.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from topopose.errors import InputError
from topopose.synth.subjects import HUMAN_DEFAULT, rx, ry, rz

_DATA = Path(__file__).with_name("data") / "makehuman_body.npz"
# MakeHuman (x: subject's left, y: up, z: forward) → body frame (x forward, y left, z up)
_MH = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_TRUNK = ("Hips", "LowerBack", "Spine", "Spine1", "LHipJoint", "RHipJoint", "LeftShoulder",
          "RightShoulder")
_HAND = ("Hand", "Thumb", "FingerBase", "HandFinger1")

# proportions: standing height (m), length factors (legs, arms, trunk), girth factors (trunk,
# limbs), head size. "random" draws them from the seed.
BUILDS = {
    "average": dict(height=1.75, leg=1.0, arm=1.0, torso=1.0, girth=1.0, limb_girth=1.0, head=1.0),
    "heavy": dict(height=1.63, leg=0.97, arm=0.98, torso=1.0, girth=1.4, limb_girth=1.3, head=1.0),
    "child": dict(height=1.36, leg=0.93, arm=0.95, torso=0.98, girth=0.9, limb_girth=0.85,
                  head=1.22),
    "lean": dict(height=1.83, leg=1.04, arm=1.03, torso=1.0, girth=0.93, limb_girth=1.05,
                 head=0.96),
}
BUILD_NAMES = tuple(BUILDS) + ("random",)
HEIGHT_RANGE = (1.1, 2.0)


def random_build(rng) -> dict:
    """Random proportions: height 1.1–2.0 m (shorter: a relatively larger head), limb and trunk
    lengths ±10 %, trunk girth 0.85–1.45, limb girth 0.85–1.3."""
    height = float(rng.uniform(*HEIGHT_RANGE))
    head = float(np.clip(1.0 + 0.4 * (1.7 - height) + rng.uniform(-0.05, 0.05), 0.92, 1.3))
    return dict(height=height, leg=float(rng.uniform(0.9, 1.1)), arm=float(rng.uniform(0.92, 1.08)),
                torso=float(rng.uniform(0.92, 1.08)), girth=float(rng.uniform(0.85, 1.45)),
                limb_girth=float(rng.uniform(0.85, 1.3)), head=head)


def make_build(build, rng, thickness=1.0) -> dict:
    """The proportions dict of ``build`` (a name of :data:`BUILDS`, ``"random"`` or a dict);
    ``thickness`` multiplies both girths."""
    if isinstance(build, dict):
        b = {**BUILDS["average"], **build}
        b.setdefault("name", "custom")
    elif build == "random" or build is None:
        b = {**random_build(rng), "name": "random"}
    elif build in BUILDS:
        b = {**BUILDS[build], "name": build}
    else:
        raise InputError(f"synth: --build {build!r} must be one of {', '.join(BUILD_NAMES)}")
    if not HEIGHT_RANGE[0] - 1e-9 <= float(b["height"]) <= HEIGHT_RANGE[1] + 1e-9:
        raise InputError(f"synth: build height must be within {HEIGHT_RANGE} m (got {b['height']})")
    b["girth"] = float(b["girth"]) * float(thickness)
    b["limb_girth"] = float(b["limb_girth"]) * float(thickness)
    return b


def _unit(v):
    return v / np.linalg.norm(v)


def _minrot(a, b):
    """Smallest rotation taking unit vector a to unit vector b (Rodrigues)."""
    a, b = _unit(a), _unit(b)
    v = np.cross(a, b)
    c = float(a @ b)
    V = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + V + V @ V / (1.0 + c)


@dataclass(frozen=True)
class Rig:
    """The rest mesh and rig in the body frame (see the module docstring)."""

    vertices: np.ndarray      # (n, 3) float64
    faces: np.ndarray         # (m, 3) int32
    names: tuple
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    skin_bones: np.ndarray    # (n, 4) int64
    skin_weights: np.ndarray  # (n, 4) float64
    neutral: np.ndarray       # (31, 3, 3): N_b
    dominant: np.ndarray      # (n,) dominant bone per vertex
    axial: np.ndarray         # (n,) position of the vertex along its dominant bone (0 head, 1 tail)
    tips: dict = field(default_factory=dict)    # name -> vertex index (crown, fingertip_l, ...)
    radii: dict = field(default_factory=dict)   # head, hand, foot radius at rest (m)

    def index(self, name):
        return self.names.index(name)


@lru_cache(maxsize=1)
def rig() -> Rig:
    """Load ``data/makehuman_body.npz`` into the body frame (cached)."""
    d = np.load(_DATA)
    V = d["vertices"].astype(np.float64) @ _MH.T
    H = d["bone_heads"].astype(np.float64) @ _MH.T
    T = d["bone_tails"].astype(np.float64) @ _MH.T
    names = tuple(str(n) for n in d["bone_names"])
    parents = d["bone_parents"].astype(np.int64)
    sb = d["skin_bones"].astype(np.int64)
    sw = d["skin_weights"].astype(np.float64)
    ix = names.index
    down = np.array([0.0, 0.0, -1.0])
    N = np.repeat(np.eye(3)[None], len(names), 0)
    for S in ("Left", "Right"):
        c = S[0]
        arm, fore, up, leg = ix(f"{S}Arm"), ix(f"{S}ForeArm"), ix(f"{S}UpLeg"), ix(f"{S}Leg")
        N[arm] = _minrot(T[arm] - H[arm], down)
        N[fore] = N[arm] @ _minrot(T[fore] - H[fore], T[arm] - H[arm])
        for n in (f"{S}Hand", f"{c}Thumb", f"{S}FingerBase", f"{S}HandFinger1"):
            N[ix(n)] = N[fore]
        N[up] = _minrot(T[up] - H[up], down)
        N[leg] = N[up] @ _minrot(T[leg] - H[leg], T[up] - H[up])
        N[ix(f"{S}Foot")] = N[ix(f"{S}ToeBase")] = N[leg]
    dom = sb[np.arange(len(sb)), np.argmax(sw, axis=1)]
    ax = T[dom] - H[dom]
    axial = np.einsum("ij,ij->i", V - H[dom], ax) / np.einsum("ij,ij->i", ax, ax)
    tips, radii = {}, {}

    def extreme(bones, origin, target):
        sel = np.flatnonzero(np.isin(dom, [ix(b) for b in bones]))
        a = _unit(target - origin)
        proj = (V[sel] - origin) @ a
        rad = np.linalg.norm((V[sel] - origin) - proj[:, None] * a, axis=1)
        return int(sel[np.argmax(proj)]), float(np.median(rad))

    head = ix("Head")
    tips["crown"], _ = extreme(("Head",), H[head], T[head])
    radii["head"] = 0.5 * float(np.ptp(V[dom == head, 1]))      # half the head's width
    for S in ("Left", "Right"):
        c, s = S[0], S[0].lower()
        hand = ix(f"{S}Hand")
        bones = (f"{S}Hand", f"{c}Thumb", f"{S}FingerBase", f"{S}HandFinger1")
        tips[f"fingertip_{s}"], radii["hand"] = extreme(bones, H[hand], T[ix(f"{S}HandFinger1")])
        foot = ix(f"{S}Foot")
        tips[f"toe_{s}"], radii["foot"] = extreme((f"{S}Foot", f"{S}ToeBase"), H[foot],
                                                  T[ix(f"{S}ToeBase")])
    return Rig(V, d["faces"].astype(np.int32), names, parents, H, T, sb, sw, N, dom, axial, tips,
               radii)


def dominant_bones() -> tuple[np.ndarray, tuple]:
    """Each mesh vertex's dominant bone (largest skinning weight; the same in every pose) as an
    index into the bone names, and the names (for the hull segmentation, thesis §13.3.1.1)."""
    r = rig()
    return r.dominant.copy(), r.names


def _scales(r: Rig, b: dict) -> np.ndarray:
    """Per-bone build matrices S_b (31, 3, 3)."""
    S = np.repeat(np.eye(3)[None], len(r.names), 0)
    for i, n in enumerate(r.names):
        a = _unit(r.tails[i] - r.heads[i])
        if n in _TRUNK:
            S[i] = np.diag([b["girth"], b["girth"], b["torso"]])
        elif n in ("Neck", "Neck1"):
            g = 0.5 * (b["girth"] + b["limb_girth"])
            S[i] = g * np.eye(3) + (b["torso"] - g) * np.outer(a, a)
        elif n == "Head":
            S[i] = b["head"] * np.eye(3)
        elif n.endswith(("Arm", "ForeArm")):
            S[i] = b["limb_girth"] * np.eye(3) + (b["arm"] - b["limb_girth"]) * np.outer(a, a)
        elif n.endswith(("UpLeg", "Leg")):
            S[i] = b["limb_girth"] * np.eye(3) + (b["leg"] - b["limb_girth"]) * np.outer(a, a)
    return S


def _frames(p: dict) -> dict:
    """F_b of every bone from the capsule human's joint angles (degrees)."""
    Rp = rz(p.get("pelvis_yaw", 0.0)) @ rx(p.get("pelvis_roll", 0.0)) @ ry(p.get("pelvis_pitch", 0.0))
    step = rz(p["spine_twist"] / 3) @ rx(p["spine_side"] / 3) @ ry(p["spine_flex"] / 3)
    F = {"Hips": Rp, "LHipJoint": Rp, "RHipJoint": Rp}
    F["LowerBack"] = Rp @ step
    F["Spine"] = F["LowerBack"] @ step
    Rs = F["Spine1"] = F["Spine"] @ step
    nstep = rz(p["neck_twist"] / 2) @ rx(p["neck_side"] / 2) @ ry(p["neck_flex"] / 2)
    F["Neck"] = Rs @ nstep
    F["Neck1"] = F["Head"] = F["Neck"] @ nstep
    for S, s, sg in (("Left", "l", 1.0), ("Right", "r", -1.0)):
        raise_ = 0.3 * max(0.0, max(p[f"sh_abd_{s}"], p[f"sh_flex_{s}"]) - 60.0)
        F[f"{S}Shoulder"] = Rs @ rx(sg * raise_)
        Ru = Rs @ ry(-p[f"sh_flex_{s}"]) @ rx(sg * p[f"sh_abd_{s}"]) @ rz(sg * p[f"sh_rot_{s}"])
        Rf = Ru @ ry(-p[f"elbow_{s}"])
        Rw = Rf @ rx(sg * p[f"wrist_dev_{s}"]) @ ry(-p[f"wrist_flex_{s}"])
        F[f"{S}Arm"], F[f"{S}ForeArm"] = Ru, Rf
        for n in (f"{S}Hand", f"{S[0]}Thumb", f"{S}FingerBase", f"{S}HandFinger1"):
            F[n] = Rw
        Rt = Rp @ ry(-p[f"hip_flex_{s}"]) @ rx(sg * p[f"hip_abd_{s}"]) @ rz(sg * p[f"hip_rot_{s}"])
        Rk = Rt @ ry(p[f"knee_{s}"])
        F[f"{S}UpLeg"], F[f"{S}Leg"] = Rt, Rk
        F[f"{S}Foot"] = F[f"{S}ToeBase"] = Rk @ ry(-p[f"ankle_{s}"])
    return F


def bone_transforms(pose: dict | None, build: dict) -> tuple[np.ndarray, np.ndarray, float]:
    """Per-bone affine maps (A (31, 3, 3), t (31, 3)) of the rest mesh for a pose and a build,
    and the uniform scale giving the build's height.

    ``pose`` None: the rest pose (A-pose, ``Q_b = I``); with the ``average`` build at the rest
    height this is the identity map up to the height scale.
    """
    r = rig()
    S = _scales(r, build)
    if pose is None:
        Q = np.repeat(np.eye(3)[None], len(r.names), 0)
    else:
        F = _frames({**HUMAN_DEFAULT, **pose})
        Q = np.stack([F[n] for n in r.names]) @ r.neutral
    A = Q @ S
    # standing height of this build (rest pose, scaled lengths): the uniform scale
    A0, t0 = _fk(r, S)
    h0 = float(np.ptp(skin(A0, t0)[:, 2]))
    u = float(build["height"]) / h0
    A, t = _fk(r, A)
    return A * u, t * u, u


def _fk(r: Rig, A):
    P = np.zeros_like(r.heads)
    P[0] = r.heads[0]
    for b in range(1, len(r.names)):
        p = r.parents[b]
        P[b] = P[p] + A[p] @ (r.heads[b] - r.heads[p])
    return A, P - np.einsum("bij,bj->bi", A, r.heads)


def skin(A, t) -> np.ndarray:
    """Linear blend skinning of the rest mesh: ``Σ_k w_k (A_{b_k} x + t_{b_k})`` (n, 3)."""
    r = rig()
    B = r.skin_bones
    X = np.einsum("nkij,nj->nki", A[B], r.vertices) + t[B]
    return np.einsum("nk,nki->ni", r.skin_weights, X)


@dataclass
class MeshBody:
    """A posed ``body``: the mesh and ground truth in the body frame, and its placement
    (``x → R x + t``) in the world. Same interface as :class:`.synth_subjects.Body` for
    :mod:`.synth` (``transformed``, ``extent``, ``separated``, ``min_gap``, ``limb_gap``,
    ``parts``, ``segments``, ``joints``) plus :meth:`render`."""

    pose: dict
    build: dict
    local: np.ndarray          # (n, 3) posed vertices, body frame
    local_pts: dict            # name -> (3,) points of parts / joints / segments, body frame
    margin: float = 0.02
    limb_margin: float | None = None
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))
    _gaps: list | None = None
    subject: str = "body"

    @property
    def height(self) -> float:
        return float(self.build["height"])

    @property
    def vertices(self) -> np.ndarray:
        return self.local @ self.R.T + self.t

    @property
    def faces(self) -> np.ndarray:
        return rig().faces

    def _w(self, p):
        return self.R @ p + self.t

    @property
    def joints(self):
        return {k[2:]: self._w(v) for k, v in self.local_pts.items() if k.startswith("j:")}

    @property
    def parts(self):
        return {k[2:]: self._w(v) for k, v in self.local_pts.items() if k.startswith("p:")}

    @property
    def segments(self):
        return {k[2:]: np.stack([self._w(v[0]), self._w(v[1])])
                for k, v in self.local_pts.items() if k.startswith("s:")}

    def transformed(self, R, t):
        R = np.asarray(R, float)
        return MeshBody(self.pose, self.build, self.local, self.local_pts, self.margin,
                        self.limb_margin, R @ self.R, R @ self.t + np.asarray(t, float),
                        self._gaps)

    def extent(self, skip=()):
        v = self.vertices
        return v.min(0), v.max(0)

    def clearances(self):
        """``(gap, group_a, group_b)`` of the limb pairs that must keep clear (module docstring)."""
        if self._gaps is None:
            from scipy.spatial import cKDTree

            r = rig()
            ix = r.index
            dom, ax = r.dominant, r.axial
            is_ = lambda names: np.isin(dom, [ix(n) for n in names])  # noqa: E731
            trunk = is_(_TRUNK + ("Neck", "Neck1", "Head"))
            g = {"trunk": trunk}
            for S, s in (("Left", "l"), ("Right", "r")):
                hand = is_((f"{S}ForeArm", f"{S}Hand", f"{S[0]}Thumb", f"{S}FingerBase",
                            f"{S}HandFinger1"))
                g[f"arm_{s}"] = hand | (is_((f"{S}Arm",)) & (ax > 0.5))
                lower = is_((f"{S}Leg", f"{S}Foot", f"{S}ToeBase"))
                g[f"leg_{s}"] = lower | is_((f"{S}UpLeg",))
                g[f"lowleg_{s}"] = lower | (is_((f"{S}UpLeg",)) & (ax > 0.5))
                g[f"shank_{s}"] = lower | (is_((f"{S}UpLeg",)) & (ax > 0.6))
            pairs = [("arm_l", "trunk"), ("arm_r", "trunk"), ("arm_l", "arm_r"),
                     ("arm_l", "leg_l"), ("arm_l", "leg_r"), ("arm_r", "leg_l"), ("arm_r", "leg_r"),
                     ("lowleg_l", "lowleg_r"), ("shank_l", "trunk"), ("shank_r", "trunk")]
            trees = {}
            out = []
            for a, b in pairs:
                if b not in trees:
                    trees[b] = cKDTree(self.local[g[b]])
                d, _ = trees[b].query(self.local[g[a]], k=1)
                out.append((float(d.min()), a, b))
            self._gaps = out
        return self._gaps

    def min_gap(self):
        return min(c[0] for c in self.clearances())

    def limb_gap(self):
        return self.min_gap()

    def separated(self):
        m = self.margin if self.limb_margin is None else self.limb_margin
        return self.min_gap() >= m

    def render(self, cam, table) -> np.ndarray:
        """Exact silhouette (bool (h, w)) of the mesh seen by ``cam`` (``table``:
        :func:`.synth_geometry.ray_table` of ``cam``)."""
        return rasterize(cam, table, self.vertices, self.faces)


def rasterize(cam, table, vertices, faces) -> np.ndarray:
    """Exact silhouette of a triangle mesh: pixels whose viewing ray meets a triangle.

    Numba kernel :func:`.synth_body_kernels.raster_kernel` (edge functions in undistorted
    normalized coordinates, with the pixel's undistorted coordinate from the ray table).
    """
    from topopose.synth.body_kernels import raster_kernel

    w, h = cam.size
    mask = np.zeros((h, w), dtype=np.bool_)
    xc = np.ascontiguousarray(np.asarray(vertices, np.float64) @ cam.R.T + cam.translation)
    dist = np.zeros(5)
    dd = np.asarray(cam.distortions, np.float64).ravel()
    full = bool(cam.fisheye) or (len(dd) > 5 and np.any(dd[5:] != 0))
    if not full:
        dist[:min(5, len(dd))] = dd[:5]
    raster_kernel(xc, np.ascontiguousarray(faces, np.int64), np.asarray(cam.matrix, np.float64),
                  dist, full, table.xy, mask)
    return mask


def pose_body(pose: dict | None, build: dict, margin: float = 0.02) -> MeshBody:
    """Pose the body (body frame) and compute its ground truth."""
    r = rig()
    A, t, scale = bone_transforms(pose, build)
    V = skin(A, t)
    pts = {}
    for i, n in enumerate(r.names):
        pts[f"j:{n}_head"] = A[i] @ r.heads[i] + t[i]
        pts[f"j:{n}_tail"] = A[i] @ r.tails[i] + t[i]
    for k, vi in r.tips.items():
        pts[f"j:{k}"] = V[vi]
    u = A[0] @ np.array([0.0, 0.0, 1.0])
    neck = pts["j:Neck_head"]
    crown = pts["j:crown"]
    rh = r.radii["head"] * scale * build["head"]
    pts["p:head"] = crown - rh * _unit(crown - neck)
    pts["s:head"] = (neck, crown)
    pts["p:torso"] = neck
    pts["s:torso"] = (neck, pts["j:Spine1_head"])
    hipc = 0.5 * (pts["j:LeftUpLeg_head"] + pts["j:RightUpLeg_head"])
    pts["p:crotch"] = hipc
    pelvis_axis = _unit(u)
    pts["s:crotch"] = (hipc - 0.04 * scale * pelvis_axis, hipc + 0.07 * scale * pelvis_axis)
    for S, s, k in (("Left", "l", "1"), ("Right", "r", "2")):
        wrist, tip = pts[f"j:{S}Hand_head"], pts[f"j:fingertip_{s}"]
        pts[f"p:hand_{k}"] = tip - r.radii["hand"] * scale * _unit(tip - wrist)
        pts[f"s:hand_{k}"] = (wrist, tip)
        ankle, toe = pts[f"j:{S}Foot_head"], pts[f"j:toe_{s}"]
        pts[f"p:foot_{k}"] = toe - r.radii["foot"] * scale * _unit(toe - ankle)
        pts[f"s:foot_{k}"] = (ankle, toe)
    return MeshBody(dict(pose or {}), build, V, pts, margin)


def body_mesh(gt: dict, frame: str) -> tuple[np.ndarray, np.ndarray]:
    """The posed mesh (world vertices (n, 3), faces (m, 3)) of a ``body`` capture frame, re-posed
    from ``gt.json`` (``synth.build``, the frame's ``pose`` and ``placement``)."""
    if gt.get("subject") != "body":
        raise InputError(f"gt.json: subject is {gt.get('subject')!r}, not 'body' (no mesh to re-pose)")
    try:
        f = gt["frames"][frame]
        body = pose_body(f["pose"], gt["synth"]["build"])
        R, t = np.array(f["placement"]["R"], float), np.array(f["placement"]["t"], float)
    except KeyError as exc:
        raise InputError(f"gt.json: frame {frame!r} has no field {exc}") from None
    return body.transformed(R, t).vertices, rig().faces.copy()


# ----------------------------------------------------------------------------- poses
def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


_ARM_MODES = ("down", "bent", "folded", "raised", "free")
_LEG_MODES = ("stand", "walk", "crouch", "knee_up")


def body_random(rng) -> dict:
    """Random plausible pose (degrees, the capsule human's angles) within anatomical limits.

    Arms (each): down, bent, folded on the chest, raised, or free; legs: standing, walking
    stride, crouching, one knee up; torso bend and twist; head turns.
    """
    p = {"spine_flex": _u(rng, -10, 35), "spine_side": _u(rng, -12, 12),
         "spine_twist": _u(rng, -25, 25), "neck_flex": _u(rng, -20, 30),
         "neck_side": _u(rng, -15, 15), "neck_twist": _u(rng, -60, 60)}
    for s in "lr":
        mode = _ARM_MODES[int(rng.integers(len(_ARM_MODES)))]
        if mode == "down":
            a = dict(sh_flex=_u(rng, -15, 20), sh_abd=_u(rng, 10, 30), sh_rot=_u(rng, -30, 30),
                     elbow=_u(rng, 0, 30))
        elif mode == "bent":
            a = dict(sh_flex=_u(rng, -10, 60), sh_abd=_u(rng, 10, 45), sh_rot=_u(rng, -40, 40),
                     elbow=_u(rng, 40, 130))
        elif mode == "folded":
            a = dict(sh_flex=_u(rng, 20, 55), sh_abd=_u(rng, 10, 30), sh_rot=_u(rng, -75, -40),
                     elbow=_u(rng, 110, 140))
        elif mode == "raised":
            a = dict(sh_flex=_u(rng, 30, 170), sh_abd=_u(rng, 60, 170), sh_rot=_u(rng, -30, 30),
                     elbow=_u(rng, 0, 70))
        else:
            a = dict(sh_flex=_u(rng, -40, 150), sh_abd=_u(rng, 10, 160), sh_rot=_u(rng, -60, 60),
                     elbow=_u(rng, 0, 140))
        a.update(wrist_flex=_u(rng, -50, 50), wrist_dev=_u(rng, -20, 20))
        p.update({f"{k}_{s}": v for k, v in a.items()})
        p.update({f"hip_abd_{s}": _u(rng, -5, 25), f"hip_rot_{s}": _u(rng, -25, 25),
                  f"ankle_{s}": _u(rng, -15, 20)})
    leg = _LEG_MODES[int(rng.integers(len(_LEG_MODES)))]
    first = "lr"[int(rng.integers(2))]
    for s in "lr":
        if leg == "stand":
            p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, -10, 20), _u(rng, 0, 20)
        elif leg == "walk":
            hf = _u(rng, 10, 35) if s == first else _u(rng, -20, -5)
            p[f"hip_flex_{s}"], p[f"knee_{s}"] = hf, _u(rng, 0, 60)
        elif leg == "crouch":
            p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, 60, 110), _u(rng, 80, 130)
            p[f"ankle_{s}"] = _u(rng, 15, 35)
            p[f"hip_abd_{s}"] = _u(rng, 5, 30)
        else:
            if s == first:
                p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, 60, 100), _u(rng, 60, 110)
            else:
                p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, -10, 10), _u(rng, 0, 15)
    if leg == "crouch":
        p["spine_flex"] = _u(rng, 10, 45)
    return p


def _arms(rng, lo_hi: dict) -> dict:
    return {f"{k}_{s}": _u(rng, *v) for s in "lr" for k, v in lo_hi.items()}


#: poses whose limbs touch the body (the hull has no branch for them), by motion name: each a
#: sampler of the joints it sets (degrees) on top of :func:`body_random`'s trunk and head
TOUCHING = {
    "hang": lambda rng: {**_arms(rng, {"sh_flex": (-10, 10), "sh_abd": (0, 6),
                                       "sh_rot": (-20, 20), "elbow": (0, 20)}),
                         **_arms(rng, {"hip_flex": (-5, 10), "knee": (0, 15), "hip_abd": (0, 8)})},
    "hips": lambda rng: {**_arms(rng, {"sh_flex": (-25, -5), "sh_abd": (35, 55),
                                       "sh_rot": (-20, 10), "elbow": (95, 120)}),
                         **_arms(rng, {"hip_flex": (-5, 10), "knee": (0, 15), "hip_abd": (0, 8)})},
    "fold": lambda rng: {**_arms(rng, {"sh_flex": (20, 55), "sh_abd": (10, 30),
                                       "sh_rot": (-75, -40), "elbow": (110, 140)}),
                         **_arms(rng, {"hip_flex": (-5, 10), "knee": (0, 15), "hip_abd": (0, 8)})},
    "jump": lambda rng: (lambda f, k: {
        **_arms(rng, {"sh_flex": (-30, 60), "sh_abd": (5, 20), "elbow": (0, 40)}),
        **{f"hip_flex_{s}": f for s in "lr"}, **{f"knee_{s}": k for s in "lr"},
        **{f"hip_abd_{s}": _u(rng, -3, 2) for s in "lr"}, **{f"hip_rot_{s}": 0.0 for s in "lr"}})(
        _u(rng, 0, 60), _u(rng, 0, 90)),
    "crouch": lambda rng: {**_arms(rng, {"sh_flex": (-10, 30), "sh_abd": (0, 10),
                                         "elbow": (0, 40)}),
                           **_arms(rng, {"hip_flex": (60, 110), "knee": (80, 130),
                                         "ankle": (15, 35), "hip_abd": (5, 30)}),
                           "spine_flex": _u(rng, 10, 45)},
}
#: the share of a touching motion's keyframes drawn free (:func:`body_random`): the limbs stand
#: apart now and then, as a subject's do
FREE_SHARE = 1 / 3


def body_touching(kind):
    """Keyframe sampler of the touching motion ``kind`` (a key of :data:`TOUCHING`): a
    :func:`body_random` pose with the limbs set by ``TOUCHING[kind]``, or, with probability
    :data:`FREE_SHARE`, the random pose itself."""
    def sample(rng) -> dict:
        p = body_random(rng)
        return p if rng.random() < FREE_SHARE else {**p, **TOUCHING[kind](rng)}
    return sample


def body_balance(rng) -> dict:
    """Random balancing pose: :func:`body_random` with one leg lifted sideways (hip abduction
    30–80°, knee nearly straight) on the other, straight, leg — as the Pose2Sim balancing trial
    (a subject on one leg, leaning away from the lifted one, arms out). The lean itself is the
    placement's (``synthetic_capture(lean=…)``)."""
    p = body_random(rng)
    up, down = ("l", "r") if rng.random() < 0.5 else ("r", "l")
    p.update({f"hip_abd_{up}": _u(rng, 30, 80), f"hip_flex_{up}": _u(rng, -15, 30),
              f"knee_{up}": _u(rng, 0, 30), f"hip_abd_{down}": _u(rng, -5, 10),
              f"hip_flex_{down}": _u(rng, -10, 10), f"knee_{down}": _u(rng, 0, 15)})
    return p


#: pose families of the body's random poses (``synthetic_capture(pose=…)``, ``topopose synth
#: --pose``): ``any`` (:func:`body_random`) or one kind of pose the left/right cues must survive
POSE_FAMILIES = ("any", "feet_out", "feet_in", "twist", "crouch", "kneel", "one_leg",
                 "arms_crossed", "lying")


def body_family(rng, family="any") -> dict:
    """Random pose of one family (:data:`POSE_FAMILIES`): :func:`body_random` with

    - ``feet_out`` / ``feet_in``: both legs standing, each foot turned out / in by 0–40°
      (hip rotation);
    - ``twist``: the torso twisted 30–70° against the pelvis (either way);
    - ``crouch``: both legs deeply flexed; ``kneel``: both knees on the floor or one (the
      other foot planted in front);
    - ``one_leg``: one leg raised, in front (knee up) or sideways, on the other straight leg;
    - ``arms_crossed``: both arms folded across the chest, hands past the midline;
    - ``lying``: any pose, laid on the floor by the placement (the capture's ``_random_frames``).
    """
    if family not in POSE_FAMILIES:
        raise InputError(f"synth: --pose {family!r} must be one of {', '.join(POSE_FAMILIES)}")
    p = body_random(rng)
    sides = ("l", "r") if rng.random() < 0.5 else ("r", "l")
    if family in ("feet_out", "feet_in"):
        sg = 1.0 if family == "feet_out" else -1.0
        for s in "lr":
            p.update({f"hip_flex_{s}": _u(rng, -10, 15), f"knee_{s}": _u(rng, 0, 20),
                      f"hip_abd_{s}": _u(rng, -5, 15), f"hip_rot_{s}": sg * _u(rng, 0, 40),
                      f"ankle_{s}": _u(rng, -10, 10)})
    elif family == "twist":
        p["spine_twist"] = float(rng.choice([-1.0, 1.0])) * _u(rng, 30, 70)
    elif family == "crouch":
        for s in "lr":
            p.update({f"hip_flex_{s}": _u(rng, 70, 115), f"knee_{s}": _u(rng, 90, 135),
                      f"ankle_{s}": _u(rng, 15, 35), f"hip_abd_{s}": _u(rng, 5, 30)})
        p["spine_flex"] = _u(rng, 10, 45)
    elif family == "kneel":
        for s in sides[:1 if rng.random() < 0.5 else 2]:       # knee(s) down
            p.update({f"hip_flex_{s}": _u(rng, -10, 15), f"knee_{s}": _u(rng, 80, 110),
                      f"ankle_{s}": _u(rng, -40, -20), f"hip_abd_{s}": _u(rng, 0, 15)})
        if p[f"knee_{sides[1]}"] < 80:                         # the other foot planted in front
            p.update({f"hip_flex_{sides[1]}": _u(rng, 70, 95), f"knee_{sides[1]}": _u(rng, 80, 100),
                      f"ankle_{sides[1]}": _u(rng, 0, 15)})
    elif family == "one_leg":
        up, down = sides
        if rng.random() < 0.5:
            p.update({f"hip_flex_{up}": _u(rng, 50, 100), f"knee_{up}": _u(rng, 40, 110)})
        else:
            p.update({f"hip_abd_{up}": _u(rng, 30, 70), f"hip_flex_{up}": _u(rng, -10, 30),
                      f"knee_{up}": _u(rng, 0, 40)})
        p.update({f"hip_flex_{down}": _u(rng, -10, 10), f"knee_{down}": _u(rng, 0, 15),
                  f"hip_abd_{down}": _u(rng, -5, 10)})
    elif family == "arms_crossed":
        for s in "lr":
            p.update({f"sh_flex_{s}": _u(rng, 20, 60), f"sh_abd_{s}": _u(rng, 5, 30),
                      f"sh_rot_{s}": _u(rng, -95, -65), f"elbow_{s}": _u(rng, 100, 140)})
    return p
