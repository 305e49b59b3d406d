"""``goal { ... }``: what should happen in a scene, checked and turned into a ``goal.Goal`` in SI.

Terms: ``BODY.position at T -> (x, y, z) m within TOL`` (a body or marker, ``goal.Reach``),
``JOINT.angle from T0 to T1 -> VALUE within TOL`` (a hinge's angle or a slider's displacement,
``goal.Hold``), ``effort: W`` (``goal.Effort``) and ``decide: NAME, ...`` (unknowns chosen
besides the unknown control sequences). Every value is known (params, no unknowns) and carries
the unit its slot needs; a bare number is in SI.
"""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysNameError, PhysStructureError, PhysTypeError, PhysUnitError, Span
from ..goal import Effort, Goal, Hold, Reach
from . import ast
from .printer import format_expr
from .units import ANGLE, LENGTH, TIME, Dim
from .words import close, shape_words

FORCE_EFFORT = Dim.of(kg=-2, m=-2, s=3)  # 1 / (N^2 s)
TORQUE_EFFORT = Dim.of(kg=-2, m=-4, s=3)  # 1 / ((N m)^2 s)
GOAL_KEYS = ("effort", "decide")
TERMS_HINT = ("a goal holds 'BODY.position at T -> (x, y, z) m within TOL', "
              "'JOINT.angle from T0 to T1 -> VALUE within TOL', 'effort: W' and 'decide: NAME, ...'")


def scene_goal(res, items) -> Goal | None:
    """The Goal of the scene's ``goal`` block (None without one); a second block is an error."""
    goals = [i for i in items if isinstance(i, ast.GoalItem)]
    for extra in goals[1:]:
        first = goals[0].span.line if goals[0].span else "?"
        res.errors.append(res.err(PhysStructureError, f"a scene has one goal (the first is at "
                                  f"line {first})", extra.span, "put every term in one goal block"))
    return res.collect(build_goal, res, goals[0]) if goals else None


def build_goal(res, item: ast.GoalItem) -> Goal:
    """The Goal of ``item``: each term checked on its own (mistakes recorded on ``res``)."""
    terms, decisions, seen = [], [], {}
    for t in item.terms:
        if isinstance(t, ast.ReachTerm):
            terms.append(res.collect(reach, res, t))
        elif isinstance(t, ast.HoldTerm):
            terms.append(res.collect(hold, res, t))
        elif t.key not in GOAL_KEYS:
            res.errors.append(res.err(PhysNameError, f"a goal has no field '{t.key}'"
                                      f"{close(t.key, GOAL_KEYS)}", t.span, TERMS_HINT))
        elif t.key in seen:
            res.errors.append(res.err(PhysNameError, f"'{t.key}' is given twice in the goal "
                                      f"(first at line {seen[t.key]})", t.span,
                                      f"write one '{t.key}:' line"))
        else:
            seen[t.key] = t.span.line if t.span else "?"
            if t.key == "effort":
                terms.append(res.collect(effort, res, t))
            else:
                decisions += res.collect(decide, res, t) or []
    if not any(isinstance(t, (ast.ReachTerm, ast.HoldTerm)) for t in item.terms):
        raise res.err(PhysStructureError, "a goal needs a point to reach or a joint to hold",
                      item.span, "e.g. ball.position at 1 s -> (2, 0, 0) m within 5 cm")
    return Goal(tuple(t for t in terms if t is not None), tuple(decisions), item.span)


