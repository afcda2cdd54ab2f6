"""Neighbourhood encoding and the directional deletion masks (thesis §4.1, §5.1.2.1, §6.1.2, §6.2.1).

The 26-bit configuration index
------------------------------
Arrays are indexed ``[x, y, z]`` (C order, z fastest).  The 27 positions of the
3×3×3 cube around a voxel ``p`` are numbered in raster (memory) order::

    k = (dx + 1) * 9 + (dy + 1) * 3 + (dz + 1),   dx, dy, dz in {-1, 0, 1}

so the centre is ``k = 13``.  The 26-bit configuration index of ``p`` (thesis
§5.1.2.1, ``K(v) = Σ 2^i v_i``) uses bit ``i = k`` for ``k < 13`` and ``i = k - 1`` for
``k > 13``: the order of the image in memory, which the thesis recommends when one
table serves every test.  ``OFFSETS[i]`` is the (dx, dy, dz) offset of bit ``i``.
Internally the kernels also use the 27-bit word (bit ``k``, centre bit 13 clear).

Directions
----------
The six subiteration directions of the 6-directional algorithms (thesis Fig. 4.9,
Alg. 10–11) are, in this order: U = +z, D = −z, N = +y, S = −y, E = +x, W = −x.
``DIRECTIONS[d]`` is the unit offset of direction ``d``; a voxel can be deleted in
subiteration ``d`` only when its neighbour in direction ``d`` is background.

Masks
-----
``PKD6_BASE`` holds the six masks M1–M6 of Palágyi & Kuba (thesis Fig. 6.1, restored in
ALGORITHMS.md §2) for direction U; ``D6I1D_BASE`` the reduced set M'1–M'7 of thesis
Fig. 6.3 (M'1 = M1 ∪ Mα, M'5 = M5 ∪ Mβ, M'7 = Mγ; ALGORITHMS.md §3).  Each mask is three
3×3 layers from the U side (dz = +1) to the D side (dz = −1); rows are dx, columns dy.
Every mask is used with its four rotations about the U–D axis; the sets of the other
directions are the images of the U set by a signed axis permutation carrying +z onto
that direction (the U sets are invariant under the reflections that fix +z, so the
choice of that map does not matter — checked in the tests).
"""
from __future__ import annotations

from functools import lru_cache
from itertools import product

import numpy as np

CENTRE = 13

#: (26, 3) int offsets, row i = neighbour of bit i.
OFFSETS = np.array([(k // 9 - 1, (k // 3) % 3 - 1, k % 3 - 1) for k in range(27) if k != CENTRE],
                   dtype=np.int64)

DIRECTION_NAMES = ("U", "D", "N", "S", "E", "W")
#: unit offsets of U, D, N, S, E, W
DIRECTIONS = np.array([(0, 0, 1), (0, 0, -1), (0, 1, 0), (0, -1, 0), (1, 0, 0), (-1, 0, 0)],
                      dtype=np.int64)

# Signed axis maps T_d (3×3 integer matrices) with T_d @ (0, 0, 1) = DIRECTIONS[d].
_DIR_MAPS = [
    np.eye(3, dtype=np.int64),                                   # U: identity
    np.diag([1, 1, -1]).astype(np.int64),                        # D: z -> -z
    np.array([[1, 0, 0], [0, 0, 1], [0, 1, 0]], dtype=np.int64),  # N: swap y, z
    np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=np.int64),  # S
    np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0]], dtype=np.int64),  # E: swap x, z
    np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]], dtype=np.int64),  # W
]


def bit_of(offset) -> int:
    """Bit index (0..25) of the neighbour at ``offset = (dx, dy, dz)``."""
    dx, dy, dz = (int(v) for v in offset)
    k = (dx + 1) * 9 + (dy + 1) * 3 + (dz + 1)
    if k == CENTRE or not (0 <= k < 27) or max(abs(dx), abs(dy), abs(dz)) > 1:
        raise ValueError(f"offset {offset} is not a 26-neighbour")
    return k if k < CENTRE else k - 1


def config_index(cube) -> int:
    """26-bit configuration index of a 3×3×3 boolean cube (its centre is ignored)."""
    c = np.asarray(cube, dtype=bool).reshape(27)
    idx = 0
    for i, (dx, dy, dz) in enumerate(OFFSETS):
        if c[(dx + 1) * 9 + (dy + 1) * 3 + (dz + 1)]:
            idx |= 1 << i
    return idx


def config_cube(index: int) -> np.ndarray:
    """3×3×3 boolean cube of a 26-bit configuration index, centre set (the voxel tested)."""
    c = np.zeros(27, dtype=bool)
    c[CENTRE] = True
    for i, (dx, dy, dz) in enumerate(OFFSETS):
        if (int(index) >> i) & 1:
            c[(dx + 1) * 9 + (dy + 1) * 3 + (dz + 1)] = True
    return c.reshape(3, 3, 3)


