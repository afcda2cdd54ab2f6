"""Articulated synthetic subjects: kinematic skeletons dressed in round cones and ellipsoids.

Each subject is a forward-kinematics function ``build(pose, thickness) -> Body`` of a dict of joint
angles (degrees), a sampler of random plausible poses, and a gait for smooth motion. Bodies are
built in a body frame (x forward, y left, z up, metres) and placed in the world afterwards.

Part positions (the names of the built-in models, see ``notes/contracts.md``) are chosen where the
end of a curve-skeleton branch lies: the far end of the last bone's *axis*, i.e. the limb's
extremity minus about one radius (a fingertip capsule's axis end is exactly one radius inside
the tip). Junction parts (torso, crotch, palm, shoulders, hips, cephalothorax) are the points where
the limbs meet. The ``segments`` give the stretch on which a correct detection may lie: the last
bone for extremities, a piece of the body axis for junctions. Anatomical ``joints`` (used by the
kinematics stage) are the bone end points; their end points (head_top, hand_l, ...) equal the part
positions (axis ends, where a skeleton ends).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from topopose.synth.geometry import Prim, clearance

SUBJECTS = ("human", "hand", "dog", "spider", "body")   # body: MakeHuman mesh (.synth_body)

PARTS = {
    "human": ["head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"],
    "hand": ["arm", "palm", "thumb", "index", "middle", "ring", "little"],
    "dog": ["head", "shoulders", "hips", "tail", "paw_1", "paw_2", "paw_3", "paw_4"],
    "spider": ["cephalothorax", "abdomen"] + [f"leg_{i}" for i in range(1, 9)],
    "body": ["head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"],
}

# the motions each subject can perform (besides "random"); "random-smooth": a continuous motion
# through random poses (:func:`topopose.synth.capture.synthetic_capture`)
MOTIONS = {"human": ("walk", "random-smooth"), "dog": ("trot", "walk"), "spider": ("walk",),
           "hand": ("grasp",), "body": ("walk", "random-smooth", "hang", "hips", "fold", "jump",
                                       "crouch")}


def rx(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _v(*x):
    return np.array(x, dtype=float)


@dataclass
class Body:
    """A posed subject.

    Attributes
    ----------
    subject : str
    prims : list of Prim
    links : dict link -> (parent link or None, proximal joint position)
    joints, parts : dict name -> (3,) array
    segments : dict part -> (2, 3) array
    margin : float
        Clearance (m) below which two non-adjacent limbs count as touching.
    limb_margin : float or None
        Clearance (m) required between limbs that are not parent/child or grandparent/grandchild
        links (two limbs meeting at a junction, or further apart): the separation of distinct
        branches of the subject in its visual hull (``synthetic_capture(margin=...)``). None: the
        same as ``margin`` (every non-adjacent pair needs ``margin``).
    border : (3,) array or None
        For the hand: the forearm axis (wrist → elbow) direction; the "arm" part is where it
        leaves the capture volume (set by placement).
    """

    subject: str
    prims: list
    links: dict
    joints: dict
    parts: dict
    segments: dict
    margin: float
    extra: dict = field(default_factory=dict)
    limb_margin: float | None = None

    def transformed(self, R, t):
        t = np.asarray(t, dtype=float)
        mv = lambda p: R @ p + t  # noqa: E731
        return Body(
            self.subject,
            [p.transformed(R, t) for p in self.prims],
            {k: (par, mv(j)) for k, (par, j) in self.links.items()},
            {k: mv(v) for k, v in self.joints.items()},
            {k: mv(v) for k, v in self.parts.items()},
            {k: np.stack([mv(s[0]), mv(s[1])]) for k, s in self.segments.items()},
            self.margin,
            {k: (R @ v if k.endswith("_dir") else mv(v)) if isinstance(v, np.ndarray) else v
             for k, v in self.extra.items()},
            self.limb_margin,
        )

    def surface_points(self, n=48, skip=()):
        return np.concatenate([p.surface_points(n) for p in self.prims if p.link not in skip])

    def extent(self, skip=()):
        pts = self.surface_points(skip=skip)
        return pts.min(0), pts.max(0)

    def clearances(self):
        """Smallest gap between limbs that do not share a joint, per primitive pair.

        Pairs inside one link are ignored. For parent/child links the sample points of both
        near the child's joint are ignored (they always touch there); for sibling links (same
        parent) the points of each near its own root joint are ignored (but one sibling's root
        touching the other further out counts). The radius of these regions is 2.5 times the
        larger limb radius plus the margin. Every other pair is tested over its whole surface. Returns the list of
        ``(gap, link_a, link_b)``; pairs whose bounding spheres are more than three margins
        apart get that lower bound instead of their exact gap.
        """
        out = []
        P = self.prims
        spheres = [p.bounding_sphere() for p in P]
        for i in range(len(P)):
            for j in range(i + 1, len(P)):
                la, lb = P[i].link, P[j].link
                if la == lb:
                    continue
                lower = (float(np.linalg.norm(spheres[i][0] - spheres[j][0]))
                         - spheres[i][1] - spheres[j][1])
                m = self.required_margin(la, lb)
                if lower > 3 * m:               # far apart: the bound is enough
                    out.append((lower, la, lb))
                    continue
                pa, ja = self.links[la]
                pb, jb = self.links[lb]
                if pb == la:                        # a is b's parent: both touch at b's joint
                    ex_a = ex_b = [jb]
                elif pa == lb:
                    ex_a = ex_b = [ja]
                elif pa is not None and pa == pb:   # siblings: each one's root is excused
                    ex_a, ex_b = [ja], [jb]
                else:
                    ex_a = ex_b = []
                rmax = max([p.ra for p in (P[i], P[j]) if p.kind == "cone"]
                           + [p.rb for p in (P[i], P[j]) if p.kind == "cone"] + [0.0])
                if rmax == 0.0:
                    rmax = min(float(np.min(P[i].semi)), float(np.min(P[j].semi)))
                rho = 2.5 * rmax + m
                out.append((clearance(P[i], P[j], ex_a, ex_b, rho), la, lb))
        return out

    def required_margin(self, la, lb) -> float:
        """Clearance the links ``la`` and ``lb`` must keep: ``margin`` for parent/child and
        grandparent/grandchild links (one limb bending at a joint; a head two links above the
        chest), ``limb_margin`` (when set) for every other pair: distinct limbs, whose contact
        would join two branches of the subject's visual hull."""
        if self.limb_margin is None:
            return self.margin
        pa, pb = self.links[la][0], self.links[lb][0]
        near = (pa == lb or pb == la
                or (pa is not None and self.links[pa][0] == lb)
                or (pb is not None and self.links[pb][0] == la))
        return self.margin if near else max(self.margin, self.limb_margin)

    def min_gap(self):
        c = self.clearances()
        return min(g for g, _, _ in c) if c else np.inf

    def limb_gap(self):
        """Smallest clearance between links held to ``limb_margin`` (``min_gap`` when unset)."""
        if self.limb_margin is None:
            return self.min_gap()
        c = [g for g, a, b in self.clearances() if self.required_margin(a, b) > self.margin]
        return min(c) if c else np.inf

    def separated(self):
        return all(g >= self.required_margin(a, b) for g, a, b in self.clearances())


