"""Topology-preserving thinning: PKD6, D6I1D, D6U, D6I2D and ACK3 (thesis ch. 4–6).

The volume is cropped to its bounding box inside a one-voxel background frame
(ALGORITHMS.md §5), thinned in place by a Numba kernel (:mod:`.thinning_kernels`)
and put back, so the result does not depend on where the object lies in the array.
Departures from the thesis text, each found necessary by the tests:

* PKD6 / D6I1D / D6U end with a sequential completion (``complete=True``): the
  directional masks do not match every simple configuration, so a few simple voxels
  (staircases, 2×2×2 blocks) can survive the parallel phase; they are removed one at
  a time (always topology-preserving), keeping K and, for curve skeletons, end points.
* ACK3 detects critical 0-cliques exactly (an essential vertex is always critical),
  not with Def. 3's antipodal-pair mask, which lets some 4-voxel components vanish.

>>> import numpy as np, topopose as tp
>>> box = np.zeros((12, 8, 8), bool); box[2:10, 2:6, 2:6] = True
>>> skel = tp.thin(box, method="d6i1d")
>>> bool(skel.any() and skel.sum() < box.sum())
True
"""
from __future__ import annotations

import mmap
import time
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from topopose.errors import InputError
from topopose.topology import neighbourhood as nb

METHODS = ("pkd6", "d6i1d", "d6u", "d6i2d", "ack3")

#: (psi, mask set, completion) of the directional methods; psi: 0 none, 1 1D isthmuses,
#: 2 2D isthmuses; completion: 0 none, 1 keeping end points, 2 ultimate
_DIRECTIONAL = {"pkd6": (0, "pkd6", 1), "d6i1d": (1, "d6", 1), "d6u": (0, "d6", 2),
                "d6i2d": (2, "d6", 0)}


@dataclass
class Thinning:
    """Result of :func:`thinning`.

    Attributes
    ----------
    skeleton : ndarray of bool
        The thinned object, same shape as the input.
    constraints : ndarray of bool
        The final constraint set K (``keep`` plus the isthmuses found), same shape.
    method : str
    iterations : int
        Iterations of the main loop, the last (stable) one included.
    deleted : int
        Voxels deleted.
    timings_ms : dict
        ``prepare`` (validation, crop, padding), ``thin`` (the kernel), ``total``.
    counters : dict
        Work counters of the directional kernels (list visits, deletion tests, isthmus
        tests, initial list size).
    """

    skeleton: np.ndarray
    constraints: np.ndarray
    method: str
    iterations: int
    deleted: int
    timings_ms: dict = field(default_factory=dict)
    counters: dict = field(default_factory=dict)


def _as_volume(volume, name="volume") -> np.ndarray:
    data = volume if isinstance(volume, np.ndarray) else getattr(volume, "data", volume)  # array or Volume
    if not isinstance(data, np.ndarray):
        raise InputError(f"{name}: expected a 3D boolean numpy array, got {type(data).__name__}")
    if data.ndim != 3:
        raise InputError(f"{name}: expected a 3D boolean array, got shape {data.shape}")
    if data.size == 0:
        raise InputError(f"{name}: the array is empty (shape {data.shape}); expected at least one voxel")
    if data.dtype != np.bool_:
        raise InputError(f"{name}: expected boolean data (dtype bool), got dtype {data.dtype}")
    return data


_HUGE = 2 << 20


