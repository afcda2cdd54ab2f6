"""The thesis' applications (§13.3): hull segmentation by flooding, pose detection by
description, pose clustering by betweenness relations."""
import itertools
import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from topopose.errors import InputError
from topopose.apps import cluster as C
from topopose.apps import detect as D
from topopose.apps import segment as S
from topopose.synth import labels
from topopose.apps.segment_kernels import depth, flood


# ============================================================================ flooding
def _graph(mask, connectivity):
    """All-pairs hop distances over the mask voxels (brute force)."""
    ijk = np.argwhere(mask)
    idx = {tuple(p): i for i, p in enumerate(ijk)}
    steps = [d for d in itertools.product((-1, 0, 1), repeat=3) if d != (0, 0, 0)
             and (connectivity == 26 or sum(map(abs, d)) == 1)]
    rows, cols = [], []
    for i, p in enumerate(ijk):
        for d in steps:
            j = idx.get(tuple(p + d))
            if j is not None:
                rows.append(i)
                cols.append(j)
    G = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(ijk),) * 2)
    return ijk, shortest_path(G, unweighted=True)


def _brute_flood(mask, seeds, start, connectivity):
    ijk, Dm = _graph(mask, connectivity)
    lab = seeds[tuple(ijk.T)]
    st = start[tuple(ijk.T)]
    out = np.zeros(mask.shape, np.int32)
    s_idx = np.flatnonzero(lab > 0)
    for x in range(len(ijk)):
        cost = st[s_idx] + Dm[s_idx, x]
        if not np.isfinite(cost.min()):
            continue
        best = cost.min()
        out[tuple(ijk[x])] = lab[s_idx][cost == best].min()      # ties: the smallest label
    return out


def _padded(mask, seeds, start, connectivity):
    m = np.pad(mask, 1).view(np.uint8)
    s = np.pad(seeds.astype(np.int32), 1)
    st = np.pad(start.astype(np.int32), 1)
    flood(m.reshape(-1), s.reshape(-1), st.reshape(-1), S._offsets(m.shape, connectivity))
    return s[1:-1, 1:-1, 1:-1]


def _random_seeds(seed, fill=0.65, n=6):
    """A random 7×6×5 mask (``fill`` of it set) with ``n`` seeds of labels 1–3 on it:
    (rng, mask, seeds)."""
    rng = np.random.default_rng(seed)
    mask = rng.random((7, 6, 5)) < fill
    seeds = np.zeros(mask.shape, np.int32)
    pts = np.argwhere(mask)
    for i in rng.choice(len(pts), n, replace=False):
        seeds[tuple(pts[i])] = rng.integers(1, 4)
    return rng, mask, seeds


@pytest.mark.parametrize("connectivity", [6, 26])
@pytest.mark.parametrize("seed", range(4))
def test_flood_equals_brute_force_geodesic_labelling(connectivity, seed):
    rng, mask, seeds = _random_seeds(seed)
    seeds[tuple(np.argwhere(~mask)[0])] = 2                    # a seed outside the mask: ignored
    zero = np.zeros(mask.shape, np.int32)
    ref = _brute_flood(mask, np.where(mask, seeds, 0), zero, connectivity)
    assert np.array_equal(S.flood_labels(mask, seeds, connectivity), ref)
    assert np.array_equal(_padded(mask, seeds, zero, connectivity), ref)
    # delayed seeds (the "part" weighting): min over seeds of start + steps
    start = np.where(seeds > 0, rng.integers(0, 4, mask.shape), 0)
    ref2 = _brute_flood(mask, np.where(mask, seeds, 0), start, connectivity)
    assert np.array_equal(_padded(mask, seeds, start, connectivity), ref2)


def _brute_weighted(mask, seeds, start):
    """Min over seeds of start + chamfer geodesic distance (26-adjacency, steps 3, 4, 5 for
    face, edge, corner neighbours), ties to the smallest label."""
    from scipy.sparse.csgraph import dijkstra

    ijk = np.argwhere(mask)
    idx = {tuple(p): i for i, p in enumerate(ijk)}
    rows, cols, w = [], [], []
    for i, p in enumerate(ijk):
        for d in itertools.product((-1, 0, 1), repeat=3):
            j = idx.get(tuple(p + d))
            if j is not None and j != i:
                rows.append(i)
                cols.append(j)
                w.append(2 + np.sum(np.abs(d)))
    G = csr_matrix((w, (rows, cols)), shape=(len(ijk),) * 2)
    lab = seeds[tuple(ijk.T)]
    s_idx = np.flatnonzero(lab > 0)
    Dm = dijkstra(G, indices=s_idx) + start[tuple(ijk.T)][s_idx][:, None]
    best = Dm.min(0)
    out = np.zeros(mask.shape, np.int32)
    for x in np.flatnonzero(np.isfinite(best)):
        out[tuple(ijk[x])] = lab[s_idx][Dm[:, x] == best[x]].min()
    return out, best


@pytest.mark.parametrize("seed", range(4))
def test_weighted_flood_equals_brute_force_dijkstra(seed):
    from topopose.apps.segment_kernels import flood_weighted, neighbours

    rng, mask, seeds = _random_seeds(seed)
    start = np.where(seeds > 0, rng.integers(0, 9, mask.shape), 0)
    ref, dist = _brute_weighted(mask, seeds, start)
    m = np.pad(mask, 1).view(np.uint8)
    idx, nb = neighbours(m.reshape(-1), S._offsets(m.shape, 26))
    assert np.array_equal(idx, np.flatnonzero(m))
    lab, d = flood_weighted(nb, S._chamfer(26), np.pad(seeds, 1).reshape(-1)[idx],
                            np.pad(start, 1).reshape(-1)[idx].astype(np.int64),
                            np.ones(len(idx), np.bool_))
    assert np.array_equal(lab, ref[mask])
    assert np.array_equal(np.where(d < 0, np.inf, d), dist)