class _B:
    """Small accumulator used by the builders."""

    def __init__(self, subject, margin):
        self.subject, self.margin = subject, margin
        self.prims, self.links, self.joints, self.parts, self.segments = [], {}, {}, {}, {}

    def link(self, name, parent, joint):
        self.links[name] = (parent, np.asarray(joint, dtype=float))

    def cone(self, link, a, b, ra, rb=None):
        self.prims.append(Prim("cone", link, np.asarray(a, float), np.asarray(b, float),
                               float(ra), float(ra if rb is None else rb)))

    def ell(self, link, c, axes, semi):
        self.prims.append(Prim("ellipsoid", link, c=np.asarray(c, float), axes=np.asarray(axes, float),
                               semi=np.asarray(semi, float)))

    def part(self, name, pos, seg0, seg1):
        self.parts[name] = np.asarray(pos, float)
        self.segments[name] = np.stack([np.asarray(seg0, float), np.asarray(seg1, float)])

    def body(self, **extra):
        return Body(self.subject, self.prims, self.links, self.joints, self.parts, self.segments,
                    self.margin, dict(extra))


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


# =============================================================================== human
HUMAN_DEFAULT = {
    "spine_flex": 0.0, "spine_side": 0.0, "spine_twist": 0.0,
    "neck_flex": 0.0, "neck_side": 0.0, "neck_twist": 0.0,
    **{f"{k}_{s}": 0.0 for s in "lr" for k in (
        "sh_flex", "sh_abd", "sh_rot", "elbow", "wrist_flex", "wrist_dev",
        "hip_flex", "hip_abd", "hip_rot", "knee", "ankle")},
}


