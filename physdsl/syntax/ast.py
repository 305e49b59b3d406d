"""The .phys syntax tree: frozen dataclasses, one per construct, each with its source ``span``.

The tree keeps what the text says (units as written, names unresolved); ``resolve`` turns it
into a checked ``Scene``. ``strip_spans`` gives a span-free copy for structural comparison.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Union

from ..errors import Span


# ---- expressions -------------------------------------------------------------------------

@dataclass(frozen=True)
class Num:
    """A number literal; ``text`` is as written (printed back verbatim)."""

    text: str
    span: Span | None = None

    @property
    def value(self) -> float:
        return float(self.text)


@dataclass(frozen=True)
class Str:
    value: str
    span: Span | None = None


@dataclass(frozen=True)
class Name:
    """A bare name: a param, a body, or an enumerated word (``rk4``, ``true``)."""

    name: str
    span: Span | None = None


@dataclass(frozen=True)
class Dotted:
    """A reference to another field: ``ball.mass``, ``rod.shape.radius``."""

    parts: tuple[str, ...]
    span: Span | None = None


@dataclass(frozen=True)
class Vector:
    items: tuple["Expr", ...]
    span: Span | None = None


@dataclass(frozen=True)
class BinOp:
    op: str  # + - * / ^
    left: "Expr"
    right: "Expr"
    span: Span | None = None


@dataclass(frozen=True)
class Neg:
    operand: "Expr"
    span: Span | None = None


@dataclass(frozen=True)
class WithUnit:
    """A value followed by a unit as written: ``5 cm``, ``(4, 0, 5) m/s``, ``euler(..) deg``."""

    value: "Expr"
    unit: str
    span: Span | None = None
    unit_span: Span | None = None


@dataclass(frozen=True)
class Arg:
    """A call argument: positional (``name`` None) or keyword."""

    name: str | None
    value: "Expr"
    span: Span | None = None


@dataclass(frozen=True)
class Call:
    """A function or constructor call: ``sqrt(x)``, ``sphere(radius: r)``, ``mesh("a.obj")``."""

    func: str
    args: tuple[Arg, ...]
    span: Span | None = None


@dataclass(frozen=True)
class Record:
    """Named values in parentheses: ``(a: 0.1 m, alpha: 90 deg, d: 0, theta: 0)``."""

    fields: tuple[Arg, ...]
    span: Span | None = None


Expr = Union[Num, Str, Name, Dotted, Vector, BinOp, Neg, WithUnit, Call, Record]


@dataclass(frozen=True)
class Dist:
    """``~ name(args)``: a numpyro distribution by snake_case name."""

    name: str
    args: tuple[Arg, ...]
    span: Span | None = None
    per_experiment: bool = False  # ``~ per_experiment name(..)``: one draw per recording


# ---- blocks --------------------------------------------------------------------------------

@dataclass(frozen=True)
class Field:
    """``key: value`` or ``key ~ dist(...)`` (``value`` is then a Dist)."""

    key: str
    value: Union[Expr, Dist]
    span: Span | None = None


@dataclass(frozen=True)
class MaterialBlock:
    block: "Block"
    span: Span | None = None


@dataclass(frozen=True)
class Block:
    fields: tuple[Union[Field, MaterialBlock], ...]
    span: Span | None = None

    def get(self, key: str) -> Field | None:
        return next((f for f in self.fields if isinstance(f, Field) and f.key == key), None)


# ---- items ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Import:
    path: str
    span: Span | None = None


@dataclass(frozen=True)
class Param:
    name: str
    value: Union[Expr, Dist]
    span: Span | None = None


@dataclass(frozen=True)
class WorldItem:
    block: Block
    span: Span | None = None


@dataclass(frozen=True)
class BodyItem:
    """``body NAME {..}`` or ``ground NAME {..}`` (kind 'body' | 'ground')."""

    kind: str
    name: str
    block: Block
    span: Span | None = None


@dataclass(frozen=True)
class JointItem:
    name: str
    kind: str
    parent: str
    child: str
    block: Block | None = None
    span: Span | None = None


@dataclass(frozen=True)
class ContactItem:
    a: str
    b: str
    block: Block | None = None
    span: Span | None = None


@dataclass(frozen=True)
class EffectItem:
    effect: str
    target: tuple[str, ...]  # (name,) or (a, b) for a pair
    block: Block | None = None
    span: Span | None = None


@dataclass(frozen=True)
class ControlItem:
    """A control input: from a CSV file's column(s), or an unknown sequence in the block."""

    name: str
    target: str
    file: str | None = None
    columns: tuple[str, ...] = ()
    block: Block | None = None
    span: Span | None = None
    setting: str | None = None  # ``from throws.push``: the manifest column of files (per recording)


