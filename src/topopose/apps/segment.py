"""Body-part segmentation of the visual hull by flooding (thesis §13.3.1.1, Fig. 13.10).

"A simple method to obtain an efficient part labeling of each voxel from our method outputs
(i.e. skeleton with matched specific points) consists of two steps: color labeling each part of
the skeleton bounded by matched points [...]; flooding the visual hull simultaneously with all
the color labeled voxels."

1. :func:`skeleton_labels`: every model arc (u, v) is matched with a data path (the alignment's
   ``arcs``); the skeleton voxels of the path's data edges (``Tree.voxels``, kept by
   :func:`topopose.data_tree`), of its inner data vertices and of a leaf at its end get the
   arc's label. Junction vertices that end several arcs, unmatched branches and deleted arcs
   stay unlabelled: the flooding gives them to the nearest arc.
2. :func:`flood_labels`: multi-source breadth-first flooding inside the hull from all the
   labelled skeleton voxels at once (:func:`.segment_kernels.flood`): each hull voxel takes the
   label of the nearest labelled voxel in steps of the 26- (or 6-) adjacency, ties to the
   smallest label. Hull voxels not connected to a labelled voxel stay 0. By default each part
   enters the flood late by how much thinner it is than the thickest part, and the fronts
   advance by chamfer step lengths (``weighting="radius"``,
   :func:`.segment_kernels.flood_weighted`): plain flooding lets the limbs' skeleton, which
   starts at a junction inside the trunk, claim much of the trunk (measured in
   ``benchmarks/applications.py``).
   Given the frame's pose and a model with joints, each part's flood is mixed with the distance
   to its bones (:func:`bone_segments`: the kinematic model's joints placed on the skeleton
   curves), so a limb begins near its first joint (neck, shoulder, hip: :data:`LIMB_START`)
   rather than at the junction inside the trunk. A head placed from the hull with no (or a
   short) skeleton branch gets a stand-in seed up to the crown (:func:`hull_part_seeds`).

Labels are 1..E in the order of the model's edges, named ``"u-v"`` (e.g. ``"torso-hand_1"``);
0 is background.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from topopose.errors import InputError


def arc_names(model) -> list:
    """Label names of a model: ``"u-v"`` per model edge, in the model's edge order (label i+1)."""
    tree = model.tree if hasattr(model, "tree") else model
    return [f"{u}-{v}" for u, v, _ in tree.edges]


#: where each limb's bones begin along the chain of its joints from the junction, per part
#: stem: 1 at its first joint (neck, shoulder, hip), 0.5 half-way from the junction (chest,
#: pelvis) to it, 1.5 half-way from it to the second joint (see :func:`bone_segments`)
LIMB_START = {"head": 0.5, "hand": 1.35, "foot": 1.0}


def bone_segments(pose, model, names=None, start=None) -> list:
    """The bones of the model's kinematic tree on one frame, each with the label of its part.

    The joints (``[[joint]]`` of the model, :func:`~topopose.sequence.kinematic_fit.kinematic_tree`)
    at their initial placement on the frame's skeleton curves
    (:func:`~topopose.sequence.kinematic_fit.initial_placement`: relative arc length, shoulders and
    hips moved beside the curve; ``pose.diagnostics["curves"]``). A bone (parent joint → child
    joint) lies on the arc of its child joint, except where an arc leaves a junction part
    (chest → neck, chest → shoulder, pelvis → hip) joined by one arc to another junction part
    (the trunk): its chain of joints belongs to the trunk up to the limb's start
    (``start``, default :data:`LIMB_START`: position along the chain in bones from the
    junction, 1 at the first joint; a bone crossing it is split there): the head's from 0.5
    (the skin of the neck bones begins at the neck's base, below the model's neck joint), the
    hand's from 1.35 with :func:`segment`'s ``bone_weight`` 0.7, the foot's from 1 — chosen on
    development seeds of the ``body`` subject by voxel accuracy (docs/decisions.md), measured
    by ``benchmarks/applications.py``.

    Returns ``[(A, B, label), ...]``: the bone's end points (capture units) and its label
    (1-based index into ``names``, default :func:`arc_names`); bones with a joint not placed
    are left out. Empty when the model declares no joints or the pose has no curves.
    """
    from topopose.sequence.joint_placement import initial_placement

    if not getattr(model, "joints", None) or not (pose.diagnostics or {}).get("curves"):
        return []
    tree, table = _bone_table(model, tuple(names or arc_names(model)),
                              tuple(sorted((LIMB_START if start is None else start).items())))
    J = initial_placement(pose, tree)
    ok = ~np.isnan(J).any(axis=1)
    out = []
    for c, p, f, core, lab in table:
        if ok[c] and ok[p]:
            M = J[p] + f * (J[c] - J[p])
            if f > 0:
                out.append((J[p].copy(), M, core))
            if f < 1 and lab:
                out.append((M.copy(), J[c].copy(), lab))
    return out