def human(pose: dict, thickness: float = 1.0) -> Body:
    """Human, 1.75 m tall (stands with the pelvis centre 0.945 m above the floor).

    Bones (m): spine pelvis→neck base 0.49, neck 0.10, head centre 0.10 above the neck top
    (head ellipsoid 0.095×0.08×0.12), shoulders ±0.175, upper arm 0.30, forearm 0.26, hand 0.15
    (axis; tip 0.18 from the wrist), hips ±0.09, thigh 0.43, shin 0.42, foot 0.16.
    ``thickness`` scales the radii of trunk and limbs (not head, hands, feet); above 1.3 the
    human wears a dress: a round cone hanging from the pelvis to the knees that joins the legs.
    """
    p = {**HUMAN_DEFAULT, **pose}
    T = float(thickness)
    b = _B("human", 0.02)
    P = _v(0, 0, 0)
    Rp = rz(p.get("pelvis_yaw", 0.0)) @ rx(p.get("pelvis_roll", 0.0)) @ ry(p.get("pelvis_pitch", 0.0))
    Rs = Rp @ rz(p["spine_twist"]) @ rx(p["spine_side"]) @ ry(p["spine_flex"])
    crotch = P + Rp @ _v(0, 0, -0.02)
    neck_base = P + Rs @ _v(0, 0, 0.49)
    mid_chest = P + Rs @ _v(0, 0, 0.30)
    Rn = Rs @ rz(p["neck_twist"]) @ rx(p["neck_side"]) @ ry(p["neck_flex"])
    neck_top = neck_base + Rn @ _v(0, 0, 0.10)
    head_c = neck_top + Rn @ _v(0.015, 0, 0.10)
    head_top = head_c + Rn @ _v(0, 0, 0.12 - 0.08)

    b.link("pelvis", None, P)
    b.ell("pelvis", P + Rp @ _v(0, 0, 0.02), Rp, [0.11 * T, 0.165 * T, 0.13])
    b.link("chest", "pelvis", P + Rs @ _v(0, 0, 0.10))
    b.ell("chest", P + Rs @ _v(0, 0, 0.32), Rs, [0.115 * T, 0.165 * T, 0.20])
    b.link("neck", "chest", neck_base)
    b.cone("neck", neck_base, neck_top, 0.05 * T)
    b.link("head", "neck", neck_top)
    b.ell("head", head_c, Rn, [0.095, 0.08, 0.12])
    if T > 1.3:   # dress: hangs vertically from the pelvis to the knees; a link of its own,
        # adjacent to nothing, so it always counts as touching the legs (never "separated")
        b.link("dress", None, P)
        b.cone("dress", P, P + _v(0, 0, -0.50), 0.17 * T, 0.22 + 0.5 * (T - 1.3))

    J = b.joints
    J["pelvis"], J["neck"], J["head_top"] = crotch, neck_base, head_top
    sh = {}
    for s, sg in (("l", 1.0), ("r", -1.0)):
        shoulder = neck_base + Rs @ _v(0, sg * 0.175, -0.04)
        sh[s] = shoulder
        Ru = Rs @ ry(-p[f"sh_flex_{s}"]) @ rx(sg * p[f"sh_abd_{s}"]) @ rz(sg * p[f"sh_rot_{s}"])
        elbow = shoulder + Ru @ _v(0, 0, -0.30)
        Rf = Ru @ ry(-p[f"elbow_{s}"])
        wrist = elbow + Rf @ _v(0, 0, -0.26)
        Rw = Rf @ rx(sg * p[f"wrist_dev_{s}"]) @ ry(-p[f"wrist_flex_{s}"])
        hand = wrist + Rw @ _v(0, 0, -0.15)
        b.link(f"upperarm_{s}", "chest", shoulder)
        b.cone(f"upperarm_{s}", shoulder, elbow, 0.048 * T, 0.040 * T)
        b.link(f"forearm_{s}", f"upperarm_{s}", elbow)
        b.cone(f"forearm_{s}", elbow, wrist, 0.040 * T, 0.032 * T)
        b.link(f"hand_{s}", f"forearm_{s}", wrist)
        b.cone(f"hand_{s}", wrist, hand, 0.033, 0.028)

        hip = crotch + Rp @ _v(0, sg * 0.09, 0)
        Rt = Rp @ ry(-p[f"hip_flex_{s}"]) @ rx(sg * p[f"hip_abd_{s}"]) @ rz(sg * p[f"hip_rot_{s}"])
        knee = hip + Rt @ _v(0, 0, -0.43)
        Rk = Rt @ ry(p[f"knee_{s}"])
        ankle = knee + Rk @ _v(0, 0, -0.42)
        Ra = Rk @ ry(-p[f"ankle_{s}"])
        toe = ankle + Ra @ _v(0.16, 0, -0.045)
        b.link(f"thigh_{s}", "pelvis", hip)
        b.cone(f"thigh_{s}", hip, knee, 0.075 * T, 0.055 * T)
        b.link(f"shin_{s}", f"thigh_{s}", knee)
        b.cone(f"shin_{s}", knee, ankle, 0.05 * T, 0.04 * T)
        b.link(f"foot_{s}", f"shin_{s}", ankle)
        b.cone(f"foot_{s}", ankle, toe, 0.04, 0.03)
        J.update({f"shoulder_{s}": shoulder, f"elbow_{s}": elbow, f"wrist_{s}": wrist,
                  f"hand_{s}": hand, f"hip_{s}": hip, f"knee_{s}": knee, f"ankle_{s}": ankle,
                  f"foot_{s}": toe})
        k = "1" if s == "l" else "2"
        b.part(f"hand_{k}", hand, wrist, hand)
        b.part(f"foot_{k}", toe, ankle, toe)
    axis = Rs @ _v(0, 0, 1)
    b.part("head", head_top, head_c - Rn @ _v(0, 0, 0.12), head_c + Rn @ _v(0, 0, 0.12))
    b.part("torso", neck_base, neck_base, mid_chest)
    b.part("crotch", crotch, crotch - 0.15 * axis, crotch + 0.15 * axis)
    return b.body()


