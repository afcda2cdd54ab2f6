"""Specific pose detection by description (thesis §13.3.2.1).

A pose is described with the syntax of the model constraints combined by boolean operators,
as the thesis writes it::

    (z-greatest hand_1 - head) XOR (z-greatest hand_2 - head)          # ask a question
    (order hand_1 - head - hand_2) AND (order hand_1 - torso - hand_2)  # wide-spread arms

Grammar (operators and keywords are case-insensitive; ``-`` or ``,`` may separate the
arguments, as in the thesis' ``A_1 - H``)::

    expr     := xor ("or" xor)*                 lowest precedence
    xor      := and ("xor" and)*
    and      := unary ("and" unary)*
    unary    := "not" unary | primary
    primary  := "(" expr ")" | "true" | "false" | relation
    relation := AXIS "-" ("greatest" | "least") PART PART      # x-, y-, z-greatest / -least
              | ("above" | "below") PART PART
              | "order" ["-" REL] PART PART PART+               # each PART between its neighbours
              | ("near" | "far") PART PART NUMBER

* ``z-greatest A B``: A is higher than B. The thesis' axes: ``z`` is the capture's up axis
  (``capture.toml`` up), ``x`` and ``y`` the two other capture axes completing a right-handed
  frame (with up = +z they are the capture's own x, y, z). ``above A B`` is ``z-greatest A B``,
  ``below A B`` is ``z-least A B``.
* ``order A B C``: B lies between A and C for the betweenness relation R_b (§12.2.2.1, the
  thesis' choice); ``order-i``, ``order-c``, ``order-p``, ``order-u`` use R_i, R_c, R_p, R_u
  (:func:`topopose.match.betweenness`). More parts: every inner part between its neighbours,
  as in a model's betweenness constraint (§12.2.2.3).
* ``near A B d`` / ``far A B d``: the distance between A and B is below / above ``d``
  (capture units).

Evaluation is strict: the value is ``None`` when a part the expression names has no position
in the frame (or the frame is not matched). Part names are matched against the frame's parts
case-insensitively; numbered and sided names resolve to each other (``hand_1`` ↔ ``left_hand``,
``hand_l``; ``hand_2`` ↔ ``right_hand``), and a pose library may define aliases (the thesis'
``A_1``, ``H``, ``T``, ``C``, ``F_1`` for the human model).
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from topopose.errors import InputError

AXES = ("x", "y", "z")
RELATIONS = ("b", "i", "c", "p", "u")
KEYWORDS = {"and", "or", "xor", "not", "true", "false"}
LIBRARY = Path(__file__).with_name("poses.toml")
#: the deepest nesting of a description (operators, ``not`` and parentheses around a relation)
MAX_DEPTH = 100
#: the largest pose library file read (bytes)
MAX_LIBRARY_BYTES = 1 << 20


class ExpressionError(InputError):
    """A description that does not parse: the message shows the column with a caret (a long
    description: the 60 characters around it)."""

    def __init__(self, text, col, message):
        self.text, self.col, self.reason = text, col, message
        lo = max(0, col - 30) if len(text) > 60 else 0
        shown = text[lo:lo + 60] if len(text) > 60 else text
        super().__init__(f"expression: {message} at column {col + 1}\n  {shown}\n  "
                         f"{' ' * (col - lo)}^")


# ----------------------------------------------------------------------------- AST
@dataclass(frozen=True)
class Rel:
    """A relation over parts: ``op`` is ``"greatest"``, ``"least"``, ``"order"``, ``"near"`` or
    ``"far"``; ``axis`` the thesis axis index (0, 1, 2) for greatest/least; ``relation`` the
    betweenness relation for order; ``value`` the distance for near/far."""

    op: str
    parts: tuple
    axis: int | None = None
    relation: str | None = None
    value: float | None = None


@dataclass(frozen=True)
class Not:
    arg: object


@dataclass(frozen=True)
class BinOp:
    op: str          # "and", "or", "xor"
    left: object
    right: object


@dataclass(frozen=True)
class Const:
    value: bool


# ----------------------------------------------------------------------------- tokens
_TOKEN = re.compile(r"\s*(?:(?P<num>\d+(?:\.\d*)?(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)"
                    r"|(?P<name>[A-Za-z_][A-Za-z0-9_.]*)|(?P<punct>[()\-,]))")


@dataclass(frozen=True)
class Token:
    kind: str        # "num", "name", "punct", "end"
    text: str
    col: int


def tokenize(text: str) -> list:
    """Tokens of a description: numbers, names, ``( ) - ,``; an ``end`` token closes the list."""
    out, pos = [], 0
    while True:
        while pos < len(text) and text[pos].isspace():
            pos += 1
        if pos >= len(text):
            out.append(Token("end", "", len(text)))
            return out
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise ExpressionError(text, pos, f"unexpected character {text[pos]!r}")
        kind = m.lastgroup
        out.append(Token(kind, m.group(kind), m.start(kind)))
        pos = m.end()


class _Parser:
    def __init__(self, text):
        self.text = text
        self.toks = tokenize(text)
        self.i = 0
        self.nest = 0            # enclosing 'not's and parentheses (bounds the recursion)

    def peek(self, k=0):
        return self.toks[min(self.i + k, len(self.toks) - 1)]

    def next(self):
        t = self.peek()
        self.i += 1
        return t

    def error(self, tok, msg):
        raise ExpressionError(self.text, tok.col, msg)

    def is_word(self, tok, *words):
        return tok.kind == "name" and tok.text.lower() in words

    def parse(self):
        node = self.expr()
        t = self.peek()
        if t.kind != "end":
            self.error(t, f"expected an operator (and, or, xor) or the end, got {t.text!r}")
        if depth(node) > MAX_DEPTH:
            self.error(self.toks[0], f"nested deeper than {MAX_DEPTH} operators")
        return node

    def deeper(self, tok):
        self.nest += 1
        if self.nest > MAX_DEPTH:
            self.error(tok, f"nested deeper than {MAX_DEPTH} levels ('not', parentheses)")

    def _binary(self, op, sub):
        node = sub()
        while self.is_word(self.peek(), op):
            self.next()
            node = BinOp(op, node, sub())
        return node

    def expr(self):
        return self._binary("or", self.xor)

    def xor(self):
        return self._binary("xor", self.and_)

    def and_(self):
        return self._binary("and", self.unary)

    def unary(self):
        if self.is_word(self.peek(), "not"):
            self.deeper(self.next())
            node = Not(self.unary())
            self.nest -= 1
            return node
        return self.primary()

    def primary(self):
        t = self.peek()
        if t.kind == "punct" and t.text == "(":
            self.deeper(self.next())
            node = self.expr()
            self.nest -= 1
            c = self.peek()
            if not (c.kind == "punct" and c.text == ")"):
                self.error(c, f"expected ')' to close the '(' at column {t.col + 1}, got "
                              f"{c.text or 'the end'!r}")
            self.next()
            return node
        if self.is_word(t, "true", "false"):
            self.next()
            return Const(t.text.lower() == "true")
        if t.kind != "name":
            self.error(t, f"expected a relation (above, below, x/y/z-greatest, x/y/z-least, order, "
                          f"near, far), 'not' or '(', got {t.text or 'the end'!r}")
        return self.relation()

    def _dash(self):
        t = self.peek()
        if t.kind == "punct" and t.text == "-":
            self.next()
            return True
        return False

    def relation(self):
        t = self.next()
        w = t.text.lower()
        if w in AXES:
            if not self._dash():
                self.error(self.peek(), f"expected '-greatest' or '-least' after {t.text!r}")
            k = self.next()
            if not self.is_word(k, "greatest", "least"):
                self.error(k, f"expected 'greatest' or 'least', got {k.text or 'the end'!r}")
            return Rel(k.text.lower(), self.parts(2), axis=AXES.index(w))
        if w in ("above", "below"):
            return Rel("greatest" if w == "above" else "least", self.parts(2), axis=2)
        if w == "order":
            rel = "b"
            nt, nt2 = self.peek(), self.peek(1)
            if nt.kind == "punct" and nt.text == "-" and nt2.kind == "name" \
                    and nt2.text.lower() in RELATIONS + tuple("r_" + r for r in RELATIONS):
                self.next()
                rel = self.next().text.lower()[-1]
            return Rel("order", self.parts(3, more=True), relation=rel)
        if w in ("near", "far"):
            parts = self.parts(2)
            m, n = self.peek(), self.peek(1)
            if m.kind == "punct" and m.text == "-" and n.kind == "num" and n.col == m.col + 1:
                self.error(m, f"the distance of {t.text!r} must be ≥ 0, got -{n.text}")
            self._sep()
            n = self.next()
            if n.kind != "num":
                self.error(n, f"expected a distance (a number) after the parts of {t.text!r}, got "
                              f"{n.text or 'the end'!r}")
            if not np.isfinite(float(n.text)):
                self.error(n, f"the distance of {t.text!r} must be a finite number, got {n.text}")
            return Rel(w, parts, value=float(n.text))
        if w in KEYWORDS or w in ("greatest", "least"):
            self.error(t, f"{t.text!r} cannot start a relation")
        self.error(t, f"unknown relation {t.text!r} (expected above, below, x/y/z-greatest, "
                      "x/y/z-least, order, near, far)")

    def _sep(self):
        t = self.peek()
        if t.kind == "punct" and t.text in "-,":
            self.next()

    def _part(self):
        t = self.peek()
        if t.kind != "name" or t.text.lower() in KEYWORDS:
            self.error(t, f"expected a part name, got {t.text or 'the end'!r}")
        self.next()
        return t.text

    def parts(self, n, more=False):
        out = [self._part()]
        while len(out) < n:
            self._sep()
            out.append(self._part())
        while more:
            t, t2 = self.peek(), self.peek(1)
            if t.kind == "punct" and t.text in "-,":
                if t2.kind == "name" and t2.text.lower() not in KEYWORDS:
                    self.next()
                    out.append(self._part())
                    continue
                break
            if t.kind == "name" and t.text.lower() not in KEYWORDS:
                out.append(self._part())
                continue
            break
        return tuple(out)


def parse(text: str):
    """Parse a pose description into its syntax tree (:class:`Rel`, :class:`Not`,
    :class:`BinOp`, :class:`Const`); raise :class:`ExpressionError` with the column.

    Examples
    --------
    >>> parse("(Z-greatest A_1 - H) XOR not above hand_2 head")      # doctest: +NORMALIZE_WHITESPACE
    BinOp(op='xor', left=Rel(op='greatest', parts=('A_1', 'H'), axis=2, relation=None, value=None),
          right=Not(arg=Rel(op='greatest', parts=('hand_2', 'head'), axis=2, relation=None, value=None)))
    """
    if not isinstance(text, str):
        raise InputError(f"expression: expected a string, got {type(text).__name__}")
    return _Parser(text).parse()


def depth(node) -> int:
    """Nesting depth of a syntax tree (a relation or constant: 1), counted without recursion."""
    best, todo = 0, [(node, 1)]
    while todo:
        n, d = todo.pop()
        best = max(best, d)
        if isinstance(n, Not):
            todo.append((n.arg, d + 1))
        elif isinstance(n, BinOp):
            todo += [(n.left, d + 1), (n.right, d + 1)]
    return best


def parts_of(node) -> set:
    """Part names an expression refers to."""
    if isinstance(node, Rel):
        return set(node.parts)
    if isinstance(node, Not):
        return parts_of(node.arg)
    if isinstance(node, BinOp):
        return parts_of(node.left) | parts_of(node.right)
    return set()


# ----------------------------------------------------------------------------- evaluation
def up_frame(up="+z") -> np.ndarray:
    """Rotation taking capture coordinates to the thesis axes (rows x, y, z; z = ``up``).

    >>> up_frame("+y") @ np.array([0.0, 1.0, 0.0])
    array([0., 0., 1.])
    """
    from topopose.capture.capture import axis_vector

    u = axis_vector(up, where="up") if isinstance(up, str) else np.asarray(up, float)
    k = int(np.argmax(np.abs(u)))
    s = float(np.sign(u[k]))
    # x, y: the next two capture axes in cyclic order (a rotation); down flips one of them too
    x = np.zeros(3)
    x[(k + 1) % 3] = 1.0
    y = np.zeros(3)
    y[(k + 2) % 3] = s
    return np.stack([x, y, s * np.eye(3)[k]])


_SIDES = {"1": ("left", "l"), "2": ("right", "r")}


def _name_variants(name: str):
    """Equivalent spellings of a part name: hand_1 ↔ left_hand / hand_left / hand_l / l_hand."""
    n = name.lower()
    out = [n]
    m = re.fullmatch(r"(.+?)_?([12])", n)
    if m:
        base, (side, s) = m.group(1), _SIDES[m.group(2)]
        out += [f"{side}_{base}", f"{base}_{side}", f"{base}_{s}", f"{s}_{base}"]
    for num, (side, s) in _SIDES.items():
        for pat in (rf"(?:{side}|{s})_(.+)", rf"(.+)_(?:{side}|{s})"):
            m = re.fullmatch(pat, n)
            if m:
                out.append(f"{m.group(1)}_{num}")
    return out


def resolve(name: str, parts: dict, aliases: dict | None = None):
    """Position of part ``name`` among ``parts`` (name → position or None), or None."""
    name = (aliases or {}).get(name.lower(), name)
    low = {k.lower(): v for k, v in parts.items()}
    for n in _name_variants(name):
        if n in low:
            return low[n]
    return None


def evaluate(node, parts: dict, up="+z", aliases: dict | None = None, margin: float = 0.0):
    """Value of an expression on one pose: True, False or None (a part it needs is missing, or
    the pose is within ``margin`` of a decision boundary).

    Parameters
    ----------
    node : str or syntax tree
    parts : dict part name -> (3,) position or None
    up : the capture's up axis (``"+z"``, ``"-y"``, ... or a vector): the thesis' z axis
    aliases : dict alias (lower case) -> part name
    margin : the parts' position uncertainty (capture units; 0: off). A relation is
        *undecided* (None) when moving one of its parts by ``margin`` along one of the thesis'
        axes changes its value; ``and``, ``or``, ``not`` follow Kleene's three-valued logic
        (``false and None`` is false, ``true or None`` is true) and ``xor`` of an undecided
        operand is undecided.

    Examples
    --------
    >>> evaluate("above hand_1 head", {"hand_1": (0, 0, 2), "head": (0, 0, 1.7)})
    True
    >>> evaluate("above hand_1 head", {"hand_1": None, "head": (0, 0, 1.7)}) is None
    True
    >>> evaluate("above hand_1 head", {"hand_1": (0, 0, 1.75), "head": (0, 0, 1.7)}, margin=0.1) is None
    True
    """
    if isinstance(node, str):
        node = parse(node)
    aliases = {k.lower(): v for k, v in (aliases or {}).items()}
    pos = {}
    for name in parts_of(node):
        p = resolve(name, parts, aliases)
        if p is None:
            return None
        try:
            p = np.asarray(p, float).reshape(3)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"part {name!r}: a position must be [x, y, z] (numbers), "
                             f"got {p!r}"[:300]) from None
        if not np.all(np.isfinite(p)):
            return None
        pos[name] = p
    R = up_frame(up)
    v = _eval(node, {k: R @ v for k, v in pos.items()}, float(margin))
    return None if v is None else bool(v)


_SHIFTS = np.vstack([np.eye(3), -np.eye(3)])


def _relation(node, pos):
    from topopose.match.betweenness import betweenness

    P = [pos[p] for p in node.parts]
    if node.op == "greatest":
        return P[0][node.axis] > P[1][node.axis]
    if node.op == "least":
        return P[0][node.axis] < P[1][node.axis]
    if node.op == "order":
        return all(betweenness(P[i - 1], P[i + 1], P[i], node.relation) for i in range(1, len(P) - 1))
    d = float(np.linalg.norm(P[0] - P[1]))
    return d < node.value if node.op == "near" else d > node.value


def _eval(node, pos, margin=0.0):
    if isinstance(node, Const):
        return node.value
    if isinstance(node, Not):
        a = _eval(node.arg, pos, margin)
        return None if a is None else not a
    if isinstance(node, BinOp):
        a, b = _eval(node.left, pos, margin), _eval(node.right, pos, margin)
        if node.op == "and":
            return False if a is False or b is False else None if a is None or b is None else True
        if node.op == "or":
            return True if a is True or b is True else None if a is None or b is None else False
        return None if a is None or b is None else a != b
    v = bool(_relation(node, pos))
    if margin > 0:
        for p in set(node.parts):
            for d in _SHIFTS:
                if bool(_relation(node, {**pos, p: pos[p] + margin * d})) != v:
                    return None
    return v


# ----------------------------------------------------------------------------- library
@dataclass(frozen=True)
class NamedPose:
    name: str
    expr: str
    description: str = ""
    thesis: str = ""
    model: str = ""


def load_library(path=None) -> tuple[dict, dict]:
    """Named poses and aliases: the built-in library (``pose/poses.toml``) updated by ``path``.

    A library file::

        [aliases.human]            # per model: alias -> part
        A_1 = "hand_1"
        [[pose]]
        name = "hands-up"
        expr = "(z-greatest hand_1 - head) and (z-greatest hand_2 - head)"
        description = "..."

    Returns ``(poses, aliases)``: name -> :class:`NamedPose`, alias (lower case) -> part
    (every model's aliases merged).
    """
    poses, aliases = {}, {}
    for f in [LIBRARY] + ([Path(path)] if path else []):
        try:
            if Path(f).is_file() and Path(f).stat().st_size > MAX_LIBRARY_BYTES:
                raise InputError(f"{f}: not a pose library (larger than "
                                 f"{MAX_LIBRARY_BYTES >> 20} MB)")
            d = tomllib.loads(Path(f).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{f}: no such pose library") from None
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as exc:
            raise InputError(f"{f}: not a readable TOML pose library "
                             f"({str(exc)[:200] or type(exc).__name__})") from None
        for model, table in (d.get("aliases") or {}).items():
            if not isinstance(table, dict):
                raise InputError(f"{f}: aliases.{model} must be a table alias = \"part\"")
            aliases.update({str(k).lower(): str(v) for k, v in table.items()})
        if not isinstance(d.get("aliases") or {}, dict) or not isinstance(d.get("pose") or [], list):
            raise InputError(f"{f}: 'aliases' must be a table and 'pose' an array of tables")
        for i, p in enumerate(d.get("pose") or []):
            if not isinstance(p, dict) or "name" not in p or "expr" not in p:
                raise InputError(f"{f}: pose[{i}] needs a name and an expr")
            if not isinstance(p["expr"], str):
                raise InputError(f"{f}: pose[{i}].expr must be a text")
            try:
                parse(p["expr"])
            except ExpressionError as exc:
                raise InputError(f"{f}: pose[{i}] ({p['name']}).expr: {exc.reason} at column "
                                 f"{exc.col + 1}") from None
            poses[str(p["name"]).lower()] = NamedPose(str(p["name"]), p["expr"],
                                                      p.get("description", ""), p.get("thesis", ""),
                                                      p.get("model", ""))
    return poses, aliases


# ----------------------------------------------------------------------------- sequences
def read_poses_file(path):
    """Poses of a ``poses.jsonl`` (sorted by frame) and its header line ({} without one)."""
    from topopose.pose.pose import read_header, read_poses

    return read_poses(path, strict=False), read_header(path) or {}


def header_up(header: dict):
    """The capture's up axis recorded in a poses header, or None."""
    for d in (header, header.get("capture") if isinstance(header.get("capture"), dict) else {}):
        up = d.get("up") if isinstance(d, dict) else None
        if isinstance(up, str):
            return up
    return None


def description_parts(pose) -> dict:
    """The points a description compares for one pose (§13.3.2.1): its parts, with the ones
    its ``diagnostics["detect_parts"]`` records in their place.

    The per-frame estimate drops the crotch below the legs' junction
    (:data:`topopose.frame.anatomy.CROTCH_DROP`, for the matching quality of flexed hips) and
    records the junction there: the pelvis (capsule human: its centre, −0.5 cm along up; ``body``:
    ``Hips_head``, +0.5 cm; development seeds), the point the thesis' "crotch between the two
    arms" needs — dropped, it leaves the hands' ball of R_b in wide-spread arms. A part the
    pose leaves unplaced stays unplaced. Measured against it on the same frames (
    ``benchmarks/applications.py`` ``peer_points``, development seeds), no better on every
    named pose: the crotch at the legs' skeleton-curve junction (closer to the pelvis on the
    capsule human, farther on ``body``) and gt.json's own points (head centre, hands one
    hand's length on) with the head and hands moved onto them.

    ``pose``: a :class:`~topopose.pose.Pose` or a dict with ``parts`` (and ``diagnostics``).
    """
    parts = pose.parts if hasattr(pose, "parts") else pose["parts"]
    diag = (pose.diagnostics if hasattr(pose, "diagnostics") else pose.get("diagnostics")) or {}
    extra = diag.get("detect_parts") or {}
    return {**parts, **{k: v for k, v in extra.items() if parts.get(k) is not None}}


def detect(poses, expr, up="+z", aliases=None, matched_only=True, margin: float = 0.0) -> list:
    """Evaluate a description on every pose: a list of ``{"frame", "value"}`` dicts.

    ``poses``: :class:`~topopose.pose.Pose` objects or dicts frame/parts(/status/diagnostics);
    each pose's points are :func:`description_parts`.
    ``value`` is None for frames that are not matched (``matched_only``), lack a part, or are
    undecided within ``margin`` (:func:`evaluate`).
    """
    from topopose.pose.pose import Pose

    node = parse(expr) if isinstance(expr, str) else expr
    if not isinstance(node, (Rel, Not, BinOp, Const)):
        raise InputError(f"detect: expr must be a description (text), got {type(expr).__name__}")
    if aliases is None:
        aliases = load_library()[1]
    margin = _margin(margin)
    out = []
    for i, p in enumerate(poses):
        if isinstance(p, dict):             # the same checks as a poses file's line
            frame = p.get("frame")
            p = Pose.from_dict({"status": "matched", **p}, source=f"detect: poses[{i}]")
        elif isinstance(p, Pose):
            frame = p.frame
        else:
            raise InputError(f"detect: poses[{i}] must be a Pose or a dict with 'frame' and "
                             f"'parts', got {type(p).__name__}")
        status = p.status
        parts = description_parts(p)
        val = None if (matched_only and status != "matched") else evaluate(node, parts, up, aliases, margin)
        out.append({"frame": frame, "value": val})
    return out


def _margin(margin) -> float:
    from topopose._paths import check_number

    return check_number(margin, "--margin", low=0) or 0.0


def intervals(results) -> list:
    """Runs of consecutive frames whose value is True: ``[(first, last, count), ...]``."""
    runs, cur = [], None
    for r in results:
        if r["value"] is True:
            if cur is None:
                cur = [r["frame"], r["frame"], 0]
            cur[1] = r["frame"]
            cur[2] += 1
        elif cur is not None:
            runs.append(tuple(cur))
            cur = None
    if cur is not None:
        runs.append(tuple(cur))
    return runs