_BONE_TABLES = {}


def _bone_table(model, names, start):
    """The kinematic tree of ``model`` and its bones ``(child, parent, f, trunk label, label)``
    for :func:`bone_segments`: the trunk takes the fraction f of the bone from its parent
    joint; cached per model, names and start."""
    from topopose.sequence.skeleton_fit import kinematic_tree
    from topopose.pose.model import part_stem

    key = (id(model), names, start)
    hit = _BONE_TABLES.get(key)
    if hit is not None and hit[0] is model:
        return hit[1], hit[2]
    index = {}
    for i, n in enumerate(names):
        u, v = n.split("-", 1)
        index[(u, v)] = index[(v, u)] = i + 1
    tree = kinematic_tree(model)
    degree = {}
    for u, v, _ in model.tree.edges:
        degree[u] = degree.get(u, 0) + 1
        degree[v] = degree.get(v, 0) + 1
    # rank of each joint along its arc: 1 for the first joint after the junction, 2, ...
    rank = [1 + sum(1 for a, t in zip(tree.arc, tree.at) if a == arc and 0 < t < at)
            for arc, at in zip(tree.arc, tree.at)]
    start = dict(start)
    table = []
    for c, p in enumerate(tree.parents):
        if p < 0:
            continue
        u, v = tree.arc[c]
        lab = index.get((u, v), 0)
        core = [index[(a, b)] for a, b, _ in model.tree.edges if u in (a, b)
                and degree.get(a, 0) > 1 and degree.get(b, 0) > 1 and (a, b) in index] \
            if degree.get(u, 0) > 1 else []
        # the trunk takes the part of the arc's chain before the limb's start
        f = float(start.get(part_stem(v), 1.0)) - (rank[c] - 1) if len(core) == 1 else 0.0
        table.append((c, p, min(max(f, 0.0), 1.0), core[0] if core else 0, lab))
    if len(_BONE_TABLES) > 16:
        _BONE_TABLES.clear()
    _BONE_TABLES[key] = (model, tree, table)
    return tree, table