@dataclass(frozen=True)
class CameraItem:
    name: str
    block: Block
    span: Span | None = None


@dataclass(frozen=True)
class LightItem:
    block: Block
    span: Span | None = None


@dataclass(frozen=True)
class ObserveItem:
    target: str
    quantity: str
    file: str
    where: tuple[str, str] | None = None  # (column, value)
    rate: Expr | None = None
    times: str | None = None
    block: Block | None = None
    span: Span | None = None


@dataclass(frozen=True)
class ExperimentsItem:
    """``experiments NAME from "glob/*/file.csv"`` or ``from "manifest.csv"``: many recordings."""

    name: str
    source: str
    span: Span | None = None


@dataclass(frozen=True)
class MarkerItem:
    """``marker NAME on BODY { position: .. }``: a massless point fixed in a body's frame."""

    name: str
    body: str
    block: Block
    span: Span | None = None


@dataclass(frozen=True)
class AliasItem:
    """``alias NAME = OTHER``: NAME stands for OTHER (``alias link0 = world`` for a loop's first parent)."""

    name: str
    target: str
    span: Span | None = None


@dataclass(frozen=True)
class ForLoop:
    """``for VAR in START..STOP { items }`` (inclusive); names like ``link{i - 1}`` inside are
    templates, expanded at resolve time (``syntax/loops.py``)."""

    var: str
    start: int
    stop: int
    items: tuple["Item", ...]
    span: Span | None = None


@dataclass(frozen=True)
class ReachTerm:
    """``ball.position at 1 s -> (2, 0, 0) m within 5 cm``: a point reached at a time."""

    target: str
    quantity: str
    at: Expr
    point: Expr
    within: Expr
    span: Span | None = None


@dataclass(frozen=True)
class HoldTerm:
    """``hinge.angle from 2 s to 5 s -> 180 deg within 0.1 rad``: a joint held over a window."""

    target: str
    quantity: str
    start: Expr
    end: Expr
    value: Expr
    within: Expr
    span: Span | None = None


@dataclass(frozen=True)
class GoalField:
    """``effort: 1e-3`` or ``decide: vx, vy``: a key with one or more values."""

    key: str
    values: tuple[Expr, ...]
    span: Span | None = None


@dataclass(frozen=True)
class GoalItem:
    """``goal { TERM ... }``: what should happen (``syntax/goals.py`` builds a ``goal.Goal``)."""

    terms: tuple[Union[ReachTerm, HoldTerm, GoalField], ...]
    span: Span | None = None


Item = Union[Param, WorldItem, BodyItem, JointItem, ContactItem, EffectItem, ControlItem,
             CameraItem, LightItem, ObserveItem, MarkerItem, AliasItem, ForLoop, GoalItem,
             ExperimentsItem]


@dataclass(frozen=True)
class SceneDecl:
    name: str
    items: tuple[Item, ...]
    span: Span | None = None


@dataclass(frozen=True)
class ParamDecl:
    """One parameter of an ``effect_type``: units (alternatives), default, prior, off, strength."""

    name: str
    units: tuple[str, ...]
    vector: bool = False
    default: Expr | None = None
    prior: Dist | None = None
    off: Expr | None = None
    strength: str | None = None  # None | 'either' | 'above' | 'below'
    span: Span | None = None


@dataclass(frozen=True)
class EffectType:
    """A library effect declaration: ``effect_type NAME on KIND [or KIND] { doc: ".." param .. }``."""

    name: str
    acts_on: tuple[str, ...]
    doc: str
    params: tuple[ParamDecl, ...]
    span: Span | None = None


@dataclass(frozen=True)
class Comment:
    text: str  # including the leading '#'
    span: Span | None = None


@dataclass(frozen=True)
class Module:
    """A whole .phys file: imports, library declarations, params and (in scene files) one scene."""

    items: tuple[Union[Import, SceneDecl, EffectType, Param], ...]
    comments: tuple[Comment, ...] = ()
    filename: str = "<string>"
    span: Span | None = None

    @property
    def scene(self) -> SceneDecl | None:
        return next((i for i in self.items if isinstance(i, SceneDecl)), None)


def strip_spans(node):
    """A copy of ``node`` (any AST value) with every span set to None, for comparisons."""
    if isinstance(node, tuple):
        return tuple(strip_spans(n) for n in node)
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        changes = {}
        for f in dataclasses.fields(node):
            value = getattr(node, f.name)
            if f.name in ("span", "unit_span") or f.name == "filename":
                changes[f.name] = None if f.name != "filename" else "<string>"
            else:
                changes[f.name] = strip_spans(value)
        return dataclasses.replace(node, **changes)
    return node