def human_random(rng) -> dict:
    """Random plausible human pose (degrees)."""
    p = {"spine_flex": _u(rng, -10, 35), "spine_side": _u(rng, -15, 15),
         "spine_twist": _u(rng, -25, 25), "neck_flex": _u(rng, -20, 30),
         "neck_side": _u(rng, -15, 15), "neck_twist": _u(rng, -45, 45)}
    for s in "lr":
        p.update({f"sh_flex_{s}": _u(rng, -40, 150), f"sh_abd_{s}": _u(rng, 0, 160),
                  f"sh_rot_{s}": _u(rng, -60, 60), f"elbow_{s}": _u(rng, 0, 140),
                  f"wrist_flex_{s}": _u(rng, -50, 50), f"wrist_dev_{s}": _u(rng, -20, 20),
                  f"hip_abd_{s}": _u(rng, -8, 40), f"hip_rot_{s}": _u(rng, -30, 30),
                  f"ankle_{s}": _u(rng, -20, 30)})
        if rng.random() < 0.6:      # standing leg
            p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, -15, 30), _u(rng, 0, 30)
        else:                       # raised / bent leg
            p[f"hip_flex_{s}"], p[f"knee_{s}"] = _u(rng, -20, 95), _u(rng, 0, 120)
    return p


def human_walk(t: float, speed: float = 1.2) -> tuple[dict, float]:
    """Walking gait at time t (s): joint angles and distance travelled along the heading.

    Stride frequency 0.9 Hz; hips ±24°, knees up to 64° in swing, arms swing ±22° opposite to
    the legs with an abduction of 8–26° (twice per stride the upper arms brush the chest: those
    frames are not separated).
    """
    ph = 2 * np.pi * 0.9 * t
    p = {"spine_flex": 4 + 2 * np.cos(2 * ph), "spine_twist": 5 * np.sin(ph), "neck_flex": 3.0,
         "pelvis_yaw": -4 * np.sin(ph), "pelvis_roll": 2 * np.cos(2 * ph)}
    for s, off in (("l", 0.0), ("r", np.pi)):
        q = ph + off
        p[f"hip_flex_{s}"] = 8 + 24 * np.sin(q)
        p[f"knee_{s}"] = 6 + 58 * ((1 + np.sin(q + 1.1)) / 2) ** 3
        p[f"ankle_{s}"] = 8 * np.sin(q - 0.6)
        p[f"hip_abd_{s}"] = 3.0
        p[f"sh_flex_{s}"] = -22 * np.sin(q)
        p[f"sh_abd_{s}"] = 17 + 9 * np.cos(2 * ph + 0.3)
        p[f"elbow_{s}"] = 20 + 12 * (1 - np.sin(q)) / 2
    return p, speed * t


# =============================================================================== hand
_FINGERS = {  # knuckle (MCP) in the hand frame, phalanx lengths, base radius, base spread (deg)
    "index": (_v(0.095, 0.028, 0.0), (0.045, 0.025, 0.020), 0.0092, 9.0),
    "middle": (_v(0.100, 0.009, 0.0), (0.050, 0.030, 0.022), 0.0095, 0.0),
    "ring": (_v(0.095, -0.010, 0.0), (0.047, 0.028, 0.021), 0.0088, -9.0),
    "little": (_v(0.085, -0.028, 0.0), (0.037, 0.021, 0.018), 0.0078, -20.0),
}