def skeleton_labels(skeleton, alignment, data, names=None, core=True) -> tuple:
    """Label the skeleton voxels of every matched model arc (step 1 of §13.3.1.1).

    Parameters
    ----------
    skeleton : (nx, ny, nz) bool array
    alignment : :class:`topopose.match.Alignment` of the model into ``data``
    data : the data tree of ``skeleton`` (:func:`topopose.data_tree`, keeps ``voxels``)
    names : label names ``"u-v"`` (default: the alignment's arcs in order)
    core : the data vertex of a junction part (model degree > 1) ending several arcs takes the
        label of the one arc joining it to another junction part when there is exactly one
        (the trunk between torso and crotch): a junction lies inside the trunk

    Returns
    -------
    (labels, names): int32 grid (0: unlabelled), and the names of labels 1..len(names).
    """
    vox = getattr(data, "voxels", None)
    if vox is None:
        raise InputError("segment: the data tree does not say which voxels make its edges; build "
                         "it with topopose.data_tree from the skeleton")
    arcs = alignment.arcs
    if names is None:
        names = [f"{u}-{v}" for u, v in arcs]
    index = {n: i + 1 for i, n in enumerate(names)}
    eid = {}
    for j, (u, v, _) in enumerate(data.edges):
        eid[(u, v)] = eid[(v, u)] = j
    degree = {v: 0 for v in data.vertices}
    for u, v, _ in data.edges:
        degree[u] += 1
        degree[v] += 1
    n_edges = len(data.edges)
    edge_label = np.zeros(n_edges + 1, np.int32)            # last slot: voxel of no edge
    vmax = max((v for v in data.vertices if isinstance(v, (int, np.integer))), default=-1)
    vertex_label = np.zeros(int(vmax) + 2, np.int32)
    for (u, v), path in arcs.items():
        lab = index.get(f"{u}-{v}") or index.get(f"{v}-{u}")
        if lab is None or not path:
            continue
        for a, b in zip(path[:-1], path[1:]):
            j = eid.get((a, b))
            if j is not None:
                edge_label[j] = lab
        inner = list(path[1:-1]) + [x for x in (path[0], path[-1]) if degree.get(x) == 1]
        for x in inner:
            if isinstance(x, (int, np.integer)) and 0 <= x <= vmax:
                vertex_label[x] = lab
    if core:
        # a junction vertex ending several arcs goes to the one arc joining two junction parts
        mdeg = {}
        for u, v in arcs:
            mdeg[u] = mdeg.get(u, 0) + 1
            mdeg[v] = mdeg.get(v, 0) + 1
        for part in mdeg:
            if mdeg[part] < 2:
                continue
            inc = [(u, v) for u, v in arcs if part in (u, v) and arcs[(u, v)]
                   and mdeg[u] > 1 and mdeg[v] > 1]
            x = alignment.mapping.get(part)
            if len(inc) == 1 and isinstance(x, (int, np.integer)) and 0 <= x <= vmax \
                    and vertex_label[x] == 0:
                u, v = inc[0]
                vertex_label[x] = index.get(f"{u}-{v}") or index.get(f"{v}-{u}") or 0
    e = vox["edge"]
    vv = vox["vertex"]
    lab = np.where(vv >= 0, vertex_label[vv], edge_label[e])
    out = np.zeros(skeleton.size, np.int32)
    out[vox["index"]] = lab
    return out.reshape(skeleton.shape), list(names)


def _offsets(shape, connectivity):
    sy, sz = shape[1] * shape[2], shape[2]
    if connectivity == 6:
        d = [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)]
    elif connectivity == 26:
        d = [x for x in itertools.product((-1, 0, 1), repeat=3) if x != (0, 0, 0)]
    else:
        raise InputError(f"segment: connectivity must be 6 or 26, got {connectivity!r}")
    return np.array([a * sy + b * sz + c for a, b, c in d], np.int64)


#: with bones, a part's own flood runs only where its bones are within this many voxels of
#: the nearest bone (see :func:`flood_labels`)
BAND = 3.0

#: default delay per weighting (see :func:`flood_labels`)
DELAY = {"part": 1.5, "radius": 1.25}


def _box(mask, bbox=None):
    if bbox is not None:
        lo, hi = bbox
        return tuple(slice(int(a), int(b) + 1) for a, b in zip(lo, hi))
    nz = [np.flatnonzero(mask.any(axis=ax)) for ax in ((1, 2), (0, 2), (0, 1))]
    if any(a.size == 0 for a in nz):
        return None
    return tuple(slice(a[0], a[-1] + 1) for a in nz)