def permutation_of(matrix) -> np.ndarray:
    """``perm[i]`` = bit that neighbour ``i`` moves to under the linear map ``matrix``."""
    m = np.asarray(matrix, dtype=np.int64)
    return np.array([bit_of(m @ o) for o in OFFSETS], dtype=np.int64)


def permute_config(index: int, perm) -> int:
    """Image of a configuration index under a bit permutation from :func:`permutation_of`."""
    out = 0
    for i, j in enumerate(perm):
        if (int(index) >> i) & 1:
            out |= 1 << int(j)
    return out


def cube_symmetries() -> list[np.ndarray]:
    """The 48 signed permutation matrices (symmetries of the cube)."""
    from itertools import permutations, product

    mats = []
    for perm in permutations(range(3)):
        for signs in product((1, -1), repeat=3):
            m = np.zeros((3, 3), dtype=np.int64)
            for r, (c, s) in enumerate(zip(perm, signs)):
                m[r, c] = s
            mats.append(m)
    return mats


# ----------------------------------------------------------------------------- masks
# Layers from the U side (dz=+1) through the middle (dz=0) to the D side (dz=-1);
# within a layer, row = dx + 1, column = dy + 1.  'p' centre, '1' object, '0'
# background, '.' free, 'x' at least one x is object.
PKD6_BASE = {
    "M1": ("000 000 000", "xxx xpx xxx", "xxx x1x xxx"),
    "M2": ("... 000 000", ".1. .p. ...", "... .1. ..."),
    "M3": ("... 00. 00.", ".1. .p1 ...", "... .1. ..."),
    "M4": ("001 000 000", "..1 .p. ...", "... .1. ..."),
    "M5": ("000 000 000", "xxx xpx 000", "x1x x0x 000"),
    "M6": ("000 000 000", "... 0p. 00.", ".1. 001 00."),
}

# thesis Fig. 6.3 (ALGORITHMS.md §3, an inference restored from the text):
# M'1 = M1 without its x condition, M'5 = M5 without its x condition, M'7 = Mγ.
D6I1D_BASE = {
    "M'1": ("000 000 000", "... .p. ...", "... .1. ..."),
    "M'2": PKD6_BASE["M2"],
    "M'3": PKD6_BASE["M3"],
    "M'4": PKD6_BASE["M4"],
    "M'5": ("000 000 000", "... .p. 000", ".1. .0. 000"),
    "M'6": PKD6_BASE["M6"],
    "M'7": ("000 000 000", "000 0p0 000", "100 000 000"),
}


def _parse(mask) -> dict:
    """{offset: char} of a mask given as three layer strings (U side first)."""
    cells = {}
    for layer, text in enumerate(mask):
        rows = text.split()
        dz = 1 - layer
        for r, row in enumerate(rows):
            for c, ch in enumerate(row):
                if (r, c, dz) == (1, 1, 0):
                    if ch != "p":
                        raise ValueError(f"mask centre must be 'p': {mask}")
                    continue
                cells[(r - 1, c - 1, dz)] = ch
    return cells


def _template(cells: dict, matrix) -> tuple[int, int, int]:
    """(ones, zeros, xs) 26-bit masks of a parsed mask mapped by ``matrix``."""
    m = np.asarray(matrix, dtype=np.int64)
    ones = zeros = xs = 0
    for off, ch in cells.items():
        b = 1 << bit_of(m @ np.array(off))
        if ch == "1":
            ones |= b
        elif ch == "0":
            zeros |= b
        elif ch == "x":
            xs |= b
    return ones, zeros, xs


_ROT_Z = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], dtype=np.int64)


def mask_templates(base: dict, direction: int) -> np.ndarray:
    """Templates ``(n, 3)`` int64 ``[ones, zeros, xs]`` of a mask set for one direction.

    A configuration ``c`` matches a template when ``c & ones == ones``, ``c & zeros == 0``
    and (``xs == 0`` or ``c & xs != 0``).  Duplicates (symmetric masks) are removed.
    """
    out = []
    seen = set()
    for mask in base.values():
        cells = _parse(mask)
        rot = np.eye(3, dtype=np.int64)
        for _ in range(4):
            t = _template(cells, _DIR_MAPS[direction] @ rot)
            if t not in seen:
                seen.add(t)
                out.append(t)
            rot = _ROT_Z @ rot
    return np.array(out, dtype=np.int64)


