"""Numba kernels of the thinning algorithms (thesis ch. 5–6).

All kernels work in place on a flat ``uint8`` copy of the volume padded with a
one-voxel background frame (ALGORITHMS.md §5), so ``p + offset`` never leaves the array
for an object voxel ``p``.  Options (thesis §5.1–5.3):

* ``border_list``: test only voxels of the border list (object voxels 6-adjacent to the
  background); when a voxel is deleted its object 6-neighbours join the list (§5.1.1).
  Without it, every object voxel is tested in every subiteration.
* ``lut``: table reads replace the mask test / the component counting (§5.1.2, §5.2):
  one read of a 2^26-entry byte table (:func:`topopose.topology.tables.load_byte_table`)
  answers, for a configuration, the six directional tests and the isthmus test (or, for
  ACK3, the simple and isthmus tests and the 2-clique geometry; its 1-clique geometry
  is a uint16 table); the sequential completion reads the simple bit plane.
* ``ccsu`` (configuration computation speed-up, §5.3), an int mode: 0 gathers the 26
  neighbours at every test; 1 ("rows") keeps, in bits 5–7 of every voxel's state
  byte, the object bits of its z-triplet (z−1, z, z+1), updated by 3 writes per
  deletion, so a configuration is assembled from 9 bytes; 2 ("full", the thesis'
  variant) keeps each listed voxel's whole 26-bit word, updated in its 26
  neighbours at every deletion.

The kernels take the arrays that travel together as one argument each: the
:class:`Neighbourhood`, a :class:`MaskSet`, ACK3's :class:`Ack3Cliques` — as plain tuples
in the named tuple's field order (Numba's dispatcher types a plain tuple on its fast path),
unpacked at the kernel's top.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import trailing_zeros

from topopose.topology.tables_kernels import (
    PLANE_ISTHMUS1D,
    PLANE_ISTHMUS2D,
    PLANE_SIMPLE,
    edge_critical,
    expand26,
    match_set,
    section2d,
    t6bar_word,
    t26_word,
    table_bit,
)


# state bits of the flat padded volume handled by the kernels
OBJ = 1      # object voxel
LISTED = 2   # has entered the candidate (border) list
KEPT = 4     # in the constraint set K
INS = 8      # ACK3: in S (simple, not in K, not kept by a crucial clique yet)
QUEUED = 16  # sequential completion: on the stack
R3 = 5       # bits 5..7: the z-triplet (z-1, z, z+1) of OBJ bits around the voxel
R3_LO = np.uint8(1 << R3)
R3_MID = np.uint8(2 << R3)
R3_HI = np.uint8(4 << R3)


class Neighbourhood(NamedTuple):
    """Flat offsets in a padded state array (ALGORITHMS.md §5)."""

    offs: np.ndarray    # the 26 neighbours (configuration bit order), then the 9 z-rows (dx, dy)
    opp: np.ndarray     # configuration bit of the opposite of each of the 26 neighbours
    off6: np.ndarray    # the 6 face neighbours (``neighbourhood.DIRECTIONS`` order)


class MaskSet(NamedTuple):
    """A set of deletion masks of the directional thinnings (thesis §6.2): the templates of
    each direction, (6, nmax, 3), their counts (6,), and the byte table of the set
    (:func:`topopose.topology.tables.load_byte_table`; read with ``lut`` only)."""

    templates: np.ndarray
    tcount: np.ndarray
    btab: np.ndarray


class Ack3Cliques(NamedTuple):
    """Clique geometry of ACK3 (thesis §5.2.1, :func:`topopose.topology.neighbourhood.ack_bits`)."""

    c2_a: np.ndarray        # (6, 8) bits of the column voxels C_i (p's layer) of each direction
    c2_b: np.ndarray        # (6, 8) ... D_i (the neighbour's layer)
    nonsimple2d: np.ndarray  # (256,) R non-simple (8/4) for the 8-bit section
    e_f1: np.ndarray        # (12,) per edge: bits of the two face neighbours around it,
    e_f2: np.ndarray
    e_ed: np.ndarray        # the edge neighbour,
    e_u: np.ndarray         # the masks of U and V,
    e_v: np.ndarray
    e_others: np.ndarray    # (12, 3) bits and flat offsets of the other 3 voxels
    e_ooff: np.ndarray
    k_bits: np.ndarray      # (8, 7) per cube: bits of the 7 other voxels,
    k_span: np.ndarray      # (8, 3) masks of the voxels beyond the vertex along x, y, z,
    k_ooff: np.ndarray      # (8, 7) flat offsets of the 7 others


@njit(cache=True, inline="always")
def gather26(vol, p, offs):
    """26-bit configuration index of voxel ``p`` (flat index): 26 byte loads."""
    c = np.int64(0)
    for i in range(26):
        c |= np.int64(vol[p + offs[i]] & OBJ) << i
    return c


@njit(cache=True, inline="always")
def gather(vol, p, offs):
    """26-bit configuration index of voxel ``p`` from the z-triplet words.

    ``offs[26 + r]`` (r = 0..8) are the flat offsets of the 9 rows (dx, dy) of the
    3×3×3 cube; each voxel's bits 5–7 hold the OBJ bits of its z-triplet (kept up to
    date on deletion), so one byte per row (9 loads instead of 26) builds the word.
    """
    w = np.int64(0)
    for r in range(9):
        w |= np.int64(vol[np.uint64(np.int64(p) + offs[26 + r])] >> R3) << (3 * r)
    return (w & 0x1FFF) | ((w >> 14) << 13)


@njit(cache=True, inline="always")
def _cfg(vol, p, offs, words, mode):
    """Configuration of ``p``: mode 0 gathers 26 voxels, 1 the 9 z-triplet words (row
    CCSU), 2 reads the full per-voxel word (the thesis' CCSU, §5.3)."""
    if mode == 2:
        return np.int64(words[p])
    if mode == 1:
        return gather(vol, p, offs)
    return gather26(vol, p, offs)


@njit(cache=True, inline="always")
def _clear(vol, p):
    """Delete voxel ``p``: clear OBJ and its bit in the z-triplets of p-1, p, p+1."""
    q = np.uint64(p)  # (unsigned indices: no wrap-around fix)
    vol[q] &= ~(np.uint8(OBJ) | R3_MID)
    vol[q - np.uint64(1)] &= ~R3_HI
    vol[q + np.uint64(1)] &= ~R3_LO


@njit(cache=True, inline="always")
def _isthmus(cfg, psi, tables, lut):
    if psi == 1:
        if lut:
            return table_bit(tables, PLANE_ISTHMUS1D, cfg) != 0
        return t26_word(expand26(cfg)) >= 2
    if psi == 2:
        if lut:
            return table_bit(tables, PLANE_ISTHMUS2D, cfg) != 0
        return t6bar_word(expand26(cfg)) >= 2
    return False


@njit(cache=True, inline="always")
def _simple(cfg, tables, lut):
    if lut:
        return table_bit(tables, PLANE_SIMPLE, cfg) != 0
    w = expand26(cfg)
    return t26_word(w) == 1 and t6bar_word(w) == 1


@njit(cache=True)
def _init_list(vol, offs, off6, border_list, ccsu, words, n_obj):
    """Initial candidate list: border voxels not in K (or every such object voxel).

    ``vol`` comes from :func:`fill_state_rows` (z-triplet bits set, ``n_obj`` object
    voxels).  The scan skips empty 8-byte words of the volume.  Listed voxels get the
    LISTED bit (and their word).
    """
    n8 = vol.size // 8
    v64 = vol[: n8 * 8].view(np.uint64)
    # flat indices (the state array has < 2^31 voxels), unsigned: an unsigned index
    # needs no wrap-around fix in the hot loops
    lst = np.empty(max(n_obj, 1), dtype=np.uint32)
    n = 0
    for w in range(n8 + 1):
        if w < n8 and v64[w] == 0:
            continue
        for p in range(8 * w, min(8 * w + 8, vol.size)):
            if vol[p] & (OBJ | KEPT) != OBJ:
                continue
            ok = True
            if border_list:  # z-neighbours from the z-triplet bits, then the 4 others
                ok = (vol[p] >> R3) != 7 or (vol[p + off6[2]] & vol[p + off6[3]] & vol[p + off6[4]]
                                             & vol[p + off6[5]] & OBJ) == 0
            if ok:
                lst[n] = p
                vol[p] |= LISTED
                n += 1
                if ccsu == 2:
                    words[p] = gather(vol, p, offs)
    return lst, n


@njit(cache=True)
def _delete(vol, dl, ndel, lst, n, nbr, border_list, ccsu, words):
    """Delete the collected voxels at once; update words and the border list. Returns new n."""
    offs, opp, off6 = nbr
    for j in range(ndel):
        _clear(vol, dl[j])
    for j in range(ndel):
        p = dl[j]
        if ccsu == 2:
            for i in range(26):
                q = np.uint64(p + offs[i])
                if vol[q] & LISTED:  # only listed voxels hold a word
                    words[q] &= ~(np.uint32(1) << np.uint32(opp[i]))
        if border_list:
            for k in range(6):
                q = np.uint64(p + off6[k])
                if vol[q] & (OBJ | LISTED | KEPT) == OBJ:
                    vol[q] |= LISTED
                    lst[n] = q
                    n += 1
                    if ccsu == 2:
                        words[q] = gather(vol, q, offs)
    return n


@njit(cache=True)
def sequential_completion(vol, lst, n, offs, tables, lut, keep_end_points):
    """Delete, one at a time, the simple voxels not in K the directional masks left.

    Sequential deletion of simple points (thesis §4.3.1, Alg. 1 with the inhibitor set
    W = K, plus the curve end points when ``keep_end_points``) always preserves
    topology.  The masks of PKD6 / M'_d do not match every simple configuration
    (e.g. staircase-like ones), so a few such voxels can survive the parallel phase;
    this pass makes the result thin: no voxel is simple unless it is in K or (for
    curve skeletons) an end point.  Candidates are the listed voxels and, after each
    deletion, its object neighbours (depth first, so the order is fixed by the
    volume alone).  Returns the number of voxels deleted.
    """
    stack = np.empty(max(lst.size, 1), dtype=np.int64)
    top = 0
    # start from the voxels simple now, in decreasing index order (popped increasing), so
    # the result does not depend on the order of the list (border list or full scan)
    for i in range(n):
        p = lst[i]
        if vol[p] & (OBJ | KEPT | QUEUED) == OBJ and _simple(gather(vol, p, offs), tables, lut):
            vol[p] |= QUEUED
            stack[top] = p
            top += 1
    stack[:top] = np.sort(stack[:top])[::-1]
    deleted = 0
    while top > 0:
        top -= 1
        p = stack[top]
        vol[p] &= ~np.uint8(QUEUED)
        if vol[p] & (OBJ | KEPT) != OBJ:
            continue
        cfg = gather(vol, p, offs)
        if not _simple(cfg, tables, lut):
            continue
        if keep_end_points and cfg & (cfg - 1) == 0:  # one neighbour: an end point
            continue
        _clear(vol, p)
        deleted += 1
        for i in range(26):
            q = p + offs[i]
            if vol[q] & (OBJ | KEPT | QUEUED) == OBJ and top < stack.size:
                vol[q] |= QUEUED
                stack[top] = q
                top += 1
    return deleted


@njit(cache=True, inline="always")
def _delete_directional(vol, dl, ndel, lst, n, nbr, opp6, border_list, ccsu, words, bk, nbk, d):
    """Delete the collected voxels of subiteration ``d`` at once.

    Updates the z-triplet bits (and the CCSU words), appends new border voxels to the
    list, and pushes every object 6-neighbour that the deletion exposes in a direction
    still to come in this iteration into that direction's bucket.  Returns the new n.
    """
    offs, opp, off6 = nbr
    for j in range(ndel):
        _clear(vol, dl[j])
    for j in range(ndel):
        p = dl[j]
        if ccsu == 2:
            for i in range(26):
                q = p + offs[i]
                if vol[q] & LISTED:  # only listed voxels hold a word
                    words[q] &= ~(np.uint32(1) << np.uint32(opp[i]))
        for k in range(6):
            q = np.uint64(p + off6[k])
            st = vol[q]
            if st & (OBJ | KEPT) != OBJ:
                continue
            e = opp6[k]  # p is q's neighbour in direction e: q is now exposed in e
            if e > d:
                bk[e, nbk[e]] = q
                nbk[e] += 1
            if border_list and st & LISTED == 0:
                vol[q] = st | LISTED
                lst[n] = q
                n += 1
                if ccsu == 2:
                    words[q] = gather(vol, q, offs)
    return n


def make_directional_thin(lut=None, ccsu=None):
    """Kernel of the 6-directional thinnings, specialized for (lut, ccsu).

    Given values become compile-time constants of the returned kernel (a closure;
    Numba caches each specialization on disk): tested at run time inside the hot
    loops they cost a factor 2–3.  With ``None`` the kernel reads them from its last
    two arguments (one generic kernel serves every combination).  Signature:
    ``(vol, nbr, tables, masks, psi, border_list, finish, stats, lut, ccsu, n_obj) ->
    (iterations, deleted)``; see :func:`_directional_body` (``n_obj``: the object voxels
    :func:`fill_state_rows` counted).
    """
    if lut is None or ccsu is None:
        @njit(cache=True)
        def directional_generic(vol, nbr, tables, masks, psi, border_list, finish, stats, lut_, ccsu_,
                                n_obj):
            return _directional_body(vol, nbr, tables, masks, psi, border_list, lut_, ccsu_, finish,
                                     stats, n_obj)

        return directional_generic
    lut = bool(lut)

    @njit(cache=True)
    def directional_thin(vol, nbr, tables, masks, psi, border_list, finish, stats, lut_, ccsu_, n_obj):
        return _directional_body(vol, nbr, tables, masks, psi, border_list, lut, ccsu, finish, stats,
                                 n_obj)

    return directional_thin


@njit(cache=True, inline="always")
def _directional_body(vol, nbr, tables, masks, psi, border_list, lut, ccsu, finish, stats, n_obj):
    """6-directional thinning: PKD6 (Alg. 10) or D6I1D/D6U/D6I2D (Alg. 11–12).

    ``vol`` is the state array (bit OBJ object, bit KEPT the constraint set K on input;
    both updated in place); ``nbr`` its :class:`Neighbourhood`.  ``masks``
    (:class:`MaskSet`) selects the mask sets (PKD6's M_d or the M'_d of §6.2.2); ``psi``
    the constraint function: 0 none (PKD6, D6U), 1 the 1D isthmuses (D6I1D), 2 the 2D
    isthmuses (D6I2D).
    Each iteration first passes over the list (dropping deleted voxels, adding the
    isthmuses to K) and sorts the voxels into six buckets by the directions in which
    they are exposed (their neighbour is background); subiteration d then tests only
    bucket d — every mask of direction d needs the d-neighbour in the background —
    plus the voxels that earlier subiterations of the iteration exposed in d.
    Each pass first gathers the configurations of its voxels, then reads the table
    for all of them, and collects the deletions and bucket entries with
    unconditional stores (the counts advance by the tests): no data-dependent branch
    to mispredict, and the indices are unsigned (no wrap-around fix per load).
    ``finish``: 0 none, 1 :func:`sequential_completion` keeping end points (curve
    skeletons), 2 without keeping them (ultimate skeletons).
    With ``lut`` the tests read ``masks.btab``, the byte table of the mask set
    (:func:`topopose.topology.tables.load_byte_table`: bits 0–5 the six directions,
    bit 5 + psi the isthmus test): one read per configuration gives the isthmus test
    and the first subiteration's answer (a later subiteration reads the table again:
    deletions may have changed the configuration, and a re-read costs less than
    keeping and checking the first one).
    ``stats`` (int64, 5) receives the number of list visits, of deletion tests, of
    isthmus tests, the initial list size and the voxels deleted by the completion.
    Returns (iterations, deleted voxels).
    """
    offs, _, off6 = nbr
    templates, tcount, btab = masks
    words = np.empty(vol.size if ccsu == 2 else 1, dtype=np.uint32)
    lst, n = _init_list(vol, offs, off6, border_list, ccsu, words, n_obj)
    stats[3] = n
    cap = lst.size + 1  # (+1: the loops below store one entry past the last kept one)
    # one block for the deletion list and the six buckets: fewer, larger allocations
    # are reused by the allocator from call to call instead of being faulted in anew
    work = np.empty(8 * cap, dtype=np.uint32)
    dl = work[:cap]
    cf = work[cap:2 * cap]  # configurations of a pass, gathered before the table reads
    bk = work[2 * cap:].reshape((6, cap))
    nbk = np.zeros(6, dtype=np.int64)
    opp6 = np.array([1, 0, 3, 2, 5, 4])
    fbit = np.empty(6, dtype=np.int64)  # bit of the face neighbour of each direction
    for d in range(6):
        for i in range(26):
            if offs[i] == off6[d]:
                fbit[d] = i
    visits = 0
    tests = 0
    itests = 0
    iterations = 0
    total = 0
    while True:
        iterations += 1
        visits += n
        for d in range(6):
            nbk[d] = 0
        # two loops: the first gathers the configurations (and drops the deleted voxels),
        # the second reads the table, so that the table reads, mostly cache misses, are
        # not queued behind the gathers and many are in flight at once
        m = 0
        for i in range(n):
            p = lst[i]
            lst[m] = p
            cf[m] = _cfg(vol, p, offs, words, ccsu)
            m += vol[p] & OBJ
        n = m
        m = 0
        ndel = 0
        for i in range(n):
            p = lst[i]
            cfg = np.int64(cf[i])
            b = np.int64(btab[cf[i]]) if lut else np.int64(0)
            if psi != 0:
                itests += 1
                isth = (b >> (5 + psi)) & 1 != 0 if lut else _isthmus(cfg, psi, tables, lut)
                if isth:
                    vol[p] |= KEPT  # constrained voxels leave the list for good
                    continue
            lst[m] = p
            m += 1
            # subiteration U (d = 0) is tested here, on the same configuration: nothing
            # has been deleted yet in this iteration.  The stores below are unconditional
            # (the counts advance by the test): no branch to mispredict.
            free = ~cfg
            if lut:
                ok = b & 1
            else:
                ok = np.int64((free >> fbit[0]) & 1 != 0 and match_set(cfg, templates, 0, tcount[0]))
            tests += (free >> fbit[0]) & 1
            dl[ndel] = p
            ndel += ok
            for d in range(1, 6):
                bk[d, nbk[d]] = p
                nbk[d] += (free >> fbit[d]) & 1
        n = m
        deleted = 0
        for d in range(6):
            if d > 0:
                nb = nbk[d]
                tests += nb
                ndel = 0
                if lut:  # (two loops, as in the first pass)
                    for i in range(nb):
                        cf[i] = _cfg(vol, bk[d, i], offs, words, ccsu)
                for i in range(nb):
                    p = bk[d, i]
                    if lut:
                        ok = (np.int64(btab[cf[i]]) >> d) & (vol[p] & OBJ)
                    else:
                        ok = np.int64(vol[p] & OBJ != 0
                                      and match_set(_cfg(vol, p, offs, words, ccsu), templates, d, tcount[d]))
                    dl[ndel] = p
                    ndel += ok
            if ndel:
                n = _delete_directional(vol, dl, ndel, lst, n, nbr, opp6, border_list, ccsu, words, bk,
                                        nbk, d)
                deleted += ndel
        total += deleted
        if deleted == 0:
            break
    stats[0] = visits
    stats[1] = tests
    stats[2] = itests
    if finish:
        # np.int64(n): n's type is int64, never the literal 0 of an early typing pass (which
        # made Numba compile the completion twice on the first run)
        stats[4] = sequential_completion(vol, lst, np.int64(n), offs, tables, lut, finish == 1)
        total += stats[4]
    return iterations, total


@njit(cache=True, inline="always")
def _clique_in_s(vol, p, cfg, bits, offs, c, n):
    """True when every voxel of clique ``c`` around ``p`` that is in X (configuration
    bit ``bits[c, k]``, flat offset ``offs[c, k]``, k < n) is also in S (ACK3, Alg. 8)."""
    k = 0
    while k < n and ((cfg >> bits[c, k]) & 1 == 0 or vol[np.uint64(p + offs[c, k])] & INS):
        k += 1
    return k == n


# ----------------------------------------------------------------------------- ACK3
def make_ack3_thin(lut=None, ccsu=None):
    """ACK3 kernel specialized for (lut, ccsu), or generic with ``None`` (see
    :func:`make_directional_thin`); signature ``(vol, nbr, tables, btab, etab, psi, border_list,
    cliques, lut, ccsu, n_obj) -> (iterations, deleted)``; see :func:`_ack3_body`."""
    if lut is None or ccsu is None:
        @njit(cache=True)
        def ack3_generic(vol, nbr, tables, btab, etab, psi, border_list, cliques, lut_, ccsu_, n_obj):
            return _ack3_body(vol, nbr, tables, btab, etab, psi, border_list, lut_, ccsu_, cliques, n_obj)

        return ack3_generic
    lut = bool(lut)

    @njit(cache=True)
    def ack3_thin(vol, nbr, tables, btab, etab, psi, border_list, cliques, lut_, ccsu_, n_obj):
        return _ack3_body(vol, nbr, tables, btab, etab, psi, border_list, lut, ccsu, cliques, n_obj)

    return ack3_thin


@njit(cache=True, inline="always")
def _ack3_body(vol, nbr, tables, btab, etab, psi, border_list, lut, ccsu, cliques, n_obj):
    """Asymmetric critical-kernel thinning ACK3 (thesis Alg. 7 / Alg. 8, §5.2).

    Per iteration: K ← K ∪ Ψ(X); S ← simple voxels of X not in K; then, visiting the
    voxels of S in list order and updating S in place (Alg. 8), a voxel that is the
    first visited member of a critical 2-clique (both voxels in S, R non-simple in the
    2D section), then of a critical 1-clique (M = X ∩ {E,F,G,H} ⊆ S with a diagonal
    pair, U and V both hit or both missed), then of a critical 0-clique (M = X ∩ cube ⊆ S
    essential: voxels on both sides of the vertex along x, y and z) leaves S (is kept);
    finally X ← X minus S.  Every critical clique of X keeps a voxel, so the critical
    kernel theorem (Bertrand 2007) guarantees that topology is preserved.

    Note: the 0-clique condition is the exact criticality of an essential vertex (its
    core is empty), not Def. 3's "contains an antipodal pair", which misses e.g. the
    4-voxel tripod {(1,0,0), (0,0,0), (1,1,0), (1,0,1)} (a voxel with three pairwise
    orthogonal face neighbours, all four simple, no crucial 2- or 1-clique) and lets a
    whole component vanish; found by the random-volume tests.

    ``vol`` and ``nbr`` as for :func:`_directional_body`; ``cliques`` (:class:`Ack3Cliques`)
    the clique geometry.
    With ``lut``, one read of ``btab``, the ACK3 byte table
    (:func:`topopose.topology.tables.load_byte_table`), gives the simple and 1D-isthmus
    tests and the 2-clique geometry towards the six face neighbours (bits 0–5), so the
    2-clique pass only checks which of those neighbours are in S; one read of
    ``etab`` (:func:`topopose.topology.tables.load_ack3_edge_table`) gives the edges
    whose 1-clique has the critical geometry, so the 1-clique pass only checks that
    their voxels are in S.
    Returns (iterations, deleted voxels).
    """
    offs, _, off6 = nbr
    c2_a, c2_b, nonsimple2d, e_f1, e_f2, e_ed, e_u, e_v, e_others, e_ooff, k_bits, k_span, k_ooff = cliques
    words = np.empty(vol.size if ccsu == 2 else 1, dtype=np.uint32)
    lst, n = _init_list(vol, offs, off6, border_list, ccsu, words, n_obj)
    # one block (fewer, larger allocations are reused from call to call, not faulted in)
    work = np.empty(3 * lst.size, dtype=np.uint32)
    cf = work[: 2 * lst.size].view(np.int64)  # configuration (| byte << 32) of the voxels of S
    sp = work[2 * lst.size:]  # the voxels of S in list order, then those deleted
    iterations = 0
    total = 0
    while True:
        iterations += 1
        m = 0
        ns = 0
        for i in range(n):
            p = lst[i]
            if vol[p] & OBJ == 0:
                continue
            cfg = _cfg(vol, p, offs, words, ccsu)
            cv = cfg
            if lut:  # one read of the ACK3 byte table: bit 6 simple, bit 7 1D isthmus
                b = btab[np.uint64(cfg)]
                cv = cfg | (np.int64(b) << 32)
                isth = (b >> 7) & 1 != 0 if psi == 1 else _isthmus(cfg, psi, tables, lut)
                simple = (b >> 6) & 1 != 0
            else:
                isth = psi != 0 and _isthmus(cfg, psi, tables, lut)
                simple = _simple(cfg, tables, lut)
            if isth:
                vol[p] |= KEPT
                continue
            lst[m] = p
            m += 1
            # (unconditional stores, the count advances by the test: no branch)
            vol[p] |= np.uint8(INS * simple)
            sp[ns] = p
            cf[ns] = cv
            ns += simple
        n = m
        # the clique passes and the deletion visit S only (in list order, as Alg. 8)
        # 2-cliques
        for i in range(ns):
            p = sp[i]
            if vol[p] & INS == 0:
                continue
            cfg = cf[i]
            if lut:  # bits 0-5 of the byte: the 2-clique towards d has R non-simple
                g = (cfg >> 32) & 63
                while g:
                    d = trailing_zeros(g)
                    g &= g - 1
                    if vol[np.uint64(p + off6[d])] & INS:
                        vol[p] &= ~np.uint8(INS)
                        break
                continue
            for d in range(6):
                if vol[np.uint64(p + off6[d])] & INS == 0:
                    continue
                if nonsimple2d[section2d(cfg, c2_a, c2_b, d)]:
                    vol[p] &= ~np.uint8(INS)
                    break
        # 1-cliques
        for i in range(ns):
            p = sp[i]
            if vol[p] & INS == 0:
                continue
            cfg = cf[i] & 0x3FFFFFF
            g = np.int64(etab[np.uint64(cfg)]) if lut else np.int64(0xFFF)
            while g:
                e = trailing_zeros(g)
                g &= g - 1
                if not lut and not edge_critical(cfg, e, e_f1, e_f2, e_ed, e_u, e_v):
                    continue
                if _clique_in_s(vol, p, cfg, e_others, e_ooff, e, 3):
                    vol[p] &= ~np.uint8(INS)
                    break
        # 0-cliques
        for i in range(ns):
            p = sp[i]
            if vol[p] & INS == 0:
                continue
            cfg = cf[i] & 0x3FFFFFF
            # essential 0-cliques: M has voxels on both sides of the vertex along x, y
            # and z (the eight cubes tested without a branch, then visited by set bit)
            g = np.int64(0)
            for c in range(8):
                ess = ((cfg & k_span[c, 0]) != 0) & ((cfg & k_span[c, 1]) != 0) & ((cfg & k_span[c, 2]) != 0)
                g |= np.int64(ess) << c
            while g:
                c = trailing_zeros(g)
                g &= g - 1
                if _clique_in_s(vol, p, cfg, k_bits, k_ooff, c, 7):
                    vol[p] &= ~np.uint8(INS)
                    break
        ndel = 0
        for i in range(ns):
            p = sp[i]
            if vol[p] & INS:
                sp[ndel] = p  # (ndel <= i: compacts S in place into the deletion list)
                ndel += 1
                vol[p] &= ~np.uint8(INS)
        if ndel:
            n = _delete(vol, sp, ndel, lst, n, nbr, border_list, ccsu, words)
        total += ndel
        if ndel == 0:
            break
    return iterations, total


@njit(cache=True)
def bounding_box_flat(flat, nx, ny, nz):
    """:func:`bounding_box` of a C-contiguous array given flat (uint8, size nx·ny·nz).

    Scans 8-byte words, skipping the zero ones, with a running (row, z) position; a
    nonzero word inside one row and inside the z range found so far only marks its
    row, the others are walked byte by byte.
    """
    rows = np.zeros((nx, ny), dtype=np.uint8)
    rflat = rows.reshape(-1)
    zlo = nz
    zhi = -1
    size = flat.size
    n8 = size // 8
    w64 = flat[: n8 * 8].view(np.uint64)
    r = 0  # (row, z) of byte 8·wpos, advanced incrementally (no division per word)
    z = 0
    wpos = 0
    for w in range(n8 + 1):
        if w < n8 and w64[w] == 0:
            continue
        z += 8 * (w - wpos)
        wpos = w
        while z >= nz:
            z -= nz
            r += 1
        p = 8 * w
        if w < n8 and z + 8 <= nz and z >= zlo and z + 7 <= zhi:
            rflat[r] = 1  # the word lies in one row, inside the z range found so far
            continue
        end = min(p + 8, size)
        rr = r
        z0 = z
        while p < end:
            if flat[p]:
                rflat[rr] = 1
                zlo = min(zlo, z0)
                zhi = max(zhi, z0)
            p += 1
            z0 += 1
            if z0 == nz:
                z0 = 0
                rr += 1
    lo = np.array([nx, ny, zlo], dtype=np.int64)
    hi = np.array([-1, -1, zhi], dtype=np.int64)
    for x in range(nx):
        for y in range(ny):
            if rows[x, y]:
                lo[0] = min(lo[0], x)
                hi[0] = max(hi[0], x)
                lo[1] = min(lo[1], y)
                hi[1] = max(hi[1], y)
    if hi[0] < 0:
        lo[2] = nz
        hi[2] = -1
    return lo, hi, rows


@njit(cache=True)
def bounding_box(data):
    """(lo, hi, rows) of the nonzero voxels of a 3D uint8 array: bounds (lo > hi if
    none) and ``rows[x, y]`` = 1 when row (x, y) holds a nonzero voxel.

    Any memory layout (the engine uses :func:`bounding_box_flat` for C-contiguous
    arrays).  Every row is first tested with a branch-free OR reduction, and only the
    nonzero rows are searched for their first and last voxel beyond the current bounds.
    """
    nx, ny, nz = data.shape
    rows = np.zeros((nx, ny), dtype=np.uint8)
    lo = np.array([nx, ny, nz], dtype=np.int64)
    hi = np.array([-1, -1, -1], dtype=np.int64)
    for x in range(nx):
        for y in range(ny):
            row = data[x, y]
            acc = np.uint8(0)
            for z in range(nz):
                acc |= row[z]
            if acc == 0:
                continue
            rows[x, y] = 1
            lo[0] = min(lo[0], x)
            hi[0] = max(hi[0], x)
            lo[1] = min(lo[1], y)
            hi[1] = max(hi[1], y)
            z = 0
            while z < lo[2] and row[z] == 0:
                z += 1
            lo[2] = min(lo[2], z)
            z = nz - 1
            while z > hi[2] and row[z] == 0:
                z -= 1
            hi[2] = max(hi[2], z)
    return lo, hi, rows


@njit(cache=True)
def fill_state_rows(data, keep, lo, hi, rows, vol):
    """Fill ``vol``, the padded state array of ``data[lo:hi+1]`` (3D uint8 views of
    bool arrays; ``vol`` flat, zero, of size (hi - lo + 3).prod()).

    One pass writes, for every voxel of the crop framed by one background voxel, the
    OBJ bit, the KEPT bit (``keep`` of the same shape as ``data``, or size 0) and the
    z-triplet bits, with branch-free row loops: each object row (``rows[x, y]`` over the
    whole array) is copied once into a zero-framed buffer, from which the OBJ bit and
    the z-triplet bits of the whole row are written in one vectorizable loop; rows
    without object voxels are not touched.  Returns (``vol``, its shape, object voxels).
    """
    nx = hi[0] - lo[0] + 1
    ny = hi[1] - lo[1] + 1
    nz = hi[2] - lo[2] + 1
    sx, sy, sz = nx + 2, ny + 2, nz + 2
    has_keep = keep.size > 0
    buf = np.zeros(nz + 2, dtype=np.uint8)
    n_obj = 0
    for x in range(nx):
        for y in range(ny):
            if not rows[lo[0] + x, lo[1] + y]:
                continue
            src = data[lo[0] + x, lo[1] + y, lo[2]:lo[2] + nz]
            cnt = 0
            for z in range(nz):
                b = src[z] & 1
                buf[z + 1] = b
                cnt += b
            n_obj += cnt
            base = ((x + 1) * sy + (y + 1)) * sz + 1
            for z in range(nz):
                vol[base + z] = buf[z + 1] | ((buf[z] | (buf[z + 1] << 1) | (buf[z + 2] << 2)) << R3)
            if has_keep:
                ks = keep[lo[0] + x, lo[1] + y, lo[2]:lo[2] + nz]
                for z in range(nz):
                    if buf[z + 1] and ks[z]:
                        vol[base + z] |= KEPT
    return vol, np.array([sx, sy, sz]), n_obj


@njit(cache=True)
def extract(vol, shape, lo, out, kout):
    """Write the result back: ``out[lo + (x, y, z)] = 1`` for the object voxels of the
    padded state array ``vol`` (flat, ``shape``) and ``kout`` for those also in K.

    ``out`` and ``kout`` are zero uint8 views of the full-size results; the scan skips
    8-byte words without an OBJ bit, and only the (few) surviving voxels are written,
    so the untouched pages of the outputs are never faulted in.
    Returns the number of object voxels.
    """
    sy, sz = shape[1], shape[2]
    n8 = vol.size // 8
    v64 = vol[: n8 * 8].view(np.uint64)
    objm = np.uint64(0x0101010101010101)
    cnt = 0
    for w in range(n8 + 1):
        if w < n8 and v64[w] & objm == 0:
            continue
        for p in range(8 * w, min(8 * w + 8, vol.size)):
            st = vol[p]
            if st & OBJ == 0:
                continue
            x = p // (sy * sz)
            r = p - x * (sy * sz)
            y = r // sz
            z = r - y * sz
            i, j, k = lo[0] + x - 1, lo[1] + y - 1, lo[2] + z - 1
            out[i, j, k] = 1
            if st & KEPT:
                kout[i, j, k] = 1
            cnt += 1
    return cnt