def hand(pose: dict, thickness: float = 1.0) -> Body:
    """Left hand, palm down (−z), fingers along +x, thumb towards +y; wrist at the origin.

    The forearm runs 0.45 m back along −x from the wrist, so it always leaves the capture volume
    (the subject is incomplete); its end stays inside the camera ring. Finger flexion bends towards the
    palm (−z); "spread" angles rotate about the palm normal.
    """
    p = {"wrist_flex": 0.0, "wrist_dev": 0.0, "pron": 0.0, **pose}
    T = float(thickness)
    b = _B("hand", 0.004)
    W = _v(0, 0, 0)
    b.link("forearm", None, _v(-0.45, 0, 0))
    b.cone("forearm", _v(-0.02, 0, 0), _v(-0.45, 0, 0), 0.026 * T, 0.04 * T)
    Rw = rx(p["pron"]) @ rz(p["wrist_dev"]) @ ry(p["wrist_flex"])
    b.link("palm", "forearm", W)
    palm_c = W + Rw @ _v(0.05, 0, -0.002)
    b.ell("palm", palm_c, Rw, [0.056 * min(T, 1.2), 0.043 * T, 0.016 * T])
    J = b.joints
    J["wrist"] = W
    for f, (mcp, lens, r0, spread) in _FINGERS.items():
        base = W + Rw @ mcp
        R1 = Rw @ rz(spread + p.get(f"{f}_spread", 0.0)) @ ry(p.get(f"{f}_mcp", 0.0))
        j1 = base + R1 @ _v(lens[0], 0, 0)
        R2 = R1 @ ry(p.get(f"{f}_pip", 0.0))
        j2 = j1 + R2 @ _v(lens[1], 0, 0)
        R3 = R2 @ ry(p.get(f"{f}_dip", 0.0))
        tip = j2 + R3 @ _v(lens[2], 0, 0)
        b.link(f"{f}1", "palm", base)
        b.cone(f"{f}1", base, j1, r0 * T, 0.9 * r0 * T)
        b.link(f"{f}2", f"{f}1", j1)
        b.cone(f"{f}2", j1, j2, 0.9 * r0 * T, 0.82 * r0 * T)
        b.link(f"{f}3", f"{f}2", j2)
        b.cone(f"{f}3", j2, tip, 0.82 * r0 * T, 0.75 * r0 * T)
        J.update({f"{f}_mcp": base, f"{f}_pip": j1, f"{f}_dip": j2, f"{f}_tip": tip})
        b.part(f, tip, j2, tip)
    # thumb: carpometacarpal joint near the wrist, on the +y side, below the palm plane
    cmc = W + Rw @ _v(0.018, 0.026, -0.008)
    R1 = Rw @ rz(38 + p.get("thumb_spread", 0.0)) @ rx(-35) @ ry(p.get("thumb_cmc", 0.0))
    m1 = cmc + R1 @ _v(0.045, 0, 0)
    R2 = R1 @ ry(p.get("thumb_mcp", 0.0))
    m2 = m1 + R2 @ _v(0.032, 0, 0)
    R3 = R2 @ ry(p.get("thumb_ip", 0.0))
    ttip = m2 + R3 @ _v(0.026, 0, 0)
    b.cone("palm", cmc, m1, 0.013 * T, 0.011 * T)    # the thumb metacarpal lies in the palm
    b.link("thumb2", "palm", m1)
    b.cone("thumb2", m1, m2, 0.0105 * T, 0.0095 * T)
    b.link("thumb3", "thumb2", m2)
    b.cone("thumb3", m2, ttip, 0.0095 * T, 0.0085 * T)
    J.update({"thumb_cmc": cmc, "thumb_mcp": m1, "thumb_ip": m2, "thumb_tip": ttip})
    b.part("thumb", ttip, m2, ttip)
    b.part("palm", 0.5 * (W + J["middle_mcp"]), W, J["middle_mcp"])
    # the "arm" part is set at placement (where the forearm leaves the capture volume)
    b.part("arm", W + _v(-0.1, 0, 0), W, W + _v(-0.1, 0, 0))
    return b.body(arm_dir=_v(-1.0, 0, 0), wrist=W)


def hand_random(rng) -> dict:
    """A natural hand posture: one grip level g in [0, 0.6] (0 wide open, 1 a fist) drives every
    finger's flexion (the long fingers' flexions are anatomically coupled), each finger deviating
    by ±10°; any wrist orientation.

    Independent random flexions of each joint (fingers 0–95° each) made fists and crossed,
    scattered fingertips in most frames: only 7 % of those postures kept the fingertips in the
    order thumb, index, middle, ring, little in the sense of R_b (thesis §12.2.2.1), the order
    the hand model's betweenness constraint asks for "a natural pose of the hand, e.g. wide
    open" (§12.3); with this sampler 87 % do (R_i: 99 %).
    """
    g = _u(rng, 0.0, 0.6)
    p = {"wrist_flex": _u(rng, -45, 45), "wrist_dev": _u(rng, -15, 20), "pron": _u(rng, -80, 80),
         "thumb_spread": 20 - 25 * g + _u(rng, -10, 10), "thumb_cmc": 5 + 30 * g + _u(rng, -10, 10),
         "thumb_mcp": max(0.0, 5 + 40 * g + _u(rng, -10, 10)),
         "thumb_ip": max(0.0, 5 + 50 * g + _u(rng, -10, 10))}
    for f in _FINGERS:
        pip = max(0.0, 95 * g + _u(rng, -10, 10))
        p.update({f"{f}_spread": _u(rng, -8, 12) * np.sign(_FINGERS[f][3] or 1.0) * (1 - g),
                  f"{f}_mcp": 80 * g + _u(rng, -10, 10), f"{f}_pip": pip,
                  f"{f}_dip": min(80.0, 0.66 * pip + _u(rng, -5, 5))})
    return p