def all_templates(base: dict) -> tuple[np.ndarray, np.ndarray]:
    """Templates of the six directions packed as ``(6, nmax, 3)`` plus counts ``(6,)``."""
    per = [mask_templates(base, d) for d in range(6)]
    nmax = max(len(t) for t in per)
    arr = np.zeros((6, nmax, 3), dtype=np.int64)
    counts = np.zeros(6, dtype=np.int64)
    for d, t in enumerate(per):
        arr[d, : len(t)] = t
        counts[d] = len(t)
    return arr, counts


def matches(index: int, templates) -> bool:
    """Pure-Python template test (reference for the kernels)."""
    for ones, zeros, xs in np.asarray(templates).reshape(-1, 3):
        if index & ones == ones and index & zeros == 0 and (xs == 0 or index & xs):
            return True
    return False


def _nonsimple2d() -> np.ndarray:
    """R non-simple in 2D (8-adjacency object, 4-adjacency background) for the 256 sections."""
    pos = [(u, v) for u in (-1, 0, 1) for v in (-1, 0, 1) if (u, v) != (0, 0)]
    out = np.zeros(256, dtype=np.uint8)

    def ncomp(cells, adj):
        cells = set(cells)
        comps = []
        while cells:
            stack = [cells.pop()]
            comp = set(stack)
            while stack:
                a = stack.pop()
                for b in list(cells):
                    if adj(a, b):
                        cells.discard(b)
                        comp.add(b)
                        stack.append(b)
            comps.append(comp)
        return comps

    a8 = lambda a, b: max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1  # noqa: E731
    a4 = lambda a, b: abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1  # noqa: E731
    for s in range(256):
        obj = [pos[k] for k in range(8) if (s >> k) & 1]
        bg = [pos[k] for k in range(8) if not (s >> k) & 1]
        t8 = len(ncomp(obj, a8))
        t4 = sum(1 for c in ncomp(bg, a4) if any(abs(u) + abs(v) == 1 for u, v in c))
        out[s] = not (t8 == 1 and t4 == 1)
    return out


@lru_cache(maxsize=1)
def ack_bits():
    """Clique geometry of ACK3 as neighbour bits (thesis §5.2.1, Def. 3; ALGORITHMS.md §4)."""
    axes = np.eye(3, dtype=np.int64)
    pos2d = [(u, v) for u in (-1, 0, 1) for v in (-1, 0, 1) if (u, v) != (0, 0)]
    c2_a = np.zeros((6, 8), dtype=np.int64)
    c2_b = np.zeros((6, 8), dtype=np.int64)
    for d, a in enumerate(DIRECTIONS):
        ax = int(np.flatnonzero(a)[0])
        e1, e2 = (axes[i] for i in range(3) if i != ax)
        for k, (u, v) in enumerate(pos2d):
            c2_a[d, k] = bit_of(u * e1 + v * e2)
            c2_b[d, k] = bit_of(a + u * e1 + v * e2)
    # 1-cliques: the 12 edges of p's cube
    e_f1, e_f2, e_ed, e_u, e_v, e_oth, e_ooff = [], [], [], [], [], [], []
    for ax in range(3):
        b, c = (i for i in range(3) if i != ax)
        for s1, s2 in product((1, -1), repeat=2):
            f1, f2 = s1 * axes[b], s2 * axes[c]
            ring = [np.zeros(3, np.int64), f1, f2, f1 + f2]
            e_f1.append(bit_of(f1))
            e_f2.append(bit_of(f2))
            e_ed.append(bit_of(f1 + f2))
            e_u.append(sum(1 << bit_of(r + axes[ax]) for r in ring))
            e_v.append(sum(1 << bit_of(r - axes[ax]) for r in ring))
            e_oth.append([bit_of(r) for r in ring[1:]])
            e_ooff.append([r for r in ring[1:]])
    # 0-cliques: the 8 unit cubes having p as a corner
    k_bits, k_pairs, k_off = [], [], []
    for sx, sy, sz in product((1, -1), repeat=3):
        ex, ey, ez = sx * axes[0], sy * axes[1], sz * axes[2]
        others = [ex, ey, ez, ex + ey, ex + ez, ey + ez, ex + ey + ez]
        k_bits.append([bit_of(o) for o in others])
        k_off.append(others)
        # voxels of the cube beyond the vertex along each axis
        k_pairs.append([sum(1 << bit_of(o) for o in others if o[ax] != 0) for ax in range(3)])
    i64 = lambda x: np.array(x, dtype=np.int64)  # noqa: E731
    return (c2_a, c2_b, _nonsimple2d(), i64(e_f1), i64(e_f2), i64(e_ed), i64(e_u), i64(e_v),
            i64(e_oth), i64(e_ooff), i64(k_bits), i64(k_pairs), i64(k_off))
