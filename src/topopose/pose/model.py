"""Model trees: the a priori description of a subject (thesis §12.1, §12.2, §12.3, Fig. 12.9).

A model is a small edge-weighted tree whose vertices are the subject's parts (extremities
and junctions) and whose edge weights are rough relative limb lengths. It may carry
optional constraints (§12.2):

- coordinate constraints (§12.2.1) on a model edge: ``above`` / ``below`` along the
  capture's up axis (or any signed axis such as ``"-y"``), e.g. head above torso;
- betweenness constraints (§12.2.2): a sequence of at least three parts, each between
  its neighbours in the sequence for a chosen relation (R_b by default, the thesis' choice
  §13.2.2.2), e.g. the five fingertips of a hand.

A *complete* model describes a subject wholly inside the capture volume; an *incomplete*
model has exactly one limb crossing the capture border, given the infinite length "inf"
(§7.3.3.1, §12.1.1).

File format (TOML, DESIGN.md "Model tree file")::

    [model]
    name = "human"
    root = "torso"          # optional
    complete = true
    threshold = 0.4         # optional default T_d
    description = "..."     # optional
    parts = ["head", ...]   # optional: declares the parts (catches typos in edges)
    [[edge]]
    parts = ["torso", "head"]
    length = 0.35           # or "inf"
    [[constraint]]
    kind = "above"          # "above" | "below" | "between"
    parts = ["head", "torso"]
    axis = "+z"             # optional; default: the capture's up axis
    relation = "b"          # "between" only: c, p, b (default), u, i
    [[mirror]]              # optional: a mirror pair of numbered parts (left and right)
    parts = ["hand_1", "hand_2"]
    names = ["left_hand", "right_hand"]
    [facing]                # optional: how to find the subject's forward direction
    feet = ["foot_1", "foot_2"]   # the arcs ending at these parts end in a foot pointing
                                  # forward and bend forward at their middle (knees)
    axis = ["hips", "shoulders"]  # or: forward is from the first part to the second
    [[joint]]               # optional: a joint of the full kinematic skeleton
    name = "elbow"
    arc = ["torso", "hand"] # a model edge; a numbered stem ("hand") stands for each member
    at = 0.55               # relative position along the arc's skeleton curve (0: first part)
    offset = [0.2, 0.1]     # optional: joint beside the curve, in trunk lengths: along the
                            # trunk ([facing] trunk = [from, to]) and outward (away from the
                            # same joint of the mirror partner); e.g. shoulders, hips
    width = [-0.3, 0.7]     # optional: instead, the joint beside the arc's start (the
                            # junction), in hull radii (the hull's largest inscribed ball:
                            # girth): along the trunk and outward; e.g. hips
    at_raised = 0.65        # optional: ``at`` when the arc's end part lies past its first
                            # part along the trunk (a hand above the chest junction)
    slide = true            # optional: the bone from the joint's parent has no constant
                            # length (the parent is a junction of the skeleton curves that
                            # slides along the trunk); e.g. the neck below the chest junction
    girdle = ["shoulder", 0.1]  # optional: this joint and a mirror pair of joints (named by
                            # the pair's joint name) are one symmetric rigid body, this joint
                            # on its mid-plane, past the pair's midpoint by the number × the
                            # pair's width; e.g. the neck and the shoulders
    extends = true          # optional: the body goes on past the joint along the bone into
                            # it (the top of the head past the skull, the heel behind the
                            # ankle): the tracked body has a capsule there, as far as the
                            # confident frames' hulls go on

Mirror pairs: once :mod:`.chirality` knows the subject's left, ``parts[0]`` (the one on the
subject's left) is output as ``names[0]`` and ``parts[1]`` as ``names[1]``; the numbered
names stay when unsure. Ground truth follows the same order (``hand_1`` is the left hand of
the synthetic subjects). Joints on a numbered arc are named ``<name>_<k>`` (``elbow_1``), then
``<side>_<name>`` (``left_elbow``) with the prefix of the mirror name (``left_`` of
``left_hand``). The joints along the arcs, joined in order of ``at`` from the model root, form
the kinematic tree (:mod:`.kinematic_fit`): a joint at ``at = 0`` or ``1`` sits on a part and
links the arcs that meet there.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from topopose.errors import InputError
from topopose.match.tree import Constraint, Tree

BUILTIN = ("human", "hand", "dog", "spider")
COORDINATE_KINDS = ("above", "below")
RELATIONS = ("c", "p", "b", "u", "i")
_AXES = ("+x", "-x", "+y", "-y", "+z", "-z", "x", "y", "z")

_MODEL_KEYS = {"name", "root", "complete", "threshold", "description", "parts"}
_EDGE_KEYS = {"parts", "length"}
_CONSTRAINT_KEYS = {"kind", "parts", "axis", "relation"}
_MIRROR_KEYS = {"parts", "names"}
_FACING_KEYS = {"feet", "axis", "trunk"}
_JOINT_KEYS = {"name", "arc", "at", "offset", "beyond", "width", "at_raised", "slide",
               "girdle", "extends"}


@dataclass(frozen=True)
class JointSpec:
    """A joint of the kinematic skeleton: ``name`` at relative position ``at`` along the model
    arc ``arc`` (first part → second part, or a numbered stem standing for each member)."""

    name: str
    arc: tuple
    at: float
    offset: tuple = (0.0, 0.0)     # (along the trunk, outward from the mirror partner) × trunk
    beyond: float = 0.0            # a tip joint (at = 1): past the end part, × the curve length
    width: tuple = (0.0, 0.0)      # (along the trunk, outward) × the hull radius, from the
                                   # arc's start (replaces offset where the radius is known)
    at_raised: float = None        # at when the arc's end part is past its first part along the
                                   # trunk ([facing] trunk = [from, to]): a raised hand
    slide: bool = False            # the bone from its parent: the frame's length, not constant
    girdle: tuple = None           # (pair's joint name, height × the pair's width): this joint
                                   # and that mirror pair, one symmetric rigid body
    extends: bool = False          # the body goes on past the joint along its bone


@dataclass
class Model:
    """A model tree (thesis §12.3).

    Attributes
    ----------
    name : str
    tree : Tree
        Vertex ids are part names; weights are relative lengths (``math.inf`` for the
        limb crossing the border of incomplete models); ``tree.constraints`` holds the
        :class:`~topopose.match.Constraint` list; ``tree.root`` is :attr:`root`.
    root : str
        The part the alignment roots the model at (§12.1.1): for a complete model a
        high-degree part (default: the part of highest degree), for an incomplete model
        the free end of the infinite edge.
    complete : bool
    threshold : float or None
        Default AHA distance threshold T_d (§12.1.1); None: accept every alignment (T_d = 2).
    description : str
    """

    name: str
    tree: Tree
    root: str | None = None
    complete: bool = True
    threshold: float | None = None
    description: str = ""
    source: str = field(default="", repr=False)
    mirrors: list = field(default_factory=list)     # [(parts (a, b), names (a, b)), ...]
    facing: dict = field(default_factory=dict)      # {"feet": [...]} and/or {"axis": [a, b]}
    joints: list = field(default_factory=list)      # [JointSpec, ...]

    def __post_init__(self):
        validate_model(self)
        if self.root is None:
            self.root = default_root(self.tree, self.complete)
        self.tree.root = self.root

    # ------------------------------------------------------------ queries
    @property
    def parts(self) -> list:
        """Part names in file order."""
        return list(self.tree.vertices)

    @property
    def constraints(self) -> list:
        return list(self.tree.constraints)

    @property
    def infinite_edge(self):
        """``(end, inner)`` of the infinite edge (incomplete models), else None."""
        for u, v, w in self.tree.edges:
            if math.isinf(w):
                return (u, v) if self.tree.degree(u) == 1 else (v, u)
        return None

    def neighbours(self, part) -> list:
        return [n for n, _ in self.tree.adjacency()[part]]

    def interchangeable(self) -> list:
        """Groups of parts a tree cannot tell apart (same name stem, same neighbours).

        E.g. ``[["hand_1", "hand_2"], ["foot_1", "foot_2"]]`` for the human model; used to
        pair numbered parts with the ground truth optimally (§13.2.2).
        """
        groups = {}
        adj = self.tree.adjacency()
        for p in self.parts:
            stem = part_stem(p)
            if stem == p:
                continue
            key = (stem, tuple(sorted(str(n) for n, _ in adj[p])))
            groups.setdefault(key, []).append(p)
        return [g for g in groups.values() if len(g) > 1]

    def pattern(self) -> Tree:
        """The tree given to the alignment: finite weights normalized to sum 1, rooted (§12.1.1)."""
        t = self.tree.normalized()
        t.root = self.root
        return t

    def without_constraints(self, kinds=COORDINATE_KINDS) -> "Model":
        """A copy without the constraints of the given kinds (e.g. for acrobatics, §13.1.2)."""
        keep = [c for c in self.tree.constraints if c.kind not in kinds]
        tree = Tree(list(self.tree.edges), vertices=list(self.tree.vertices), root=self.root,
                    constraints=keep)
        return replace(self, tree=tree)

    # ------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        m = {"name": self.name, "root": self.root, "complete": self.complete}
        if self.threshold is not None:
            m["threshold"] = float(self.threshold)
        if self.description:
            m["description"] = self.description
        m["parts"] = [str(p) for p in self.parts]
        edges = [{"parts": [str(u), str(v)], "length": ("inf" if math.isinf(w) else float(w))}
                 for u, v, w in self.tree.edges]
        out = {"model": m, "edge": edges}
        cons = []
        for c in self.tree.constraints:
            d = {"kind": c.kind, "parts": [str(p) for p in c.parts]}
            if c.axis is not None:
                d["axis"] = c.axis
            if c.relation is not None:
                d["relation"] = c.relation
            cons.append(d)
        if cons:
            out["constraint"] = cons
        if self.mirrors:
            out["mirror"] = [{"parts": list(p), "names": list(n)} for p, n in self.mirrors]
        if self.facing:
            out["facing"] = {k: list(v) for k, v in self.facing.items()}
        if self.joints:
            out["joint"] = [{"name": j.name, "arc": list(j.arc), "at": float(j.at)}
                            | ({"offset": [float(x) for x in j.offset]} if any(j.offset) else {})
                            | ({"beyond": float(j.beyond)} if j.beyond else {})
                            | ({"width": [float(x) for x in j.width]} if any(j.width) else {})
                            | ({"at_raised": float(j.at_raised)} if j.at_raised is not None
                               else {})
                            | ({"slide": True} if j.slide else {})
                            | ({"girdle": [j.girdle[0], float(j.girdle[1])]} if j.girdle
                               else {})
                            | ({"extends": True} if j.extends else {})
                            for j in self.joints]
        return out

    def save(self, path) -> None:
        """Write the model as TOML (DESIGN.md format), readable by :func:`load_model`."""
        import tomli_w

        Path(path).write_text(tomli_w.dumps(self.to_dict()))


def part_stem(part: str) -> str:
    """A numbered part's stem (``hand_1`` → ``hand``); other names as they are."""
    s = str(part)
    head, sep, tail = s.rpartition("_")
    return head if sep and tail.isdigit() and head else s


