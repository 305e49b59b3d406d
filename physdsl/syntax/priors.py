"""Priors: ``~ dist(args)`` checked (the distribution exists, its arguments are named and
bound once, carry the unknown's unit or none, satisfy their constraints) and turned into a
``scene.Prior`` and an ``Unknown`` of the scene."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysNameError, PhysTypeError, PhysUnitError
from ..scene import Prior, Unknown
from . import ast, dists
from .expressions import R, broadcast
from .units import Dim
from .words import close, fmt, shape_words


def prior(res, node: ast.Dist, dim: Dim | None):
    """(Prior, draw shape, dim, discrete, support words) of ``~ name(args)``; ``dim``: the
    field's dimension (None: taken from the arguments)."""
    obj = dists.find(node.name)
    if obj is None:
        raise res.err(PhysNameError, f"unknown distribution '{node.name}'"
                      f"{close(node.name, dists.catalogue())}", node.span,
                      "any numpyro distribution by its snake_case name, e.g. normal, "
                      "half_normal, uniform, log_normal, beta, gamma")
    bound, order = _bind(res, node, obj)
    target = _check_units(res, node, bound, dim)
    _check_constraints(res, node, obj, bound)
    # shape and support
    sample = {n: (r.expr.array() if isinstance(r.expr, E.Const) else np.ones(r.shape))
              for n, (a, r) in bound.items()}
    args = [sample[n] for kw, n in order if kw is None]
    kwargs = {n: sample[n] for kw, n in order if kw is not None}
    shape, discrete, support = dists.draw_info(obj, args, kwargs)
    if shape is None:
        shape = ()
        for (a, r) in bound.values():
            shape = broadcast(shape, r.shape, node.span)
    pr = Prior(node.name, tuple(bound[n][1].expr for kw, n in order if kw is None),
               tuple((n, bound[n][1].expr) for kw, n in order if kw is not None))
    return pr, shape, target, discrete, support


def _bind(res, node: ast.Dist, obj):
    """The arguments by name ({name: (ast.Arg, R)}) and in written order ((keyword, name))."""
    pos_names, kw_names = dists.arg_names(obj)
    bound: dict[str, tuple[ast.Arg, R]] = {}
    order: list[tuple[str | None, str]] = []
    npos = 0
    for a in node.args:
        if a.name is None:
            if npos >= len(pos_names):
                raise res.err(PhysTypeError, f"{node.name} takes at most {len(pos_names)} "
                              f"positional argument{'s' * (len(pos_names) != 1)} "
                              f"({', '.join(pos_names)})", a.span,
                              f"name the others, e.g. {kw_names[0]}: ..." if kw_names else None)
            name = pos_names[npos]
            npos += 1
        else:
            name = a.name
            if name not in pos_names + kw_names:
                raise res.err(PhysNameError, f"{node.name} has no argument '{name}'"
                              f"{close(name, pos_names + kw_names)}", a.span,
                              f"its arguments: {', '.join(pos_names + kw_names)}")
        if name in bound:
            raise res.err(PhysTypeError, f"argument '{name}' of {node.name} given twice", a.span)
        bound[name] = (a, res.expr(a.value))
        order.append((a.name, name))
    missing = [n for n in dists.required_args(obj) if n not in bound]
    if missing:
        raise res.err(PhysTypeError, f"{node.name} needs argument '{missing[0]}'", node.span,
                      f"e.g. {node.name}({', '.join(n + ': ...' for n in missing)})")
    return bound, order


def _check_units(res, node: ast.Dist, bound, dim: Dim | None) -> Dim | None:
    """The unknown's dimension (``dim``, else from an argument); each argument carries it
    to the power ``dists.unit_power`` says, or none."""
    log_space = node.name in dists.LOG_SPACE
    power = {n: dists.unit_power(node.name, n) for n in bound}
    target = dim
    if target is None:
        for n, (a, r) in bound.items():
            if r.dim is not None and power[n] is not None:
                target = r.dim ** (1.0 / power[n])
                break
    for n, (a, r) in bound.items():
        if r.dim is None:
            continue
        if power[n] is None:
            if not r.dim.dimensionless:
                why = "lives in log space" if log_space else "is a plain number"
                raise res.err(PhysUnitError, f"{node.name}'s '{n}' {why}; it takes no unit",
                              a.value.span, "the unknown takes the field's unit (SI)")
        elif target is not None:
            want = target ** power[n]
            if not r.dim.same(want):
                raise res.err(PhysUnitError, f"{node.name}'s '{n}' is {r.dim.name()}, but the "
                              f"value needs {want.name()}", a.value.span,
                              f"write it in {want.si_text()}")
    return target


def _check_constraints(res, node: ast.Dist, obj, bound) -> None:
    """Known arguments satisfy their constraints (a positive scale, low < high, ...)."""
    cons = dists.arg_constraints(obj, set(bound))
    for n, (a, r) in bound.items():
        c = cons.get(n)
        if c is not None and E.is_constant(r.expr):
            ok = dists.satisfies(c, r.expr.array())
            if ok is False:
                raise res.err(PhysTypeError, f"{node.name}'s '{n}' must be "
                              f"{dists.constraint_words(c)}, got {fmt(r.expr.array())}",
                              a.value.span)
    if node.name == "uniform" and "low" in bound and "high" in bound:
        lo, hi = bound["low"][1].expr, bound["high"][1].expr
        if isinstance(lo, E.Const) and isinstance(hi, E.Const) and np.any(lo.array() >= hi.array()):
            raise res.err(PhysTypeError, "uniform needs low < high", node.span)


def make_unknown(res, path: str, node: ast.Dist, dim: Dim | None, shape, spec_) -> R:
    """The field ``path`` written ``~ dist(...)``: recorded as an unknown, valued by its Ref."""
    pr, dshape, target, discrete, support = prior(res, node, dim)
    if shape is not None and dshape != shape:
        if dshape == ():
            dshape = shape
        else:
            label = path.rsplit(".", 1)[-1]
            raise res.err(PhysTypeError, f"the prior of '{label}' draws {shape_words(dshape)}, "
                          f"but '{label}' needs {shape_words(shape)}", node.span)
    if spec_ is not None and spec_.shape is None and dshape not in ((), (3,)):
        raise res.err(PhysTypeError, f"the prior draws {shape_words(dshape)}; "
                      "a single number or 3 numbers are needed", node.span)
    if spec_ is not None and spec_.constant:
        raise res.err(PhysTypeError, f"'{path.rsplit('.', 1)[-1]}' must be a known value, "
                      "not an unknown", node.span)
    unit = target.si_text() if target is not None else "1"
    res.unknowns[path] = Unknown(path, pr, tuple(dshape), unit, node.span, (), discrete,
                                 node.per_experiment)
    res.supports[path] = support
    return R(E.Ref(path), target, tuple(dshape))
