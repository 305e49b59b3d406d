"""Scene arithmetic: an AST expression with units -> an SI ``physdsl.expr.Expr``, its dimension
and shape, checked (units agree, shapes broadcast, functions known).

The one translation of written values; the resolver, ``--init`` start values and ``sample``
use it, and ``physdsl.expr.evaluate`` computes the result. Known parts are folded to constants.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from .. import expr as E
from ..errors import PhysError, PhysNameError, PhysTypeError, PhysUnitError, Span
from . import ast
from .schema import SHAPE_ARGS
from .units import ANGLE, DIMLESS, Dim, UnitError, known_units, lookup, parse_unit
from .words import close

FUNCS = {"sqrt", "sin", "cos", "tan", "exp", "log", "abs", "atan2", "norm", "euler", "quat",
         "axis_angle"}


class R(NamedTuple):
    """A resolved value: SI expression, dimension (None: a bare number, takes any) and shape."""

    expr: E.Expr
    dim: Dim | None
    shape: tuple[int, ...]


def plain_error(cls, msg: str, span: Span | None, hint: str | None = None) -> PhysError:
    """The error ``cls(msg, span, hint)`` without source text (the caller may add it)."""
    return cls(msg, span, hint)


def constants_only(node) -> R:
    """A scope without names: only ``pi``; any other name is unknown."""
    if isinstance(node, ast.Name) and node.name == "pi":
        return PI
    head = node.name if isinstance(node, ast.Name) else node.parts[0]
    raise PhysNameError(f"unknown name '{head}'", node.span,
                        "declare it with 'param NAME: value' or 'param NAME ~ dist(...)'")


@dataclass(frozen=True)
class Scope:
    """What names mean where an expression is written.

    ``lookup(node)``: the R of an ``ast.Name`` or ``ast.Dotted`` (it raises for unknown names;
    any exception passes through ``to_expr`` untouched). ``is_param(word)``: whether a bare
    word is a value's name (an error when written as a unit). ``err(cls, msg, span, hint)``:
    builds each error (e.g. with the file's text for the caret)."""

    lookup: Callable[[object], R] = constants_only
    is_param: Callable[[str], bool] = lambda word: False
    err: Callable[..., PhysError] = plain_error


def to_expr(node, scope: Scope = Scope()) -> R:
    """``R(expr, dim, shape)`` of the AST expression ``node``: ``expr`` an ``Expr`` in SI
    (``E.Ref``s only where ``scope.lookup`` returned them), ``dim`` its ``units.Dim`` (None: a
    bare number, fits any unit), ``shape`` its shape. Raises PhysError (unit, shape, name
    mistakes) built by ``scope.err``. Pure: evaluate the result with ``physdsl.expr.evaluate``
    (values of draws: ``jax.vmap`` it over the draw axis)."""
    return _Translate(scope).expr(node)


PI = R(E.Const(float(np.pi)), None, ())


def const(value) -> E.Const:
    """A numeric value (scalar or nested) as a Const of floats."""
    arr = np.asarray(value, dtype=float)
    return E.Const(float(arr) if arr.ndim == 0 else _tup(arr.tolist()))


def _tup(x):
    return tuple(_tup(i) for i in x) if isinstance(x, list) else float(x)


_NP = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": np.power}
_NPF = {"sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp,
        "log": np.log, "abs": np.abs, "atan2": np.arctan2, "norm": np.linalg.norm}


def binary(op: str, a: E.Expr, b: E.Expr) -> E.Expr:
    """``a op b``, folded when both are known."""
    if isinstance(a, E.Const) and isinstance(b, E.Const):
        with np.errstate(all="ignore"):
            return const(_NP[op](a.array(), b.array()))
    return E.Binary(op, a, b)


def call(func: str, args: tuple) -> E.Expr:
    """``func(*args)`` (a name of ``E.FUNCTIONS``), folded when every argument is known."""
    if all(isinstance(a, E.Const) for a in args):
        with np.errstate(all="ignore"):
            if func in _NPF:
                return const(_NPF[func](*[a.array() for a in args]))
            fn, _ = E.FUNCTIONS[func]
            return const(np.asarray(fn(*[a.array() for a in args])))
    return E.Call(func, args)


def vec(items: list[E.Expr]) -> E.Expr:
    """The vector of ``items``, a Const when every item is known."""
    if all(isinstance(i, E.Const) for i in items):
        return E.Const(tuple(i.value for i in items))
    return E.Vec(tuple(items))


def broadcast(a, b, span, what="combine", err=plain_error) -> tuple[int, ...]:
    """The broadcast of shapes ``a`` and ``b``; a PhysTypeError where they do not fit."""
    try:
        return tuple(np.broadcast_shapes(a, b))
    except ValueError:
        raise err(PhysTypeError, f"cannot {what} values of shapes {a} and {b}", span) from None


def is_unit(symbol: str) -> bool:
    """True when ``symbol`` is a unit's name."""
    try:
        lookup(symbol)
        return True
    except UnitError:
        return False


def unify(dims, spans, what="add", err=plain_error) -> Dim | None:
    """The one dimension of ``dims`` (None entries take any); an error where two differ."""
    known = [(d, s) for d, s in zip(dims, spans) if d is not None]
    if not known:
        return None
    d0, _ = known[0]
    for d, s in known[1:]:
        if not d.same(d0):
            raise err(PhysUnitError, f"cannot {what} {d0.name()} and {d.name()}", s,
                      "both sides need the same kind of unit")
    return d0


def unit(text: str, span: Span | None, err=plain_error) -> tuple[float, Dim]:
    """(scale to SI, dimension) of the unit ``text``; a PhysUnitError with a near unit."""
    try:
        return parse_unit(text)
    except UnitError as ex:
        hint = None
        if "/" in text or "*" in text:
            hint = "to divide by a value, put spaces around '/': '2 m / L'"
        sugg = close(ex.part, known_units())
        raise err(PhysUnitError, f"{ex}{sugg}", span,
                  hint or "units: m cm mm km g kg s ms min h Hz N J W Pa rad deg, "
                          "products N*m, quotients m/s, powers m/s^2") from None


class _Translate:
    """``to_expr`` by node kind (one scope's lookups and error builder)."""

    def __init__(self, scope: Scope):
        self.scope = scope
        self.err = scope.err

    def expr(self, node) -> R:
        span = getattr(node, "span", None)
        if isinstance(node, ast.Num):
            return R(E.Const(node.value), None, ())
        if isinstance(node, (ast.Name, ast.Dotted)):
            return self.scope.lookup(node)
        if isinstance(node, ast.Vector):
            rs = [self.expr(i) for i in node.items]
            dim = unify([r.dim for r in rs], [getattr(i, "span", span) for i in node.items],
                        "put in one vector", self.err)
            if len({r.shape for r in rs}) > 1:
                raise self.err(PhysTypeError, "the items of a vector must have the same shape",
                               span)
            return R(vec([r.expr for r in rs]), dim, (len(rs),) + rs[0].shape)
        if isinstance(node, ast.Neg):
            r = self.expr(node.operand)
            if isinstance(r.expr, E.Const):
                return R(const(-r.expr.array()), r.dim, r.shape)
            return R(E.Unary("-", r.expr), r.dim, r.shape)
        if isinstance(node, ast.BinOp):
            return self.binop(node)
        if isinstance(node, ast.WithUnit):
            return self.with_unit(node)
        if isinstance(node, ast.Call):
            return self.call(node, None)
        if isinstance(node, ast.Str):
            raise self.err(PhysTypeError, f"a string (\"{node.value}\") is not a value here", span,
                           "numbers, vectors and names go here")
        if isinstance(node, ast.Record):
            raise self.err(PhysTypeError, "named values in parentheses only go in 'dh:'", span)
        if isinstance(node, ast.Dist):
            raise self.err(PhysTypeError, "'~ dist(...)' only goes right after a field name", span)
        raise self.err(PhysTypeError, "not a value", span)

    def binop(self, node: ast.BinOp) -> R:
        a, b = self.expr(node.left), self.expr(node.right)
        op = node.op
        shape = broadcast(a.shape, b.shape, node.span)
        if op in "+-":
            dim = unify([a.dim, b.dim], [node.left.span, node.right.span],
                        "add" if op == "+" else "subtract", self.err)
            return R(binary(op, a.expr, b.expr), dim, shape)
        if op in "*/":
            if a.dim is None and b.dim is None:
                dim = None
            else:
                da, db = a.dim or DIMLESS, b.dim or DIMLESS
                dim = da * db if op == "*" else da / db
            return R(binary(op, a.expr, b.expr), dim, shape)
        # power: the exponent is a known plain number
        if b.dim is not None and not b.dim.dimensionless:
            raise self.err(PhysUnitError, f"an exponent must be a plain number, not {b.dim.name()}",
                           node.right.span)
        if a.dim is not None and not a.dim.dimensionless and not isinstance(b.expr, E.Const):
            raise self.err(PhysTypeError, "the exponent of a value with a unit must be a known number",
                           node.right.span)
        dim = a.dim ** float(np.asarray(b.expr.value)) if (a.dim is not None and isinstance(b.expr, E.Const)
                                                          and np.ndim(b.expr.value) == 0) else a.dim
        return R(binary("^", a.expr, b.expr), dim, shape)

    def with_unit(self, node: ast.WithUnit) -> R:
        for part in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", node.unit):
            if self.scope.is_param(part) and not is_unit(part):
                hint = (f"write '* {part}' to multiply by it" if node.unit == part else
                        f"put spaces around '/' or '*' to compute with it, e.g. '1 m / {part}'")
                raise self.err(PhysUnitError, f"'{part}' in the unit '{node.unit}' is a param, not a "
                               "unit", node.unit_span, hint)
        scale, udim = unit(node.unit, node.unit_span, self.err)
        if isinstance(node.value, ast.Call) and node.value.func == "euler":
            return self.call(node.value, (scale, udim, node.unit_span))
        r = self.expr(node.value)
        if r.dim is not None and not (r.dim.dimensionless and not r.dim.is_angle):
            raise self.err(PhysUnitError, f"this value already has a unit ({r.dim.si_text()}); "
                           f"cannot add '{node.unit}'", node.unit_span,
                           "write the unit once, after the number or the parentheses")
        e = r.expr if scale == 1.0 else binary("*", r.expr, E.Const(scale))
        return R(e, udim, r.shape)

    def call(self, node: ast.Call, unit_) -> R:
        f = node.func
        span = node.span
        if f in SHAPE_ARGS:
            raise self.err(PhysTypeError, f"a shape ('{f}(...)') only goes in 'shape:'", span)
        if f not in FUNCS:
            raise self.err(PhysNameError, f"unknown function '{f}'{close(f, FUNCS)}", span,
                           "functions: " + ", ".join(sorted(FUNCS)))
        for a in node.args:
            if a.name is not None and f not in ("euler", "quat", "axis_angle"):
                raise self.err(PhysTypeError, f"'{f}' takes no named arguments", a.span)
        rs = [self.expr(a.value) for a in node.args]
        if f == "euler":
            return self.euler(node, rs, unit_)
        if unit_ is not None:
            raise self.err(PhysUnitError, "a unit after a function call only works for euler(...)",
                           span)
        if f == "quat":
            return self.quat(node, rs)
        if f == "axis_angle":
            if len(rs) != 2 or rs[0].shape != (3,) or rs[1].shape != ():
                raise self.err(PhysTypeError, "axis_angle(axis, angle) takes a 3-vector and an angle",
                               span)
            return R(call("quat_from_axis_angle", (rs[0].expr, rs[1].expr)), DIMLESS, (4,))
        arity = E.FUNCTIONS[f][1]
        if len(rs) != arity:
            raise self.err(PhysTypeError, f"'{f}' takes {arity} argument{'s' * (arity > 1)}, "
                           f"got {len(rs)}", span)
        if f in ("sin", "cos", "tan", "exp", "log"):
            d = rs[0].dim
            if d is not None and not d.dimensionless:
                raise self.err(PhysUnitError, f"'{f}' needs an angle or a plain number, not "
                               f"{d.name()}", node.args[0].span)
            return R(call(f, (rs[0].expr,)), None, rs[0].shape)
        if f == "sqrt":
            d = rs[0].dim
            return R(call(f, (rs[0].expr,)), d ** 0.5 if d is not None else None, rs[0].shape)
        if f == "abs":
            return R(call(f, (rs[0].expr,)), rs[0].dim, rs[0].shape)
        if f == "norm":
            return R(call(f, (rs[0].expr,)), rs[0].dim, ())
        # atan2
        unify([rs[0].dim, rs[1].dim], [a.span for a in node.args], "compare", self.err)
        shape = broadcast(rs[0].shape, rs[1].shape, span)
        return R(call("atan2", (rs[0].expr, rs[1].expr)), ANGLE, shape)

    def euler(self, node: ast.Call, rs: list[R], unit_) -> R:
        """``euler(x, y, z) deg``: the unit quaternion of three angles."""
        if len(rs) == 3 and all(r.shape == () for r in rs):
            v, dims = vec([r.expr for r in rs]), [r.dim for r in rs]
        elif len(rs) == 1 and rs[0].shape == (3,):
            v, dims = rs[0].expr, [rs[0].dim]
        else:
            raise self.err(PhysTypeError, "euler(...) takes three angles (about x, y, z)", node.span,
                           "e.g. euler(0, 0, 90) deg")
        for d, a in zip(dims, node.args):
            if d is not None and not d.dimensionless:
                raise self.err(PhysUnitError, f"euler angles must be angles, not {d.name()}", a.span)
        if unit_ is not None:
            scale, udim, uspan = unit_
            if not udim.is_angle:
                raise self.err(PhysUnitError, f"euler(...) needs an angle unit (deg or rad), "
                               f"not '{udim.si_text()}'", uspan, "e.g. euler(0, 0, 90) deg")
            v = binary("*", v, E.Const(scale))
        return R(call("quat_from_euler", (v,)), DIMLESS, (4,))

    def quat(self, node: ast.Call, rs: list[R]) -> R:
        """``quat(w, x, y, z)``, normalised when known."""
        if len(rs) == 4 and all(r.shape == () for r in rs):
            q = vec([r.expr for r in rs])
        elif len(rs) == 1 and rs[0].shape == (4,):
            q = rs[0].expr
        else:
            raise self.err(PhysTypeError, "quat(...) takes four numbers w, x, y, z", node.span)
        if isinstance(q, E.Const):
            arr = q.array()
            n = float(np.linalg.norm(arr))
            if n == 0:
                raise self.err(PhysTypeError, "a quaternion cannot be zero", node.span,
                               "the identity is quat(1, 0, 0, 0)")
            q = const(arr / n)
        return R(q, DIMLESS, (4,))