def default_root(tree: Tree, complete: bool):
    """The rooting of §12.1.1: highest-degree part (complete) or the infinite limb's end."""
    if not complete:
        for u, v, w in tree.edges:
            if math.isinf(w):
                return u if tree.degree(u) == 1 else v
    adj = tree.adjacency()
    return max(tree.vertices, key=lambda v: len(adj[v]))  # first of highest degree


def validate_model(m: Model) -> None:
    """Raise :class:`InputError` for anything that is not a usable model tree."""
    where = m.source or f"model {m.name!r}"
    t = m.tree
    adj = t.adjacency()
    infinite = [(u, v) for u, v, w in t.edges if math.isinf(w)]
    if len(infinite) > 1:
        raise InputError(f"{where}: edges {infinite} are both infinite; a model has at most one "
                         "infinite edge (the limb crossing the capture border)")
    if infinite:
        u, v = infinite[0]
        if m.complete:
            raise InputError(f"{where}: model.complete = true but edge {list(infinite[0])} has length "
                             "\"inf\"; set complete = false for a limb crossing the border")
        if len(adj[u]) != 1 and len(adj[v]) != 1:
            raise InputError(f"{where}: infinite edge {list(infinite[0])} must end at a part with no "
                             "other edge (the end crossing the capture border)")
    elif not m.complete:
        raise InputError(f"{where}: model.complete = false needs one edge of length \"inf\" "
                         "(the limb crossing the capture border)")
    if all(w == 0 for _, _, w in t.edges if math.isfinite(w)) and t.edges:
        raise InputError(f"{where}: every finite edge length is 0; give relative lengths > 0")
    if m.root is not None:
        if m.root not in adj:
            raise InputError(f"{where}: model.root {m.root!r} is not a part (parts: {list(adj)})")
        if not m.complete and len(adj[m.root]) != 1:
            raise InputError(f"{where}: model.root of an incomplete model must be the free end of "
                             f"the infinite edge, got {m.root!r}")
    if m.threshold is not None and not (isinstance(m.threshold, (int, float)) and m.threshold >= 0):
        raise InputError(f"{where}: model.threshold must be a number >= 0, got {m.threshold!r}")
    names = set()
    for i, (ps, ns) in enumerate(m.mirrors):
        mw = f"{where}: mirror[{i}]"
        if len(ps) != 2 or len(ns) != 2 or not all(isinstance(x, str) and x for x in (*ps, *ns)):
            raise InputError(f"{mw}: parts and names must be two names each")
        for p in ps:
            if p not in adj:
                raise InputError(f"{mw}: unknown part {p!r} (parts: {list(adj)})")
        for x in ns:
            if x in adj or x in names:
                raise InputError(f"{mw}: name {x!r} is already a part or a mirror name")
            names.add(x)
    for k, v in m.facing.items():
        if k not in _FACING_KEYS:
            raise InputError(f"{where}: [facing] has unknown field {k!r}; expected feet, axis")
        if not isinstance(v, (list, tuple)) or not all(p in adj for p in v):
            raise InputError(f"{where}: facing.{k} must list parts of the model, got {v!r}")
        if k in ("axis", "trunk") and len(v) != 2:
            raise InputError(f"{where}: facing.{k} must be two parts [from, to], got {v!r}")
    stems = {}
    for p in adj:
        stems.setdefault(part_stem(p), []).append(p)
    for i, j in enumerate(m.joints):
        jw = f"{where}: joint[{i}]"
        if not isinstance(j.name, str) or not j.name:
            raise InputError(f"{jw}: field 'name' must be a non-empty string")
        for field in ("offset", "width"):
            pair = getattr(j, field)
            if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                               for x in pair)):
                raise InputError(f"{jw}: field '{field}' must be two numbers [along, outward]")
            if any(pair) and len(m.facing.get("trunk", ())) != 2:
                raise InputError(f"{jw}: field '{field}' needs [facing] trunk = [from, to] "
                                 "(two parts)")
        if j.at_raised is not None and (
                isinstance(j.at_raised, bool) or not isinstance(j.at_raised, (int, float))
                or not 0.0 < float(j.at_raised) < 1.0 or len(m.facing.get("trunk", ())) != 2):
            raise InputError(f"{jw}: field 'at_raised' must be a number in (0, 1), with [facing] "
                             f"trunk = [from, to]; got {j.at_raised!r}")
        if not isinstance(j.slide, bool):
            raise InputError(f"{jw}: field 'slide' must be true or false, got {j.slide!r}")
        if not isinstance(j.extends, bool):
            raise InputError(f"{jw}: field 'extends' must be true or false, got {j.extends!r}")
        if j.girdle is not None and (
                not isinstance(j.girdle, (list, tuple)) or len(j.girdle) != 2
                or not isinstance(j.girdle[0], str) or isinstance(j.girdle[1], bool)
                or not isinstance(j.girdle[1], (int, float)) or not -1.0 <= j.girdle[1] <= 1.0
                or j.girdle[0] not in {x.name for x in m.joints} or j.girdle[0] == j.name):
            raise InputError(f"{jw}: field 'girdle' must be [another joint's name, a number in "
                             f"[-1, 1]], got {j.girdle!r}")
        if (not isinstance(j.arc, (list, tuple)) or len(j.arc) != 2
                or not all(isinstance(x, str) for x in j.arc)):
            raise InputError(f"{jw}: field 'arc' must be two part names (or numbered stems)")
        a, b = j.arc
        for x in (a, b):
            if x not in adj and x not in stems:
                raise InputError(f"{jw}: unknown part {x!r} in arc (parts: {list(adj)})")
        ea = [a] if a in adj else stems[a]
        eb = [b] if b in adj else stems[b]
        if not any(y in (n for n, _ in adj[x]) for x in ea for y in eb):
            raise InputError(f"{jw}: arc {[a, b]} is not a model edge")
        if (isinstance(j.at, bool) or not isinstance(j.at, (int, float))
                or not 0.0 <= float(j.at) <= 1.0):
            raise InputError(f"{jw}: field 'at' must be a number in [0, 1], got {j.at!r}")
        if (isinstance(j.beyond, bool) or not isinstance(j.beyond, (int, float))
                or not 0.0 <= float(j.beyond) <= 1.0 or (j.beyond and float(j.at) != 1.0)):
            raise InputError(f"{jw}: field 'beyond' must be a number in [0, 1] on a joint at "
                             f"at = 1, got {j.beyond!r}")
    for i, c in enumerate(t.constraints):
        cw = f"{where}: constraint[{i}]"
        if not isinstance(c, Constraint):
            raise InputError(f"{cw}: expected a Constraint")
        for p in c.parts:
            if p not in adj:
                raise InputError(f"{cw}: unknown part {p!r} (parts: {list(adj)})")
        if len(set(c.parts)) != len(c.parts):
            raise InputError(f"{cw}: a part appears twice in parts {list(c.parts)}")
        if c.kind in COORDINATE_KINDS:
            if len(c.parts) != 2:
                raise InputError(f"{cw}: kind {c.kind!r} takes exactly 2 parts, got {list(c.parts)}")
            a, b = c.parts
            if b not in (n for n, _ in adj[a]):
                raise InputError(f"{cw}: parts {a!r} and {b!r} are not adjacent; a coordinate "
                                 "constraint must be on a model edge (§12.2.1)")
            if c.axis is not None and str(c.axis).strip().lower() not in _AXES:
                raise InputError(f"{cw}: axis {c.axis!r} must be one of +x, -x, +y, -y, +z, -z")
            if c.relation is not None:
                raise InputError(f"{cw}: field 'relation' only applies to kind \"between\"")
        elif c.kind == "between":
            if len(c.parts) < 3:
                raise InputError(f"{cw}: kind \"between\" needs a sequence of at least 3 parts")
            if c.relation is not None and c.relation not in RELATIONS:
                raise InputError(f"{cw}: relation {c.relation!r} must be one of {', '.join(RELATIONS)}")
            if c.axis is not None:
                raise InputError(f"{cw}: field 'axis' only applies to kinds \"above\"/\"below\"")
        else:
            raise InputError(f"{cw}: kind {c.kind!r} must be one of \"above\", \"below\", \"between\"")


