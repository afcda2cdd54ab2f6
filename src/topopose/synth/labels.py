"""Ground-truth body-part labels of the synthetic subjects' hulls (for the segmentation of thesis
§13.3.1.1 and its benchmark)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from topopose.synth.body import dominant_bones
from topopose.synth.geometry import sdf

#: the links of the synthetic subjects grouped by the model arc (body part) they belong to,
#: for ground truth (``Prim.link`` → arc name; the left side is numbered 1)
SYNTH_LINK_ARCS = {
    "human": {"head": "torso-head", "neck": "torso-head",
              "chest": "torso-crotch", "pelvis": "torso-crotch", "dress": "torso-crotch",
              **{f"{seg}_{s}": f"torso-hand_{k}" for s, k in (("l", 1), ("r", 2))
                 for seg in ("upperarm", "forearm", "hand")},
              **{f"{seg}_{s}": f"crotch-foot_{k}" for s, k in (("l", 1), ("r", 2))
                 for seg in ("thigh", "shin", "foot")}},
}


def body_bone_arc(bone: str) -> str:
    """The human model's arc of a bone of the ``body`` subject's rig (``cmu_mb``): head and neck →
    torso-head; the arm from the upper arm down (the clavicle ``*Shoulder`` stays in the trunk)
    → torso-hand_k; the leg from the thigh down (the ``*HipJoint`` stays in the trunk) →
    crotch-foot_k; the rest (hips, back, spine, clavicles, hip joints) → torso-crotch.
    Left is 1, as in gt.json.

    Anatomy: the ``UpLeg`` bone's skin covers the thigh and the gluteal region (buttock and
    lateral hip up to about the iliac crest, above the crotch): regional anatomy counts the
    gluteal region in the lower limb, so it is the leg's. The neck has no part of its own in the
    model, whose torso point is the neck base (gt.json): it lies on the torso–head arc. The
    clavicle and hip-joint bones (40 and 29 of 13,380 vertices) skin the root of the neck above
    the clavicle and the groin, trunk regions in surface anatomy, so they stay in the trunk;
    ``benchmarks/applications.py`` also measures the other choice (the bones lie on the model's
    torso→hand and crotch→foot arcs)."""
    if bone.startswith(("Neck", "Head")):
        return "torso-head"
    k = "1" if bone.startswith("L") else "2"
    if any(x in bone for x in ("Arm", "Hand", "Thumb", "Finger")):
        return f"torso-hand_{k}"
    if any(x in bone for x in ("UpLeg", "Leg", "Foot", "Toe")) and "Hip" not in bone:
        return f"crotch-foot_{k}"
    return "torso-crotch"


def synthetic_truth(volume, body, names, subject="human", bone_arc=None) -> np.ndarray:
    """Ground-truth labels of a hull of a synthetic subject; 0 outside the hull.

    Capsule subjects: each hull voxel takes the arc of the nearest primitive's link (signed
    distance, :func:`~topopose.synth.geometry.sdf`), grouped by
    :data:`SYNTH_LINK_ARCS`. The ``body`` subject (a :class:`~topopose.synth.body.MeshBody`):
    the dominant bone (largest skinning weight) of the nearest posed mesh vertex, grouped by
    :func:`body_bone_arc` (or ``bone_arc``: bone name → arc name).
    """
    hull = volume.data
    ijk = np.argwhere(hull)
    X = np.asarray(volume.origin, float) + ijk * float(volume.voxel_size)
    index = {n: i + 1 for i, n in enumerate(names)}
    for n in list(index):
        u, v = n.split("-", 1)
        index.setdefault(f"{v}-{u}", index[n])
    out = np.zeros(hull.shape, np.int32)
    if hasattr(body, "vertices") and not hasattr(body, "prims"):
        dom, bones = dominant_bones()
        lab_of_bone = np.array([index[(bone_arc or body_bone_arc)(b)] for b in bones], np.int32)
        _, nearest = cKDTree(body.vertices).query(X, k=1)
        out[tuple(ijk.T)] = lab_of_bone[dom[nearest]]
        return out
    arcs = SYNTH_LINK_ARCS[subject]
    D = np.stack([sdf(p, X) for p in body.prims], 1)
    lab_of_prim = np.array([index[arcs[p.link]] for p in body.prims], np.int32)
    out[tuple(ijk.T)] = lab_of_prim[np.argmin(D, 1)]
    return out
