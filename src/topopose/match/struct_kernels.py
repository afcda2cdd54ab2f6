"""Numba kernels of the trees' node and item structure for the alignments (thesis ch. 8–10, see
:mod:`topopose.match.align_kernels`): nodes numbered children first, items (arcs, possibly
merged chains) and their deletion costs."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _tz(x):
    """Index of the lowest set bit of x > 0."""
    t = 0
    while (x & 1) == 0:
        x >>= 1
        t += 1
    return t


@njit(cache=True)
def _bfs(s, aptr, adj, adjw, par, parw, queue):
    """Breadth-first search from ``s`` over the CSR adjacency (aptr, adj, adjw): ``queue`` gets
    the visit order, ``par`` / ``parw`` each vertex's parent and parent-edge weight (-1 at ``s``).
    Returns the number of vertices reached."""
    par[:] = -2
    par[s] = -1
    queue[0] = s
    head = 0
    tail = 1
    while head < tail:
        x = queue[head]
        head += 1
        for q in range(aptr[x], aptr[x + 1]):
            y = adj[q]
            if par[y] == -2:
                par[y] = x
                parw[y] = adjw[q]
                queue[tail] = y
                tail += 1
    return tail


@njit(cache=True)
def build_struct(n, eu, ev, ew, root, merge):
    """Node/item description of a tree with ``n`` vertices (indices 0..n-1).

    Parameters
    ----------
    eu, ev : int64 arrays, ew : float64 array — the edges.
    root : vertex index, or -1 for an unrooted tree.
    merge : allow merged chains as items (η on both sides, AHA on the data side).

    Returns
    -------
    tuple (node_v, node_par, ch_ptr, ch_idx, soff, it_ptr, it_node, it_up, it_w,
    item_of, base_item, roots, nxt)
    """
    m = eu.shape[0]
    deg = np.zeros(n, np.int64)
    for e in range(m):
        deg[eu[e]] += 1
        deg[ev[e]] += 1
    aptr = np.zeros(n + 1, np.int64)
    for v in range(n):
        aptr[v + 1] = aptr[v] + deg[v]
    fill = aptr[:n].copy()
    adj = np.empty(2 * m, np.int64)
    adjw = np.empty(2 * m, np.float64)
    for e in range(m):
        a = eu[e]
        b = ev[e]
        adj[fill[a]] = b
        adjw[fill[a]] = ew[e]
        fill[a] += 1
        adj[fill[b]] = a
        adjw[fill[b]] = ew[e]
        fill[b] += 1
    # next hop and path weight between every pair of vertices
    nxt = np.full((n, n), -1, np.int64)
    dist = np.zeros((n, n), np.float64)
    queue = np.empty(n, np.int64)
    par = np.empty(n, np.int64)
    parw = np.empty(n, np.float64)
    for s in range(n):
        tail = _bfs(s, aptr, adj, adjw, par, parw, queue)
        for k in range(1, tail):      # BFS order: a vertex's parent comes before it
            y = queue[k]
            nxt[y, s] = par[y]
            dist[s, y] = dist[s, par[y]] + parw[y]
    # nodes
    if root >= 0:
        nn = n
        # BFS order from the root; nodes = reversed BFS order (children first)
        _bfs(root, aptr, adj, adjw, par, parw, queue)
        node_v = np.empty(nn, np.int64)
        node_par = np.empty(nn, np.int64)
        nid = np.empty(n, np.int64)
        for k in range(nn):
            v = queue[n - 1 - k]
            node_v[k] = v
            node_par[k] = par[v]
            nid[v] = k
        nch = np.zeros(nn, np.int64)
        for k in range(nn):
            v = node_v[k]
            nch[k] = deg[v] - (1 if node_par[k] >= 0 else 0)
        ch_ptr = np.zeros(nn + 1, np.int64)
        for k in range(nn):
            ch_ptr[k + 1] = ch_ptr[k] + nch[k]
        ch_idx = np.empty(ch_ptr[nn], np.int64)
        for k in range(nn):
            v = node_v[k]
            c = ch_ptr[k]
            for q in range(aptr[v], aptr[v + 1]):
                y = adj[q]
                if y != node_par[k]:
                    ch_idx[c] = nid[y]
                    c += 1
        roots = np.empty(1, np.int64)
        roots[0] = nid[root]
    else:
        nn = 2 * m + n
        # subtree sizes when rooted at vertex 0
        par[:] = -2
        par[0] = -1
        queue[0] = 0
        head = 0
        tail = 1
        while head < tail:
            x = queue[head]
            head += 1
            for q in range(aptr[x], aptr[x + 1]):
                y = adj[q]
                if par[y] == -2:
                    par[y] = x
                    queue[tail] = y
                    tail += 1
        sz = np.ones(n, np.int64)
        for t in range(n - 1, 0, -1):
            x = queue[t]
            sz[par[x]] += sz[x]
        tv = np.empty(nn, np.int64)
        tp = np.empty(nn, np.int64)
        size = np.empty(nn, np.int64)
        k = 0
        for v in range(n):
            for q in range(aptr[v], aptr[v + 1]):
                u = adj[q]
                tv[k] = v
                tp[k] = u
                if par[v] == u:
                    size[k] = sz[v]
                else:
                    size[k] = n - sz[u]
                k += 1
        for v in range(n):
            tv[k] = v
            tp[k] = -1
            size[k] = n + 1
            k += 1
        # stable counting sort by subtree size: children before parents
        cnt = np.zeros(n + 3, np.int64)
        for k in range(nn):
            cnt[size[k] + 1] += 1
        for t in range(1, n + 3):
            cnt[t] += cnt[t - 1]
        order = np.empty(nn, np.int64)
        for k in range(nn):
            order[cnt[size[k]]] = k
            cnt[size[k]] += 1
        node_v = np.empty(nn, np.int64)
        node_par = np.empty(nn, np.int64)
        ed_id = np.full((n, n), -1, np.int64)
        rt_id = np.empty(n, np.int64)
        for k in range(nn):
            o = order[k]
            node_v[k] = tv[o]
            node_par[k] = tp[o]
            if tp[o] >= 0:
                ed_id[tv[o], tp[o]] = k
            else:
                rt_id[tv[o]] = k
        nch = np.zeros(nn, np.int64)
        for k in range(nn):
            nch[k] = deg[node_v[k]] - (1 if node_par[k] >= 0 else 0)
        ch_ptr = np.zeros(nn + 1, np.int64)
        for k in range(nn):
            ch_ptr[k + 1] = ch_ptr[k] + nch[k]
        ch_idx = np.empty(ch_ptr[nn], np.int64)
        for k in range(nn):
            v = node_v[k]
            c = ch_ptr[k]
            for q in range(aptr[v], aptr[v + 1]):
                y = adj[q]
                if y != node_par[k]:
                    ch_idx[c] = ed_id[y, v]
                    c += 1
        roots = rt_id.copy()
    soff = np.zeros(nn + 1, np.int64)
    for k in range(nn):
        soff[k + 1] = soff[k] + (np.int64(1) << (ch_ptr[k + 1] - ch_ptr[k]))
    # items
    it_ptr = np.zeros(nn + 1, np.int64)
    for k in range(nn):
        cnt = 0
        if node_par[k] >= 0:
            if not merge:
                cnt = 1
            elif root >= 0:
                a = node_par[k]
                while a >= 0:
                    cnt += 1
                    a = par[a]
            else:
                v = node_v[k]
                for a in range(n):
                    if a != v and nxt[v, a] == node_par[k]:
                        cnt += 1
        it_ptr[k + 1] = it_ptr[k] + cnt
    ni = it_ptr[nn]
    it_node = np.empty(ni, np.int64)
    it_up = np.empty(ni, np.int64)
    it_w = np.empty(ni, np.float64)
    item_of = np.full((nn, n), -1, np.int64)
    base_item = np.full(nn, -1, np.int64)
    for k in range(nn):
        if node_par[k] < 0:
            continue
        v = node_v[k]
        c = it_ptr[k]
        if not merge:
            it_up[c] = node_par[k]
            c += 1
        elif root >= 0:
            a = node_par[k]
            while a >= 0:
                it_up[c] = a
                c += 1
                a = par[a]
        else:
            for a in range(n):
                if a != v and nxt[v, a] == node_par[k]:
                    it_up[c] = a
                    c += 1
        for c in range(it_ptr[k], it_ptr[k + 1]):
            it_node[c] = k
            it_w[c] = dist[it_up[c], v]
            item_of[k, it_up[c]] = c
        base_item[k] = item_of[k, node_par[k]]
    return node_v, node_par, ch_ptr, ch_idx, soff, it_ptr, it_node, it_up, it_w, item_of, base_item, roots, nxt


@njit(cache=True)
def deletion_costs(ch_ptr, ch_idx, soff, it_ptr, base_item, delarc, zero):
    """Cost of deleting each pruned tree (item) and each sub-forest (Prop. 19 / 24 / 26).

    ``zero``: every deletion is free (data side with the cut operation, Prop. 24).
    """
    nn = ch_ptr.shape[0] - 1
    ni = it_ptr[nn]
    delsub = np.zeros(ni, np.float64)
    delfor = np.zeros(soff[nn], np.float64)
    if zero:
        return delsub, delfor
    for k in range(nn):
        c0 = ch_ptr[k]
        nc = ch_ptr[k + 1] - c0
        o = soff[k]
        for mask in range(1, np.int64(1) << nc):
            low = mask & -mask
            t = _tz(low)
            delfor[o + mask] = delfor[o + (mask ^ low)] + delsub[base_item[ch_idx[c0 + t]]]
        full = delfor[o + (np.int64(1) << nc) - 1]
        for it in range(it_ptr[k], it_ptr[k + 1]):
            delsub[it] = delarc[it] + full
    return delsub, delfor