def flood_labels(mask, seeds, connectivity: int = 26, weighting: str = "none", bbox=None,
                 delay: float | None = None, bones=None, bone_weight: float = 0.7,
                 band: float = BAND):
    """Flood ``mask`` from the labelled voxels of ``seeds`` (step 2 of §13.3.1.1).

    ``weighting="none"`` (the thesis' plain flooding): each voxel of ``mask`` connected to a
    seed gets the label of its geodesic nearest seed inside the mask (steps of the 26- or
    6-adjacency, breadth first, :func:`.segment_kernels.flood`), ties to the smallest label;
    voxels connected to no seed stay 0.

    ``weighting="radius"`` (default of :func:`segment`): each part enters the flood late by how
    much thinner it is than the thickest part: the seeds of label L start at
    ``delay · (D − r_L)``, r_L being the median over L's seeds of their distance to the hull's
    border (1 + the Euclidean distance to the nearest voxel on the border: the part's radius)
    and D the largest r_L, and the fronts advance by the chamfer length of each step (3, 4, 5
    for face, edge, corner steps, ÷ 3 ≈ 1, √2, √3; :func:`.segment_kernels.flood_weighted`,
    Dial's bucket queue). A voxel goes
    to the part whose skeleton ball reaches it soonest: the thick trunk keeps its flanks
    against the thin limbs whose skeleton starts beside its spine, inside the trunk (plain
    flooding gives them much of the trunk). ``delay = 1.25`` (voxels per voxel of radius) was
    chosen on seeds 1 and 11 of the ``body`` subject (voxel accuracy, docs/decisions.md);
    ``benchmarks/applications.py`` measures on other seeds.

    ``bones`` (with ``weighting="radius"``): ``[(A, B, label), ...]`` segments in voxel
    coordinates of ``mask`` (:func:`bone_segments`); each voxel then takes the label L
    minimizing ``(1 − bone_weight) · T_L + bone_weight · B_L``, T_L being L's own flood
    (its start plus the geodesic distance from its seeds, run for each label alone)
    and B_L the distance to L's nearest bone (labels without a bone: T_L); voxels no label
    reaches stay 0. L's flood runs only on its seeds and on the voxels where B_L is within
    ``band`` voxels of the nearest bone's distance, where it can win
    (:func:`.segment_kernels.flood_parts`, all the labels in one call). On the 26 good
    development frames, ``band = 3`` gives the labels of the unrestricted floods
    (``band=inf``) on 0.9996 of the voxels (the worst frame 0.990; voxel accuracy 0.9055
    against 0.9054; ``band`` 5: all of them) in 2.5 times less flooding time. The
    kinematic model's joints say where a limb begins (near its first joint, not at the
    junction inside the trunk; :data:`LIMB_START`) and the bones follow the limb's axis
    where the curve skeleton bends into the trunk. ``bone_weight = 0.7`` was chosen with the
    delay on the same seeds (limbs from their first joint: 0.897 / 0.898 / 0.894 / 0.875 for
    0.9 / 0.8 / 0.5 / 0, the bones alone 0.891; with the limb starts, 26 good frames: 0.904
    / 0.906 / 0.905 for 0.7 / 0.8 / 0.9, delay 1 / 1.5: 0.904 / 0.904; re-chosen with the
    hand's start on the merged pipeline, 38 good frames: see :func:`bone_segments`; weight
    0.9, delay 1 / 1.5, band 2 / 5 with hand 1.25: 0.896, 0.897 / 0.899, 0.900 / 0.899).
    Subtracting each part's radius from its bone distance (the distance to a capsule's
    surface) lets the thick trunk win everywhere (hand 1): 0.876 (half the radius), 0.838 (all).

    ``weighting="part"`` (part-weighted, kept for comparison): the same idea in
    breadth-first steps (``delay`` 1.5 steps per step of the border distance
    :func:`.segment_kernels.depth`).

    Runs on the mask's bounding box (``bbox``: ([x0, y0, z0], [x1, y1, z1]) inclusive, as
    ``Volume.diagnostics["bbox"]``, or computed).

    Examples
    --------
    >>> m = np.ones((5, 1, 1), bool); s = np.zeros((5, 1, 1), np.int32); s[0], s[4] = 1, 2
    >>> flood_labels(m, s, 6).ravel().tolist()
    [1, 1, 1, 2, 2]
    """
    from topopose.apps.segment_kernels import depth, flood

    mask = np.asarray(mask, bool)
    seeds = np.asarray(seeds)
    if mask.ndim != 3 or seeds.shape != mask.shape:
        raise InputError(f"segment: mask and seeds must be 3D arrays of one shape, got {mask.shape}"
                         f" and {seeds.shape}")
    if weighting not in ("none", "part", "radius"):
        raise InputError(f"segment: weighting must be 'none', 'part' or 'radius', got {weighting!r}")
    if bones and weighting != "radius":
        raise InputError(f"segment: bones need weighting='radius', got {weighting!r}")
    out = np.zeros(mask.shape, np.int32)
    box = _box(mask, bbox)
    if box is None:
        return out
    sub_m = np.pad(mask[box], 1).view(np.uint8)
    sub_s = np.pad(seeds[box].astype(np.int32), 1)
    offsets = _offsets(sub_m.shape, connectivity)
    flat_m, flat_s = sub_m.reshape(-1), sub_s.reshape(-1)
    if weighting == "none":
        flood(flat_m, flat_s, np.zeros(flat_m.size, np.int32), offsets)
    elif weighting == "part":
        d = depth(flat_m, offsets)
        sel = (flat_s > 0) & (flat_m > 0)
        r = np.zeros(int(flat_s.max()) + 1)
        for lab in np.unique(flat_s[sel]):
            r[lab] = np.median(d[sel & (flat_s == lab)])
        late = (r.max() - r[flat_s]) * (DELAY[weighting] if delay is None else delay)
        flood(flat_m, flat_s, np.round(late).astype(np.int32), offsets)
    else:
        if bones:
            shift = np.array([b.start for b in box], float) - 1
            bones = [(np.asarray(a, float) - shift, np.asarray(b, float) - shift, lab)
                     for a, b, lab in bones]
        flat_s[:] = _radius_flood(flat_m, flat_s, sub_m.shape, offsets, connectivity,
                                  DELAY["radius"] if delay is None else delay, bones, bone_weight,
                                  band)
    out[box] = sub_s[1:-1, 1:-1, 1:-1]
    return out