def test_radius_weighting_moves_the_boundary_towards_the_narrowing():
    """A dumbbell along x: a thick bar (radius 6, the trunk, x < 14) and a thin one (radius 1.5,
    a limb); the limb's skeleton starts inside the trunk (x = 11), as a limb's branch starts at a
    junction. On the axis the fronts meet half-way between the seeds' ends with plain flooding;
    with the radius weighting the limb starts ``tau = delay · (r_trunk − r_limb)`` late (radii:
    the seeds' median distance to the border) and the trunk's front overruns its seeds up to
    x = 8 + tau, at the narrowing; the trunk's flanks beside the limb's seeds stay in the trunk."""
    from scipy import ndimage

    x, y, z = np.mgrid[0:48, 0:15, 0:15]
    rr = np.hypot(y - 7, z - 7)
    mask = ((x >= 1) & (x < 14) & (rr <= 6)) | ((x >= 14) & (x < 46) & (rr <= 1.5))
    seeds = np.zeros(mask.shape, np.int32)
    seeds[5:9, 7, 7] = 1
    seeds[11:45, 7, 7] = 2
    plain = S.flood_labels(mask, seeds, 26, "none")
    assert (plain[1:10, 7, 7] == 1).all() and (plain[10:46, 7, 7] == 2).all()   # (8 + 11) / 2
    edt = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1, 1:-1]
    tau = S.DELAY["radius"] * (np.median(edt[seeds == 1]) - np.median(edt[seeds == 2]))
    boundary = 8 + tau
    assert 12 <= boundary <= 14
    out = S.flood_labels(mask, seeds, 26, "radius")
    axis = out[:, 7, 7]
    assert (axis[1:int(np.floor(boundary)) + 1] == 1).all()
    assert (axis[int(np.floor(boundary)) + 1:46] == 2).all()
    flank = mask & (x >= 10) & (x < 14) & (rr >= 3)          # beside the limb's seeds
    assert (out[flank] == 1).all() and np.mean(plain[flank] == 1) < 0.9


@pytest.mark.parametrize("seed,band", [(0, np.inf), (1, np.inf), (2, np.inf), (3, 1.0),
                                       (4, 0.5), (5, 0.0)])
