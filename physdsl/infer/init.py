"""Start values given by a user (``--init name=value[,name=value]``), read like scene values.

Each value is parsed by the scene grammar and translated like a scene's values
(``syntax.expressions.to_expr``: units, dimensions, vectors), then checked against its unknown (name, dimension, shape, the prior's
support). Errors are PhysErrors placed in the ``--init`` text itself (file ``--init``, line 1,
a caret under the offending part), so they read like errors in a scene file.
"""
from __future__ import annotations

from dataclasses import replace

import jax
import numpy as np

from ..errors import (InferenceError, PhysError, PhysNameError, PhysTypeError, PhysUnitError,
                      Span, UsageError)
from ..expr import evaluate, is_constant
from ..syntax import ast
from ..syntax.dists import constraint_words, find, satisfies
from ..syntax.expressions import to_expr
from ..syntax.parser import parse_field
from ..syntax.units import parse_unit
from ..syntax.words import close
from .base import value_and_grad_fn
from .problem import model_problem, start_position

SOURCE = "--init"


def parse_init(text: str, unknowns) -> dict[str, np.ndarray]:
    """``name=value[,name=value]`` -> {unknown name: SI value}; ``unknowns``: the Scene's."""
    by_name = {u.name: u for u in unknowns}
    out: dict[str, np.ndarray] = {}
    for start, item in _items(text):
        if "=" not in item:
            raise _error(UsageError, text, start, start + len(item),
                         "expected name=value", "e.g. --init 'ball.velocity=(3, 0, 2.5) m/s'")
        name_raw, value = item.split("=", 1)
        name = name_raw.strip()
        n0 = start + len(name_raw) - len(name_raw.lstrip())
        if name not in by_name:
            raise _error(PhysNameError, text, n0, n0 + max(len(name), 1),
                         f"'{name}' is not an unknown of the scene{close(name, by_name)}",
                         "unknowns: " + ", ".join(by_name))
        if name in out:
            raise _error(UsageError, text, n0, n0 + len(name), f"'{name}' is given twice", None)
        v0 = start + len(name_raw) + 1
        out[name] = _value(text, v0, value, by_name[name])
    if not out:
        raise _error(UsageError, text, 0, max(len(text), 1), "no start values given",
                     "e.g. --init 'h0=1.1 m, ball.velocity=(3, 0, 2.5) m/s'")
    return out


def start_values(init, unknowns) -> dict[str, np.ndarray]:
    """``init`` as {name: SI value}: the CLI's ``name=value, ...`` text, or a dict whose
    values are numbers (SI) or value text with units (``"(3, 0, 2.5) m/s"``); checked alike."""
    if isinstance(init, str):
        return parse_init(init, unknowns)
    out = {}
    for name, v in dict(init).items():
        if isinstance(v, str):
            out.update(parse_init(f"{name}={v}", unknowns))
            continue
        text = f"{name}={_fmt(np.asarray(v, dtype=float))}"
        out.update(parse_init(text, unknowns))  # names, shapes and supports as for text
        out[name] = np.asarray(v, dtype=float)  # the numbers exactly as given
    return out


def with_init(model, settings, init):
    """``settings`` whose first start (``Settings.start``) holds the values ``init`` (see
    ``start_values``), after checking that the log density is finite there. The other chains
    (or starts of the multistart) are unchanged, so the optimisation from the given values
    competes with them and the best basin wins."""
    values = start_values(init, model.unknowns)
    problem = model_problem(model)
    x = start_position(problem, jax.random.PRNGKey(settings.seed), values)
    v, g = value_and_grad_fn(problem)(jax.numpy.asarray(x))
    if not (np.isfinite(float(v)) and np.all(np.isfinite(np.asarray(g)))):
        raise InferenceError("the log density is not finite at the start values given with "
                             f"--init ({', '.join(values)})",
                             hint="the rollout may blow up there, or the data may be impossible "
                                  "from there: give other values")
    start = dict(settings.start)
    start.update(dict(start_setting(values)))
    return replace(settings, start=tuple(start.items()))


def start_setting(values: dict) -> tuple:
    """Constrained values by name as the ``start`` setting of a fit (hashable plain numbers:
    it enters the run's fingerprint)."""
    return tuple((k, np.asarray(v, dtype=float).tolist()) for k, v in values.items())