def _zeros(shape, dtype=bool) -> np.ndarray:
    """``np.zeros(shape, dtype)``; from 4 MB on, backed by anonymous memory advised for
    transparent huge pages (where the OS offers them), so that a call touching the
    array across the grid takes a few 2 MB page faults instead of thousands of 4 kB
    ones (the kernels write these arrays sparsely; measured: the page faults were a
    sixth of D6I1D's time on the 800k-voxel body)."""
    n = 1
    for s in shape:
        n *= int(s)
    if n < (4 << 20) or not hasattr(mmap, "MADV_HUGEPAGE"):  # (bool and uint8: 1 byte each)
        return np.zeros(shape, dtype=dtype)
    nbytes = n * np.dtype(dtype).itemsize
    try:
        buf = mmap.mmap(-1, nbytes + _HUGE, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
        buf.madvise(mmap.MADV_HUGEPAGE)
    except (OSError, ValueError, AttributeError):
        return np.zeros(shape, dtype=dtype)
    raw = np.frombuffer(buf, dtype=np.uint8)
    start = (-raw.ctypes.data) % _HUGE
    return raw[start:start + nbytes].view(dtype).reshape(shape)


@lru_cache(maxsize=64)
def _shape_offsets(shape):
    """The kernels' neighbourhood and ACK3 cliques in a padded state array of ``shape``
    (:class:`~.thinning_kernels.Neighbourhood`, :class:`~.thinning_kernels.Ack3Cliques`), with
    flat offsets: the 26 neighbours then the 9 z-rows, the 6 face neighbours, ACK3's edge and
    cube voxels. Plain tuples (Numba's dispatcher types them on its fast path), cached per
    shape: repeated calls on one grid skip this setup; the kernels only read them."""
    from topopose.topology.thinning_kernels import Ack3Cliques, Neighbourhood

    rows = [(dx, dy, 0) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
    opp, _ = _bits()
    nbr = Neighbourhood(_flat_offsets(np.concatenate([nb.OFFSETS, rows]), shape), opp,
                        _flat_offsets(nb.DIRECTIONS, shape))
    ack = Ack3Cliques(*nb.ack_bits())
    cliques = ack._replace(e_ooff=_flat_offsets(ack.e_ooff, shape), k_ooff=_flat_offsets(ack.k_ooff, shape))
    return tuple(nbr), tuple(cliques)


def _flat_offsets(offsets, shape) -> np.ndarray:
    _, sy, sz = shape
    o = np.asarray(offsets, dtype=np.int64)
    return o[..., 0] * (sy * sz) + o[..., 1] * sz + o[..., 2]


@lru_cache(maxsize=1)
def _bits():
    """Shape-independent bit tables of the kernels."""
    opp = np.array([nb.bit_of(-o) for o in nb.OFFSETS], dtype=np.int64)
    pk, pkn = nb.all_templates(nb.PKD6_BASE)
    d6, d6n = nb.all_templates(nb.D6I1D_BASE)
    return opp, {"pkd6": (pk, pkn), "d6": (d6, d6n)}


def _bbox(data):
    """(lo, hi, rows): bounds of the object and which (x, y) rows hold object voxels."""
    from topopose.topology.thinning_kernels import bounding_box, bounding_box_flat

    u = data.view(np.uint8)
    if u.flags.c_contiguous:
        return bounding_box_flat(u.reshape(-1), *u.shape)
    return bounding_box(u)


def thinning(volume, method: str = "d6i1d", keep=None, *, border_list: bool = True,
             lut: bool = True, ccsu=True, complete: bool = True, specialized=None) -> Thinning:
    """Thin a volume and return the skeleton with the constraint set and counters.

    See :func:`thin` for the parameters.  ``specialized``: compile the options into the
    kernel (a kernel per combination, 2–3× faster); ``None`` (default) does so for the
    default options only and uses one generic kernel for the others (benchmarks of
    the optimizations pass ``True`` so that every variant is compiled alike).
    """
    t0 = time.perf_counter()
    data = _as_volume(volume)
    if not isinstance(method, str) or method.lower() not in METHODS:
        raise InputError(f"method: unknown thinning method {method!r}; expected one of {', '.join(METHODS)}")
    method = method.lower()
    modes = {False: 0, True: 1, "rows": 1, "full": 2}
    if not isinstance(ccsu, (bool, str)) or ccsu not in modes:
        raise InputError(f"ccsu: expected True, False, 'rows' or 'full', got {ccsu!r}")
    mode = modes[ccsu]
    if keep is not None:
        keep = _as_volume(keep, "keep")
        if keep.shape != data.shape:
            raise InputError(f"keep: shape {keep.shape} differs from the volume's {data.shape}")
    out = _zeros(data.shape)
    kout = _zeros(data.shape)
    lo, hi, rows_any = _bbox(data)
    if lo[0] > hi[0]:  # no object voxel
        return Thinning(out, kout, method, 0, 0, {"total": (time.perf_counter() - t0) * 1e3})
    from topopose.topology.thinning_kernels import MaskSet, extract, fill_state_rows

    kin = keep.view(np.uint8) if keep is not None else np.zeros((0, 0, 0), dtype=np.uint8)
    size = int((hi[0] - lo[0] + 3) * (hi[1] - lo[1] + 3) * (hi[2] - lo[2] + 3))
    if size >= 1 << 31:
        raise InputError(f"volume: the object's bounding box (+1 voxel frame) holds {size} voxels; "
                         "the thinning kernels index voxels with 32-bit integers (at most 2^31 - 1)")
    vf = _zeros((size,), np.uint8)
    vf, shp, n_obj = fill_state_rows(data.view(np.uint8), kin, lo, hi, rows_any, vf)
    shape = tuple(int(v) for v in shp)
    tables = _tables() if lut else _no_tables()
    nbr, cliques = _shape_offsets(shape)
    t1 = time.perf_counter()
    if method in _DIRECTIONAL:
        psi, which, fin = _DIRECTIONAL[method]
        templates, tcount = _bits()[1][which]
        stats = np.zeros(5, dtype=np.int64)
        kernel = _kernel("directional", bool(lut), mode, specialized)
        btab = _byte_table(which) if lut else _no_tables().ravel()
        masks = tuple(MaskSet(templates, tcount, btab))
        iters, deleted = kernel(vf, nbr, tables, masks, psi, bool(border_list), fin if complete else 0, stats,
                                bool(lut), mode, int(n_obj))
        counters = dict(zip(("visits", "tests", "isthmus_tests", "initial_list", "completion_deleted"),
                            stats.tolist()))
    else:
        ack3_thin = _kernel("ack3", bool(lut), mode, specialized)
        counters = {}
        btab = _byte_table("ack3") if lut else _no_tables().ravel()
        etab = _edge_table() if lut else _no_edge_table()
        iters, deleted = ack3_thin(vf, nbr, tables, btab, etab, 1, bool(border_list), cliques, bool(lut),
                                   mode, int(n_obj))
    t2 = time.perf_counter()
    extract(vf, shp, lo, out.view(np.uint8), kout.view(np.uint8))  # sparse write-back
    t3 = time.perf_counter()
    return Thinning(out, kout, method, int(iters), int(deleted),
                    {"prepare": (t1 - t0) * 1e3, "thin": (t2 - t1) * 1e3, "total": (t3 - t0) * 1e3},
                    counters)


@lru_cache(maxsize=None)
def _kernel(kind, lut, mode, specialized=None):
    """The kernel for these options: specialized (options compiled in) for the default
    options or when ``specialized``; else the generic kernel (options read at run time)."""
    if specialized is None:
        specialized = lut and mode == 1
    return _make_kernel(kind, lut, mode) if specialized else _make_kernel(kind, None, None)


@lru_cache(maxsize=None)
def _make_kernel(kind, lut, mode):
    from topopose.topology import thinning_kernels as tk

    if kind == "ack3":
        return tk.make_ack3_thin(lut, mode)
    return tk.make_directional_thin(lut, mode)


def _tables():
    from topopose.topology.tables import load_tables

    return load_tables()


def _byte_table(kind):
    from topopose.topology.tables import load_byte_table

    return load_byte_table(kind)


def _edge_table():
    from topopose.topology.tables import load_ack3_edge_table

    return load_ack3_edge_table()


@lru_cache(maxsize=1)
def _no_edge_table():
    t = np.zeros(1, dtype=np.uint16)
    t.setflags(write=False)
    return t


@lru_cache(maxsize=1)
def _no_tables():
    """Stand-in for the tables when ``lut=False`` (read-only, like the real ones, so the
    generic kernel is compiled once)."""
    t = np.zeros((15, 1), dtype=np.uint8)
    t.setflags(write=False)
    return t


def thin(volume, method: str = "d6i1d", keep=None, *, border_list: bool = True, lut: bool = True,
         ccsu=True, complete: bool = True) -> np.ndarray:
    """Curve (or ultimate, or surface) skeleton by topology-preserving thinning.

    Parameters
    ----------
    volume : ndarray of bool, shape (nx, ny, nz), or a :class:`topopose.Volume`
        The object X (26-adjacency; background 6-adjacency).  It may touch the array
        border: it is thinned inside a one-voxel background frame.
    method : {"d6i1d", "pkd6", "d6u", "d6i2d", "ack3"}
        * ``"pkd6"``: Palágyi–Kuba 6-subiteration thinning (thesis §6.1.2, Alg. 10),
          curve skeleton keeping curve end points.
        * ``"d6i1d"``: isthmus-based 6-directional thinning (thesis §6.2, Alg. 11–12):
          K ← K ∪ {1D isthmuses} each iteration, then six subiterations with masks M'_d.
        * ``"d6u"``: D6I1D with Ψ = ∅, ultimate skeleton (thesis §6.4.1).
        * ``"d6i2d"``: D6I1D with Ψ = 2D isthmuses, surface skeleton (thesis §6.4.2).
        * ``"ack3"``: asymmetric critical-kernel thinning with 1D isthmuses (thesis
          §5.2, Alg. 7 in its LUT form Alg. 8).
    keep : ndarray of bool, optional
        Voxels that must survive (the initial constraint set K, e.g.
        :func:`border_constraint` for incomplete models, thesis §12.1).
    border_list, lut : bool
        Border list (thesis §5.1.1) and look-up tables (§5.1.2, §5.2) instead of
        testing every object voxel / matching masks and counting components.
    ccsu : bool or {"rows", "full"}
        Configuration computation speed-up (§5.3).  ``True`` / ``"rows"``: every voxel
        keeps the object bits of its z-triplet, updated on deletion (3 writes), so a
        configuration is read from 9 bytes instead of 26 (fastest here);
        ``"full"``: the thesis' variant, each listed voxel keeps its whole 26-bit word,
        updated in the 26 neighbours of every deleted voxel; ``False``: gather the 26
        neighbours at every test.
        None of these options changes the result (ACK3 without ``border_list`` visits
        voxels in another order, so its asymmetric choices may differ).
    complete : bool
        After the parallel directional phase, delete sequentially (thesis §4.3.1) the
        simple voxels the masks could not reach: not in K and, for PKD6 / D6I1D, not
        curve end points; for D6U all of them (ultimate skeleton).  This makes the
        result thin (no voxel simple unless in K or an end point).  No effect on
        D6I2D and ACK3.

    Returns
    -------
    ndarray of bool, same shape as ``volume``.

    Raises
    ------
    InputError
        Not a 3D boolean array, an empty array, a ``keep`` of another shape, or an
        unknown method.
    """
    return thinning(volume, method, keep, border_list=border_list, lut=lut, ccsu=ccsu,
                    complete=complete).skeleton


def border_constraint(volume) -> np.ndarray:
    """Keep mask for incomplete models (thesis §12.1).

    The object voxel nearest (Euclidean, ties broken by the lowest index) to the
    centroid of the object voxels lying on the array boundary; an empty mask when the
    object does not touch the boundary.
    """
    data = _as_volume(volume)
    out = np.zeros(data.shape, dtype=bool)
    onb = np.zeros(data.shape, dtype=bool)
    for ax in range(3):
        for end in (0, -1):
            idx = [slice(None)] * 3
            idx[ax] = end
            onb[tuple(idx)] = data[tuple(idx)]
    pts = np.argwhere(onb)
    if len(pts) == 0:
        return out
    c = pts.mean(axis=0)
    obj = np.argwhere(data)
    d2 = ((obj - c) ** 2).sum(axis=1)
    out[tuple(obj[int(np.argmin(d2))])] = True
    return out
