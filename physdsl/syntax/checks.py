"""A resolved value held to what its field accepts (``schema.Spec``): dimension, shape,
known-ness; errors name the field and show how to write it."""
from __future__ import annotations

from .. import expr as E
from ..errors import PhysTypeError, PhysUnitError
from . import ast
from .expressions import R
from .printer import format_expr
from .schema import Spec
from .units import Dim
from .words import shape_words


def check(r: R, spec_: Spec, label: str, node, err) -> R:
    """``r`` if it fits ``spec_``; else the error (built by ``err``)
    that names field ``label`` and shows how to write it. A bare number takes the field's unit."""
    span = getattr(node, "span", None)
    if r.dim is not None and not any(r.dim.same(d) for d in spec_.dims):
        want = spec_.dims[0]
        if isinstance(node, ast.WithUnit):
            example = _example(node.value, want)
            raise err(PhysUnitError,
                      f"unit '{node.unit}' is {r.dim.name().split(' (')[0]}, but '{label}' needs "
                      f"{want.name()}", span, f"write the {label.replace('_', ' ')} in "
                      f"{want.si_text()}, e.g. {example}")
        alts = " or ".join(d.name() for d in spec_.dims)
        raise err(PhysUnitError, f"'{label}' needs {alts}, but this value is "
                  f"{r.dim.name()}", span, f"write it in {spec_.dims[0].si_text()}")
    if spec_.shape is not None and r.shape != spec_.shape:
        raise err(PhysTypeError, f"'{label}' needs {shape_words(spec_.shape)}, got "
                  f"{shape_words(r.shape)}", span,
                  f"e.g. {label}: ({', '.join(['0'] * spec_.shape[0])})"
                  if len(spec_.shape) == 1 else None)
    if spec_.constant and not E.is_constant(r.expr):
        raise err(PhysTypeError, f"'{label}' must be a known value, not an unknown",
                  span, "write a number with a unit")
    return R(r.expr, r.dim if r.dim is not None else spec_.dims[0], r.shape)


def _example(node, dim: Dim) -> str:
    try:
        return f"{format_expr(node)} {dim.si_text()}"
    except Exception:  # noqa: BLE001
        return dim.si_text()