def _chamfer(connectivity):
    """Integer costs of the neighbour offsets of :func:`_offsets`, in the same order: the
    chamfer 3, 4, 5 for face, edge and corner steps (÷ 3 ≈ 1, √2, √3)."""
    if connectivity == 6:
        return np.full(6, 3, np.int64)
    return np.array([(0, 3, 4, 5)[sum(map(abs, x))] for x in itertools.product((-1, 0, 1), repeat=3)
                     if x != (0, 0, 0)], np.int64)


def _radius_flood(flat_m, flat_s, shape, offsets, connectivity, delay, bones, weight, band):
    """Labels of :func:`flood_labels` with ``weighting="radius"`` (flat arrays of the padded
    box; ``bones`` in its voxel coordinates)."""
    from scipy.spatial import cKDTree

    from topopose.apps.segment_kernels import bone_distance, flood_parts, flood_weighted, neighbours

    idx, nb = neighbours(flat_m, offsets)
    steps = _chamfer(connectivity)
    s = flat_s[idx].astype(np.int32)
    out = np.zeros(flat_m.size, np.int32)
    labs = np.unique(s[s > 0])
    if len(labs) == 0:
        return out
    # each seed's distance to the background: 1 + the distance to the nearest border voxel
    X = np.stack(np.unravel_index(idx, shape), 1).astype(float)
    border = (nb < 0).any(1)
    # (an unbalanced tree builds in half the time; the query is exact all the same)
    r, _ = cKDTree(X[border], balanced_tree=False, compact_nodes=False).query(X[s > 0])
    R = np.zeros(int(s.max()) + 1)
    for lab in labs:
        R[lab] = 1.0 + np.median(r[s[s > 0] == lab])
    late = np.round(3 * delay * (R.max() - R[s])).astype(np.int64)
    if not bones:
        out[idx] = flood_weighted(nb, steps, s, late, np.ones(len(idx), np.bool_))[0]
        return out
    nlab = int(max(R.size - 1, max(bl for _, _, bl in bones)))
    bd = bone_distance(X, np.array([a for a, _, _ in bones], float),
                       np.array([b for _, b, _ in bones], float),
                       np.array([bl for _, _, bl in bones], np.int64), nlab)
    out[idx] = flood_parts(nb, steps, s, late, bd, weight, band)
    return out


#: where the seed of a part placed from the hull begins, as a fraction of the way from its
#: junction part to it (see :func:`hull_part_seeds`)
HULL_PART_START = 0.5


