"""The mirrored limbs of a capsule body (:mod:`.body`) and other starts for a limb the
track lost (:func:`.tracker.track_sequence` refits a frame from them)."""
from __future__ import annotations

import numpy as np

from topopose.sequence.body import CapsuleBody


def mirror_groups(names) -> list:
    """Pairs of joint index lists that mirror each other: the joints whose names end ``_1``
    and ``_2`` on the same base name, grouped by the limb (the numbered part) they follow."""
    groups = {}
    for j, n in enumerate(names):
        base, _, k = str(n).rpartition("_")
        if base and k in ("1", "2"):
            groups.setdefault(base, {})[k] = j
    return [(groups[b]["1"], groups[b]["2"]) for b in groups if len(groups[b]) == 2]


def limb_pairs(body: CapsuleBody) -> list:
    """The body's mirrored limbs: per pair of mirror joints (:func:`mirror_groups`) whose
    parent is none (the shoulders, the hips), ``((a, b), (bones of a, bones of b))``: each
    limb's bones that turn (its joint's and those below it, outside a rigid group)."""
    pairs = mirror_groups(body.names)
    mirrored = {j for p in pairs for j in p}
    grouped = {int(j) for g in body.groups for j in g}
    below = body.ancestry()
    return [((a, b), tuple([k for k in range(len(body.names)) if below[k, s] and k not in grouped]
                           for s in (a, b)))
            for a, b in pairs if body.parents[a] not in mirrored]


def limb_starts(body: CapsuleBody, D, P, pair) -> list:
    """Other starts for one pair of mirrored limbs (:func:`limb_pairs`) of the pose (root,
    ``D``) at joints ``P``: both limbs, and each alone, hanging straight along the trunk (from
    the root towards ``body.trunk``); each limb alone as its twin mirrored across the plane
    midway between their first joints (a limb the track lost is where the other one is seen,
    or hangs). Returns the directions of each start."""
    (a, b), bones = pair
    twin = {j: k for p in mirror_groups(body.names) for j, k in (p, p[::-1])}
    n = P[b] - P[a]
    n = n / max(float(np.linalg.norm(n)), 1e-12)
    out = []
    if body.trunk >= 0:
        t = P[body.trunk] - P[body.root]
        t = t / max(float(np.linalg.norm(t)), 1e-12)
        for limbs in (bones[0] + bones[1], bones[0], bones[1]):
            E = D.copy()
            E[limbs] = t
            out.append(E)
    for limb in bones:
        limb = [j for j in limb if j in twin]
        E = D.copy()
        v = D[[twin[j] for j in limb]]
        E[limb] = v - 2.0 * (v @ n)[:, None] * n
        out.append(E)
    return out