def reach(res, t: ast.ReachTerm) -> Reach:
    """``TARGET.position at T -> POINT within TOL`` on a body or marker."""
    kind = res.items_by_name.get(t.target)
    if kind not in ("body", "marker"):
        names = [n for n, k in res.items_by_name.items() if k in ("body", "marker")]
        what = f"'{t.target}' is a {kind}" if kind else \
            f"unknown body or marker '{t.target}'{close(t.target, names)}"
        hint = (f"a joint is held over a window: {t.target}.angle from T0 to T1 -> VALUE within "
                "TOL" if kind == "joint" else "a goal reaches the position of a body or a marker")
        raise res.err(PhysNameError, f"a goal reaches a body or a marker; {what}",
                      _head(t, t.target), hint)
    if t.quantity != "position":
        raise res.err(PhysNameError, f"a goal reaches a position, not '{t.quantity}'",
                      _head(t, f"{t.target}.{t.quantity}"),
                      f"write {t.target}.position at T -> (x, y, z) m within TOL")
    name = f"{t.target}.position"
    at = _time(res, t.at, "the time after 'at'")
    point = _known(res, t.point, LENGTH, (3,), f"the point {name} reaches")
    within = _positive(res, t.within, LENGTH, f"the tolerance of {name}")
    return Reach(t.target, at, tuple(float(x) for x in point), within, t.span)


def hold(res, t: ast.HoldTerm) -> Hold:
    """``JOINT.angle from T0 to T1 -> VALUE within TOL`` on a hinge (rad) or slider (m)."""
    joint = res.joint_index.get(t.target)
    if joint is None or joint.kind not in ("hinge", "slider"):
        kind = res.items_by_name.get(t.target)
        what = (f"'{t.target}' is a {joint.kind} joint" if joint is not None else
                f"'{t.target}' is a {kind}" if kind else
                f"unknown joint '{t.target}'{close(t.target, res.joint_index)}")
        hint = (f"a body's goal is a point to reach: {t.target}.position at T -> (x, y, z) m "
                "within TOL" if kind in ("body", "marker") else
                "a goal holds the coordinate of a hinge (angle) or a slider (displacement)")
        raise res.err(PhysNameError, f"a goal holds a hinge or a slider; {what}",
                      _head(t, t.target), hint)
    slider = joint.kind == "slider"
    names = ("angle", "position") if slider else ("angle",)
    if t.quantity not in names:
        raise res.err(PhysNameError, f"a goal holds a {joint.kind}'s coordinate "
                      f"'{t.target}.angle', not '{t.quantity}'", _head(t, f"{t.target}.{t.quantity}"),
                      f"write {t.target}.angle from T0 to T1 -> VALUE within TOL"
                      + (" (a slider's angle is its displacement in m)" if slider else ""))
    dim = LENGTH if slider else ANGLE
    name = f"{t.target}.{t.quantity}"
    start = _time(res, t.start, "the time after 'from'")
    end = _time(res, t.end, "the time after 'to'")
    if end <= start:
        raise res.err(PhysTypeError, f"the window of {name} ends before it starts "
                      f"({start:g} s to {end:g} s)", _over(t.start, t.end),
                      "write 'from' the earlier time 'to' the later one")
    value = float(_known(res, t.value, dim, (), f"the value {name} is held at"))
    within = _positive(res, t.within, dim, f"the tolerance of {name}")
    return Hold(t.target, value, start, end, within, t.span)


def effort(res, t: ast.GoalField) -> Effort:
    """``effort: W``: a non-negative weight on the integral of u² (per N² s or (N m)² s)."""
    node = _one(res, t)
    r = res.expr(node)
    if r.dim is not None and not (r.dim.same(FORCE_EFFORT) or r.dim.same(TORQUE_EFFORT)):
        raise res.err(PhysUnitError, f"the effort weight is per N^2 s (or per (N m)^2 s), but "
                      f"this value is {r.dim.name()}", node.span,
                      "write a plain number, the weight in SI: effort: 1e-3")
    value = _constant(res, r, node, "the effort weight", ())
    if value < 0:
        raise res.err(PhysTypeError, f"the effort weight must be 0 or more, got {value:g}",
                      node.span, "a larger weight prefers gentler controls: effort: 1e-3")
    return Effort(float(value), t.span)