def hull_part_seeds(hull, seeds, pose, names, origin, voxel_size, start=None,
                    skeleton_index=None) -> list:
    """Seeds for the parts placed from the hull whose skeleton branch is missing or short
    (``seeds`` changed in place).

    The estimator places the head from the hull when thinning gives it no branch
    (``pose.diagnostics["from_hull"]``, :func:`topopose.frame.tips.head_from_hull`: the
    crown); its arc then labels no skeleton voxel and plain flooding gives the head to the
    trunk. The hull voxels on the segment from the arc's other end (the torso part) a
    fraction ``start`` (default :data:`HULL_PART_START`) of the way to the placed point, up
    to that point, take the arc's label where no other label is: a straight stand-in for the
    missing branch (the neck and the head's axis).

    When the arc has a branch, its end often stops short of the crown (a stub out of the
    trunk: 0.21–0.34 m below it on 3 of 27 good development frames, where the head got 4–24 %
    of its voxels): the segment then runs from the branch's voxel nearest the placed point
    to it.

    Chosen on seeds 1 and 11 of the ``body`` subject (37 good frames, voxel accuracy of
    :func:`segment` with pose and model; ``start`` 0.5 and the extension of short branches:
    0.900, head recall 0.83 against 0.54 without these seeds). Held out:
    ``benchmarks/applications.py``.

    ``skeleton_index``: flat indices of the skeleton voxels (only they carry arc labels;
    default: the whole grid is searched). Returns the stand-in bones ``[(A, B, label)]`` in
    voxel coordinates, for the bone term of :func:`flood_labels`.
    """
    out = []
    diag = pose.diagnostics or {}
    for part in diag.get("from_hull") or ():
        x = pose.parts.get(part)
        for i, n in enumerate(names):
            u, v = n.split("-", 1)
            other = v if u == part else u if v == part else None
            if other is None or x is None or pose.parts.get(other) is None:
                continue
            B = (np.asarray(x, float) - origin) / voxel_size
            own = np.argwhere(seeds == i + 1) if skeleton_index is None else np.stack(
                np.unravel_index(skeleton_index[seeds.flat[skeleton_index] == i + 1], seeds.shape), 1)
            if len(own):     # the branch ends short of the placed point: extend it
                A = own[np.argmin(np.linalg.norm(own - B, axis=1))].astype(float)
            else:
                f = HULL_PART_START if start is None else start
                A0 = (np.asarray(pose.parts[other], float) - origin) / voxel_size
                A = A0 + f * (B - A0)
            k = int(np.ceil(2 * np.linalg.norm(B - A))) + 1
            ijk = np.unique(np.rint(A + np.linspace(0, 1, k)[:, None] * (B - A)).astype(int), axis=0)
            ijk = ijk[np.all((ijk >= 0) & (ijk < hull.shape), axis=1)]
            ijk = ijk[hull[tuple(ijk.T)] & (seeds[tuple(ijk.T)] == 0)]
            if len(ijk):
                seeds[tuple(ijk.T)] = i + 1
                out.append((A, B, i + 1))
    return out


def segment(volume, skeleton, alignment, data=None, *, names=None, connectivity: int = 26,
            weighting: str = "radius", delay: float | None = None, pose=None, model=None,
            bone_weight: float = 0.7, limb_start=None, band: float = BAND):
    """Body-part segmentation of a visual hull (thesis §13.3.1.1).

    Parameters
    ----------
    volume : :class:`topopose.Volume` or (nx, ny, nz) bool array — the visual hull
    skeleton : bool array of the same shape — its curve skeleton
    alignment : the model's alignment into the data tree (``FrameEstimator.estimate(frame,
        detail=True)`` gives volume, skeleton, data tree and alignment of a frame)
    data : the data tree of ``skeleton`` (default: rebuilt with :func:`topopose.data_tree`;
        vertex ids are deterministic, so they are the alignment's)
    names : label names (default ``"u-v"`` per pattern arc of the alignment)
    connectivity : 26 (default) or 6
    weighting, delay : ``"radius"`` (default; delay 1.25), ``"part"`` (part-weighted;
        delay 1.5) or ``"none"`` (the thesis' plain flooding), see :func:`flood_labels`
    pose, model, bone_weight : with the frame's :class:`~topopose.pose.Pose` (its skeleton
        curves) and a model declaring joints (``human``), the radius weighting also follows
        the model's bones (:func:`bone_segments`; ``volume`` must then be a
        :class:`topopose.Volume`, for its origin and voxel size)
    limb_start, band : where each limb's bones begin (:func:`bone_segments`, default
        :data:`LIMB_START`) and the band of each part's own flood (:func:`flood_labels`)

    With ``pose`` (and ``volume`` a :class:`topopose.Volume`), a part the estimator placed from
    the hull (the head, ``pose.diagnostics["from_hull"]``) whose skeleton branch is missing or
    short gets a stand-in seed and bone up to the placed point (:func:`hull_part_seeds`).

    Returns
    -------
    (labels, names): int32 grid, 0 background and unreached hull voxels, label i the arc
    ``names[i - 1]``.
    """
    from topopose.skeleton import data_tree

    hull = volume.data if hasattr(volume, "data") else volume
    bbox = (getattr(volume, "diagnostics", None) or {}).get("bbox")
    hull = np.asarray(hull, bool)
    skeleton = np.asarray(skeleton, bool)
    if skeleton.shape != hull.shape:
        raise InputError(f"segment: skeleton shape {skeleton.shape} differs from the hull's {hull.shape}")
    if data is None or getattr(data, "voxels", None) is None:
        data = data_tree(skeleton)
    seeds, names = skeleton_labels(skeleton, alignment, data, names)
    bones, hull_bones = None, []
    if pose is not None and hasattr(volume, "origin"):
        o, h = np.asarray(volume.origin, float), float(volume.voxel_size)
        hull_bones = hull_part_seeds(hull, seeds, pose, names, o, h,
                                     skeleton_index=data.voxels["index"])
    if pose is not None and model is not None and weighting == "radius":
        if not hasattr(volume, "origin"):
            raise InputError("segment: the bones need the hull as a topopose.Volume (origin, "
                             "voxel size), not a bare array")
        bones = [((a - o) / h, (b - o) / h, lab)
                 for a, b, lab in bone_segments(pose, model, names, limb_start)]
        bones = bones + hull_bones if bones else None
    return flood_labels(hull, seeds, connectivity, weighting, bbox=bbox, delay=delay, bones=bones,
                        bone_weight=bone_weight, band=band), names