def _items(text: str):
    """(offset, text) of each comma-separated item outside parentheses; a piece without '='
    joins the next (names of contact effects hold a comma: ``restitution@floor,ball...``)."""
    depth, start, pieces = 0, 0, []
    for i, ch in enumerate(text):
        depth += {"(": 1, ")": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            pieces.append((start, i))
            start = i + 1
    if text[start:].strip() or start == 0:
        pieces.append((start, len(text)))
    merged: list[tuple[int, int]] = []
    for a, b in pieces:
        if merged and "=" not in text[merged[-1][0]:merged[-1][1]]:
            merged[-1] = (merged[-1][0], b)
        else:
            merged.append((a, b))
    for a, b in merged:
        yield a, text[a:b]


def _value(text: str, offset: int, value: str, unknown) -> np.ndarray:
    """The SI value of ``value`` (at ``offset`` in ``text``) for ``unknown``, checked."""
    lead = len(value) - len(value.lstrip())
    col = offset + lead  # 0-based column of the value in ``text``
    body = value.strip()
    if not body:
        raise _error(UsageError, text, offset, offset + 1, f"no value for '{unknown.name}'",
                     f"e.g. {unknown.name}=1 {unknown.unit}")
    # the value at its own columns, after a placeholder key, so spans point into ``text``
    src = ("k:" + " " * (col - 2) + body) if col >= 2 else "k: " + body
    shift = 0 if col >= 2 else col - 3
    try:
        node = parse_field(src, SOURCE).value
        if isinstance(node, ast.Dist):
            raise PhysTypeError("a start value is a value, not '~ dist(...)'",
                                Span(SOURCE, 1, col + 1, 1, col + len(body) + 1))
        r = to_expr(node)  # numbers with units: no names but pi
        if not is_constant(r.expr):
            raise PhysTypeError("a start value must be a number with a unit, not an expression "
                                "of other values", Span(SOURCE, 1, col + 1, 1, col + len(body) + 1))
    except PhysError as ex:
        raise _relocate(ex, text, shift) from None
    span = Span(SOURCE, 1, col + 1, 1, col + len(body) + 1)
    want = parse_unit(unknown.unit)[1]
    if r.dim is not None and not r.dim.same(want):
        raise PhysUnitError(f"'{unknown.name}' needs {want.name()}, but this value is "
                            f"{r.dim.name()}", span, f"write it in {want.si_text()}",
                            source=text)
    if tuple(r.shape) != tuple(unknown.shape):
        example = ("(" + ", ".join(["0"] * unknown.shape[0]) + ")") if len(unknown.shape) == 1 \
            else "0"
        raise PhysTypeError(f"'{unknown.name}' needs {_shape_words(unknown.shape)}, got "
                            f"{_shape_words(r.shape)}", span,
                            f"e.g. {unknown.name}={example}{_unit(unknown)}", source=text)
    x = np.asarray(evaluate(r.expr, {}), dtype=float)
    support = _support(unknown)
    if support is not None:
        if satisfies(support, x) is False:
            raise PhysTypeError(f"{_fmt(x)}{_unit(unknown)} is outside the support of "
                                f"'{unknown.name}' ({constraint_words(support)})", span,
                                "give a value its prior allows", source=text)
    return x


def _support(unknown):
    """The prior's support constraint where its arguments are constants, else None."""
    obj = find(unknown.prior.dist)
    args = list(unknown.prior.args) + [v for _, v in unknown.prior.kwargs]
    if obj is None or not all(is_constant(a) for a in args):
        return None
    try:
        d = obj(*[np.asarray(evaluate(a, {}), dtype=float) for a in unknown.prior.args],
                **{k: np.asarray(evaluate(v, {}), dtype=float) for k, v in unknown.prior.kwargs},
                validate_args=False)
        return d.support
    except Exception:  # noqa: BLE001 - a prior whose support cannot be built is not checked
        return None


def _unit(unknown) -> str:
    return "" if unknown.unit == "1" else f" {unknown.unit}"


def _shape_words(shape) -> str:
    return "a single number" if tuple(shape) == () else \
        f"a vector of {shape[0]}" if len(shape) == 1 else "an array of shape " + "x".join(map(str, shape))


def _fmt(x: np.ndarray) -> str:
    return f"{float(x):g}" if x.ndim == 0 else "(" + ", ".join(f"{v:g}" for v in x.ravel()) + ")"


def _error(cls, text: str, a: int, b: int, message: str, hint: str | None) -> PhysError:
    """``cls`` placed at columns [a, b) (0-based) of the ``--init`` text."""
    return cls(message, Span(SOURCE, 1, a + 1, 1, max(b, a + 1) + 1), hint, source=text)


def _relocate(ex: PhysError, text: str, shift: int) -> PhysError:
    """``ex`` (raised on the shifted parse text) placed in the ``--init`` text."""
    s = ex.span
    if s is not None:
        end = s.end_column + shift if s.end_column else None
        ex.span = Span(SOURCE, 1, max(s.column + shift, 1), 1 if s.end_line else None, end)
    ex.source = text
    ex.message = ex.message.replace("the end of the file", "the end of the --init text")
    return ex


__all__ = ["parse_init", "start_setting", "start_values", "with_init"]
