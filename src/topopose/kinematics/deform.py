"""Deforming a pERG onto the pERG of another frame (Mukasa §2.3.1).

The nodes of the *initial model* (a pERG with its node connectivity) move towards the
nodes of a *target* pERG under

- the external force of eq. 2–3 (Burr's symmetric point-set deformation, ref. [3]): every
  model node n is paired with its nearest target point and every target point m with its
  nearest model node; the force at a point p is the α-weighted mean of the model-side
  drifts plus the β-weighted mean of the target-side drifts, with weights exp(-d/σ);
- the internal force of eq. 4: springs between every pair of model nodes within 2 hops,
  of rest length their distance in the initial model (constraint (a), "maintain the
  distance between nodes as much as possible"). The paper's extra term −k'·q_v is left out
  (k' = 0).

The equation of motion q' = F_int(q) + F_ext(q) is integrated with backward Euler: the
spring force is linearized (fixed directions per step) so that each step is one sparse
linear solve ``(I + dt·k·L) q⁺ = q + dt (F_ext(q) − k·c(q))`` with L the Laplacian of the
2-hop spring graph; σ shrinks geometrically over the steps (coarse-to-fine, as in Burr).

Target points are the target pERG's nodes plus points sampled along its edges (every
half node spacing), so a model node is drawn to the graph's curve and not only to its
(unevenly spaced) nodes.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix, identity
from scipy.sparse.linalg import factorized
from scipy.spatial import cKDTree


def two_hop_pairs(n: int, edges: np.ndarray) -> np.ndarray:
    """Pairs (i < j) of nodes joined by a path of 1 or 2 edges (eq. 4's v_j)."""
    if len(edges) == 0:
        return np.zeros((0, 2), np.int64)
    A = coo_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]],
                                              np.r_[edges[:, 1], edges[:, 0]])), shape=(n, n)).tocsr()
    A2 = (A + A @ A).tocoo()
    m = A2.row < A2.col
    return np.stack([A2.row[m], A2.col[m]], 1).astype(np.int64)


def densify(positions: np.ndarray, edges: np.ndarray, step: float) -> np.ndarray:
    """The nodes plus points every ``step`` along the edges of a graph."""
    pts = [positions]
    for a, b in edges:
        d = float(np.linalg.norm(positions[b] - positions[a]))
        k = int(d // step)
        if k >= 1:
            t = (np.arange(1, k + 1) / (k + 1))[:, None]
            pts.append(positions[a] + t * (positions[b] - positions[a]))
    return np.concatenate(pts)


class Deformer:
    """Deform a fixed model graph (node count and connectivity) onto target point sets.

    Parameters
    ----------
    rest : (n, 3) node positions of the initial model (defines the spring rest lengths).
    edges : (e, 2) model edges.
    k : spring stiffness (relative to the unit external force).
    dt : time step of the backward Euler integration.
    steps : number of integration steps per target.
    sigma : (start, end) of the external force's σ, in world units.
    """

    def __init__(self, rest, edges, *, k: float = 1.0, dt: float = 0.5, steps: int = 30,
                 sigma=(0.1, 0.02)):
        self.rest = np.asarray(rest, float)
        self.edges = np.asarray(edges, np.int64).reshape(-1, 2)
        n = len(self.rest)
        self.pairs = two_hop_pairs(n, self.edges)
        deg = np.bincount(self.edges.ravel(), minlength=n)
        self.leaves = np.nonzero(deg == 1)[0]
        p = self.pairs
        self.L0 = np.linalg.norm(self.rest[p[:, 1]] - self.rest[p[:, 0]], axis=1)
        self.k, self.dt, self.steps = float(k), float(dt), int(steps)
        self.sigma = (float(sigma[0]), float(sigma[1]))
        w = np.ones(len(p))
        A = coo_matrix((np.r_[w, w], (np.r_[p[:, 0], p[:, 1]], np.r_[p[:, 1], p[:, 0]])), shape=(n, n)).tocsr()
        deg = np.asarray(A.sum(1)).ravel()
        Lap = coo_matrix((deg, (np.arange(n), np.arange(n))), shape=(n, n)).tocsr() - A
        self._solve = factorized((identity(n, format="csc") + self.dt * self.k * Lap).tocsc())

    def spring_offsets(self, q):
        """c(q): Σ_j L_ij u_ij per node (the rest-length part of the linearized springs)."""
        p = self.pairs
        d = q[p[:, 1]] - q[p[:, 0]]
        nrm = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        u = d / nrm[:, None] * self.L0[:, None]
        c = np.zeros_like(q)
        np.add.at(c, p[:, 0], u)
        np.add.at(c, p[:, 1], -u)
        return c

    def external(self, q, target, tree, sigma):
        """Eq. 2–3 at the model nodes ``q``."""
        _, j = tree.query(q)
        fa = target[j] - q                                   # drift of model node n
        _, i = cKDTree(q).query(target)
        fb = target - q[i]                                   # drift of the model node paired with m
        # α-weighted mean over model nodes of fa; β-weighted mean over target points of fb
        d_a = np.linalg.norm(q[:, None, :] - q[None, :, :], axis=2)
        A = np.exp(-(d_a - d_a.min(1, keepdims=True)) / sigma)
        F = (A @ fa) / A.sum(1, keepdims=True)
        d_b = np.linalg.norm(q[:, None, :] - q[i][None, :, :], axis=2)
        B = np.exp(-(d_b - d_b.min(1, keepdims=True)) / sigma)
        F += (B @ fb) / B.sum(1, keepdims=True)
        return F

    def fit(self, q0, target_points, target_ends=None) -> np.ndarray:
        """Deform from node positions ``q0`` onto the points ``target_points``.

        ``target_ends``: optional end points of the target graph. Each end node of the model
        (degree 1) is then also pulled to its nearest target end point when it lies within
        2σ_start (an addition to eq. 2: nearest-point forces are blind along a chain, and
        the end points are the parts ``topopose run`` needs).
        """
        q = np.asarray(q0, float).copy()
        target = np.asarray(target_points, float)
        tree = cKDTree(target)
        s0, s1 = self.sigma
        ends = None
        if target_ends is not None and len(target_ends) and len(self.leaves):
            ends = np.asarray(target_ends, float).reshape(-1, 3)
            etree = cKDTree(ends)
        for it in range(self.steps):
            sigma = s0 * (s1 / s0) ** (it / max(self.steps - 1, 1))
            F = self.external(q, target, tree, sigma)
            if ends is not None:
                d, j = etree.query(q[self.leaves])
                near = d < 2 * s0
                F[self.leaves[near]] += ends[j[near]] - q[self.leaves[near]]
            rhs = q + self.dt * (F - self.k * self.spring_offsets(q))
            q = np.stack([self._solve(rhs[:, c]) for c in range(3)], 1)
        return q