def hand_grasp(t: float, freq: float = 0.5) -> tuple[dict, float]:
    """Hand opening (spread, straight) and closing (fist) at ``freq`` Hz; g = 0 open, 1 closed."""
    g = (1 - np.cos(2 * np.pi * freq * t)) / 2
    p = {"wrist_flex": 10 * np.sin(2 * np.pi * 0.3 * t), "wrist_dev": 4.0, "pron": 10.0,
         "thumb_spread": 20 - 25 * g, "thumb_cmc": 5 + 30 * g, "thumb_mcp": 5 + 40 * g,
         "thumb_ip": 5 + 50 * g}
    for f, (_, _, _, spread) in _FINGERS.items():
        p.update({f"{f}_spread": (1 - g) * 0.8 * spread, f"{f}_mcp": -5 + 85 * g,
                  f"{f}_pip": 3 + 95 * g, f"{f}_dip": 2 + 65 * g})
    return p, 0.0


# =============================================================================== dog
_DOG_LEGS = {  # name, at shoulders (S) or hips (H), side, lengths, radii
    "fl": ("S", 1.0, (0.25, 0.22, 0.075), (0.048, 0.034, 0.026)),
    "fr": ("S", -1.0, (0.25, 0.22, 0.075), (0.048, 0.034, 0.026)),
    "rl": ("H", 1.0, (0.26, 0.25, 0.075), (0.062, 0.036, 0.026)),
    "rr": ("H", -1.0, (0.26, 0.25, 0.075), (0.062, 0.036, 0.026)),
}
_DOG_PAW = {"fl": "paw_1", "fr": "paw_2", "rl": "paw_3", "rr": "paw_4"}
_DOG_JOINTS = {"fl": ("shoulder_l", "elbow_l", "wrist_l", "paw_fl"),
               "fr": ("shoulder_r", "elbow_r", "wrist_r", "paw_fr"),
               "rl": ("hip_l", "knee_l", "ankle_l", "paw_rl"),
               "rr": ("hip_r", "knee_r", "ankle_r", "paw_rr")}


def dog(pose: dict, thickness: float = 1.0) -> Body:
    """Medium dog: body 0.60 m between shoulders and hips, legs ~0.55 m, neck 0.22, tail 0.32.

    Leg angles: ``<leg>_swing`` (forward positive), ``<leg>_abd``, ``<leg>_bend`` (lower leg,
    backward positive), ``<leg>_paw``. Neck elevation/yaw, head pitch/yaw, tail elevation/yaw/curl.
    """
    p = {"body_pitch": 0.0, "body_roll": 0.0, "body_bend": 0.0, "neck_elev": 40.0, "neck_yaw": 0.0,
         "head_pitch": -35.0, "head_yaw": 0.0, "tail_elev": 20.0, "tail_yaw": 0.0, "tail_curl": 0.0,
         **{f"{k}_{leg}": 0.0 for leg in _DOG_LEGS for k in ("swing", "abd", "bend", "paw")},
         **pose}
    T = float(thickness)
    b = _B("dog", 0.02)
    Rb = rx(p["body_roll"]) @ ry(-p["body_pitch"])
    H = _v(0, 0, 0)
    Rf = Rb @ rz(p["body_bend"])                      # front half may turn sideways
    S = H + Rb @ _v(0.30, 0, 0) + Rf @ _v(0.30, 0, 0.03)
    b.link("rear", None, H)
    mid = H + Rb @ _v(0.30, 0, 0)
    b.ell("rear", H + Rb @ _v(0.16, 0, 0.0), Rb, [0.24, 0.13 * T, 0.15 * T])
    b.link("front", "rear", mid)
    b.ell("front", mid + Rf @ _v(0.15, 0, 0.015), Rf, [0.25, 0.14 * T, 0.16 * T])
    J = b.joints
    J["hips"], J["shoulders"] = H, S
    neck_base = S + Rf @ _v(0.08, 0, 0.08)
    Rn = Rf @ rz(p["neck_yaw"]) @ ry(-p["neck_elev"])
    neck_end = neck_base + Rn @ _v(0.22, 0, 0)
    b.link("neck", "front", neck_base)
    b.cone("neck", neck_base, neck_end, 0.065 * T, 0.05 * T)
    Rh = Rn @ rz(p["head_yaw"]) @ ry(-p["head_pitch"])
    head_c = neck_end + Rh @ _v(0.07, 0, 0.02)
    semi = _v(0.13, 0.065, 0.07)
    nose = head_c + Rh @ _v(semi[0] - semi[2], 0, 0)
    b.link("head", "neck", neck_end)
    b.ell("head", head_c, Rh, semi)
    tail_base = H + Rb @ _v(-0.08, 0, 0.07)
    Rt1 = Rb @ rz(180 + p["tail_yaw"]) @ ry(-p["tail_elev"])
    tail_mid = tail_base + Rt1 @ _v(0.16, 0, 0)
    Rt2 = Rt1 @ ry(-p["tail_curl"])
    tail_tip = tail_mid + Rt2 @ _v(0.16, 0, 0)
    b.link("tail1", "rear", tail_base)
    b.cone("tail1", tail_base, tail_mid, 0.032 * T, 0.022 * T)
    b.link("tail2", "tail1", tail_mid)
    b.cone("tail2", tail_mid, tail_tip, 0.022 * T, 0.014 * T)
    J.update({"neck": neck_base, "head_top": nose, "head_base": neck_end, "tail_base": tail_base,
              "tail_mid": tail_mid, "tail_tip": tail_tip})
    for leg, (where, sg, lens, rad) in _DOG_LEGS.items():
        root, Rr = (S, Rf) if where == "S" else (H, Rb)
        body_link = "front" if where == "S" else "rear"
        top = root + Rr @ _v(0, sg * 0.085, -0.06)
        R1 = Rr @ ry(-p[f"swing_{leg}"]) @ rx(sg * p[f"abd_{leg}"])
        j1 = top + R1 @ _v(0, 0, -lens[0])
        R2 = R1 @ ry(p[f"bend_{leg}"])
        j2 = j1 + R2 @ _v(0, 0, -lens[1])
        R3 = R2 @ ry(-p[f"paw_{leg}"])
        tip = j2 + R3 @ _v(lens[2], 0, -0.02)
        b.link(f"{leg}1", body_link, top)
        b.cone(f"{leg}1", top, j1, rad[0] * T, rad[1] * T)
        b.link(f"{leg}2", f"{leg}1", j1)
        b.cone(f"{leg}2", j1, j2, rad[1] * T, rad[2] * T)
        b.link(f"{leg}3", f"{leg}2", j2)
        b.cone(f"{leg}3", j2, tip, rad[2], rad[2] * 0.95)
        n = _DOG_JOINTS[leg]
        J.update({n[0]: top, n[1]: j1, n[2]: j2, n[3]: tip})
        b.part(_DOG_PAW[leg], tip, j2, tip)
    ax = Rf @ _v(1, 0, 0)
    axr = Rb @ _v(1, 0, 0)
    b.part("head", nose, neck_end, nose)
    b.part("shoulders", S, S + 0.06 * ax, S - 0.15 * ax)
    b.part("hips", H, H + 0.15 * axr, H - 0.06 * axr)
    b.part("tail", tail_tip, tail_mid, tail_tip)
    return b.body()


