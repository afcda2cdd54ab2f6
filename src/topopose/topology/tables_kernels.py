"""Numba kernels: connectivity numbers on 27-bit words and the 2^26 look-up tables.

Connectivity numbers (thesis §4.1.1.3) are computed with bit-parallel flood fills on
the 27-bit word of the 3×3×3 cube (bit ``k = 9(dx+1) + 3(dy+1) + (dz+1)``): a dilation
is a handful of shifts and masks, so one T26 / T̄6 pair costs well under a microsecond.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

FULL27 = (1 << 27) - 1
CENTRE_BIT = 1 << 13


def _mask27(pred):
    m = 0
    for k in range(27):
        a, b, c = k // 9, (k // 3) % 3, k % 3
        if pred(a, b, c):
            m |= 1 << k
    return m


# positions whose coordinate is not 0 / not 2 (to stop shifts wrapping around)
_NOT_A0 = _mask27(lambda a, b, c: a != 0)
_NOT_A2 = _mask27(lambda a, b, c: a != 2)
_NOT_B0 = _mask27(lambda a, b, c: b != 0)
_NOT_B2 = _mask27(lambda a, b, c: b != 2)
_NOT_C0 = _mask27(lambda a, b, c: c != 0)
_NOT_C2 = _mask27(lambda a, b, c: c != 2)
#: face neighbours (N6*) and N18* in the 27-bit word
N6_27 = _mask27(lambda a, b, c: abs(a - 1) + abs(b - 1) + abs(c - 1) == 1)
N18_27 = _mask27(lambda a, b, c: abs(a - 1) + abs(b - 1) + abs(c - 1) in (1, 2))


@njit(cache=True, inline="always")
def expand26(cfg):
    """26-bit configuration index -> 27-bit word (centre bit clear)."""
    return (cfg & 0x1FFF) | ((cfg >> 13) << 14)


@njit(cache=True, inline="always")
def compress27(w):
    """27-bit word -> 26-bit configuration index (centre dropped)."""
    return (w & 0x1FFF) | ((w >> 14) << 13)


@njit(cache=True, inline="always")
def _dil6(w):
    return (w | ((w << 1) & _NOT_C0) | ((w >> 1) & _NOT_C2) | ((w << 3) & _NOT_B0)
            | ((w >> 3) & _NOT_B2) | ((w << 9) & _NOT_A0) | ((w >> 9) & _NOT_A2)) & FULL27


@njit(cache=True, inline="always")
def _dil26(w):
    w = w | ((w << 1) & _NOT_C0) | ((w >> 1) & _NOT_C2)
    w = w | ((w << 3) & _NOT_B0) | ((w >> 3) & _NOT_B2)
    w = w | ((w << 9) & _NOT_A0) | ((w >> 9) & _NOT_A2)
    return w & FULL27


@njit(cache=True)
def t26_word(w):
    """T26(p, X): number of 26-components of X ∩ N26*(p) (27-bit word, centre ignored)."""
    s = w & (FULL27 ^ CENTRE_BIT)
    n = 0
    while s:
        comp = s & (-s)
        while True:
            nxt = _dil26(comp) & s
            if nxt == comp:
                break
            comp = nxt
        s &= ~comp
        n += 1
    return n


@njit(cache=True)
def t6bar_word(w):
    """T̄6 = T6(p, X̄): 6-components of the 6-geodesic neighbourhood G6(p, X̄) (§4.1.1.3).

    G6(p, X̄) = N6²(p, X̄): the background 6-neighbours of ``p`` plus their background
    6-neighbours inside N26*(p); its 6-components are the 6-components of X̄ ∩ N18*(p)
    that contain a 6-neighbour of ``p``.
    """
    s = (~w) & N18_27
    seeds = s & N6_27
    n = 0
    while seeds:
        comp = seeds & (-seeds)
        while True:
            nxt = _dil6(comp) & s
            if nxt == comp:
                break
            comp = nxt
        s &= ~comp
        seeds &= ~comp
        n += 1
    return n


@njit(cache=True, inline="always")
def match_set(cfg, templates, d, count):
    """True when ``cfg`` matches one template of set ``d`` (``templates[d, :count]``)."""
    for m in range(count):
        ones = templates[d, m, 0]
        if cfg & ones != ones:
            continue
        if cfg & templates[d, m, 1]:
            continue
        xs = templates[d, m, 2]
        if xs != 0 and (cfg & xs) == 0:
            continue
        return True
    return False


# plane numbers of the packed table
PLANE_PKD6 = 0      # 0..5: PKD6 deletable in U, D, N, S, E, W
PLANE_D6 = 6        # 6..11: deletable by the D6I1D masks M'_d
PLANE_SIMPLE = 12
PLANE_ISTHMUS1D = 13
PLANE_ISTHMUS2D = 14
N_PLANES = 15


@njit(cache=True, parallel=True)
def build_tables(pk_t, pk_n, d6_t, d6_n, dir_bits):
    """All 15 bit planes of the 2^26 table, shape (15, 2^23) uint8 (bit ``c & 7`` of byte ``c >> 3``)."""
    nbytes = 1 << 23
    out = np.zeros((N_PLANES, nbytes), dtype=np.uint8)
    for j in prange(nbytes):
        lo = np.int64(0)   # planes 0..7, 8 bits each
        hi = np.int64(0)   # planes 8..14
        for b in range(8):
            cfg = np.int64(j * 8 + b)
            w = expand26(cfg)
            v = np.int64(0)
            t26 = t26_word(w)
            t6 = t6bar_word(w)
            if t26 == 1 and t6 == 1:
                v |= 1 << PLANE_SIMPLE
            if t26 >= 2:
                v |= 1 << PLANE_ISTHMUS1D
            if t6 >= 2:
                v |= 1 << PLANE_ISTHMUS2D
            for d in range(6):
                if (cfg >> dir_bits[d]) & 1:
                    continue  # every mask of direction d needs its d-neighbour in the background
                if match_set(cfg, pk_t, d, pk_n[d]):
                    v |= 1 << (PLANE_PKD6 + d)
                if match_set(cfg, d6_t, d, d6_n[d]):
                    v |= 1 << (PLANE_D6 + d)
            for p in range(8):
                lo |= ((v >> p) & 1) << (8 * p + b)
            for p in range(8, N_PLANES):
                hi |= ((v >> p) & 1) << (8 * (p - 8) + b)
        for p in range(8):
            out[p, j] = np.uint8((lo >> (8 * p)) & 0xFF)
        for p in range(8, N_PLANES):
            out[p, j] = np.uint8((hi >> (8 * (p - 8))) & 0xFF)
    return out


@njit(cache=True, inline="always")
def table_bit(tables, plane, cfg):
    return (tables[plane, cfg >> 3] >> (cfg & 7)) & 1


@njit(cache=True, parallel=True)
def pack_byte_table(tables, planes):
    """One byte per configuration: bit ``k`` = plane ``planes[k]`` of the bit table.

    ``tables`` (15, 2^23) bit planes; ``planes`` (8,) plane numbers.  Returns a 2^26
    uint8 array, so one read answers the eight tests of a configuration (ALGORITHMS.md
    §5, the packed-byte design).
    """
    nbytes = tables.shape[1]
    out = np.empty(nbytes * 8, dtype=np.uint8)
    for j in prange(nbytes):
        for b in range(8):
            v = 0
            for k in range(8):
                v |= ((tables[planes[k], j] >> b) & 1) << k
            out[j * 8 + b] = np.uint8(v)
    return out


@njit(cache=True, inline="always")
def section2d(cfg, c2_a, c2_b, d):
    """8-bit 2D section of the 2-clique {p, p + d} (ACK3, thesis §5.2.2): bit k set
    when column k of R (``c2_a[d, k]`` in p's layer or ``c2_b[d, k]`` in the
    neighbour's) holds an object voxel."""
    s8 = 0
    for k in range(8):
        if ((cfg >> c2_a[d, k]) | (cfg >> c2_b[d, k])) & 1:
            s8 |= 1 << k
    return s8


@njit(cache=True, inline="always")
def edge_critical(cfg, e, e_f1, e_f2, e_ed, e_u, e_v):
    """1-clique geometry around edge ``e`` (thesis §5.2.1, Def. 3): X ∩ {E, F, G, H}
    holds a diagonal pair and the sets U and V are both hit or both missed."""
    diag = ((cfg >> e_ed[e]) & 1) | ((cfg >> e_f1[e]) & (cfg >> e_f2[e]) & 1)
    return diag != 0 and ((cfg & e_u[e]) != 0) == ((cfg & e_v[e]) != 0)


@njit(cache=True, parallel=True)
def build_ack3_byte_table(tables, c2_a, c2_b, nonsimple2d, dir_bits):
    """ACK3 byte table (thesis §5.2.2, Alg. 8; ALGORITHMS.md §4), one uint8 per configuration.

    Bit ``d`` (0–5): the d-neighbour is an object voxel and R, the centre column of the
    3×3×2 block around the face shared with it, is not simple in the 2D section
    (``nonsimple2d`` of the 8-bit section, ``c2_a/c2_b`` the bits of its columns): the
    2-clique {p, p + d} is critical when both its voxels are simple and unconstrained.
    Bit 6: simple (plane 12 of ``tables``); bit 7: 1D isthmus (plane 13).
    """
    n = tables.shape[1] * 8
    out = np.empty(n, dtype=np.uint8)
    for c in prange(n):
        cfg = np.int64(c)
        v = 0
        for d in range(6):
            if (cfg >> dir_bits[d]) & 1 == 0:
                continue
            if nonsimple2d[section2d(cfg, c2_a, c2_b, d)]:
                v |= 1 << d
        v |= ((tables[12, c >> 3] >> (c & 7)) & 1) << 6
        v |= ((tables[13, c >> 3] >> (c & 7)) & 1) << 7
        out[c] = np.uint8(v)
    return out


@njit(cache=True, parallel=True)
def build_ack3_edge_table(e_f1, e_f2, e_ed, e_u, e_v):
    """ACK3 1-clique geometry (thesis §5.2.1, Def. 3; ALGORITHMS.md §4), one uint16 per
    configuration: bit ``e`` (0–11) when, around edge ``e`` of p's cube, X ∩ {E, F, G, H}
    holds a diagonal pair (p and the edge neighbour, or the two face neighbours) and
    the voxel sets U and V on either side are both hit or both missed by X.
    """
    n = 1 << 26
    out = np.empty(n, dtype=np.uint16)
    for c in prange(n):
        cfg = np.int64(c)
        v = 0
        for e in range(12):
            if edge_critical(cfg, e, e_f1, e_f2, e_ed, e_u, e_v):
                v |= 1 << e
        out[c] = np.uint16(v)
    return out
