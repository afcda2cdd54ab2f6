"""Numba kernels of the tracker (:mod:`.tracker`)."""
import numpy as np
from numba import njit


#: metres: the margin of the bound that passes a capsule in :func:`capsule_normal_equations`,
#: far above the rounding of the distances it compares (~1e-14 m)
BOUND_SLACK = 1e-9


@njit(cache=True, nogil=True)
def capsule_normal_equations(Q, U, A, B, radii, par, bone, G, cols, h, weight, one_sided, H,
                             g, first):
    """Add one robust capsule term's normal equations to ``H`` (n, n) and ``g`` (n,).

    Each data point ``Q[m]`` (or, when ``U`` has rows, the ray from ``Q[m]`` along ``U[m]``:
    its point nearest the capsule) is paired with its nearest capsule surface (bone ``k`` from
    ``A[k]`` to ``B[k]``, radius ``radii[k]``); the residual is the distance to that surface
    (``one_sided``: only where positive, outside the capsule), Huber-weighted beyond ``h``,
    times ``weight``. ``G`` (J, 3, n): the joints' derivatives; ``par[k]`` / ``bone[k]``: the
    joints at the bone's ends; ``cols[j]``: the parameters joint ``j`` depends on (-1: padding;
    a bone's child joint depends on every parameter its parent does). Returns the weighted
    cost.

    ``first`` (M,): the capsule tried first for each point, set to the one found (its nearest,
    or, ``one_sided``, the first found holding it: the point adds nothing then). The nearest
    is the first of least distance in the capsules' order whichever is tried first, so
    ``first`` changes the work (the last call's on the same points: the other capsules are
    then mostly passed), never the result.
    """
    M = Q.shape[0]
    nb = A.shape[0]
    rays = U.shape[0] > 0
    row = np.empty(cols.shape[1])
    cost = 0.0
    S = np.empty((nb, 4))                  # each bone's vector and its squared length
    C = np.empty((nb, 4))                  # its centre, and half its length plus its radius
    for k in range(nb):
        S[k, 0] = B[k, 0] - A[k, 0]
        S[k, 1] = B[k, 1] - A[k, 1]
        S[k, 2] = B[k, 2] - A[k, 2]
        S[k, 3] = max(S[k, 0] * S[k, 0] + S[k, 1] * S[k, 1] + S[k, 2] * S[k, 2], 1e-12)
        for c in range(3):
            C[k, c] = A[k, c] + 0.5 * S[k, c]
        C[k, 3] = 0.5 * np.sqrt(S[k, 3]) + radii[k]
    by = np.zeros(3)
    bx = np.zeros(3)
    for m in range(M):
        best = 1e300
        bk = -1
        bt = 0.0
        bd = 0.0
        k0 = first[m] if 0 <= first[m] < nb else 0
        for kk in range(-1, nb):           # k0 first, then the others in order
            k = k0 if kk < 0 else kk
            if kk == k0:
                continue
            if bk >= 0:
                # a bound below the capsule's surface distance from the point (the ray): the
                # centre's, less half the bone and the radius; a capsule surely farther than
                # the nearest so far is passed (the nearest stays the same, bit for bit)
                c0 = C[k, 0] - Q[m, 0]
                c1 = C[k, 1] - Q[m, 1]
                c2 = C[k, 2] - Q[m, 2]
                if rays:
                    p = max(c0 * U[m, 0] + c1 * U[m, 1] + c2 * U[m, 2], 0.0)
                    c0 -= p * U[m, 0]
                    c1 -= p * U[m, 1]
                    c2 -= p * U[m, 2]
                if np.sqrt(c0 * c0 + c1 * c1 + c2 * c2) - C[k, 3] > best + BOUND_SLACK:
                    continue
            s0 = S[k, 0]
            s1 = S[k, 1]
            s2 = S[k, 2]
            ll = S[k, 3]
            if rays:
                w0 = A[k, 0] - Q[m, 0]
                w1 = A[k, 1] - Q[m, 1]
                w2 = A[k, 2] - Q[m, 2]
                bb = s0 * U[m, 0] + s1 * U[m, 1] + s2 * U[m, 2]
                dd = w0 * s0 + w1 * s1 + w2 * s2
                ee = w0 * U[m, 0] + w1 * U[m, 1] + w2 * U[m, 2]
                t = (bb * ee - dd) / max(ll - bb * bb, 1e-12)
                t = min(max(t, 0.0), 1.0)
                lam = max(bb * t + ee, 0.0)
                y0 = Q[m, 0] + lam * U[m, 0]
                y1 = Q[m, 1] + lam * U[m, 1]
                y2 = Q[m, 2] + lam * U[m, 2]
            else:
                y0 = Q[m, 0]
                y1 = Q[m, 1]
                y2 = Q[m, 2]
                t = ((y0 - A[k, 0]) * s0 + (y1 - A[k, 1]) * s1 + (y2 - A[k, 2]) * s2) / ll
                t = min(max(t, 0.0), 1.0)
            x0 = A[k, 0] + t * s0
            x1 = A[k, 1] + t * s1
            x2 = A[k, 2] + t * s2
            d = np.sqrt((y0 - x0) ** 2 + (y1 - x1) ** 2 + (y2 - x2) ** 2)
            if d - radii[k] < best or (d - radii[k] == best and k < bk):
                best = d - radii[k]
                bk, bt, bd = k, t, d
                by[0], by[1], by[2] = y0, y1, y2
                bx[0], bx[1], bx[2] = x0, x1, x2
            if one_sided and best <= 0.0:  # inside a capsule: the nearest's residual too
                break
        first[m] = bk
        if bk < 0:
            continue
        res = best
        if one_sided and res <= 0.0:
            continue
        a = abs(res)
        wt = weight * (1.0 if a <= h else h / a)
        inv = 1.0 / max(bd, 1e-9)
        n0 = (by[0] - bx[0]) * inv
        n1 = (by[1] - bx[1]) * inv
        n2 = (by[2] - bx[2]) * inv
        p, c = par[bk], bone[bk]
        nc = 0
        for q in range(cols.shape[1]):
            i = cols[c, q]
            if i < 0:
                break
            row[q] = -((n0 * G[p, 0, i] + n1 * G[p, 1, i] + n2 * G[p, 2, i]) * (1.0 - bt)
                       + (n0 * G[c, 0, i] + n1 * G[c, 1, i] + n2 * G[c, 2, i]) * bt)
            nc += 1
        for a in range(nc):
            i = cols[c, a]
            wi = wt * row[a]
            g[i] += wi * res
            for b in range(nc):
                H[i, cols[c, b]] += wi * row[b]
        cost += wt * res * res
    return cost