def dog_random(rng) -> dict:
    p = {"body_pitch": _u(rng, -8, 12), "body_roll": _u(rng, -6, 6), "body_bend": _u(rng, -25, 25),
         "neck_elev": _u(rng, 0, 70), "neck_yaw": _u(rng, -45, 45),
         "head_pitch": _u(rng, -60, 10), "head_yaw": _u(rng, -25, 25),
         "tail_elev": _u(rng, -40, 70), "tail_yaw": _u(rng, -50, 50), "tail_curl": _u(rng, -40, 40)}
    for leg in _DOG_LEGS:
        front = leg.startswith("f")
        p.update({f"swing_{leg}": _u(rng, -30, 45), f"abd_{leg}": _u(rng, 0, 20),
                  f"bend_{leg}": _u(rng, -10, 70) if front else _u(rng, -70, 10),
                  f"paw_{leg}": _u(rng, -20, 30)})
    return p


def dog_trot(t: float, freq: float = 2.0, speed: float = 1.6) -> tuple[dict, float]:
    """Trot: diagonal legs (front-left with rear-right) in phase, ±28° swing, lower legs fold
    during swing; head bobs, tail wags."""
    ph = 2 * np.pi * freq * t
    p = {"neck_elev": 35 + 3 * np.sin(2 * ph), "head_pitch": -35.0, "tail_elev": 25.0,
         "tail_yaw": 25 * np.sin(ph), "tail_curl": 10 * np.sin(ph - 0.5),
         "body_pitch": 1.5 * np.sin(2 * ph)}
    for leg, off in (("fl", 0.0), ("rr", 0.0), ("fr", np.pi), ("rl", np.pi)):
        q = ph + off
        front = leg.startswith("f")
        lift = ((1 + np.cos(q)) / 2) ** 2
        p[f"swing_{leg}"] = 28 * np.sin(q) + (5 if front else -8)
        p[f"bend_{leg}"] = (8 + 55 * lift) if front else -(12 + 45 * lift)
        p[f"abd_{leg}"] = 3.0
        p[f"paw_{leg}"] = 10 * np.sin(q)
    return p, speed * t


def dog_walk(t: float) -> tuple[dict, float]:
    p, _ = dog_trot(t, freq=1.1)
    return p, 0.8 * t


# =============================================================================== spider
_SPIDER_ANGLES = (32.0, 65.0, 98.0, 130.0)   # leg yaw from forward, legs 1..4 (front → back)


