"""The values a (proto-)program's draws give every parameter: drawn unknowns, and fields written
as expressions of the standard-normal params ``proto_zK`` (computed with the language's one
translation, ``syntax.expressions.to_expr``, and ``expr.evaluate``); and a draw's concrete text."""
from __future__ import annotations

import dataclasses
import re
from typing import Mapping

import jax
import numpy as np

from .. import expr as E
from .. import syntax
from ..export.literals import literal
from ..export.program import scene_decl, set_unknown, snippet, with_items
from ..syntax import ast as A
from ..syntax.expressions import PI, R, Scope, to_expr
from ..syntax.printer import format_module
from ..syntax.units import DIMLESS, Dim, parse_unit

Z_NAME = re.compile(r"^(proto_)+z\d+$")


def _refs(node, names: set[str]) -> bool:
    """True when ast ``node`` mentions one of ``names`` as a bare name."""
    if isinstance(node, A.Name):
        return node.name in names
    if isinstance(node, tuple):
        return any(_refs(n, names) for n in node)
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return any(_refs(getattr(node, f.name), names) for f in dataclasses.fields(node)
                   if f.name not in ("span", "unit_span"))
    return False


def derived_fields(module) -> list[tuple[str, object]]:
    """(unknown-style name, ast expression) of every param or field written directly as an
    expression of the standard-normal params ``proto_zK`` (what export writes for
    correlated unknowns), in program order."""
    decl = module.scene
    z = {i.name for i in decl.items if isinstance(i, A.Param) and Z_NAME.match(i.name)}
    out = []
    for item in decl.items:
        if isinstance(item, A.Param) and item.name not in z and not isinstance(item.value, A.Dist):
            if _refs(item.value, z):
                out.append((item.name, item.value))
            continue
        block = getattr(item, "block", None)
        if block is None:
            continue
        if isinstance(item, (A.BodyItem, A.JointItem)):
            prefix = item.name
        elif isinstance(item, A.EffectItem):
            prefix = None
        elif isinstance(item, A.ObserveItem):
            prefix = f"{item.target}.{item.quantity}"
        else:
            continue
        for f in block.fields:
            if isinstance(f, A.Field) and not isinstance(f.value, A.Dist) and _refs(f.value, z):
                name = (f"{item.effect}@{','.join(item.target)}.{f.key}" if prefix is None
                        else f"{prefix}.{f.key}")
                out.append((name, f.value))
    return out


def _scope(known: Mapping[str, R]) -> Scope:
    """Names resolve to ``known`` (and ``pi``); any other name raises KeyError."""
    def lookup(node) -> R:
        if isinstance(node, A.Name) and node.name in known:
            return known[node.name]
        if isinstance(node, A.Name) and node.name == "pi":
            return PI
        raise KeyError(node.name if isinstance(node, A.Name) else ".".join(node.parts))

    return Scope(lookup=lookup)


def expression_value(node, env: Mapping[str, tuple[np.ndarray, Dim]], n: int | None = None):
    """(value in SI, Dim) of the AST expression ``node`` over ``env`` (name -> (value, Dim)).

    ``n``: every value of ``env`` holds ``n`` draws along a first axis, and so does the
    result ((n,) or (n, D)); None: single values. A name outside ``env`` (e.g. a dotted
    reference) raises KeyError.
    """
    skip = 0 if n is None else 1
    r = to_expr(node, _scope({k: R(E.Ref(k), d, tuple(np.shape(v))[skip:]) for k, (v, d) in env.items()}))
    used = {k: np.asarray(env[k][0], dtype=float) for k in E.references(r.expr)}
    if n is None:
        value = E.evaluate(r.expr, used)
    elif used:
        value = jax.vmap(lambda v: E.evaluate(r.expr, v))(used)
    else:
        value = np.broadcast_to(np.asarray(E.evaluate(r.expr, {})), (n, *r.shape))
    return np.asarray(value, dtype=float), (r.dim if r.dim is not None else DIMLESS)


def _param_env(module, values: Mapping[str, np.ndarray], units: Mapping[str, str], n: int):
    """SI values and dimensions of every param computable from the drawn ``values``."""
    env = {}
    for name, v in values.items():
        unit = units.get(name, "1")
        env[name] = (np.asarray(v, dtype=float), DIMLESS if unit in ("", "1") else parse_unit(unit)[1])
    pending = [i for i in module.scene.items if isinstance(i, A.Param) and not isinstance(i.value, A.Dist)]
    for _ in range(len(pending) + 1):  # params may refer to later ones
        rest = []
        for p in pending:
            try:
                env[p.name] = expression_value(p.value, env, n)
            except KeyError:
                rest.append(p)
        if len(rest) == len(pending):
            break
        pending = rest
    return env


def parameter_values(module, draws: Mapping[str, np.ndarray], units: Mapping[str, str]):
    """Every parameter of the program per draw: the drawn unknowns (without ``proto_zK``) and
    the fields written as expressions of ``proto_zK``; name -> ((n, *shape) SI, unit)."""
    n = len(next(iter(draws.values())))
    env = _param_env(module, draws, units, n)
    out = {}
    for name, v in draws.items():
        if not Z_NAME.match(name):
            out[name] = (np.asarray(v, dtype=float), units.get(name, "1"))
    for name, node in derived_fields(module):
        value, dim = expression_value(node, env, n)
        out[name] = (value, dim.si_text())
    return out


def concrete_text(module, values: Mapping[str, tuple[np.ndarray, str]], source: str = "") -> str:
    """The program with every unknown and every field written as an expression of the
    standard-normal params replaced by its value ``{name: (value, unit)}`` (literal, SI)."""
    for name, (v, unit) in values.items():
        module = set_unknown(module, name, snippet(f"x: {literal(v, unit)}"))
    decl = scene_decl(module)
    items = [i for i in decl.items if not (isinstance(i, A.Param) and Z_NAME.match(i.name))]
    return syntax.format_source(format_module(with_items(module, decl, items), source))


def columns(params: Mapping[str, np.ndarray]) -> list[str]:
    """Column names of parameter values: ``name`` or ``name[i]`` per vector component."""
    out = []
    for name, v in params.items():
        size = int(np.size(v))
        out += [name] if np.ndim(v) == 0 else [f"{name}[{i}]" for i in range(size)]
    return out
