"""Synthetic captures with exact silhouettes and ground truth (``topopose synth``).

The test data of every stage and of ``topopose demo``: no download anywhere. A subject
(:mod:`.synth_subjects`: human, hand, dog, spider; :mod:`.synth_body`: body, the MakeHuman mesh
posed by skinning, rasterized exactly) is posed — random plausible poses per frame, a
continuous motion through random poses (``random-smooth``), or a smooth gait (``walk``, ``trot``,
``grasp``) — placed in the capture volume, and seen by a ring
of calibrated cameras. Silhouettes are exact images of the union of round cones and ellipsoids,
lens distortion included (:mod:`.synth_geometry`). Optional silhouette noise (levels 1–3: border
erosion/dilation, false blobs, holes) and a thickness factor (thick coat; a dress above 1.3)
reproduce the difficulties of real silhouettes discussed in the thesis (Raynal, ch. 9–10, the
quality of the visual hull and its effect on the skeleton).

The folder written by :func:`synthesize` is a capture folder exactly as DESIGN.md says, plus
``gt.json`` (format in ``notes/contracts.md``). Per frame, ``gt.json`` holds:

* ``parts``: the model parts. Extremities (head, hands, feet, fingertips, paws, tail tip, leg
  tips, abdomen tip) are the far end of the last bone's *axis* — the limb's extremity minus about
  one radius, where a curve-skeleton branch ends (human head: 4 cm below the top of the head,
  on its vertical axis). Junctions: human torso = neck base (shoulder centre), crotch = hip
  centre; hand palm = midpoint of wrist and middle knuckle, arm = where the forearm axis leaves
  the capture volume; dog shoulders / hips = front / rear spine points where the legs attach;
  spider cephalothorax = its centre.
* ``segments``: for extremities the last bone (wrist → hand end, ankle → toe, last phalanx...),
  for junctions a piece of the body axis through the part (torso: neck base → mid-chest, crotch:
  ±15 cm along the spine, shoulders/hips: 6 cm outwards and 15 cm inwards along the body).
  Every part lies on its segment.
* ``joints``: anatomical joints (bone end points; end points equal the parts).
* ``separated``: no two limbs that do not share a joint come closer than the subject's margin
  (human, dog 2 cm; spider 8 mm; hand 4 mm); near a shared joint adjacent limbs are allowed to
  touch (:meth:`.synth_subjects.Body.clearances`). ``gap`` is the smallest such clearance (m).
  With ``margin=`` (the limbs of ``separated`` poses at least that far apart, e.g. 3 voxels of
  the working grid), ``separated`` tests distinct limbs against it and ``limb_gap`` is their
  smallest clearance; ``synth.limb_margin`` records it.

``gt["synth"]`` records the generator's arguments (``random-smooth``: also ``keyframes``, the
keyframes' frame indices).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry.camera import Camera
from topopose.capture.capture import Capture
from topopose.synth.geometry import ray_table, render
from topopose.synth.body import (TOUCHING, MeshBody, body_balance, body_family, body_random,
                                 body_touching, make_build, pose_body)
from topopose.synth.subjects import (BUILD, GAIT, HUMAN_DEFAULT, MOTIONS, PARTS, RANDOM, SUBJECTS,
                             human_walk, rz, ry)

# the body subject (:mod:`.synth_body`) poses the MakeHuman mesh with the capsule human's angles;
# its build (proportions) is chosen per capture, see synthetic_capture
RANDOM["body"] = body_random
GAIT[("body", "walk")] = human_walk

# default capture volume (min, max) and placement margin per subject (metres)
VOLUMES = {
    "human": ((-1.25, -1.25, -0.05), (1.25, 1.25, 2.30), 0.06),
    "dog": ((-0.90, -0.90, -0.04), (0.90, 0.90, 1.10), 0.05),
    "spider": ((-0.45, -0.45, -0.02), (0.45, 0.45, 0.35), 0.02),
    "hand": ((-0.15, -0.15, 0.85), (0.15, 0.15, 1.15), 0.012),
    "body": ((-1.25, -1.25, -0.05), (1.25, 1.25, 2.45), 0.06),   # up to 2.0 m, arms raised
}
_MAX_TRIES = 400
# flat subjects are seen from above (a ring at the subject's height sees a spider edge-on; a
# hand, palm down at the cameras' height, is seen edge-on too: its visual hull was a blob with
# fused fingers, its skeleton a web with no finger ends — hand captures look down at the hand)
ELEVATION = {"spider": 35.0, "hand": 40.0}


# ----------------------------------------------------------------------------- cameras
def camera_ring(volume, count=8, size=(640, 480), rng=None, distort=True, elevation=None,
                layout="ring"):
    """A ring of ``count`` cameras around ``volume`` looking at its centre.

    Radius twice the half-diagonal of the volume's footprint (at least 0.8), heights alternating
    around 30 % above the volume's centre (a 1.75 m human: cameras at 1.5–2.2 m), focal length
    chosen so the whole volume fits in the image (also after distortion). Every other camera
    gets a small lens distortion (k1, k2, p1, p2), which the silhouettes honour. ``elevation``
    (degrees): cameras look down from about that angle instead (flat subjects: the spider).
    ``layout="pairs"``: the azimuths are not even but two pairs facing each other, as phones
    set up around a person in a room (the Pose2Sim balancing recording: cameras at 12°, −38°,
    135°, −154° around the subject: pairs 50° and 71° apart, each nearly opposite one of the
    other pair, so that opposite views see nearly the same outline and the hull keeps more
    phantom volume than with four cameras 90° apart): within a pair 40–80° apart, the second
    pair 160–200° further round; heights, radius and aim as the ring's (4 cameras only).
    """
    rng = np.random.default_rng(0) if rng is None else rng
    lo, hi = (np.asarray(v, float) for v in volume)
    centre = (lo + hi) / 2
    ext = hi - lo
    radius = max(2.0 * 0.5 * float(np.hypot(ext[0], ext[1])), 0.8)
    w, h = int(size[0]), int(size[1])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    az0 = rng.uniform(0, 2 * np.pi)
    if layout == "pairs":
        if count != 4:
            raise InputError(f"synth: camera layout 'pairs' needs 4 cameras (got {count})")
        g1, g2, opp = rng.uniform(40, 80), rng.uniform(40, 80), rng.uniform(160, 200)
        steps = np.radians([0.0, g1, opp, opp + g2])
    elif layout == "ring":
        steps = 2 * np.pi * np.arange(count) / count
    else:
        raise InputError(f"synth: camera layout must be 'ring' or 'pairs' (got {layout!r})")
    cams = []
    for i in range(count):
        az = az0 + steps[i] + np.radians(rng.uniform(-5, 5))
        jitter = rng.uniform(-0.04, 0.04)
        if elevation is None:
            zc = centre[2] + ext[2] * (0.3 + (0.15 if i % 2 == 0 else -0.12) + jitter)
        else:                   # look down at a flat subject from about ``elevation`` degrees
            el = elevation + (8.0 if i % 2 == 0 else -8.0) + 100 * jitter
            zc = centre[2] + radius * np.tan(np.radians(el))
        C = np.array([centre[0] + radius * np.cos(az), centre[1] + radius * np.sin(az), zc])
        target = centre + rng.uniform(-0.03, 0.03, 3) * ext
        f = target - C
        f /= np.linalg.norm(f)
        right = np.cross(f, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(f, right)
        R = np.stack([right, down, f])
        roll = np.radians(rng.uniform(-2, 2))
        Rroll = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0], [0, 0, 1]])
        R = Rroll @ R
        t = -R @ C
        xc = corners @ R.T + t
        xn = xc[:, :2] / xc[:, 2:3]
        cx = w / 2 - 0.5 + rng.uniform(-4, 4)
        cy = h / 2 - 0.5 + rng.uniform(-4, 4)
        foc = 0.92 * min((min(cx, w - 1 - cx)) / np.max(np.abs(xn[:, 0])),
                         (min(cy, h - 1 - cy)) / np.max(np.abs(xn[:, 1])))
        if distort and i % 2 == 1:
            dist = np.array([rng.uniform(-0.09, 0.04), rng.uniform(-0.02, 0.02),
                             rng.uniform(-8e-4, 8e-4), rng.uniform(-8e-4, 8e-4)])
        else:
            dist = np.zeros(4)
        rvec = cv2.Rodrigues(R)[0].ravel()
        for _ in range(40):
            K = np.array([[foc, 0, cx], [0, foc, cy], [0, 0, 1.0]])
            cam = Camera(f"cam_{i + 1:02d}", (w, h), K, dist, rvec, t)
            px = cam.project(corners)
            if np.all(px[:, 0] >= 2) and np.all(px[:, 0] <= w - 3) and np.all(px[:, 1] >= 2) \
                    and np.all(px[:, 1] <= h - 3):
                break
            foc *= 0.95
        cams.append(cam)
    return cams


# ----------------------------------------------------------------------------- noise
def add_noise(mask, level, rng):
    """Silhouette noise of ``level`` 0–3 (0: none).

    The random draws do not depend on ``level`` (the same generator state gives nested noise), so
    a higher level perturbs the mask more: border dilation by up to ``level`` pixels or erosion
    by up to ``level / 2`` (thin limbs of a distant subject are a few pixels wide),
    ``2·level`` false blobs (discs of radius 2–4+level px) in about half of the cameras, and
    ``2·level`` holes (discs of radius 1+level px) inside the silhouette.
    """
    sign = 1 if rng.random() < 0.5 else -1
    mag = rng.uniform(0.6, 1.0)
    blobs_here = rng.random() < 0.5
    h, w = mask.shape
    blob_xy = rng.uniform([0, 0], [w, h], size=(6, 2))
    blob_r = rng.uniform(2, 4, size=6)
    ys, xs = np.nonzero(mask)
    hole_pick = rng.integers(0, max(len(ys), 1), size=6)
    if level <= 0:
        return mask.copy()
    m = mask.astype(np.uint8) * 255
    k = int(round(level * mag * (1.0 if sign > 0 else 0.5)))
    if k > 0:
        ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
        m = cv2.dilate(m, ker) if sign > 0 else cv2.erode(m, ker)
    n = 2 * int(level)
    if blobs_here:
        for (x, y), r in zip(blob_xy[:n], blob_r[:n]):
            cv2.circle(m, (int(x), int(y)), int(round(r + level)), 255, -1)
    if len(ys):
        for i in hole_pick[:n]:
            cv2.circle(m, (int(xs[i]), int(ys[i])), int(level) + 1, 0, -1)
    return m > 127


# ----------------------------------------------------------------------------- placement
def _check_args(subject, frames, cameras, size, noise, motion, thickness, fps, separated):
    if subject not in SUBJECTS:
        raise InputError(f"synth: --subject {subject!r} must be one of {', '.join(SUBJECTS)}")
    if motion != "random" and motion not in MOTIONS[subject]:
        ok = ", ".join(("random",) + MOTIONS[subject])
        raise InputError(f"synth: --motion {motion!r} does not apply to subject {subject!r} "
                         f"(expected one of {ok})")
    if separated and motion != "random":
        raise InputError(f"synth: --separated applies to random poses only (got --motion {motion})")
    if separated and subject == "human" and float(thickness) > 1.3:
        raise InputError("synth: --separated is impossible with --thickness > 1.3 "
                         "(the human wears a dress that joins the legs)")
    if int(frames) < 1:
        raise InputError(f"synth: --frames must be ≥ 1 (got {frames})")
    if int(cameras) < 1:
        raise InputError(f"synth: --cameras must be ≥ 1 (got {cameras})")
    if len(size) != 2 or min(int(size[0]), int(size[1])) < 16:
        raise InputError(f"synth: --size must be WxH with both ≥ 16 (got {size})")
    if int(noise) not in (0, 1, 2, 3):
        raise InputError(f"synth: --noise must be 0, 1, 2 or 3 (got {noise})")
    if not 0.5 <= float(thickness) <= 2.5:
        raise InputError(f"synth: --thickness must be within [0.5, 2.5] (got {thickness})")
    if not float(fps) > 0:
        raise InputError(f"synth: fps must be > 0 (got {fps})")


def _orientation(subject, rng):
    yaw = rng.uniform(0, 360)
    if subject == "hand":      # forearm axis tilted up to ±25° from horizontal
        return rz(yaw) @ ry(rng.uniform(-25, 25))
    return rz(yaw)


def _grounded(body, subject):
    """Translate the body so that its lowest point touches the floor z = 0 (not the hand)."""
    if subject == "hand":
        return body
    lo, _ = body.extent()
    return body.transformed(np.eye(3), np.array([0.0, 0.0, -lo[2]]))


def _fit_offset(lo, hi, vlo, vhi, margin, rng, axes):
    """Random offset putting the box [lo, hi] inside [vlo + margin, vhi - margin] along ``axes``;
    along the other (vertical) axis the box is not moved and must already fit: from the floor
    ``vlo`` up to ``vhi - margin`` (None when it does not fit)."""
    off = np.zeros(3)
    for a in set(range(3)) - set(axes):
        if lo[a] < vlo[a] or hi[a] > vhi[a] - margin:
            return None
    for a in axes:
        a0 = vlo[a] + margin - lo[a]
        a1 = vhi[a] - margin - hi[a]
        if a0 > a1:
            return None
        off[a] = rng.uniform(a0, a1)
    return off


def _set_arm_part(body, vlo, vhi):
    """Hand: the "arm" part is where the forearm axis (wrist → elbow) leaves the volume."""
    W = body.joints["wrist"]
    d = body.extra["arm_dir"]
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (vhi - W) / d, np.where(d < 0, (vlo - W) / d, np.inf))
    te = float(np.min(t))
    X = W + te * d
    body.parts["arm"] = X
    body.segments["arm"] = np.stack([W, X])
    body.joints["arm_border"] = X
    return body


def _random_frames(subject, n, rng, thickness, separated, vlo, vhi, margin, limb_margin=None,
                   build=None, lean=0.0, pose="any"):
    build, sample = build or BUILD[subject], RANDOM[subject]
    if lean and subject == "body":
        sample = body_balance
    elif pose != "any":
        sample = lambda r: body_family(r, pose)  # noqa: E731
    axes = (0, 1, 2) if subject == "hand" else (0, 1)
    skip = ("forearm",) if subject == "hand" else ()
    bodies = []
    for f in range(n):
        for _ in range(_MAX_TRIES):
            body = build(sample(rng), thickness)
            body.limb_margin = limb_margin
            if separated and not body.separated():
                continue
            R = _orientation(subject, rng)
            if lean:            # tilted about a random horizontal axis by lean/3 … lean degrees
                R = rz(rng.uniform(0, 360)) @ ry(rng.uniform(lean / 3, lean)) @ R
            if pose == "lying":  # laid down: on the back, a side or the front, head any way
                R = rz(rng.uniform(0, 360)) @ ry(rng.uniform(80, 100)) @ rz(rng.uniform(0, 360))
            body = _grounded(body.transformed(R, np.zeros(3)), subject)
            lo, hi = body.extent(skip=skip)
            off = _fit_offset(lo, hi, vlo, vhi, margin, rng, axes)
            if off is None:
                continue
            bodies.append(body.transformed(np.eye(3), off))
            break
        else:
            raise InputError(f"synth: could not sample a {'separated ' if separated else ''}{subject} "
                             f"pose fitting the volume in {_MAX_TRIES} tries (thickness {thickness})")
    return bodies


def _motion_frames(subject, motion, n, fps, rng, thickness, vlo, vhi, margin, build=None):
    gait = GAIT[(subject, motion)]
    build = build or BUILD[subject]
    R = _orientation(subject, rng)
    heading = R @ np.array([1.0, 0.0, 0.0])
    heading[2] = 0.0
    t0 = rng.uniform(0, 2.0)                    # random gait phase
    raw = []
    for f in range(n):
        pose, dist = gait(t0 + f / fps)
        raw.append((build(pose, thickness), dist))
    d0 = raw[0][1]
    dmid = 0.5 * (raw[0][1] + raw[-1][1]) - d0
    bodies = []
    for body, dist in raw:
        b = body.transformed(R, heading * (dist - d0 - dmid))
        bodies.append(_grounded(b, subject))
    skip = ("forearm",) if subject == "hand" else ()
    ext = np.array([b.extent(skip=skip) for b in bodies])
    lo, hi = ext[:, 0].min(0), ext[:, 1].max(0)
    axes = (0, 1, 2) if subject == "hand" else (0, 1)
    off = _fit_offset(lo, hi, vlo, vhi, margin, rng, axes)
    if off is None:                      # the path is longer (or the gait taller) than the volume:
        off = np.zeros(3)                # grow the volume (written to capture.toml) to hold it all
        for a in axes:
            off[a] = (vlo[a] + vhi[a]) / 2 - (lo[a] + hi[a]) / 2
        vlo = np.minimum(vlo, lo + off - margin)
        vhi = np.maximum(vhi, hi + off + margin)
    return [b.transformed(np.eye(3), off) for b in bodies], vlo, vhi


# ``random-smooth`` (:func:`_smooth_frames`): a keyframe every KEY_INTERVAL seconds (drawn per
# interval), the root moved by at most KEY_DRIFT m per horizontal axis and the heading turned by
# at most KEY_TURN degrees from one keyframe to the next; the keyframe poses are the successive
# draws of the subject's random poses from np.random.default_rng([seed, POSE_STREAM])
SMOOTH = "random-smooth"
KEY_INTERVAL = (0.8, 1.5)
KEY_DRIFT = 0.4
KEY_TURN = 90.0
POSE_STREAM = 11


def min_jerk(u):
    """Minimum-jerk easing ``10u³ − 15u⁴ + 6u⁵`` of ``u`` in [0, 1]: from 0 to 1 with zero
    velocity and acceleration at both ends, so a motion eased from keyframe to keyframe has
    continuous velocities (zero at the keyframes); its largest slope is 1.875, at u = ½."""
    u = np.asarray(u, float)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u ** 2)


def smooth_keyframes(n, fps, rng) -> list[int]:
    """Keyframe frame indices of a ``random-smooth`` sequence of ``n`` frames: 0, then steps of
    ``round(uniform(KEY_INTERVAL) × fps)`` frames (at least 2) until the last frame is reached
    (the last keyframe may lie beyond it)."""
    keys = [0]
    while keys[-1] < n - 1:
        keys.append(keys[-1] + max(2, int(round(rng.uniform(*KEY_INTERVAL) * fps))))
    return keys


def ease_keyframes(values, keys, n) -> np.ndarray:
    """Values (K, ...) given at the keyframes ``keys`` → per frame 0 … n-1, eased from keyframe
    to keyframe by :func:`min_jerk` (a keyframe's frame gets its value exactly)."""
    values = np.asarray(values, float)
    out = np.empty((n,) + values.shape[1:])
    for k in range(len(keys) - 1):
        a, b = keys[k], keys[k + 1]
        f = np.arange(a, min(b, n))
        s = min_jerk((f - a) / (b - a)).reshape((-1,) + (1,) * (values.ndim - 1))
        out[f] = values[k] + (values[k + 1] - values[k]) * s
    if keys[-1] <= n - 1:
        out[keys[-1]] = values[-1]
    return out


def _smooth_frames(subject, n, fps, rng, seed, thickness, vlo, vhi, margin, build=None,
                   sample=None):
    """A continuous motion through random poses (``motion="random-smooth"``, human and body):
    keyframe poses drawn as ``random`` draws them, joint angles, heading and root position
    eased between keyframes (:func:`min_jerk`), the body grounded in every frame. Each
    keyframe's root position is drawn (a drift of at most KEY_DRIFT from the previous one)
    inside every adjacent frame's feasible box (the positions keeping that frame's posed body
    inside the volume): between two keyframes the root moves on a segment, so every frame
    fits. A pose too wide or too tall for the volume grows it (written to capture.toml), as
    the walk does. ``sample`` draws the keyframe poses (default: the subject's random poses)."""
    build, sample = build or BUILD[subject], sample or RANDOM[subject]
    keys = smooth_keyframes(n, fps, rng)
    prng = np.random.default_rng([int(seed), POSE_STREAM])
    kposes = [{**HUMAN_DEFAULT, **sample(prng)} for _ in keys]
    names = sorted(kposes[0])
    angles = ease_keyframes([[p[a] for a in names] for p in kposes], keys, n)
    yaw = [rng.uniform(0, 360)]
    for _ in keys[1:]:
        yaw.append(yaw[-1] + rng.uniform(-KEY_TURN, KEY_TURN))
    yaws = ease_keyframes(yaw, keys, n)
    bodies, boxes = [], []
    for f in range(n):
        pose = {a: float(x) for a, x in zip(names, angles[f])}
        body = _grounded(build(pose, thickness).transformed(rz(yaws[f]), np.zeros(3)), subject)
        lo, hi = body.extent()
        bodies.append(body)
        boxes.append((vlo[:2] + margin - lo[:2], vhi[:2] - margin - hi[:2]))
    pos = []
    for k, key in enumerate(keys):
        near = range(keys[max(k - 1, 0)], min(keys[min(k + 1, len(keys) - 1)], n - 1) + 1)
        blo = np.max([boxes[f][0] for f in near], axis=0)
        bhi = np.min([boxes[f][1] for f in near], axis=0)
        bhi = np.where(blo > bhi, (blo + bhi) / 2, bhi)      # too wide: the middle (grown below)
        blo = np.minimum(blo, bhi)
        if not pos:
            pos.append(rng.uniform(blo, bhi))
        else:
            pos.append(np.clip(pos[-1] + rng.uniform(-KEY_DRIFT, KEY_DRIFT, 2), blo, bhi))
    xy = ease_keyframes(pos, keys, n)
    bodies = [b.transformed(np.eye(3), [x, y, 0.0]) for b, (x, y) in zip(bodies, xy)]
    ext = np.array([b.extent() for b in bodies])
    lo, hi = ext[:, 0].min(0), ext[:, 1].max(0)
    vlo, vhi = vlo.copy(), np.maximum(vhi, hi + margin)      # grounded: the floor stays
    vlo[:2] = np.minimum(vlo[:2], lo[:2] - margin)
    return bodies, vlo, vhi, keys


def subject_height(subject, thickness=1.0) -> float:
    """The normalizing height of gt.json: human standing height, others their largest extent
    (body: the height of its ``average`` build; a body capture records its own build's height)."""
    if subject == "body":
        from topopose.synth.body import BUILDS
        return float(BUILDS["average"]["height"])
    body = BUILD[subject]({}, 1.0)
    if subject == "hand":
        lo, hi = body.extent(skip=("forearm",))
        return float(np.max(hi - lo))
    lo, hi = body.extent()
    if subject == "human":
        return float(hi[2] - lo[2])
    return float(np.max(hi - lo))


# ----------------------------------------------------------------------------- main entry points
def _l(x):
    return [round(float(v), 6) for v in np.asarray(x).ravel()]


def synthetic_capture(subject="human", frames=10, seed=0, cameras=8, size=(640, 480), noise=0,
                      motion="random", thickness=1.0, separated=False, fps=25, *,
                      margin=None, build=None, layout="ring", lean=0.0, pose="any") -> Capture:
    """Synthetic capture in memory (``masks`` set, ``options["gt"]`` = the gt.json dict,
    ``options["bodies"]`` = the posed :class:`.synth_subjects.Body` of each frame, ``path`` None).

    Parameters
    ----------
    subject : "human" | "hand" | "dog" | "spider" | "body"
        ``body``: the anatomically real MakeHuman mesh posed by skinning (:mod:`.synth_body`).
    frames : int
    seed : int
        Same seed, same capture (poses, placement, cameras, noise).
    cameras : int
        Number of cameras of the ring.
    size : (w, h)
    noise : 0..3
        Silhouette noise level (:func:`add_noise`).
    motion : "random" | "random-smooth" | "walk" | "trot" | "grasp"
        ``random``: independent random plausible poses per frame, random placement and yaw
        (unrelated frames: no identity over time).
        ``random-smooth`` (human, body): a continuous motion through random poses, as a subject
        moves in a real capture: keyframes every 0.8–1.5 s (:func:`smooth_keyframes`; frame
        indices in ``gt["synth"]["keyframes"]``) whose poses are the successive draws of the
        random poses from ``np.random.default_rng([seed, 11])``; joint angles, heading (turning
        by at most 90° from keyframe to keyframe) and root position (drifting by at most
        0.4 m per axis) eased between keyframes by :func:`min_jerk` (continuous velocities),
        every frame inside the volume (:func:`_smooth_frames`).
        ``hang``, ``hips``, ``fold``, ``jump``, ``crouch`` (body): the same continuous motion
        through keyframes whose limbs touch the body (:data:`.synth_body.TOUCHING`: arms
        hanging, hands on the hips, arms folded, feet together bending and stretching as
        before a jump — grounded, never in the air — and crouching), one in three free.
        ``walk`` (human, dog, spider), ``trot`` (dog), ``grasp`` (hand): smooth gait at ``fps``,
        moving through the volume (except the hand).
    thickness : float
        Limb radius factor (coat); > 1.3 gives the human a dress joining the legs.
    separated : bool
        Random poses only: rejection-sample poses whose non-adjacent limbs keep clear of each
        other by the subject's margin (human 2 cm).
    fps : float
    margin : float, optional
        Clearance (m) that ``separated`` demands between distinct limbs (links that are not
        parent/child or grandparent/grandchild; :meth:`.synth_subjects.Body.required_margin`),
        instead of the subject's anatomical margin. The thesis' "limbs separated" (§13.2.2.1)
        means separated *in the visual hull at the working resolution*: a 2 cm clearance is one
        voxel at 100³ for a human, and touching hull voxels merge the limbs (and a hull is
        larger than the body), so quality studies ask for a few voxels, e.g. ``3 × voxel size``
        (``benchmarks/quality.py``). Recorded in gt.json (``synth.limb_margin``; per frame
        ``limb_gap``, the smallest such clearance).
    build : str or dict, optional
        ``body`` only: its proportions, a preset (``average``, ``heavy``, ``child``, ``lean``),
        ``random`` (the default: height 1.1–2.0 m, lengths and girths drawn from the seed) or a
        dict of :data:`.synth_body.BUILDS` keys. ``thickness`` multiplies its girths. Recorded
        in ``gt["synth"]["build"]``; per frame ``pose`` and ``placement`` re-pose the exact
        mesh (:func:`.synth_body.body_mesh`).
    layout : "ring" | "pairs"
        Camera azimuths (:func:`camera_ring`): even, or two facing pairs as phones in a room.
    lean : float
        Random poses only: each pose tilted about a random horizontal axis by ``lean``/3 …
        ``lean`` degrees, then grounded (a leaning, balancing subject); the ``body`` then
        stands on one leg with the other lifted sideways (:func:`.synth_body.body_balance`).
        0 (default): upright.
    pose : str
        ``body`` random poses only: a pose family of :data:`.synth_body.POSE_FAMILIES`
        (:func:`.synth_body.body_family`; ``lying``: laid on the floor); ``any`` (default).
    """
    _check_args(subject, frames, cameras, size, noise, motion, thickness, fps, separated)
    if pose != "any" and (subject != "body" or motion != "random"):
        raise InputError(f"synth: --pose applies to the body's random poses only (got --subject "
                         f"{subject} --motion {motion})")
    rng = np.random.default_rng(seed)
    if margin is not None and not float(margin) >= 0:
        raise InputError(f"synth: margin must be a clearance ≥ 0 in metres (got {margin})")
    limb_margin = None if margin is None else float(margin)
    if build is not None and subject != "body":
        raise InputError(f"synth: --build applies to the body subject only (got --subject {subject})")
    vlo, vhi, place = (np.array(v, float) if i < 2 else v for i, v in enumerate(VOLUMES[subject]))
    make = None
    if subject == "body":
        props = make_build(build, rng, thickness)
        make = lambda pose, _thickness: pose_body(pose, props)  # noqa: E731
    keys = None
    if motion == "random":
        bodies = _random_frames(subject, int(frames), rng, thickness, separated, vlo, vhi, place,
                                limb_margin, build=make, lean=float(lean), pose=pose)
    elif motion == SMOOTH or motion in TOUCHING:
        bodies, vlo, vhi, keys = _smooth_frames(
            subject, int(frames), float(fps), rng, seed, thickness, vlo, vhi, place, build=make,
            sample=body_touching(motion) if motion in TOUCHING else None)
    else:
        bodies, vlo, vhi = _motion_frames(subject, motion, int(frames), float(fps), rng, thickness,
                                          vlo, vhi, place, build=make)
    if subject == "hand":
        bodies = [_set_arm_part(b, vlo, vhi) for b in bodies]
    cams = camera_ring((vlo, vhi), int(cameras), (int(size[0]), int(size[1])), rng,
                       elevation=ELEVATION.get(subject), layout=layout)
    tables = [ray_table(c) for c in cams]
    names = [f"{i:06d}" for i in range(int(frames))]
    masks, gframes = {}, {}
    for fi, (name, body) in enumerate(zip(names, bodies)):
        ms = []
        for ci, (cam, tab) in enumerate(zip(cams, tables)):
            m = body.render(cam, tab) if isinstance(body, MeshBody) else render(cam, tab, body.prims)
            if noise:
                m = add_noise(m, int(noise), np.random.default_rng([int(seed), 7, fi, ci]))
            ms.append(m)
        masks[name] = ms
        gap = body.min_gap()
        gframes[name] = {
            "parts": {k: _l(body.parts[k]) for k in PARTS[subject]},
            "segments": {k: [_l(body.segments[k][0]), _l(body.segments[k][1])] for k in PARTS[subject]},
            "joints": {k: _l(v) for k, v in body.joints.items()},
            "separated": bool(body.separated()),
            "gap": round(float(gap), 6),
        }
        if body.limb_margin is not None:
            gframes[name]["limb_gap"] = round(float(body.limb_gap()), 6)
        if isinstance(body, MeshBody):         # full precision: re-posing gives the exact mesh
            gframes[name]["pose"] = {k: float(v) for k, v in body.pose.items()}
            gframes[name]["placement"] = {"R": body.R.tolist(), "t": body.t.tolist()}
    height = bodies[0].height if subject == "body" else subject_height(subject, thickness)
    gt = {"subject": subject, "units": "m", "up": "+z",
          "height": round(height, 6),
          "parts": list(PARTS[subject]), "frames": gframes,
          "synth": {"seed": int(seed), "motion": motion, "noise": int(noise),
                    "thickness": float(thickness), "separated": bool(separated), "fps": float(fps),
                    "margin": float(bodies[0].margin),
                    "limb_margin": None if bodies[0].limb_margin is None
                    else float(bodies[0].limb_margin)}}
    if subject == "body":
        gt["synth"]["build"] = bodies[0].build
    if keys is not None:
        gt["synth"]["keyframes"] = [int(k) for k in keys]
    if lean:
        gt["synth"]["lean"] = float(lean)
    if pose != "any":
        gt["synth"]["pose"] = pose
    if layout != "ring":
        gt["synth"]["layout"] = layout
    cap = Capture(cams, names, None, "+z", "m", float(fps), (vlo.copy(), vhi.copy()),
                  {"gt": gt, "bodies": bodies}, masks)
    return cap


def synthesize(out, subject="human", frames=10, seed=0, cameras=8, size=(640, 480), noise=0,
               motion="random", thickness=1.0, separated=False, fps=25, *, margin=None,
               build=None, pose="any") -> Path:
    """Write a synthetic capture folder (DESIGN.md layout + gt.json) and return its path.

    Arguments as :func:`synthetic_capture`.
    """
    cap = synthetic_capture(subject, frames, seed, cameras, size, noise, motion, thickness,
                            separated, fps, margin=margin, build=build, pose=pose)
    return write_capture(cap, out)


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def _toml(d, prefix=""):
    """Compact TOML (one line per key, Pose2Sim style) of nested dicts of numbers/strings/lists."""
    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")
    out = ""
    if prefix and lines:
        out += f"[{prefix}]\n"
    out += "".join(x + "\n" for x in lines)
    for k, v in tables:
        if out:
            out += "\n"
        out += _toml(v, f"{prefix}.{k}" if prefix else k)
    return out


def write_capture(cap: Capture, out) -> Path:
    """Write an in-memory capture (masks set) as a capture folder; a capture already there is
    replaced (its frame folders deleted first, so no stale frame stays beside the new
    calibration; ``topopose synth`` asks for ``--force`` before that)."""
    import shutil

    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        for sub in ("silhouettes", "images", "backgrounds"):
            if (out / sub).is_dir():
                shutil.rmtree(out / sub)
        (out / "gt.json").unlink(missing_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the output folder ({exc})") from None
    calib = {}
    for c in cap.cameras:
        calib[c.name] = {"name": c.name, "size": [int(c.size[0]), int(c.size[1])],
                         "matrix": [[float(v) for v in row] for row in c.matrix],
                         "distortions": [float(v) for v in c.distortions],
                         "rotation": [float(v) for v in c.rotation],
                         "translation": [float(v) for v in c.translation],
                         "fisheye": bool(c.fisheye)}
    calib["metadata"] = {"adjusted": False, "error": 0.0, "generator": "topopose synth"}
    (out / "calibration.toml").write_text(_toml(calib))
    capt = {"capture": {"up": cap.up, "units": cap.units, "fps": float(cap.fps or 25)}}
    if cap.volume is not None:
        capt["capture"]["volume"] = {"min": [float(v) for v in cap.volume[0]],
                                     "max": [float(v) for v in cap.volume[1]]}
    (out / "capture.toml").write_text(_toml(capt))
    for ci, c in enumerate(cap.cameras):
        d = out / "silhouettes" / c.name
        d.mkdir(parents=True, exist_ok=True)
        for f in cap.frames:
            img = cap.masks[f][ci].astype(np.uint8) * 255
            if not cv2.imwrite(str(d / f"{f}.png"), img):
                raise InputError(f"{d / (f + '.png')}: could not write the silhouette")
    gt = cap.options.get("gt")
    if gt is not None:
        (out / "gt.json").write_text(json.dumps(gt, indent=1))
    return out