# ----------------------------------------------------------------------------- outputs
def label_colours(n: int) -> np.ndarray:
    """(n + 1, 3) uint8 colours: grey for 0, then tab10 / tab20."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    out = np.zeros((n + 1, 3), np.uint8)
    out[0] = (128, 128, 128)
    for i in range(n):
        out[i + 1] = np.round(np.array(cmap(i % cmap.N)[:3]) * 255)
    return out


def write_label_mesh(path, labels, names, origin=(0, 0, 0), voxel_size=1.0) -> int:
    """A coloured triangle mesh (ASCII PLY, vertex colours) of each label's voxels
    (``skimage.measure.marching_cubes`` per label). Returns the number of faces."""
    from skimage.measure import marching_cubes

    cols = label_colours(len(names))
    verts, faces, vcol = [], [], []
    nv = 0
    for lab in range(1, len(names) + 1):
        m = labels == lab
        if m.sum() < 2:
            continue
        v, f, _, _ = marching_cubes(np.pad(m, 1).astype(np.float32), 0.5)
        v = (v - 1) * float(voxel_size) + np.asarray(origin, float)
        verts.append(v)
        faces.append(f + nv)
        vcol.append(np.repeat(cols[lab][None], len(v), 0))
        nv += len(v)
    V = np.concatenate(verts) if verts else np.zeros((0, 3))
    F = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    C = np.concatenate(vcol) if vcol else np.zeros((0, 3), np.uint8)
    with open(path, "w") as fh:
        fh.write("ply\nformat ascii 1.0\ncomment topopose segmentation: "
                 + ", ".join(f"{i + 1}={n}" for i, n in enumerate(names)) + "\n")
        fh.write(f"element vertex {len(V)}\nproperty float x\nproperty float y\nproperty float z\n"
                 "property uchar red\nproperty uchar green\nproperty uchar blue\n")
        fh.write(f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
        for p, c in zip(V, C):
            fh.write(f"{p[0]:.5f} {p[1]:.5f} {p[2]:.5f} {c[0]} {c[1]} {c[2]}\n")
        for f in F:
            fh.write(f"3 {f[0]} {f[1]} {f[2]}\n")
    return len(F)


def camera_masks(cap, labels, origin, voxel_size, silhouettes=None) -> list:
    """Per-camera label images (uint8, 0 background) of a labelled hull.

    Every labelled voxel centre is projected with the hull's projection tables
    (:meth:`topopose.geometry.carver.HullCarver.project_voxels`), nearest voxel last so it wins;
    with ``silhouettes`` (one bool mask per camera) every silhouette pixel takes the label of
    the nearest projected pixel.
    """
    from scipy import ndimage

    from topopose.hull.hull import get_carver

    ijk = np.argwhere(labels > 0)
    lab = labels[tuple(ijk.T)]
    carver = get_carver(cap, np.asarray(origin, float), float(voxel_size), labels.shape)
    pix = carver.project_voxels(ijk)
    world = np.asarray(origin, float) + ijk * float(voxel_size)
    out = []
    for c, cam in enumerate(cap.cameras):
        w, h = cam.size
        img = np.zeros(h * w, np.uint8)
        order = np.argsort(-np.linalg.norm(world - cam.center, axis=1))
        p = pix[order, c]
        ok = p >= 0
        img[p[ok]] = lab[order][ok]
        img = img.reshape(h, w)
        if silhouettes is not None:
            sil = np.asarray(silhouettes[c], bool)
            if img.any():
                _, (ii, jj) = ndimage.distance_transform_edt(img == 0, return_indices=True)
                img = np.where(sil, img[ii, jj], 0).astype(np.uint8)
        out.append(img)
    return out


def segmentation_figure(path, cap, frame, model, detail, up=(0, 0, 1), max_points=15000,
                        pose=None) -> None:
    """Picture of a frame's segmentation: the hull's surface voxels coloured by body part (3D)
    beside the label masks of up to four cameras (``pose``: the frame's pose, for the bones of
    :func:`segment`)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from scipy import ndimage

    from topopose.geometry.axes import up_rotation

    if detail is None or detail.alignment is None:
        raise InputError(f"segment: frame {frame!r} has no alignment to segment with")
    names = arc_names(model)
    labels, _ = segment(detail.volume, detail.skeleton, detail.alignment, detail.data, names=names,
                        pose=pose, model=model)
    vol = detail.volume
    cols = label_colours(len(names))
    surf = labels * (labels > 0) * (~ndimage.binary_erosion(labels > 0))
    ijk = np.argwhere(surf > 0)
    if len(ijk) > max_points:
        ijk = ijk[np.random.default_rng(0).choice(len(ijk), max_points, replace=False)]
    w = vol.world(ijk) @ up_rotation(up).T
    lab = labels[tuple(ijk.T)]
    ncam = min(4, len(cap.cameras))
    fig = plt.figure(figsize=(4 + 2.4 * ncam, 4.4), dpi=80)
    gs = fig.add_gridspec(1, 1 + ncam, width_ratios=[1.6] + [1] * ncam)
    ax = fig.add_subplot(gs[0, 0], projection="3d")
    ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=3, c=cols[lab] / 255.0, depthshade=False)
    span = (w.max(0) - w.min(0)).max() / 2 if len(w) else 1
    mid = (w.max(0) + w.min(0)) / 2 if len(w) else np.zeros(3)
    for setl, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setl(m - span, m + span)
    ax.set_title(f"frame {frame}", fontsize=9)
    for i, n in enumerate(names):
        ax.plot([], [], "s", color=cols[i + 1] / 255.0, label=n)
    ax.legend(fontsize=6, loc="upper left")
    sils = cap.silhouettes(frame)
    masks = camera_masks(cap, labels, vol.origin, vol.voxel_size, sils)
    for c in range(ncam):
        a = fig.add_subplot(gs[0, 1 + c])
        img = masks[c]
        ys, xs = np.nonzero(img)
        a.imshow(cols[img])
        if len(ys):
            a.set_xlim(xs.min() - 10, xs.max() + 10)
            a.set_ylim(ys.max() + 10, ys.min() - 10)
        a.set_title(cap.cameras[c].name, fontsize=8)
        a.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def renumbered_accuracy(pred, truth, names, return_mapping=False):
    """Voxel accuracy over the voxels labelled in ``truth``, best over the renumberings of
    numbered parts (a tree cannot tell hand_1 from hand_2: the pipeline numbers them freely).
    With ``return_mapping``: also the label map (array, predicted label → truth label)."""
    from topopose.apps.cluster import renumberings

    parts = sorted({p for n in names for p in n.split("-", 1)})
    index = {n: i + 1 for i, n in enumerate(names)}
    sel = truth > 0
    t, p = truth[sel], pred[sel]
    if t.size == 0:
        return (math.nan, np.arange(len(names) + 1)) if return_mapping else math.nan
    best, best_m = -1.0, None
    for perm in renumberings(parts):
        ren = {a: parts[perm[i]] for i, a in enumerate(parts)}
        m = np.arange(len(names) + 1)
        for n, i in index.items():
            u, v = n.split("-", 1)
            j = index.get(f"{ren[u]}-{ren[v]}") or index.get(f"{ren[v]}-{ren[u]}")
            if j is not None:
                m[i] = j
        acc = float(np.mean(m[p] == t))
        if acc > best:
            best, best_m = acc, m
    return (best, best_m) if return_mapping else best