def model_from_dict(d: dict, source: str = "model") -> Model:
    """Build a :class:`Model` from the parsed TOML; every error names ``source`` and the field."""
    if not isinstance(d, dict):
        raise InputError(f"{source}: expected a TOML document")
    unknown = set(d) - {"model", "edge", "constraint", "mirror", "facing", "joint"}
    if unknown:
        raise InputError(f"{source}: unknown table(s) {sorted(unknown)}; expected [model], [[edge]], "
                         "[[constraint]], [[mirror]], [facing], [[joint]]")
    meta = d.get("model")
    if not isinstance(meta, dict):
        raise InputError(f"{source}: missing table [model] (with name, complete, optional root)")
    bad = set(meta) - _MODEL_KEYS
    if bad:
        raise InputError(f"{source}: [model] has unknown field(s) {sorted(bad)}; expected "
                         f"{sorted(_MODEL_KEYS)}")
    name = meta.get("name", Path(source).stem)
    if not isinstance(name, str) or not name:
        raise InputError(f"{source}: model.name must be a non-empty string")
    complete = meta.get("complete", True)
    if not isinstance(complete, bool):
        raise InputError(f"{source}: model.complete must be true or false, got {complete!r}")
    declared = meta.get("parts")
    if declared is not None:
        if not isinstance(declared, list) or not all(isinstance(p, str) for p in declared):
            raise InputError(f"{source}: model.parts must be a list of part names")
        dup = sorted({p for p in declared if declared.count(p) > 1})
        if dup:
            raise InputError(f"{source}: model.parts declares {dup} twice")
    edges_in = d.get("edge")
    if not isinstance(edges_in, list) or not edges_in:
        raise InputError(f"{source}: no [[edge]] tables; a model needs at least one edge")
    edges, seen = [], set()
    for i, e in enumerate(edges_in):
        ew = f"{source}: edge[{i}]"
        if not isinstance(e, dict):
            raise InputError(f"{ew}: expected a table with parts and length")
        bad = set(e) - _EDGE_KEYS
        if bad:
            raise InputError(f"{ew}: unknown field(s) {sorted(bad)}; expected parts, length")
        parts = e.get("parts")
        if (not isinstance(parts, list) or len(parts) != 2
                or not all(isinstance(p, str) and p for p in parts)):
            raise InputError(f"{ew}: field 'parts' must be two part names, got {parts!r}")
        a, b = parts
        if a == b:
            raise InputError(f"{ew}: parts {parts} join a part to itself")
        if declared is not None:
            for p in parts:
                if p not in declared:
                    raise InputError(f"{ew}: unknown part {p!r} (model.parts: {declared})")
        key = frozenset(parts)
        if key in seen:
            raise InputError(f"{ew}: duplicate edge {parts}")
        seen.add(key)
        if "length" not in e:
            raise InputError(f"{ew}: missing field 'length' (a relative length or \"inf\")")
        w = e["length"]
        if isinstance(w, str):
            if w.strip().lower() not in ("inf", "+inf", "infinity"):
                raise InputError(f"{ew}: length {w!r} must be a number or \"inf\"")
            w = math.inf
        elif isinstance(w, bool) or not isinstance(w, (int, float)) or math.isnan(w) or w < 0:
            raise InputError(f"{ew}: length {w!r} must be a number >= 0 or \"inf\"")
        edges.append((a, b, float(w)))
    verts = None
    if declared is not None:
        used = {p for a, b, _ in edges for p in (a, b)}
        missing = [p for p in declared if p not in used]
        if missing and len(declared) > 1:
            raise InputError(f"{source}: part(s) {missing} declared in model.parts but on no edge")
        verts = list(declared)
    cons = []
    for i, c in enumerate(d.get("constraint") or []):
        cw = f"{source}: constraint[{i}]"
        if not isinstance(c, dict):
            raise InputError(f"{cw}: expected a table with kind and parts")
        bad = set(c) - _CONSTRAINT_KEYS
        if bad:
            raise InputError(f"{cw}: unknown field(s) {sorted(bad)}; expected {sorted(_CONSTRAINT_KEYS)}")
        kind = c.get("kind")
        parts = c.get("parts")
        if not isinstance(parts, list) or not all(isinstance(p, str) for p in parts):
            raise InputError(f"{cw}: field 'parts' must be a list of part names")
        rel = c.get("relation")
        if isinstance(rel, str):
            rel = rel.strip().lower().removeprefix("r_").removeprefix("r")
            rel = rel or None
        cons.append(Constraint(kind=kind, parts=tuple(parts), axis=c.get("axis"), relation=rel))
    try:
        tree = Tree(edges, vertices=verts, constraints=cons)
    except InputError as exc:
        raise InputError(f"{source}: {exc}".replace("tree: ", "")) from None
    mirrors, joints = [], []
    for i, mi in enumerate(d.get("mirror") or []):
        if not isinstance(mi, dict) or set(mi) != _MIRROR_KEYS:
            raise InputError(f"{source}: mirror[{i}]: expected a table with exactly parts, names")
        mirrors.append((tuple(mi["parts"]), tuple(mi["names"])))
    facing = d.get("facing") or {}
    if not isinstance(facing, dict):
        raise InputError(f"{source}: [facing] must be a table (feet, axis)")
    for i, j in enumerate(d.get("joint") or []):
        if not isinstance(j, dict) or not {"name", "arc", "at"} <= set(j) <= _JOINT_KEYS:
            raise InputError(f"{source}: joint[{i}]: expected a table with name, arc, at "
                             "(and optional offset, beyond, width, at_raised, slide, girdle, extends)")
        off = j.get("offset", (0.0, 0.0))
        joints.append(JointSpec(j["name"], tuple(j["arc"]) if isinstance(j["arc"], list)
                                else j["arc"], j["at"],
                                tuple(off) if isinstance(off, list) else off,
                                j.get("beyond", 0.0),
                                tuple(j["width"]) if isinstance(j.get("width"), list)
                                else j.get("width", (0.0, 0.0)), j.get("at_raised"),
                                j.get("slide", False),
                                tuple(j["girdle"]) if isinstance(j.get("girdle"), list)
                                else j.get("girdle"), j.get("extends", False)))
    return Model(name=name, tree=tree, root=meta.get("root"), complete=complete,
                 threshold=meta.get("threshold"), description=meta.get("description", ""),
                 source=source, mirrors=mirrors, facing=dict(facing), joints=joints)