@njit(cache=True, nogil=True)
def bone_bases(D):
    """Two unit vectors normal to each direction ``D`` (J, 3) and to each other, (J, 3, 2):
    :func:`.tracker._basis`, the same operations in the same order."""
    J = D.shape[0]
    E = np.empty((J, 3, 2))
    for j in range(J):
        d0, d1, d2 = D[j, 0], D[j, 1], D[j, 2]
        if abs(d0) < 0.9:
            a0, a1, a2 = 1.0, 0.0, 0.0
        else:
            a0, a1, a2 = 0.0, 1.0, 0.0
        e0 = d1 * a2 - d2 * a1
        e1 = d2 * a0 - d0 * a2
        e2 = d0 * a1 - d1 * a0
        nrm = max(np.sqrt(e0 * e0 + e1 * e1 + e2 * e2), 1e-12)
        e0 /= nrm
        e1 /= nrm
        e2 /= nrm
        E[j, 0, 0], E[j, 1, 0], E[j, 2, 0] = e0, e1, e2
        E[j, 0, 1] = d1 * e2 - d2 * e1
        E[j, 1, 1] = d2 * e0 - d0 * e2
        E[j, 2, 1] = d0 * e1 - d1 * e0
    return E


@njit(cache=True, nogil=True)
def joint_jacobian(D, lengths, bones, col, width, anc, n):
    """The joints' derivatives ``G`` (J, 3, n) by the fit's parameters at directions ``D``,
    each bone's ``M`` (nb, 3, 3: its end's move by its block's ``width[b]`` parameters from
    column ``col[b]``) and the bones' bases ``E`` (:func:`bone_bases`): :meth:`.tracker._Fitter
    .jacobian`, the same operations in the same order. ``anc`` (J, J): joint ``k`` moves with
    bone ``j``."""
    J = D.shape[0]
    E = bone_bases(D)
    G = np.zeros((J, 3, n))
    for k in range(J):
        for r in range(3):
            G[k, r, r] = 1.0
    M = np.zeros((bones.shape[0], 3, 3))
    for b in range(bones.shape[0]):
        j = bones[b]
        L = lengths[j]
        if width[b] == 2:
            for r in range(3):
                M[b, r, 0] = L * E[j, r, 0]
                M[b, r, 1] = L * E[j, r, 1]
        else:                       # L × (−skew(D[j])), its zeros negative as NumPy's
            v0, v1, v2 = D[j, 0], D[j, 1], D[j, 2]
            M[b, 0, 0], M[b, 0, 1], M[b, 0, 2] = L * -0.0, L * v2, L * -v1
            M[b, 1, 0], M[b, 1, 1], M[b, 1, 2] = L * -v2, L * -0.0, L * v0
            M[b, 2, 0], M[b, 2, 1], M[b, 2, 2] = L * v1, L * -v0, L * -0.0
        c = col[b]
        for k in range(J):
            if anc[k, j]:
                for r in range(3):
                    for q in range(width[b]):
                        G[k, r, c + q] += M[b, r, q]
    return G, M, E


