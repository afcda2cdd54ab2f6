"""Edge-weighted unordered trees, rooted or unrooted (thesis §8.1).

The one tree type shared by the stages: the data tree built from a skeleton
(:func:`topopose.data_tree`), the model tree of a subject
(:func:`topopose.load_model`) and both inputs of :func:`topopose.align`.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Hashable, Iterable

import numpy as np

from topopose.errors import InputError

INF = math.inf


@dataclass(frozen=True)
class Constraint:
    """A constraint of a model tree (thesis §12.2).

    kind : ``"above"`` / ``"below"`` (coordinate constraint on the model edge
        joining ``parts[0]`` and ``parts[1]``, along ``axis``; §12.2.1) or
        ``"between"`` (betweenness sequence over similar limbs, §12.2.2).
    parts : the part names, in order.
    axis : a signed axis such as ``"+z"`` or ``"-y"``; None means the capture's up axis.
    relation : for ``"between"``: one of ``"c", "p", "b", "u", "i"`` (R_c ... R_i); default ``"b"``.
    """

    kind: str
    parts: tuple
    axis: str | None = None
    relation: str | None = None


def _parse_id(key):
    """JSON object keys are strings: give back ints for canonical integer ids."""
    if isinstance(key, str) and key.lstrip("-").isdigit() and str(int(key)) == key:
        return int(key)
    return key


def _weight(w, where):
    if isinstance(w, str):
        if w.strip().lower() in ("inf", "+inf", "infinity"):
            return INF
        raise InputError(f"{where}: weight {w!r} is not a number or \"inf\"")
    try:
        w = float(w)
    except (TypeError, ValueError):
        raise InputError(f"{where}: weight {w!r} is not a number or \"inf\"") from None
    return w


@dataclass
class Tree:
    """An edge-weighted tree.

    Parameters
    ----------
    edges : list of (u, v, weight)
        Weights are non-negative floats; ``math.inf`` is allowed (the limb that
        crosses the capture border, thesis §7.3.3.1).
    vertices : list, optional
        Vertex ids in a fixed order; by default the ids met in ``edges``.
        Give it for a tree with a single vertex and no edge.
    positions : dict id -> array (3,) or None, optional
        World position of each vertex (data trees).
    labels : dict id -> str or None, optional
    root : id or None
        None: the tree is unrooted.
    constraints : list of Constraint
        Model-tree constraints (used by :func:`topopose.align`).
    diagnostics : dict
        Facts about how the tree was built (cycles broken, loops dropped, ...).
    voxels : dict or None
        Data trees built by :func:`topopose.data_tree`: which skeleton voxel makes which vertex
        or edge (``index``: C-order linear indices of the skeleton voxels, ``vertex``: vertex
        id or −1, ``edge``: index in ``edges`` or −1, per voxel). Not saved to JSON.

    Examples
    --------
    >>> t = Tree([("a", "b", 1.0), ("b", "c", 2.0)], root="a")
    >>> t.degree("b"), t.total_weight()
    (2, 3.0)
    """

    edges: list
    vertices: list | None = None
    positions: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    root: Hashable | None = None
    constraints: list = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)
    voxels: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        self.edges = [(u, v, _weight(w, f"edge ({u!r}, {v!r})")) for u, v, w in self.edges]
        if self.vertices is None:
            seen = dict.fromkeys(self.positions)
            for u, v, _ in self.edges:
                seen.setdefault(u)
                seen.setdefault(v)
            self.vertices = list(seen)
        else:
            self.vertices = list(self.vertices)
        self.positions = {k: (None if p is None else np.asarray(p, dtype=float).reshape(3))
                          for k, p in self.positions.items()}
        self.validate()

    # ------------------------------------------------------------------ checks
    def validate(self, name: str = "tree") -> None:
        """Raise :class:`InputError` unless this is a tree with valid weights and root."""
        vs = set(self.vertices)
        if len(vs) != len(self.vertices):
            raise InputError(f"{name}: duplicate vertex ids")
        if not self.vertices:
            raise InputError(f"{name}: the tree has no vertex")
        parent = {v: v for v in vs}

        def find(x):
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for u, v, w in self.edges:
            if u not in vs or v not in vs:
                raise InputError(f"{name}: edge ({u!r}, {v!r}) names a vertex not in the tree")
            if u == v:
                raise InputError(f"{name}: edge ({u!r}, {v!r}) is a self-loop")
            if math.isnan(w) or w < 0:
                raise InputError(f"{name}: edge ({u!r}, {v!r}) has weight {w}; weights must be >= 0 (or inf)")
            ru, rv = find(u), find(v)
            if ru == rv:
                raise InputError(f"{name}: edge ({u!r}, {v!r}) closes a cycle; a tree has none")
            parent[ru] = rv
        if len(self.edges) != len(self.vertices) - 1:
            raise InputError(f"{name}: the graph is disconnected ({len(self.vertices)} vertices, "
                             f"{len(self.edges)} edges)")
        if self.root is not None and self.root not in vs:
            raise InputError(f"{name}: root {self.root!r} is not a vertex of the tree")

    # ------------------------------------------------------------------ queries
    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    def adjacency(self) -> dict:
        """Map each vertex to a list of (neighbour, weight), in edge order."""
        adj = {v: [] for v in self.vertices}
        for u, v, w in self.edges:
            adj[u].append((v, w))
            adj[v].append((u, w))
        return adj

    def degree(self, v) -> int:
        return sum((u == v) + (w == v) for u, w, _ in self.edges)

    def max_degree(self) -> int:
        adj = self.adjacency()
        return max((len(n) for n in adj.values()), default=0)

    def total_weight(self) -> float:
        """Sum of the finite weights."""
        return float(sum(w for _, _, w in self.edges if math.isfinite(w)))

    def normalized(self) -> "Tree":
        """A copy whose finite weights sum to 1 (thesis §12.1); infinite weights stay."""
        s = self.total_weight()
        edges = [(u, v, (w / s if s > 0 and math.isfinite(w) else w)) for u, v, w in self.edges]
        return Tree(edges, vertices=list(self.vertices), positions=dict(self.positions),
                    labels=dict(self.labels), root=self.root, constraints=list(self.constraints),
                    diagnostics=dict(self.diagnostics), voxels=self.voxels)

    def rooted(self, root) -> "Tree":
        """A copy rooted at ``root`` (None: unrooted)."""
        t = Tree(list(self.edges), vertices=list(self.vertices), positions=dict(self.positions),
                 labels=dict(self.labels), root=None, constraints=list(self.constraints),
                 diagnostics=dict(self.diagnostics), voxels=self.voxels)
        if root is not None and root not in set(t.vertices):
            raise InputError(f"tree: root {root!r} is not a vertex of the tree")
        t.root = root
        return t

    # ------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        """The JSON form of DESIGN.md (infinite weights as the string "inf")."""
        verts = {}
        for v in self.vertices:
            p = self.positions.get(v)
            verts[str(v)] = {"position": None if p is None else [float(x) for x in p],
                             "label": self.labels.get(v)}
        out = {"vertices": verts,
               "edges": [[u, v, ("inf" if math.isinf(w) else float(w))] for u, v, w in self.edges],
               "root": self.root}
        if self.diagnostics:
            out["diagnostics"] = _jsonable(self.diagnostics)
        return out

    @classmethod
    def from_dict(cls, d: dict, source: str = "tree") -> "Tree":
        """Build a tree from its JSON form; ``source`` names the file in errors."""
        if not isinstance(d, dict) or "edges" not in d:
            raise InputError(f"{source}: expected an object with 'vertices' and 'edges'")
        verts = d.get("vertices") or {}
        if not isinstance(verts, dict):
            raise InputError(f"{source}: field 'vertices' must be an object id -> {{position, label}}")
        ids = [_parse_id(k) for k in verts]
        positions, labels = {}, {}
        for k, key in zip(ids, verts):
            rec = verts[key] or {}
            pos = rec.get("position")
            if pos is not None:
                pos = np.asarray(pos, dtype=float)
                if pos.shape != (3,) or not np.all(np.isfinite(pos)):
                    raise InputError(f"{source}: vertices.{key}.position must be 3 finite numbers")
            positions[k] = pos
            labels[k] = rec.get("label")
        edges = []
        for i, e in enumerate(d["edges"]):
            if not isinstance(e, (list, tuple)) or len(e) != 3:
                raise InputError(f"{source}: edges[{i}] must be [u, v, weight]")
            u, v = (_parse_id(str(x)) if not isinstance(x, int) else x for x in e[:2])
            edges.append((u, v, _weight(e[2], f"{source}: edges[{i}]")))
        root = d.get("root")
        if root is not None and not isinstance(root, int):
            root = _parse_id(str(root))
        try:
            return cls(edges, vertices=ids or None, positions=positions, labels=labels,
                       root=root, diagnostics=d.get("diagnostics") or {})
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None

    def save(self, path) -> None:
        """Write the tree as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path) -> "Tree":
        """Read a tree JSON file."""
        path = Path(path)
        try:
            d = json.loads(path.read_text())
        except FileNotFoundError:
            raise InputError(f"{path}: no such file") from None
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"{path}: not a JSON tree ({exc})") from None
        return cls.from_dict(d, source=str(path))

    def to_networkx(self):
        """A ``networkx.Graph`` with ``weight``, ``position`` and ``label`` attributes."""
        import networkx as nx

        g = nx.Graph(root=self.root)
        for v in self.vertices:
            g.add_node(v, position=self.positions.get(v), label=self.labels.get(v))
        for u, v, w in self.edges:
            g.add_edge(u, v, weight=w)
        return g

    @classmethod
    def from_networkx(cls, g, root=None) -> "Tree":
        """Build a tree from a ``networkx.Graph`` (edge attribute ``weight``, default 1)."""
        edges = [(u, v, data.get("weight", 1.0)) for u, v, data in g.edges(data=True)]
        positions = {v: d.get("position") for v, d in g.nodes(data=True) if d.get("position") is not None}
        labels = {v: d.get("label") for v, d in g.nodes(data=True) if d.get("label") is not None}
        if root is None:
            root = g.graph.get("root")
        return cls(edges, vertices=list(g.nodes), positions=positions, labels=labels, root=root)


def _jsonable(x):
    """Plain JSON types: arrays to lists, numpy scalars to Python, non-finite floats to \"inf\"/null."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    return str(x)


def as_tree(obj, root=None, name="tree") -> Tree:
    """Accept a :class:`Tree`, an object with a ``.tree`` attribute (a model) or an edge list."""
    if isinstance(obj, Tree):
        return obj if root is None else obj.rooted(root)
    if hasattr(obj, "tree") and isinstance(obj.tree, Tree):
        return obj.tree if root is None else obj.tree.rooted(root)
    if isinstance(obj, Iterable):
        try:
            edges = [tuple(e) for e in obj]
        except TypeError:
            raise InputError(f"{name}: expected a Tree or a list of (u, v, weight)") from None
        if any(len(e) != 3 for e in edges):
            raise InputError(f"{name}: every edge must be (u, v, weight)")
        try:
            return Tree(edges, root=root)
        except InputError as exc:
            raise InputError(f"{name}: {exc}") from None
    raise InputError(f"{name}: expected a Tree or a list of (u, v, weight), got {type(obj).__name__}")