def test_bone_vote_equals_brute_force(seed, band):
    """With bones, each voxel takes the label minimizing (1 − w) · (own flood) + w · (distance
    to the label's bones): per label a brute-force Dijkstra (chamfer steps / 3) on the voxels
    where its bones are within ``band`` of the nearest bone (and its seeds) and a
    point-segment distance."""
    rng, mask, seeds = _random_seeds(seed, fill=0.7, n=8)
    bones = [(rng.random(3) * 6, rng.random(3) * 6, lab) for lab in (1, 1, 2)]   # label 3: none
    w = 0.7
    out = S.flood_labels(mask, seeds, 26, "radius", delay=0.0, bones=bones, bone_weight=w,
                         band=band)
    ijk = np.argwhere(mask).astype(float)
    labs = sorted(set(seeds[mask].tolist()) - {0})
    bd = {}
    for lab in labs:
        segs = []
        for a, b, bl in bones:
            if bl == lab:
                lam = np.clip((ijk - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
                segs.append(np.linalg.norm(ijk - (a + lam[:, None] * (b - a)), axis=1))
        bd[lab] = np.min(segs, 0) if segs else None
    bmin = np.min([b for b in bd.values() if b is not None], 0)
    score = []
    for lab in labs:
        sub = mask.copy()
        if bd[lab] is not None:
            keep = (bd[lab] <= bmin + band) | (seeds[mask] == lab)
            sub[tuple(ijk[~keep].astype(int).T)] = False
        _, t = _brute_weighted(sub, np.where(seeds == lab, lab, 0), np.zeros(mask.shape))
        t = np.full(len(ijk), np.inf) if t.size == 0 else t
        if t.size != len(ijk):                   # distances on the sub-mask's voxels
            full = np.full(len(ijk), np.inf)
            full[sub[mask]] = t
            t = full
        t = t / 3
        score.append(t if bd[lab] is None else (1 - w) * t + w * bd[lab])
    score = np.array(score)
    ref = np.zeros(mask.shape, np.int32)
    ok = np.isfinite(score.min(0))
    ref[tuple(ijk[ok].astype(int).T)] = np.array(labs)[np.argmin(score, 0)[ok]]
    assert np.array_equal(out, ref)
    with pytest.raises(InputError):
        S.flood_labels(mask, seeds, 26, "part", bones=bones)


def _straight_pose():
    """A human pose with straight skeleton curves: (part positions, Pose)."""
    from topopose.pose.pose import Pose

    P = {"torso": (0, 0, 1.4), "head": (0, 0, 1.75), "crotch": (0, 0, 0.9),
         "hand_1": (-0.7, 0, 1.4), "hand_2": (0.7, 0, 1.4), "foot_1": (-0.2, 0, 0.0),
         "foot_2": (0.2, 0, 0.0)}
    curves = {k: np.linspace(P["crotch" if k.startswith("foot") else "torso"], P[k], 16).tolist()
              for k in P if k != "torso"}
    return P, Pose("0", "matched", 0.0, {k: np.array(v, float) for k, v in P.items()},
                   diagnostics={"curves": curves})


def test_bone_segments_put_each_limb_from_its_first_joint():
    """Human model, straight curves: the first bone of each limb's arc (chest → shoulder,
    chest → neck, pelvis → hip) is the trunk's, the next ones the limb's."""
    from topopose.pose.model import load_model
    from topopose.pose.pose import Pose

    model = load_model("human")
    names = S.arc_names(model)
    P, pose = _straight_pose()
    bones = S.bone_segments(pose, model, names, start={})     # every limb from its first joint
    lab = {n: i + 1 for i, n in enumerate(names)}
    assert len(bones) == 19
    for a, b, L in bones:
        if b[2] > 1.7:                                           # neck → skull (at 0.58 → 0.93)
            assert L == lab["torso-head"]
        elif abs(b[0]) > 0.3 and b[2] > 1.0:                     # elbows, wrists, fingertips
            assert L == lab[f"torso-hand_{1 if b[0] < 0 else 2}"]
        elif b[2] < 0.6:                                         # knees and below
            assert L == lab[f"crotch-foot_{1 if b[0] < 0 else 2}"]
    firsts = [L for a, b, L in bones if np.allclose(a, P["torso"]) or np.allclose(a, P["crotch"])]
    assert len(firsts) == 6 and set(firsts) == {lab["torso-crotch"]}   # from chest, pelvis: trunk
    assert S.bone_segments(Pose("0", "matched", 0.0, pose.parts), model, names) == []


def test_bone_segments_split_the_chain_at_the_limb_start():
    """``start``: the trunk takes each limb's chain of joints up to the given position (in
    bones from the junction), the limb the rest: head 0.5 splits chest → neck at its middle,
    hand 1.45 gives the trunk chest → shoulder and 45 % of shoulder → elbow."""
    from topopose.sequence.kinematic_fit import initial_placement, kinematic_tree
    from topopose.pose.model import load_model

    model = load_model("human")
    names = S.arc_names(model)
    lab = {n: i + 1 for i, n in enumerate(names)}
    P, pose = _straight_pose()
    tree = kinematic_tree(model)
    J = dict(zip(tree.names, initial_placement(pose, tree)))
    bones = S.bone_segments(pose, model, names, start={"head": 0.5, "hand": 1.45})
    assert len(bones) == 22                     # neck and both upper arms split in two

    def has(a, b, L):
        return any(np.allclose(a, x) and np.allclose(b, y) and L == m for x, y, m in bones)

    mid = J["chest"] + 0.5 * (J["neck"] - J["chest"])
    assert has(J["chest"], mid, lab["torso-crotch"]) and has(mid, J["neck"], lab["torso-head"])
    for k in (1, 2):
        sh, el = J[f"shoulder_{k}"], J[f"elbow_{k}"]
        m = sh + 0.45 * (el - sh)
        assert has(J["chest"], sh, lab["torso-crotch"]) and has(sh, m, lab["torso-crotch"])
        assert has(m, el, lab[f"torso-hand_{k}"])
        assert has(J[f"hip_{k}"], J[f"knee_{k}"], lab[f"crotch-foot_{k}"])
        assert has(J["pelvis"], J[f"hip_{k}"], lab["torso-crotch"])


def test_flood_ties_go_to_the_smallest_label():
    mask = np.ones((5, 1, 1), bool)
    seeds = np.zeros(mask.shape, np.int32)
    seeds[0], seeds[4] = 3, 2
    assert S.flood_labels(mask, seeds, 6).ravel().tolist() == [3, 3, 2, 2, 2]
    seeds[0], seeds[4] = 2, 3
    assert S.flood_labels(mask, seeds, 6).ravel().tolist() == [2, 2, 2, 3, 3]


@pytest.mark.parametrize("connectivity", [6, 26])
def test_depth_is_steps_to_the_border(connectivity):
    rng = np.random.default_rng(7)
    mask = np.zeros((9, 8, 7), bool)
    mask[1:-1, 1:-1, 1:-1] = rng.random((7, 6, 5)) < 0.9
    m = np.pad(mask, 1).view(np.uint8)
    d = depth(m.reshape(-1), S._offsets(m.shape, connectivity)).reshape(m.shape)[1:-1, 1:-1, 1:-1]
    ijk, Dm = _graph(mask, connectivity)
    steps = [np.array(s) for s in itertools.product((-1, 0, 1), repeat=3) if s != (0, 0, 0)
             and (connectivity == 26 or sum(map(abs, s)) == 1)]
    border = np.array([any(not mask[tuple(np.clip(p + s, 0, np.array(mask.shape) - 1))]
                           or np.any(p + s < 0) or np.any(p + s >= mask.shape) for s in steps)
                       for p in ijk])
    ref = 1 + Dm[border].min(0)
    assert np.array_equal(d[tuple(ijk.T)], ref.astype(int))
    assert not d[~mask].any()


def _y_skeleton():
    """A Y: a stem along z and two arms; ends at the three tips, one junction."""
    s = np.zeros((15, 15, 15), bool)
    for k in range(2, 8):
        s[7, 7, k] = True
    for d in range(1, 6):
        s[7 - d, 7, 7 + d] = s[7 + d, 7, 7 + d] = True
    return s


def test_tree_voxels_make_the_vertices_and_edges():
    from topopose import data_tree

    rng = np.random.default_rng(1)
    skel = _y_skeleton()
    skel[rng.integers(0, 15, 3), 1, rng.integers(0, 15, 3)] = True    # small extra components
    t = data_tree(skel, origin=(1.0, 2.0, 3.0), voxel_size=0.5)
    vox = t.voxels
    assert np.array_equal(vox["index"], np.flatnonzero(skel))
    world = np.array([1.0, 2.0, 3.0]) + np.argwhere(skel) * 0.5
    for v in t.vertices:                       # vertices are the centroids of their voxels
        sel = vox["vertex"] == v
        assert sel.any()
        assert np.allclose(world[sel].mean(0), t.positions[v])
    assert set(vox["edge"][vox["edge"] >= 0]) == set(range(len(t.edges)))
    assert not np.any((vox["vertex"] >= 0) & (vox["edge"] >= 0))
    # edge voxels touch both of the edge's vertices' voxels (26-adjacency)
    for j, (u, v, _) in enumerate(t.edges):
        e = np.argwhere(skel)[vox["edge"] == j]
        for w in (u, v):
            q = np.argwhere(skel)[vox["vertex"] == w]
            assert np.abs(e[:, None, :] - q[None, :, :]).max(2).min() == 1
    # normalized / rooted copies keep them
    assert t.normalized().voxels is vox


def test_skeleton_labels_follow_the_matched_arcs():
    from topopose import data_tree

    skel = _y_skeleton()
    t = data_tree(skel)
    tip = {k: min(t.vertices, key=lambda v: np.linalg.norm(t.positions[v] - np.array(p)))
           for k, p in {"foot": (7, 7, 2), "a1": (2, 7, 12), "a2": (12, 7, 12), "j": (7, 7, 7)}.items()}
    arcs = {("j", "foot"): [tip["j"], tip["foot"]], ("j", "a1"): [tip["j"], tip["a1"]],
            ("j", "a2"): None}                                                # a deleted arc
    al = SimpleNamespace(arcs=arcs, mapping={"j": tip["j"], "foot": tip["foot"], "a1": tip["a1"],
                                             "a2": None})
    lab, names = S.skeleton_labels(skel, al, t)
    assert names == ["j-foot", "j-a1", "j-a2"]
    assert set(np.unique(lab[skel])) <= {0, 1, 2}
    assert (lab[7, 7, 2:6] == 1).all() and lab[7, 7, 2] == 1                     # stem and its tip
    assert lab[2, 7, 12] == 2 and lab[4, 7, 10] == 2
    assert lab[12, 7, 12] == 0 and lab[10, 7, 10] == 0                          # deleted arc
    assert lab[7, 7, 7] == 0                                                   # the junction
    assert not lab[~skel].any()
    # flooding a thick Y from them: voxels nearest the labelled stem take label 1
    from scipy import ndimage

    hull = ndimage.binary_dilation(skel, iterations=1)
    out, _ = S.segment(hull, skel, al, t, weighting="none")
    ref = _brute_flood(hull, lab, np.zeros(hull.shape, np.int32), 26)
    assert np.array_equal(out, ref)
    assert out[7, 7, 2] == 1 and out[12, 7, 12] == 1    # the deleted arm: tie between 1 and 2 -> 1


def test_segment_synthetic_human_against_ground_truth(tmp_path):
    from topopose.synth.capture import synthetic_capture
    from topopose.frame.estimate import FrameEstimator

    cap = synthetic_capture("human", frames=2, seed=11, separated=True, margin=0.06)
    est = FrameEstimator(cap, "human", 64)
    names = S.arc_names(est.model)
    accs = []
    for fi, f in enumerate(cap.frames):
        pose, det = est.estimate(f, detail=True)
        if pose.status != "matched":
            continue
        lab, nm = S.segment(det.volume, det.skeleton, det.alignment, det.data, names=names)
        assert nm == names
        hull = det.volume.data
        assert not lab[~hull].any() and (lab[hull] > 0).mean() > 0.99
        bl, _ = S.segment(det.volume, det.skeleton, det.alignment, det.data, names=names,
                          pose=pose, model=est.model)                      # with the bones
        assert not bl[~hull].any() and (bl[hull] > 0).mean() > 0.99
        accs.append(S.renumbered_accuracy(bl, labels.synthetic_truth(det.volume, cap.options["bodies"][fi],
                                                                names), names))
        truth = labels.synthetic_truth(det.volume, cap.options["bodies"][fi], names)
        accs.append(S.renumbered_accuracy(lab, truth, names))
        masks = S.camera_masks(cap, lab, det.volume.origin, det.volume.voxel_size, cap.silhouettes(f))
        sil = np.asarray(cap.silhouettes(f)[0], bool)
        assert masks[0].shape == sil.shape and not masks[0][~sil].any()
        assert (masks[0][sil] > 0).mean() > 0.95
        nf = S.write_label_mesh(tmp_path / "m.ply", lab, names, det.volume.origin, det.volume.voxel_size)
        assert nf > 100 and (tmp_path / "m.ply").read_text().startswith("ply\n")
    assert accs and min(accs) > 0.75


def test_renumbered_accuracy_forgives_swapped_numbers():
    names = ["t-h_1", "t-h_2", "t-c"]
    truth = np.array([1, 1, 2, 2, 3, 0])
    pred = np.array([2, 2, 1, 1, 3, 3])
    assert S.renumbered_accuracy(pred, truth, names) == 1.0
    assert S.renumbered_accuracy(np.array([2, 2, 1, 3, 3, 3]), truth, names) == 0.8
    acc, m = S.renumbered_accuracy(pred, truth, names, return_mapping=True)
    assert acc == 1.0 and m[pred[truth > 0]].tolist() == truth[truth > 0].tolist()


# ============================================================================ detection
def test_parse_trees():
    R = D.Rel
    assert D.parse("(z-greatest A_1 - H) XOR (z-greatest A_2 - H)") == D.BinOp(
        "xor", R("greatest", ("A_1", "H"), axis=2), R("greatest", ("A_2", "H"), axis=2))
    # the thesis' spacing "z - greatest", and precedence not > and > xor > or
    assert D.parse("z - greatest a b or not x-least a b and order c, d, e xor far a b 2") == D.BinOp(
        "or", R("greatest", ("a", "b"), axis=2),
        D.BinOp("xor",
                D.BinOp("and", D.Not(R("least", ("a", "b"), axis=0)),
                        R("order", ("c", "d", "e"), relation="b")),
                R("far", ("a", "b"), value=2.0)))
    assert D.parse("above p q and below q p") == D.BinOp(
        "and", R("greatest", ("p", "q"), axis=2), R("least", ("q", "p"), axis=2))
    assert D.parse("ORDER-I a b c d") == R("order", ("a", "b", "c", "d"), relation="i")
    assert D.parse("near hand_1 - head 0.25") == R("near", ("hand_1", "head"), value=0.25)
    assert D.parse("((true)) and not false") == D.BinOp("and", D.Const(True), D.Not(D.Const(False)))
    assert D.parse("Above x1 x2 OR above x3 x4").op == "or"


@pytest.mark.parametrize("text, col", [
    ("above head", 10),                      # missing second part: at the end
    ("above a b and", 13),
    ("(above a b", 10),
    ("z-great a b", 2),
    ("near a b x", 9),
    ("hands a b", 0),
    ("above a b c", 10),
    ("above a b $ c", 10),
    ("above a and b", 8),
    ("order a b", 9),
    ("w-greatest a b", 0),
    ("", 0),
    ("above a b)", 9),
])
def test_error_columns(text, col):
    with pytest.raises(D.ExpressionError) as e:
        D.parse(text)
    assert e.value.col == col
    assert str(e.value).endswith("\n  " + text + "\n  " + " " * col + "^")


def test_evaluate_on_hand_made_positions():
    P = {"head": (0, 0, 1.7), "torso": (0, 0, 1.45), "crotch": (0, 0, 0.95),
         "hand_1": (0.1, 0.3, 1.9), "hand_2": (0.0, -0.8, 1.4), "foot_1": (0, 0.1, 0), "foot_2": (0, -0.1, 0)}
    lib, aliases = D.load_library()
    val = {n: D.evaluate(p.expr, P, "+z", aliases) for n, p in lib.items()}
    assert val == {"hands-up": False, "ask-a-question": True, "wide-spread-arms": False,
                   "acrobatic": False}
    for n, p in lib.items():                # the thesis' notation says the same
        assert D.evaluate(p.thesis, P, "+z", aliases) == val[n]
    Q = dict(P, hand_1=(0, 0.9, 1.45), hand_2=(0, -0.9, 1.45))
    assert D.evaluate(lib["wide-spread-arms"].expr, Q) is True
    # crotch: 0.5 below the shoulders; ball of diameter 1.8 centred at torso height holds it
    assert D.evaluate("order hand_1 crotch hand_2", Q) is True
    assert D.evaluate("order hand_1 crotch hand_2", dict(Q, crotch=(0, 0, 0.5))) is False
    # R_b is the ball of diameter hand_1 hand_2 (thesis §12.2.2.1), not the projection on their
    # line (R_p) nor an order along an axis: 0.95 from the hands' midpoint, radius 0.9
    assert D.evaluate("order-p hand_1 crotch hand_2", dict(Q, crotch=(0, 0, 0.5))) is True
    assert D.evaluate("order hand_1 crotch hand_2", dict(Q, crotch=(0, 0, 0.56))) is True
    assert D.evaluate("near hand_1 hand_2 1.9", Q) and not D.evaluate("near hand_1 hand_2 1.7", Q)
    assert D.evaluate("x-least head hand_1 or y-greatest head hand_2", P) is True
    # missing part: null; unknown part: null
    assert D.evaluate("above hand_1 head", dict(P, hand_1=None)) is None
    assert D.evaluate("above thumb head or true", P) is None
    # up = +y: the thesis' z is the capture's y
    Py = {k: (v[0], v[2], -v[1]) for k, v in P.items()}
    assert D.evaluate("z-greatest hand_1 head", Py, "+y") is True
    assert D.evaluate("z-greatest hand_1 head", Py, "+z") is False
    assert D.evaluate("z-greatest hand_1 head", {k: (v[0], v[1], -v[2]) for k, v in P.items()}, "-z")
    # sided names resolve to numbered ones and back
    sided = {"head": P["head"], "left_hand": P["hand_1"], "right_hand": P["hand_2"]}
    assert D.evaluate("above hand_1 head and not above hand_2 head", sided) is True
    assert D.evaluate("above left_hand head", {"head": P["head"], "hand_1": P["hand_1"]}) is True
    assert D.evaluate("above hand_r head", {"head": P["head"], "hand_2": P["hand_2"]}) is False


def test_detect_sequence_intervals_and_cli(tmp_path, capsys):
    from topopose.cli import main

    frames = []
    for i in range(8):
        up = i in (2, 3, 4, 6)
        frames.append({"frame": f"{i:06d}", "status": "matched" if i != 5 else "rejected",
                       "distance": 0.1,
                       "parts": {"head": [0, 1.7, 0], "hand_1": [0, 1.9 if up else 1.0, 0],
                                 "hand_2": [0, 1.0, 0] if i != 7 else None}})
    f = tmp_path / "poses.jsonl"
    f.write_text(json.dumps({"model": "human", "capture": {"up": "+y"}}) + "\n"
                 + "".join(json.dumps(d) + "\n" for d in frames))
    assert main(["detect", str(f), "above hand_1 head", "--output", str(tmp_path / "o.jsonl"),
                 "--csv", str(tmp_path / "o.csv")]) == 0
    res = [json.loads(x) for x in (tmp_path / "o.jsonl").read_text().splitlines()]
    assert [r["value"] for r in res] == [False, False, True, True, True, None, True, False]
    assert "000002 .. 000004  (3 frames)" in capsys.readouterr().out
    assert (tmp_path / "o.csv").read_text().splitlines()[3] == "000002,1"
    assert main(["detect", str(f), "--pose", "ask-a-question", "--output", str(tmp_path / "q.jsonl")]) == 0
    res = [json.loads(x)["value"] for x in (tmp_path / "q.jsonl").read_text().splitlines()]
    assert res == [False, False, True, True, True, None, True, None]
    assert main(["detect", str(f), "above hand_1 head or"]) == 2
    assert "^" in capsys.readouterr().err
    assert main(["detect", str(f), "--pose", "nope"]) == 2


def test_wide_spread_arms_compares_the_crotch_before_its_drop(tmp_path):
    """§13.3.2.1 with R_b, hand-computed: hands at (±0.8, 0, 1.4) hold the legs' junction
    (0.95 up: the angle hand–junction–hand is obtuse, (−0.8, 0.45)·(0.8, 0.45) < 0) between
    them, not a crotch dropped to 0.55 ((−0.8, 0.85)·(0.8, 0.85) > 0). The detection compares
    the junction a pose records in diagnostics["detect_parts"], through poses.jsonl too; an
    unplaced crotch stays unplaced."""
    from topopose.cli import main

    parts = {"head": [0, 0, 1.7], "torso": [0, 0, 1.3], "crotch": [0, 0, 0.55],
             "hand_1": [-0.8, 0, 1.4], "hand_2": [0.8, 0, 1.4]}
    expr = D.load_library()[0]["wide-spread-arms"].expr
    junction = {"detect_parts": {"crotch": [0, 0, 0.95]}}
    plain = {"frame": "000000", "status": "matched", "parts": parts}
    recorded = {**plain, "frame": "000001", "diagnostics": junction}
    lost = {**recorded, "frame": "000002", "parts": {**parts, "crotch": None}}
    assert D.description_parts(recorded)["crotch"] == [0, 0, 0.95]
    assert D.description_parts(plain) == parts
    assert [r["value"] for r in D.detect([plain, recorded, lost], expr)] == [False, True, None]
    f = tmp_path / "poses.jsonl"
    f.write_text("".join(json.dumps({**d, "distance": 0.1}) + "\n" for d in (plain, recorded, lost)))
    assert main(["detect", str(f), "--pose", "wide-spread-arms", "--output", str(tmp_path / "o.jsonl")]) == 0
    res = [json.loads(x)["value"] for x in (tmp_path / "o.jsonl").read_text().splitlines()]
    assert res == [False, True, None]


def test_user_library(tmp_path):
    lib = tmp_path / "lib.toml"
    lib.write_text('[aliases.me]\nHD = "head"\n[[pose]]\nname = "hand-high"\nexpr = "above hand_1 HD"\n')
    poses, aliases = D.load_library(lib)
    assert "hand-high" in poses and "hands-up" in poses and aliases["hd"] == "head"
    assert D.evaluate(poses["hand-high"].expr, {"head": (0, 0, 1), "hand_1": (0, 0, 2)}, aliases=aliases)
    lib.write_text('[[pose]]\nname = "bad"\nexpr = "above a"\n')
    with pytest.raises(InputError, match="column 8"):
        D.load_library(lib)


# ============================================================================ clustering
def test_relation_sets_of_hand_computed_poses():
    # a straight line a-b-c-d: every inner point lies between any two points around it
    line = {"a": (0, 0, 0), "b": (1, 0, 0), "c": (2, 0, 0), "d": (3, 0, 0)}
    assert C.relation_set(line) == {("a", "b", "c"), ("a", "b", "d"), ("a", "c", "d"),
                                    ("b", "c", "d")}
    # a square: the diagonal's ends see the other corners at 90°: not strictly inside the ball
    sq = {"a": (0, 0, 0), "b": (1, 0, 0), "c": (1, 1, 0), "d": (0, 1, 0)}
    assert C.relation_set(sq) == set()
    # a T: the stem's top is between the bar's ends; nothing else
    t = {"l": (-1, 0, 0), "m": (0, 0.1, 0), "r": (1, 0, 0), "s": (0, -3, 0)}
    assert C.relation_set(t) == {("l", "m", "r")}
    assert C.relation_set(dict(t, s=None)) == {("l", "m", "r")}


def test_similarity_of_a_frame_with_a_part_unplaced():
    """A frame with a part unplaced is compared on the triples both frames define: the same pose
    with a hand missing has similarity 1 with the whole pose (counted as absent relations it
    would be |A ∩ B| / |A| < 1), and a different pose is judged on the shared parts only, which
    a brute-force Jaccard over those parts' relation sets gives."""
    parts = ["head", "hand_1", "hand_2", "torso", "foot_1"]
    A = {"head": (0, 0, 2), "hand_1": (0, 1, 1), "hand_2": (0, -1, 1.5), "torso": (0, 0, 1),
         "foot_1": (0, 0.2, 0)}
    part = dict(A, hand_2=None)
    Bp = {"head": (0, 0, 2), "hand_1": (0, 1, 2.5), "hand_2": None, "torso": (0, 0, 1),
          "foot_1": (0.5, 0.9, 0.6)}
    frames = [A, part, Bp]
    M = C.relation_matrix(frames, parts)
    V = C.defined_matrix(frames, parts)
    assert V[0].all() and V[1].sum() == len(C.triples([p for p in parts if p != "hand_2"]))
    S = C.similarity_matrix(M, None, defined=V)
    assert S[0, 1] == 1.0
    old = C.similarity_matrix(M, None)[0, 1]
    assert old == pytest.approx(len(C.relation_set(part)) / len(C.relation_set(A))) and old < 1
    shared = [p for p in parts if p != "hand_2"]
    sa = C.relation_set({p: A[p] for p in shared})
    sb = C.relation_set({p: Bp[p] for p in shared})
    assert sa != sb
    assert S[0, 2] == pytest.approx(len(sa & sb) / len(sa | sb))


def test_similarity_renumbering_and_ari():
    parts = ["head", "hand_1", "hand_2", "torso"]
    A = {"head": (0, 0, 2), "hand_1": (0, 1, 1), "hand_2": (0, -1, 3), "torso": (0, 0, 1)}
    B = dict(A, hand_1=A["hand_2"], hand_2=A["hand_1"])           # the same pose, renumbered
    M = C.relation_matrix([A, B], parts)
    assert not np.array_equal(M[0], M[1])
    assert C.similarity_matrix(M, parts)[0, 1] == 1.0
    plain = C.similarity_matrix(M, None)[0, 1]
    sa, sb = C.relation_set(A), C.relation_set(B)
    assert plain == pytest.approx(len(sa & sb) / len(sa | sb))
    # ARI: identical partitions up to names, a hand-computed one, independent ones near 0
    assert C.adjusted_rand_index([0, 0, 1, 1, 2], [5, 5, 3, 3, 9]) == 1.0
    # contingency [[2,1,0],[0,1,2]]: sum C(nij,2)=2, rows 3+3=6, cols 1+1+1=3, C(6,2)=15
    # ARI = (2 - 6*3/15) / ((6+3)/2 - 6*3/15) = 0.8 / 3.3
    assert C.adjusted_rand_index([0, 0, 0, 1, 1, 1], [0, 0, 1, 1, 2, 2]) == pytest.approx(0.8 / 3.3)
    rng = np.random.default_rng(0)
    assert abs(C.adjusted_rand_index(rng.integers(0, 3, 3000), rng.integers(0, 3, 3000))) < 0.02


def _jittered(K=4, per=12, noise=0.03, seed=0):
    rng = np.random.default_rng(seed)
    parts = ["head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"]
    base = [{p: rng.normal(0, 0.6, 3) for p in parts} for _ in range(K)]
    poses, truth = [], []
    for i in range(K * per):
        k = int(rng.integers(K))
        pos = {p: base[k][p] + rng.normal(0, noise, 3) for p in parts}
        if rng.random() < 0.5:                         # the pipeline numbers limbs freely
            pos["hand_1"], pos["hand_2"] = pos["hand_2"], pos["hand_1"]
        poses.append({"frame": f"{i:06d}", "status": "matched", "parts": pos})
        truth.append(k)
    return poses, truth


@pytest.mark.parametrize("auto", ["gap", "silhouette"])
def test_clustering_finds_known_poses(auto):
    poses, truth = _jittered()
    res = C.cluster_poses(poses, auto=auto)
    assert res.k == 4
    assert C.adjusted_rand_index(res.labels, truth) == 1.0
    for c, m in enumerate(res.medoids):
        assert res.labels[res.frames.index(m)] == c
    assert C.cluster_poses(poses, clusters=2).k == 2
    assert C.cluster_poses(poses, threshold=1.0).k == 1


def test_cluster_cli(tmp_path):
    from topopose.cli import main

    poses, truth = _jittered(K=3, per=5)
    poses[0]["status"] = "failed"
    f = tmp_path / "p.jsonl"
    f.write_text("".join(json.dumps({**p, "distance": 0.1, "parts": {k: list(map(float, v))
                                                                      for k, v in p["parts"].items()}})
                         + "\n" for p in poses))
    assert main(["cluster", str(f), "--output", str(tmp_path / "c.jsonl"),
                 "--figure", str(tmp_path / "c.png")]) == 0
    res = [json.loads(x) for x in (tmp_path / "c.jsonl").read_text().splitlines()]
    assert res[0]["cluster"] is None
    assert C.adjusted_rand_index([r["cluster"] for r in res[1:]], truth[1:]) == 1.0
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_body_bones_group_into_the_human_arcs():
    bones = ('Hips', 'LHipJoint', 'LeftUpLeg', 'LowerBack', 'RHipJoint', 'RightUpLeg', 'Spine',
             'Spine1', 'LeftLeg', 'LeftShoulder', 'Neck', 'Neck1', 'RightLeg', 'RightShoulder',
             'Head', 'LeftArm', 'LeftFoot', 'LeftForeArm', 'LeftHand', 'LeftToeBase', 'RightArm',
             'RightFoot', 'RightForeArm', 'RightHand', 'RightToeBase', 'LThumb', 'LeftFingerBase',
             'LeftHandFinger1', 'RThumb', 'RightFingerBase', 'RightHandFinger1')
    want = {"torso-head": {"Neck", "Neck1", "Head"},
            "torso-crotch": {"Hips", "LHipJoint", "RHipJoint", "LowerBack", "Spine", "Spine1",
                             "LeftShoulder", "RightShoulder"},
            "torso-hand_1": {"LeftArm", "LeftForeArm", "LeftHand", "LThumb", "LeftFingerBase",
                             "LeftHandFinger1"},
            "torso-hand_2": {"RightArm", "RightForeArm", "RightHand", "RThumb", "RightFingerBase",
                             "RightHandFinger1"},
            "crotch-foot_1": {"LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"},
            "crotch-foot_2": {"RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"}}
    got = {}
    for b in bones:
        got.setdefault(labels.body_bone_arc(b), set()).add(b)
    assert got == want
    from topopose.pose.model import load_model

    assert set(want) == set(S.arc_names(load_model("human")))


def test_margin_band_matches_brute_force_shifts():
    """Oracle: a relation is undecided iff some part moved by the margin along ±x, ±y, ±z (brute
    force over all shifts, with the plain evaluator) changes its value; Kleene logic on top."""
    rng = np.random.default_rng(3)
    names = ("head", "hand_1", "hand_2", "torso")
    rels = ["z-greatest hand_1 head", "x-least hand_2 torso", "near hand_1 hand_2 0.5",
            "far head torso 0.3", "order hand_1 torso hand_2"]
    shifts = [s * e for e in np.eye(3) for s in (1, -1)]
    n_und = 0
    for _ in range(150):
        P = {n: rng.normal(0, 0.3, 3) for n in names}
        m = 0.08
        for r in rels:
            v = D.evaluate(r, P)
            flips = any(D.evaluate(r, {**P, p: P[p] + m * d}) != v
                        for p in D.parts_of(D.parse(r)) for d in shifts)
            got = D.evaluate(r, P, margin=m)
            assert got == (None if flips else v), (r, P)
            n_und += got is None
    assert 20 < n_und < 600                     # the band is exercised, not everywhere
    # Kleene: false and undecided -> false; true or undecided -> true; xor/not undecided -> null
    P = {"head": (0, 0, 1.70), "hand_1": (0, 0, 1.72), "hand_2": (0, 0, 1.0)}
    assert D.evaluate("above hand_1 head", P) is True
    assert D.evaluate("above hand_1 head", P, margin=0.05) is None
    assert D.evaluate("above hand_1 head and above hand_2 head", P, margin=0.05) is False
    assert D.evaluate("above hand_1 head or below hand_2 head", P, margin=0.05) is True
    assert D.evaluate("above hand_1 head xor above hand_2 head", P, margin=0.05) is None
    assert D.evaluate("not above hand_1 head", P, margin=0.05) is None
    assert D.evaluate("above hand_1 head", P, margin=0.01) is True
    res = D.detect([{"frame": "0", "parts": P}], "above hand_1 head", margin=0.05)
    assert res == [{"frame": "0", "value": None}]


def test_detect_cli_margin(tmp_path):
    from topopose.cli import main

    frames = [{"frame": f"{i}", "status": "matched", "distance": 0.1,
               "parts": {"head": [0, 0, 1.7], "hand_1": [0, 0, z]}}
              for i, z in enumerate((1.72, 1.9, 1.5, 1.68))]
    f = tmp_path / "poses.jsonl"
    f.write_text("".join(json.dumps(d) + "\n" for d in frames))
    out = tmp_path / "o.jsonl"
    assert main(["detect", str(f), "above hand_1 head", "--output", str(out)]) == 0
    assert [json.loads(x)["value"] for x in out.read_text().splitlines()] == [True, True, False, False]
    assert main(["detect", str(f), "above hand_1 head", "--margin", "0.05", "--output", str(out)]) == 0
    assert [json.loads(x)["value"] for x in out.read_text().splitlines()] == [None, True, False, None]


def test_body_truth_groups_the_nearest_vertex_bone():
    """Oracle: on voxels placed at mesh vertices, the truth is the vertex's dominant bone's arc;
    ``bone_arc`` replaces the grouping."""
    from scipy.spatial.distance import cdist

    from topopose.synth.body import BUILDS, dominant_bones, pose_body
    from topopose.hull.volume import Volume
    from topopose.pose.model import load_model

    body = pose_body({}, BUILDS["average"])
    names = S.arc_names(load_model("human"))
    vs = 0.05
    lo = body.vertices.min(0) - vs
    ijk = np.round((body.vertices - lo) / vs).astype(int)
    grid = np.zeros(ijk.max(0) + 2, bool)
    grid[tuple(ijk.T)] = True
    vol = Volume(grid, lo, vs)
    truth = labels.synthetic_truth(vol, body, names)
    dom, bones = dominant_bones()
    X = lo + np.argwhere(grid) * vs
    near = np.argmin(cdist(X, body.vertices), 1)                                # brute force
    want = [names.index(labels.body_bone_arc(bones[dom[i]])) + 1 for i in near]
    assert truth[grid].tolist() == want
    assert set(np.unique(truth[grid])) == set(range(1, 7))
    alt = labels.synthetic_truth(vol, body, names, bone_arc=lambda b: "torso-head")
    assert np.all(alt[grid] == 1) and np.all(alt[~grid] == 0)


def _trunk_and_head():
    """A trunk (cylinder r 5, z 2..22), a neck (r 2, z 23..25) and a head (ball r 4 about
    z 29; the crown at z 33), on the axis x = y = 8; voxels of 0.5 at origin (1, 2, 3)."""
    from topopose.hull.volume import Volume

    x, y, z = np.mgrid[0:17, 0:17, 0:36]
    rr = np.hypot(x - 8, y - 8)
    head = np.sqrt(rr ** 2 + (z - 29) ** 2) <= 4
    hull = ((z >= 2) & (z <= 22) & (rr <= 5)) | ((z >= 23) & (z <= 25) & (rr <= 2)) | head
    vol = Volume(hull, origin=(1.0, 2.0, 3.0), voxel_size=0.5)
    world = lambda k: vol.world(np.array([8, 8, k]))                      # noqa: E731
    pose = SimpleNamespace(parts={"head": world(33), "torso": world(20), "crotch": world(3)},
                           diagnostics={"from_hull": ["head"]})
    return vol, head, z, pose


def test_head_placed_from_the_hull_gets_a_seed_inside_the_head():
    """No head branch in the skeleton (the estimator placed the head from the hull): the stand-in
    seed runs from half-way between the torso part and the crown up to the crown, inside the
    neck and head; a branch that ends short is extended from its end to the crown only."""
    vol, head, z, pose = _trunk_and_head()
    names = ["torso-head", "torso-crotch"]
    seeds = np.zeros(vol.data.shape, np.int32)
    seeds[8, 8, 3:21] = 2
    bones = S.hull_part_seeds(vol.data, seeds, pose, names, vol.origin, vol.voxel_size)
    new = np.argwhere(seeds == 1)
    assert len(new) >= 6 and vol.data[tuple(new.T)].all()
    assert new[:, 2].min() >= 26 and new[:, 2].max() == 33 and (new[:, :2] == 8).all()
    assert head[tuple(new[new[:, 2] >= 26].T)].all()           # the seed lies inside the head
    assert len(bones) == 1 and bones[0][2] == 1 and np.allclose(bones[0][1], [8, 8, 33])
    assert (seeds[8, 8, 3:21] == 2).all()                        # other labels untouched
    stub = np.zeros(vol.data.shape, np.int32)                    # a branch ending at z = 24
    stub[8, 8, 21:25] = 1
    S.hull_part_seeds(vol.data, stub, pose, names, vol.origin, vol.voxel_size,
                      skeleton_index=np.flatnonzero(stub))
    assert (stub[8, 8, 21:34] == 1).all() and (stub == 1).sum() == 13
    no_hull = SimpleNamespace(parts=pose.parts, diagnostics={})  # head on its branch: nothing
    s0 = np.zeros(vol.data.shape, np.int32)
    assert S.hull_part_seeds(vol.data, s0, no_hull, names, vol.origin, vol.voxel_size) == [] \
        and not s0.any()


def test_segment_labels_a_head_without_a_skeleton_branch():
    """The skeleton is the trunk's axis only (no head branch, the head arc deleted): without the
    pose the head part labels nothing; with it the head ball goes to the head, the trunk stays
    the trunk's."""
    from topopose import data_tree

    vol, head, z, pose = _trunk_and_head()
    skel = np.zeros(vol.data.shape, bool)
    skel[8, 8, 3:21] = True
    t = data_tree(skel)
    ends = sorted(t.vertices, key=lambda v: t.positions[v][2])
    al = SimpleNamespace(arcs={("torso", "head"): None, ("torso", "crotch"): [ends[-1], ends[0]]},
                         mapping={"torso": ends[-1], "crotch": ends[0], "head": None})
    names = ["torso-head", "torso-crotch"]
    plain, _ = S.segment(vol, skel, al, t, names=names)
    assert not (plain == 1).any()
    lab, _ = S.segment(vol, skel, al, t, names=names, pose=pose)
    assert np.mean(lab[head] == 1) > 0.95
    trunk = vol.data & (z <= 20)
    assert np.mean(lab[trunk] == 2) > 0.99 and not lab[~vol.data].any()
