"""The hull's clean-up: the tolerant consensus, its largest 26-connected part, cavities filled."""
from __future__ import annotations

import numpy as np

from topopose.errors import InputError
from topopose.hull import hull_kernels as K


def _label26(sub: np.ndarray) -> tuple:
    """26-connected labels of a boolean / uint8 array and their number (cc3d, else scipy)."""
    try:
        import cc3d

        return cc3d.connected_components(sub, connectivity=26, return_N=True)
    except ImportError:
        from scipy import ndimage

        return ndimage.label(sub, structure=np.ones((3, 3, 3), bool))


def consensus_hull_labels(lab: np.ndarray, lo, hi, repair: int = 1,
                          max_removed: float = 0.2) -> tuple:
    """The consensus hull from one carve's labels, in place (thesis §2.3.2.2).

    A visual hull with tolerance k keeps the voxels seen as subject by C − k cameras
    (§2.3.2.2): it survives a hole or an eroded border in one silhouette, but it also keeps the
    *phantom volume* that only C − k cameras fail to carve — with a ring of cameras, regions
    sticking out of the subject by up to ~20 cm that become skeleton branches matched as a head
    or a hand (measured in ``benchmarks/quality.py``; see ``FrameEstimator``'s ``repair``). The
    consensus hull keeps a tolerant voxel only within ``repair`` voxels (26-neighbourhood
    steps) of the strict hull (tolerance 0) of the same grid — the strict hull's tunnels and
    gaps of up to about 2 × ``repair`` voxels are mended, protrusions are not — and then the
    largest 26-component T ∩ near of the tolerant hull's largest component T. When that would
    remove more than ``max_removed`` of T, one camera lost the subject (or much of it): that is
    what the tolerance is for, T is kept (phantom volume is a few percent of a hull, 2–5 % on
    synthetic humans at 100³).

    One carve (:meth:`HullCarver.carve` with ``levels=True``) labels both hulls (2 strict, 1
    tolerant only); here, on the labels' bounding box only: a kernel marks the tolerant voxels
    with a strict voxel within ``repair`` (:func:`.hull_kernels.consensus_near`), one
    26-labelling (cc3d) gives its largest component L, and when |L| is more than half the
    tolerant voxels L provably lies in T, whose size and other components follow from a
    breadth-first grouping of the few tolerant voxels outside L
    (:func:`.hull_kernels.consensus_select`). Otherwise (rare: the tolerant hull is split into
    comparable pieces, or a silhouette is empty so the strict hull is) T is labelled
    explicitly. Same result as carving both hulls, keeping T, dilating the strict hull in T's
    bounding box and labelling again (tested); the dilation here is not limited to that box,
    which only matters for ``repair`` ≥ 2.

    Parameters
    ----------
    lab : uint8 array (nx, ny, nz)
        Labels of the carve; overwritten with the result (0 / 1).
    lo, hi : (3,) ints
        Inclusive bounding box of the labelled voxels (``HullCarver.stats[6:12]``).

    Returns
    -------
    (dropped, voxels, lo, hi, diagnostics)
        Sizes of the tolerant hull's other components (largest first), voxels kept, the kept
        voxels' bounding box, and the diagnostics entries (see :func:`visual_hull`).
    """
    lo = np.asarray(lo, dtype=np.int64)
    hi = np.asarray(hi, dtype=np.int64)
    box = tuple(slice(int(a), int(b) + 1) for a, b in zip(lo, hi))
    sub = np.empty(tuple(int(b - a + 1) for a, b in zip(lo, hi)), dtype=np.uint8)
    idx = np.empty(sub.size, dtype=np.int64)      # only the tolerant voxels' pages get touched
    ntol, nstrict = K.consensus_near(lab, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], int(repair),
                                     sub, idx)
    ntol = int(ntol)
    info = {"repair": int(repair), "strict_voxels": int(nstrict), "tolerant_voxels": ntol}
    cl, n = _label26(sub)
    res = np.zeros(12, dtype=np.int64)
    drop = np.empty(max(ntol, 1), dtype=np.int64)
    K.consensus_select(lab, cl, int(n), lo[0], lo[1], lo[2], idx, ntol, float(max_removed), sub,
                       res, drop)
    if res[0] == 0:
        info["path"] = "one-pass"
        dropped = sorted((int(x) for x in drop[: res[5]]), reverse=True)
        nvox = int(res[1] if not res[4] else res[2])
        removed, skipped = int(res[3]), bool(res[4])
        nlo, nhi = res[6:9].copy(), res[9:12].copy()
    else:                               # label the tolerant hull itself
        info["path"] = "labelled"
        view = lab[box]
        tol = view != 0
        near = sub.view(bool) if sub.dtype == np.uint8 else sub.astype(bool)
        dropped = keep_largest_component(tol)
        n_t = int(np.count_nonzero(tol))
        keep = tol & near
        if keep.any():
            lab2, n2 = _label26(keep)
            if n2 > 1:
                sizes = np.bincount(lab2.ravel())
                sizes[0] = 0
                keep = lab2 == int(np.argmax(sizes))
        n_k = int(np.count_nonzero(keep))
        removed = n_t - n_k
        skipped = removed > max_removed * n_t
        out = tol if skipped else keep
        view[...] = out
        nvox = n_t if skipped else n_k
        nlo, nhi = lo.copy(), hi.copy()
        for ax in range(3):
            other = tuple(a for a in range(3) if a != ax)
            nz = np.flatnonzero(out.any(axis=other))
            if nz.size:
                nlo[ax], nhi[ax] = lo[ax] + nz[0], lo[ax] + nz[-1]
    diag = {"consensus": info}
    diag["consensus_skipped" if skipped else "consensus_removed"] = int(removed)
    return dropped, nvox, nlo, nhi, diag