@njit(cache=True, nogil=True)
def chain_positions(root, D, lengths, parents, order, r0):
    """Joint positions (J, 3) from the root's (joint ``r0``) and the bones' directions ``D``
    (J, 3), joints in ``order`` (parents first): :func:`.body.joint_positions`, the same
    operations in the same order."""
    J = D.shape[0]
    P = np.zeros((J, 3))
    for c in range(3):
        P[r0, c] = root[c]
    for j in order:
        p = parents[j]
        if p >= 0:
            for c in range(3):
                P[j, c] = P[p, c] + lengths[j] * D[j, c]
    return P


@njit(cache=True, nogil=True)
def near_surface(Q, A, B, radii, tolerance):
    """How many points ``Q`` (M, 3) lie within ``tolerance`` of a capsule's surface (bone
    ``k`` from ``A[k]`` to ``B[k]``, radius ``radii[k]``): the distance to the nearest point
    of each segment, less the radius, in :func:`.tracker.agreement`'s operations."""
    nb = A.shape[0]
    n = 0
    for m in range(Q.shape[0]):
        for k in range(nb):
            s0 = B[k, 0] - A[k, 0]
            s1 = B[k, 1] - A[k, 1]
            s2 = B[k, 2] - A[k, 2]
            ll = max(s0 * s0 + s1 * s1 + s2 * s2, 1e-12)
            q0 = Q[m, 0] - A[k, 0]
            q1 = Q[m, 1] - A[k, 1]
            q2 = Q[m, 2] - A[k, 2]
            t = min(max((q0 * s0 + q1 * s1 + q2 * s2) / ll, 0.0), 1.0)
            x0 = Q[m, 0] - (A[k, 0] + t * s0)
            x1 = Q[m, 1] - (A[k, 1] + t * s1)
            x2 = Q[m, 2] - (A[k, 2] + t * s2)
            d = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            if abs(d - radii[k]) <= tolerance:
                n += 1
                break
    return n


@njit(cache=True, nogil=True)
def normal_equations(J, r):
    """``H = Jᵀ J`` (n, n) and ``g = Jᵀ r`` (n,) of rows ``J`` (M, n) and residuals ``r``
    (M,): each entry the sum over the rows in order, as ``np.einsum("mi,mj->ij", J, J)`` and
    ``np.einsum("mi,m->i", J, r)``, the rows' zeros passed (adding a zero product changes no
    sum)."""
    M, n = J.shape
    H = np.zeros((n, n))
    g = np.zeros(n)
    nz = np.empty(n, np.int64)
    for m in range(M):
        c = 0
        for i in range(n):
            if J[m, i] != 0.0:
                nz[c] = i
                c += 1
        for a in range(c):
            i = nz[a]
            for b in range(c):
                H[i, nz[b]] += J[m, i] * J[m, nz[b]]
            g[i] += J[m, i] * r[m]
    return H, g