def builtin_path(name: str):
    return resources.files("topopose.pose").joinpath("models", f"{name}.toml")


def load_model(name_or_path, constraints: bool = True) -> Model:
    """Load a built-in model (``human``, ``hand``, ``dog``, ``spider``) or a TOML file.

    Parameters
    ----------
    name_or_path : str, Path or Model
    constraints : bool
        False drops the coordinate constraints (above/below), e.g. for acrobatics where
        the torso is often above the head (thesis §13.1.2, *children* data set);
        betweenness constraints are kept.

    Raises
    ------
    InputError
        Unknown name, missing/unreadable file, or an invalid model (the message names the
        file and the field).
    """
    if isinstance(name_or_path, Model):
        m = name_or_path
    else:
        s = str(name_or_path)
        if s in BUILTIN and not Path(s).exists():
            res = builtin_path(s)
            m = model_from_dict(tomllib.loads(res.read_text()), source=f"built-in model {s!r}")
            m.source = ""
        else:
            p = Path(s)
            if not p.exists():
                raise InputError(f"model {s!r}: no such file and not a built-in model "
                                 f"({', '.join(BUILTIN)})")
            try:
                d = tomllib.loads(p.read_text())
            except tomllib.TOMLDecodeError as exc:
                raise InputError(f"{p}: not valid TOML ({exc})") from None
            except (OSError, UnicodeDecodeError) as exc:
                raise InputError(f"{p}: cannot read model file ({exc})") from None
            m = model_from_dict(d, source=str(p))
    if not constraints:
        m = m.without_constraints()
    return m


def guess_model(pose, name=None):
    """The model a poses file was made with: ``name``, or the built-in with the same parts."""
    if name:
        return load_model(name)
    if pose.diagnostics.get("model") in BUILTIN:
        return load_model(pose.diagnostics["model"])
    keys = set(pose.parts)
    for b in BUILTIN:
        m = load_model(b)
        mirror = {n for _, names in m.mirrors for n in names}
        if set(m.parts) == keys or (keys & mirror and keys <= set(m.parts) | mirror):
            return m
    raise InputError("--model: the poses' parts match no built-in model; give --model FILE.toml")