def keep_largest_component(occ: np.ndarray, bbox=None) -> list:
    """Keep the largest 26-connected component of ``occ`` in place; sizes of the others.

    Labelling runs on the bounding box ``bbox`` (slices) of the occupied voxels when given.
    """
    from scipy import ndimage

    sub = occ[bbox] if bbox is not None else occ
    try:
        import cc3d

        lab, n = cc3d.connected_components(sub.view(np.uint8), connectivity=26, return_N=True)
        n = int(n)
        if n <= 1:
            return []
        if sub.dtype == bool:            # sizes and the largest kept in two passes (a kernel)
            sizes, best = K.keep_label(sub, lab, n)
            if best >= 0:
                others = np.delete(sizes, [0, best])
                return sorted((int(s) for s in others if s > 0), reverse=True)
    except ImportError:
        lab, n = ndimage.label(sub, structure=np.ones((3, 3, 3), bool))
    if n <= 1:
        return []
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    best = int(np.argmax(sizes))
    sub &= lab == best
    others = np.delete(sizes, [0, best])
    return sorted((int(s) for s in others if s > 0), reverse=True)


def fill_cavities(occ: np.ndarray, bbox=None) -> tuple:
    """Fill the cavities of a boolean volume in place; returns (cavities, voxels filled).

    A cavity is a background component (6-adjacency, the dual of the object's 26-adjacency)
    that does not reach the outside — for a visual hull, a pocket of silhouette noise enclosed
    by the subject, which topology-preserving thinning would have to keep as a closed surface.
    Same result as ``scipy.ndimage.binary_fill_holes`` (tested), in one pass over the rows of
    the object's bounding box plus a search of the few background voxels lying between object
    voxels of their row (:func:`.hull_kernels.fill_cavities`).

    Parameters
    ----------
    occ : bool array (nx, ny, nz), C-contiguous
    bbox : ([imin, jmin, kmin], [imax, jmax, kmax]), optional
        An inclusive voxel box holding every True voxel (``Volume.diagnostics["bbox"]`` of
        :func:`visual_hull`); computed when omitted.
    """
    if occ.dtype != bool or occ.ndim != 3 or not occ.flags.c_contiguous:
        raise InputError(f"fill_cavities: argument occ must be a C-contiguous 3D bool array, got "
                         f"{occ.dtype} {occ.shape}")
    if bbox is None:
        pxy = occ.any(axis=2)
        xs = np.flatnonzero(pxy.any(axis=1))
        if xs.size == 0:
            return 0, 0
        ys = np.flatnonzero(pxy.any(axis=0))
        zs = np.flatnonzero(occ[xs[0]: xs[-1] + 1, ys[0]: ys[-1] + 1].any(axis=(0, 1)))
        lo, hi = (xs[0], ys[0], zs[0]), (xs[-1], ys[-1], zs[-1])
    else:
        lo, hi = (np.clip(np.asarray(b, dtype=np.int64).reshape(3), 0, np.array(occ.shape) - 1)
                  for b in bbox)
    n, filled = K.fill_cavities(occ.view(np.uint8), int(lo[0]), int(lo[1]), int(lo[2]),
                                int(hi[0]), int(hi[1]), int(hi[2]))
    return int(n), int(filled)