@njit(cache=True, nogil=True)
def nearest_voxels(x, X, u0, vs, start, items, shape, size):
    """Each point of ``x`` (N, 3)'s nearest row of ``X`` (M, 3) and its distance, as
    ``scipy.spatial.cKDTree(X).query(x)`` gives them (the same distance, bit for bit; of equal
    distances the first row): (N,) distances, (N,) rows.

    The rows of ``X`` are voxel centres, ``X[m] ≈ u0 + ijk[m] × vs`` (``ijk`` ≥ 0, integer),
    bucketed by ``ijk // size`` in a grid of ``shape`` buckets: bucket ``b``'s rows are
    ``items[start[b]:start[b + 1]]`` (``b`` in C order). The buckets are searched in rings
    around the point's, each passed when surely farther than the nearest so far
    (:data:`BOUND_SLACK`), until a ring surely is.
    """
    n = x.shape[0]
    dist = np.empty(n)
    rows = np.empty(n, np.int64)
    nx, ny, nz = shape[0], shape[1], shape[2]
    reach = max(nx, max(ny, nz))
    u = np.empty(3)
    b = np.empty(3, np.int64)
    for q in range(n):
        for a in range(3):
            u[a] = (x[q, a] - u0[a]) / vs                 # the voxel coordinates
            b[a] = min(max(int(np.floor(u[a] / size)), 0), shape[a] - 1)
        best = np.inf
        bd = np.inf
        bi = -1
        for r in range(reach + 1):
            # a ring r buckets away lies beyond (r - 1) × size voxels of the point
            if bi >= 0 and (r - 1) * size * vs > bd + BOUND_SLACK:
                break
            for c0 in range(max(b[0] - r, 0), min(b[0] + r, nx - 1) + 1):
                for c1 in range(max(b[1] - r, 0), min(b[1] + r, ny - 1) + 1):
                    for c2 in range(max(b[2] - r, 0), min(b[2] + r, nz - 1) + 1):
                        if max(abs(c0 - b[0]), max(abs(c1 - b[1]), abs(c2 - b[2]))) != r:
                            continue
                        cell = (c0 * ny + c1) * nz + c2
                        if start[cell] == start[cell + 1]:
                            continue
                        if bi >= 0:                         # the bucket's nearest voxel
                            g2 = 0.0
                            lo0 = c0 * size - u[0]
                            hi0 = u[0] - (c0 * size + size - 1)
                            lo1 = c1 * size - u[1]
                            hi1 = u[1] - (c1 * size + size - 1)
                            lo2 = c2 * size - u[2]
                            hi2 = u[2] - (c2 * size + size - 1)
                            g = max(lo0, max(hi0, 0.0))
                            g2 += g * g
                            g = max(lo1, max(hi1, 0.0))
                            g2 += g * g
                            g = max(lo2, max(hi2, 0.0))
                            g2 += g * g
                            if np.sqrt(g2) * vs > bd + BOUND_SLACK:
                                continue
                        for t in range(start[cell], start[cell + 1]):
                            m = items[t]
                            d0 = x[q, 0] - X[m, 0]
                            d1 = x[q, 1] - X[m, 1]
                            d2 = x[q, 2] - X[m, 2]
                            dd = (d0 * d0 + d1 * d1) + d2 * d2
                            if dd < best or (dd == best and m < bi):
                                best = dd
                                bi = m
                                bd = np.sqrt(dd)
        dist[q] = bd
        rows[q] = bi
    return dist, rows


@njit(cache=True, nogil=True)
def inside_rows(S, dist, near, surface, origin, voxel, lo, occupancy, need, sk, start, end, G,
                h, deep, w):
    """The inside term's weighted rows (M, n) and residuals (M,) (:meth:`.tracker._Fitter.terms`)
    of the bones' axis points ``S`` (M, 3), each ``need[m]`` inside the hull: the signed
    distance ``sd`` (``dist``, the distance to the nearest surface voxel ``surface[near]``,
    positive where ``occupancy`` — the grid's voxels from ``lo`` on, of size ``voxel`` from
    ``origin`` — holds the point), ``r = need − sd``, one-sided (``deep`` × Huber at ``h``
    below zero), its row through the point's bone's ends (``G[start]``, ``G[end]``, dP/dθ, at
    ``sk`` along it), all × ``w`` — as the NumPy expressions in that method give them, bit
    for bit."""
    M, n = S.shape[0], G.shape[2]
    rows = np.empty((M, n))
    res = np.empty(M)
    shape = occupancy.shape
    for m in range(M):
        i0 = np.int64(np.rint((S[m, 0] - origin[0]) / voxel)) - lo[0]
        i1 = np.int64(np.rint((S[m, 1] - origin[1]) / voxel)) - lo[1]
        i2 = np.int64(np.rint((S[m, 2] - origin[2]) / voxel)) - lo[2]
        if i0 < 0 or i0 >= shape[0] or i1 < 0 or i1 >= shape[1] or i2 < 0 or i2 >= shape[2]:
            held = False
        else:
            held = occupancy[i0, i1, i2]
        s = 1.0 if held else -1.0
        d = dist[m]
        den = max(d, 1e-9)
        q = near[m]
        g0 = (S[m, 0] - surface[q, 0]) / den * s
        g1 = (S[m, 1] - surface[q, 1]) / den * s
        g2 = (S[m, 2] - surface[q, 2]) / den * s
        r = need[m] - s * d
        act = 1.0 if r > 0 else deep * min(1.0, h / max(-r, 1e-12))
        act = np.sqrt(act)
        t = sk[m]
        a0, a1, a2 = g0 * (1 - t), g1 * (1 - t), g2 * (1 - t)
        b0, b1, b2 = g0 * t, g1 * t, g2 * t
        p, e = start[m], end[m]
        wa = w * act
        for j in range(n):
            x = a0 * G[p, 0, j] + a1 * G[p, 1, j] + a2 * G[p, 2, j]
            y = b0 * G[e, 0, j] + b1 * G[e, 1, j] + b2 * G[e, 2, j]
            rows[m, j] = -(x + y) * wa
        res[m] = r * w * act
    return rows, res
