"""The 2^26 look-up tables: exact, cross-checked against an independent BFS, cached.

Oracles: a second implementation of the definitions of thesis §4.1 (BFS over the
coordinates of the 3×3×3 cube, no bit tricks) on all 2^26 configurations; a pure
Python template matcher on random configurations; symmetry facts about the masks.
"""
import subprocess
import sys
import time

import numpy as np
import pytest
from numba import njit, prange

from topopose.topology import neighbourhood as nb
from topopose.topology import t6bar, t26, is_simple, config_index, config_cube
from topopose.topology.tables import load_tables, table_key, cache_dir

# ----------------------------------------------------------------------------- BFS oracle
_COORDS = np.array([(k // 9 - 1, (k // 3) % 3 - 1, k % 3 - 1) for k in range(27)], dtype=np.int64)


def _adjacency(kind):
    adj = -np.ones((27, 26), dtype=np.int64)
    for a in range(27):
        m = 0
        for b in range(27):
            d = np.abs(_COORDS[a] - _COORDS[b])
            if a != b and ((kind == 26 and d.max() == 1) or (kind == 6 and d.sum() == 1)):
                adj[a, m] = b
                m += 1
    return adj


ADJ26 = _adjacency(26)
ADJ6 = _adjacency(6)
# bit i of the 26-bit index -> cube cell k (centre 13 skipped)
CELL = np.array([k for k in range(27) if k != 13], dtype=np.int64)
L1 = np.abs(_COORDS).sum(axis=1)
LINF = np.abs(_COORDS).max(axis=1)


def _adjmask(adj):
    m = np.zeros(27, dtype=np.int64)
    for a in range(27):
        for b in adj[a]:
            if b >= 0:
                m[a] |= 1 << int(b)
    return m


AM26 = _adjmask(ADJ26)
AM6 = _adjmask(ADJ6)
FACE27 = sum(1 << k for k in range(27) if L1[k] == 1)
# index of a power of two 2^k (k < 36) from 2^k mod 37 (2 is a primitive root mod 37)
MOD37 = np.zeros(37, dtype=np.int64)
for _k in range(36):
    MOD37[(1 << _k) % 37] = _k


@njit(cache=True)
def _components(member, adjm, mod37):
    """Number of connected components of the cell set ``member`` (27-bit), by a BFS
    with an explicit queue of cells; ``adjm[c]`` is the set of cells adjacent to c."""
    queue = np.empty(27, dtype=np.int64)
    seen = 0
    n = 0
    for s in range(27):
        if not (member >> s) & 1 or (seen >> s) & 1:
            continue
        n += 1
        seen |= 1 << s
        head = 0
        tail = 1
        queue[0] = s
        while head < tail:
            c = queue[head]
            head += 1
            new = adjm[c] & member & ~seen
            while new:
                low = new & -new
                b = mod37[low % 37]
                new ^= low
                seen |= 1 << b
                queue[tail] = b
                tail += 1
    return n


@njit(cache=True)
def _bfs_chunk(j0, j1, cell, am26, am6, face27, mod37, out):
    for j in range(j0, j1):
        b0 = 0
        b1 = 0
        b2 = 0
        for b in range(8):
            cfg = j * 8 + b
            x = 0
            for i in range(26):
                x |= ((cfg >> i) & 1) << cell[i]
            # T26: 26-components of X ∩ N26*(p)
            t26v = _components(x, am26, mod37)
            # G6(p, X̄) = N6²(p, X̄): background 6-neighbours of p, plus their background
            # 6-neighbours inside N26*(p) (p itself excluded); then its 6-components.
            bg = ((1 << 27) - 1) & ~x & ~(1 << 13)
            g6 = face27 & bg
            first = g6
            c = 0
            while first:
                if first & 1:
                    g6 |= am6[c] & bg
                first >>= 1
                c += 1
            t6v = _components(g6, am6, mod37)
            if t26v == 1 and t6v == 1:
                b0 |= 1 << b
            if t26v >= 2:
                b1 |= 1 << b
            if t6v >= 2:
                b2 |= 1 << b
        out[0, j] = b0
        out[1, j] = b1
        out[2, j] = b2


@njit(cache=True, parallel=True)
def bfs_planes(cell, am26, am6, face27, mod37):
    """Simple / 1D isthmus / 2D isthmus bits of every configuration, by BFS (3 packed planes)."""
    nbytes = 1 << 23
    out = np.zeros((3, nbytes), dtype=np.uint8)
    nchunks = 256
    step = nbytes // nchunks
    for k in prange(nchunks):
        _bfs_chunk(k * step, (k + 1) * step, cell, am26, am6, face27, mod37, out)
    return out


@pytest.fixture(scope="module")
def tables():
    return load_tables()


def test_bfs_cross_check_all_configurations(tables):
    """Simple, 1D- and 2D-isthmus planes equal an independent BFS on all 2^26 configurations."""
    ref = bfs_planes(CELL, AM26, AM6, FACE27, MOD37)
    for k, plane in enumerate((12, 13, 14)):
        diff = np.flatnonzero(ref[k] != tables[plane])
        assert diff.size == 0, f"plane {plane}: {diff.size} bytes differ, first at {diff[:5]}"


def test_every_deleted_configuration_is_simple(tables):
    simple = tables[12]
    for plane in range(12):
        bad = np.unpackbits(tables[plane] & ~simple).sum()
        assert bad == 0, f"plane {plane} deletes {bad} non-simple configurations"
    # and every mask set deletes something in its own direction only
    counts = [int(np.unpackbits(tables[p]).sum()) for p in range(12)]
    assert len(set(counts[:6])) == 1 and len(set(counts[6:])) == 1 and counts[0] > 10**6


def test_d6i1d_extra_configurations_are_end_points(tables):
    """M'_d deletes exactly PKD6's configurations plus the end points whose only
    neighbour lies on the side opposite to d (thesis §6.2.1: Mα, Mβ, Mγ)."""
    for d in range(6):
        pk = np.unpackbits(tables[d], bitorder="little").astype(bool)
        d6 = np.unpackbits(tables[6 + d], bitorder="little").astype(bool)
        assert not np.any(pk & ~d6)  # M'_d matches everything M_d matches
        extra = np.flatnonzero(d6 & ~pk)
        opposite = -nb.DIRECTIONS[d]
        want = sorted(1 << i for i, o in enumerate(nb.OFFSETS) if o @ opposite == 1)
        assert sorted(extra.tolist()) == want


def test_isthmus_and_simple_planes_are_consistent(tables):
    s = tables[12]
    assert not np.any(s & tables[13]) and not np.any(s & tables[14])


def test_mask_tables_against_python_templates(tables):
    rng = np.random.default_rng(1)
    # random configurations, biased towards sparse and dense ones, with the d-neighbour free
    cfgs = rng.integers(0, 1 << 26, 400)
    dense = rng.integers(0, 1 << 26, 400) | rng.integers(0, 1 << 26, 400)
    sparse = rng.integers(0, 1 << 26, 400) & rng.integers(0, 1 << 26, 400) & rng.integers(0, 1 << 26, 400)
    cfgs = np.concatenate([cfgs, dense, sparse, [0, (1 << 26) - 1]])
    for d in range(6):
        tp = nb.mask_templates(nb.PKD6_BASE, d)
        t6 = nb.mask_templates(nb.D6I1D_BASE, d)
        for c in cfgs.tolist():
            c0 = c & ~(1 << nb.bit_of(nb.DIRECTIONS[d]))
            for cc in (c, c0):
                got = (tables[d, cc >> 3] >> (cc & 7)) & 1
                assert got == nb.matches(cc, tp), (d, cc)
                got = (tables[6 + d, cc >> 3] >> (cc & 7)) & 1
                assert got == nb.matches(cc, t6), (d, cc)


def _template_set(t):
    return {tuple(r) for r in np.asarray(t).tolist()}


def test_mask_sets_symmetry():
    """The U set is invariant under the 8 symmetries fixing +z, so the direction sets
    do not depend on which map carries U onto the direction; every template of
    direction d requires the d-neighbour to be background."""
    for base in (nb.PKD6_BASE, nb.D6I1D_BASE):
        sets = [_template_set(nb.mask_templates(base, d)) for d in range(6)]
        for m in nb.cube_symmetries():
            perm = nb.permutation_of(m)
            img = np.array(m) @ np.array([0, 0, 1])
            d = [tuple(x) for x in nb.DIRECTIONS.tolist()].index(tuple(img.tolist()))
            mapped = {tuple(nb.permute_config(v, perm) if v else 0 for v in t) for t in sets[0]}
            assert mapped == sets[d]
        for d in range(6):
            db = 1 << nb.bit_of(nb.DIRECTIONS[d])
            assert all(z & db for _, z, _ in sets[d])


def test_encoding_round_trip_and_examples():
    rng = np.random.default_rng(0)
    for c in rng.integers(0, 1 << 26, 50).tolist():
        assert config_index(config_cube(c)) == c
    assert nb.bit_of((-1, -1, -1)) == 0 and nb.bit_of((0, 0, -1)) == 12 and nb.bit_of((0, 0, 1)) == 13
    assert nb.bit_of((1, 1, 1)) == 25
    # a voxel inside a solid: T26 = 1, T6bar = 0 -> not simple
    full = (1 << 26) - 1
    assert t26(full) == 1 and t6bar(full) == 0 and not is_simple(full)
    # isolated voxel: T26 = 0, T6bar = 1
    assert t26(0) == 0 and t6bar(0) == 1
    # a straight curve point (neighbours up and down): 1D isthmus
    c = (1 << nb.bit_of((0, 0, 1))) | (1 << nb.bit_of((0, 0, -1)))
    assert t26(c) == 2 and t6bar(c) == 1
    # a point of a plane z = 0: 2D isthmus (background above and below)
    cube = np.zeros((3, 3, 3), bool)
    cube[:, :, 1] = True
    assert t26(cube) == 1 and t6bar(cube) == 2
    # volume + point form, voxels outside the array are background
    vol = np.zeros((2, 2, 2), bool)
    vol[0, 0, 0] = vol[1, 1, 1] = True
    assert t26(vol, (0, 0, 0)) == 1


def test_cache_on_disk_and_fast_reload(tables):
    path = cache_dir() / f"luts-{table_key()}.npy"
    assert path.exists()
    code = ("import time, numpy; t=time.perf_counter(); from topopose.topology.tables import load_tables; "
            "t2=load_tables(); print(time.perf_counter()-t, int(t2[12, 12345]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    dt, val = out.stdout.split()
    assert float(dt) < 1.0
    assert int(val) == int(tables[12, 12345])


# ----------------------------------------------------------------------------- byte tables
def test_byte_tables_match_bit_planes(tables):
    """The packed byte tables (one read per configuration) equal the bit planes they pack."""
    from topopose.topology.tables import BYTE_PLANES, load_byte_table, lookup

    rng = np.random.default_rng(7)
    idx = np.concatenate([rng.integers(0, 1 << 26, 400_000), np.arange(1 << 13),
                          (1 << 26) - 1 - np.arange(1 << 13)])
    for kind in ("d6", "pkd6"):
        btab = load_byte_table(kind)
        assert btab.shape == (1 << 26,) and btab.dtype == np.uint8
        for k, plane in enumerate(BYTE_PLANES[kind]):
            assert np.array_equal((btab[idx] >> k) & 1, lookup(plane, idx).astype(np.uint8)), (kind, k)


def _ncomp2d(cells, adj):
    cells, n = set(cells), 0
    while cells:
        stack = [cells.pop()]
        n += 1
        while stack:
            a = stack.pop()
            for b in [b for b in cells if adj(a, b)]:
                cells.discard(b)
                stack.append(b)
    return n


def _ack3_oracle(cfg):
    """ACK3 byte and edge bits of one configuration from the coordinates (thesis §5.2.1,
    ALGORITHMS.md §4): no shared code with the table builders."""
    c = nb.config_cube(cfg)
    at = lambda o: bool(c[o[0] + 1, o[1] + 1, o[2] + 1])  # noqa: E731
    byte = 0
    ring = [(u, v) for u in (-1, 0, 1) for v in (-1, 0, 1) if (u, v) != (0, 0)]
    a8 = lambda a, b: max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1  # noqa: E731
    a4 = lambda a, b: abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1  # noqa: E731
    for d, a in enumerate(nb.DIRECTIONS):
        if not at(a):
            continue
        ax = int(np.flatnonzero(a)[0])
        e1, e2 = (np.eye(3, dtype=int)[i] for i in range(3) if i != ax)
        q = {(u, v): at(u * e1 + v * e2) or at(a + u * e1 + v * e2) for u, v in ring}
        obj = [r for r in ring if q[r]]
        bg = [r for r in ring if not q[r]]
        t8 = _ncomp2d(obj, a8)
        t4 = sum(1 for comp in _components2d(bg, a4) if any(abs(u) + abs(v) == 1 for u, v in comp))
        if not (t8 == 1 and t4 == 1):
            byte |= 1 << d
    edges = 0
    e = 0
    for ax in range(3):
        b1, b2 = (i for i in range(3) if i != ax)
        for s1 in (1, -1):
            for s2 in (1, -1):
                f1 = np.zeros(3, int)
                f1[b1] = s1
                f2 = np.zeros(3, int)
                f2[b2] = s2
                axis = np.zeros(3, int)
                axis[ax] = 1
                quad = [np.zeros(3, int), f1, f2, f1 + f2]
                diag = at(f1 + f2) or (at(f1) and at(f2))
                hu = any(at(r + axis) for r in quad)
                hv = any(at(r - axis) for r in quad)
                if diag and hu == hv:
                    edges |= 1 << e
                e += 1
    return byte, edges


def _components2d(cells, adj):
    cells, out = set(cells), []
    while cells:
        stack = [cells.pop()]
        comp = set(stack)
        while stack:
            a = stack.pop()
            for b in [b for b in cells if adj(a, b)]:
                cells.discard(b)
                comp.add(b)
                stack.append(b)
        out.append(comp)
    return out


def test_ack3_tables_match_definitions(tables):
    """ACK3's byte table (2-clique geometry, simple, 1D isthmus) and 1-clique edge table
    equal a coordinate-level transcription of the clique definitions on random
    configurations (dense and sparse ones)."""
    from topopose.topology.tables import load_ack3_edge_table, load_byte_table, lookup

    btab = load_byte_table("ack3")
    etab = load_ack3_edge_table()
    rng = np.random.default_rng(11)
    cfgs = [int(x) for x in rng.integers(0, 1 << 26, 300)]
    for density in (0.2, 0.5, 0.8):
        bits = rng.random((300, 26)) < density
        cfgs += [int((b * (1 << np.arange(26))).sum()) for b in bits]
    for cfg in cfgs:
        byte, edges = _ack3_oracle(cfg)
        assert int(btab[cfg]) & 63 == byte, cfg
        assert (int(btab[cfg]) >> 6) & 1 == int(lookup(12, cfg)), cfg
        assert (int(btab[cfg]) >> 7) & 1 == int(lookup(13, cfg)), cfg
        assert int(etab[cfg]) == edges, cfg