def decide(res, t: ast.GoalField) -> list[str]:
    """``decide: NAME, ...``: unknowns of the scene (written with '~') to choose."""
    out = []
    for node in t.values:
        if not isinstance(node, (ast.Name, ast.Dotted)):
            raise res.err(PhysTypeError, f"'decide' lists unknowns by name, not "
                          f"'{format_expr(node)}'", getattr(node, "span", t.span),
                          "e.g. decide: vx, ball.velocity")
        path = node.name if isinstance(node, ast.Name) else ".".join(node.parts)
        if path in out:
            raise res.err(PhysNameError, f"'{path}' is decided twice", node.span)
        u = res.unknowns.get(path)
        if u is None:
            if path in res.sources:
                msg = f"'{path}' is a known value, not an unknown"
                hint = ("to decide it, make it an unknown: "
                        + ("param " if "." not in path else "") + f"{path} ~ normal(MEAN, SD)")
            else:
                msg = f"unknown name '{path}'{close(path, res.unknowns)}"
                hint = ("a decision is an unknown written with '~'; the scene's unknowns: "
                        + (", ".join(res.unknowns) or "none"))
            raise res.err(PhysNameError, f"'decide' names unknowns; {msg}", node.span, hint)
        if u.discrete:
            raise res.err(PhysTypeError, f"'{path}' takes whole values; a decision is chosen "
                          "by gradient and must be continuous", node.span)
        out.append(path)
    return out


# ---- values ----------------------------------------------------------------------------------

def _one(res, t: ast.GoalField):
    """The one value of field ``t`` (``effort: 1e-3``)."""
    if len(t.values) != 1:
        raise res.err(PhysTypeError, f"'{t.key}' takes one value, got {len(t.values)}",
                      _over(t.values[0], t.values[-1]), f"e.g. {t.key}: 1e-3")
    return t.values[0]


def _time(res, node, what: str) -> float:
    value = float(_known(res, node, TIME, (), what))
    if value < 0:
        raise res.err(PhysTypeError, f"{what} must be 0 s or later, got {value:g} s", node.span)
    return value


def _positive(res, node, dim: Dim, what: str) -> float:
    value = float(_known(res, node, dim, (), what))
    if not value > 0:
        raise res.err(PhysTypeError, f"{what} must be positive, got {value:g} {dim.si_text()}",
                      node.span, "the tolerance is how near counts as met, e.g. within 1 cm")
    return value


def _known(res, node, dim: Dim, shape: tuple[int, ...], what: str) -> np.ndarray:
    """The SI value of ``node``: of dimension ``dim`` (a bare number is SI), ``shape``, known."""
    r = res.expr(node)
    if r.dim is not None and not r.dim.same(dim):
        number = format_expr(node.value) if isinstance(node, ast.WithUnit) else "1"
        example = f"{number} {dim.si_text()}"
        raise res.err(PhysUnitError, f"{what} is {dim.name()}, but this value is {r.dim.name()}",
                      node.span, f"write it in {dim.si_text()}, e.g. {example}")
    return _constant(res, r, node, what, shape)


def _constant(res, r, node, what: str, shape: tuple[int, ...]) -> np.ndarray:
    if r.shape != shape:
        raise res.err(PhysTypeError, f"{what} is {shape_words(shape)}, got {shape_words(r.shape)}",
                      node.span, "e.g. (2, 0, 0.5) m" if shape == (3,) else None)
    names = sorted(E.references(r.expr))
    if names:
        raise res.err(PhysTypeError, f"{what} depends on the unknown '{names[0]}'; a goal is "
                      "made of known values", node.span, "write a number or a known param; to "
                      f"choose an unknown, name it in 'decide: {names[0]}'")
    value = np.asarray(E.constant_value(r.expr), dtype=float)
    if not np.all(np.isfinite(value)):
        raise res.err(PhysTypeError, f"{what} is not a finite number", node.span)
    return value


# ---- spans -----------------------------------------------------------------------------------

def _head(t, text: str) -> Span | None:
    """The span of the first ``len(text)`` characters of term ``t`` (its ITEM.QUANTITY)."""
    s = t.span
    if s is None:
        return None
    return Span(s.file, s.line, s.column, s.line, s.column + len(text))


def _over(a, b) -> Span | None:
    """The span from node ``a`` to the end of node ``b``."""
    if a.span is None or b.span is None:
        return a.span or b.span
    return Span(a.span.file, a.span.line, a.span.column, b.span.end_line, b.span.end_column)