def spider(pose: dict, thickness: float = 1.0) -> Body:
    """Spider (a large toy one, leg span ~0.6 m): cephalothorax and abdomen ellipsoids, eight
    legs of three segments (femur 0.11 up-out, tibia 0.11, metatarsus 0.10 down to the floor).

    Legs 1–4 are the left legs front to back, legs 5–8 the right legs front to back.
    """
    p = {"abd_pitch": 0.0, "abd_yaw": 0.0, **pose}
    T = float(thickness)
    b = _B("spider", 0.008)
    C = _v(0, 0, 0)
    b.link("ceph", None, C)
    b.ell("ceph", C, np.eye(3), [0.055, 0.045, 0.028 * T])
    ped = C + _v(-0.06, 0, 0.005)
    Ra = rz(p["abd_yaw"]) @ ry(-p["abd_pitch"])
    semi = _v(0.085, 0.045, 0.04 * T)
    ac = ped + Ra @ _v(-0.095, 0, 0.012)
    atip = ac + Ra @ _v(-(semi[0] - 0.5 * (semi[1] + semi[2])), 0, 0)
    b.link("abdomen", "ceph", ped)
    b.ell("abdomen", ac, Ra, semi)
    b.cone("abdomen", C + _v(-0.045, 0, 0.004), ac + Ra @ _v(0.06, 0, 0), 0.016 * T)   # pedicel
    J = b.joints
    J.update({"cephalothorax": C, "pedicel": ped, "abdomen_tip": atip})
    for i in range(8):
        sg = 1.0 if i < 4 else -1.0
        k = i % 4
        yaw = sg * (_SPIDER_ANGLES[k] + p.get(f"yaw_{i + 1}", 0.0))
        Ry = rz(yaw)
        coxa = C + Ry @ _v(0.05, 0, 0.0)
        R1 = Ry @ ry(-p.get(f"femur_{i + 1}", 40.0))
        knee = coxa + R1 @ _v(0.11, 0, 0)
        R2 = R1 @ ry(p.get(f"tibia_{i + 1}", 75.0))
        ank = knee + R2 @ _v(0.11, 0, 0)
        R3 = R2 @ ry(p.get(f"meta_{i + 1}", 30.0))
        tip = ank + R3 @ _v(0.10, 0, 0)
        n = f"leg{i + 1}"
        b.link(f"{n}a", "ceph", coxa)
        b.cone(f"{n}a", coxa, knee, 0.014 * T, 0.012 * T)
        b.link(f"{n}b", f"{n}a", knee)
        b.cone(f"{n}b", knee, ank, 0.012 * T, 0.010 * T)
        b.link(f"{n}c", f"{n}b", ank)
        b.cone(f"{n}c", ank, tip, 0.010 * T, 0.008 * T)
        J.update({f"{n}_coxa": coxa, f"{n}_knee": knee, f"{n}_ankle": ank, f"{n}_tip": tip})
        b.part(f"leg_{i + 1}", tip, ank, tip)
    b.part("cephalothorax", C, C + _v(0.03, 0, 0), C - _v(0.06, 0, 0))
    b.part("abdomen", atip, ac, atip + Ra @ _v(-0.5 * (semi[1] + semi[2]), 0, 0))
    return b.body()


def spider_random(rng) -> dict:
    p = {"abd_pitch": _u(rng, -15, 35), "abd_yaw": _u(rng, -20, 20)}
    for i in range(1, 9):
        p.update({f"yaw_{i}": _u(rng, -8, 8), f"femur_{i}": _u(rng, 15, 70),
                  f"tibia_{i}": _u(rng, 40, 110), f"meta_{i}": _u(rng, 0, 50)})
    return p


def spider_walk(t: float, freq: float = 1.5, speed: float = 0.25) -> tuple[dict, float]:
    """Alternating tetrapod gait: legs L1, R2, L3, R4 swing together, the others in antiphase."""
    ph = 2 * np.pi * freq * t
    p = {"abd_pitch": 8 + 2 * np.sin(2 * ph), "abd_yaw": 3 * np.sin(ph)}
    for i in range(8):
        side = 0 if i < 4 else 1
        q = ph + np.pi * ((i % 2 + side) % 2)
        lift = ((1 + np.cos(q)) / 2) ** 2
        sg = 1.0 if i < 4 else -1.0
        p[f"yaw_{i + 1}"] = -sg * 7 * np.sin(q)
        p[f"femur_{i + 1}"] = 38 + 14 * lift
        p[f"tibia_{i + 1}"] = 75 - 8 * lift
        p[f"meta_{i + 1}"] = 30.0
    return p, speed * t


BUILD = {"human": human, "hand": hand, "dog": dog, "spider": spider}
RANDOM = {"human": human_random, "hand": hand_random, "dog": dog_random, "spider": spider_random}
GAIT = {("human", "walk"): human_walk, ("dog", "trot"): dog_trot, ("dog", "walk"): dog_walk,
        ("spider", "walk"): spider_walk, ("hand", "grasp"): hand_grasp}
