"""to_expr: a written value with units becomes an SI Expr whose evaluation matches the
arithmetic done by hand; names come from the scope (draws of params evaluate per draw)."""
from __future__ import annotations

import math

import jax
import numpy as np
import pytest

from physdsl import expr as E
from physdsl.errors import PhysNameError, PhysUnitError
from physdsl.syntax import ast
from physdsl.syntax.expressions import R, Scope, to_expr
from physdsl.syntax.parser import parse_field
from physdsl.syntax.units import ANGLE, LENGTH, Dim


def value(text: str, scope: Scope = Scope()) -> R:
    return to_expr(parse_field(f"x: {text}").value, scope)

def test_constants_fold_to_si():
    r = value("2 cm * sin(30 deg) + 1 mm")
    assert isinstance(r.expr, E.Const) and r.dim.same(LENGTH) and r.shape == ()
    assert r.expr.value == pytest.approx(0.02 * 0.5 + 0.001, rel=1e-12)
    q = value("euler(0, 0, 90) deg")
    assert r.shape == () and q.shape == (4,)
    np.testing.assert_allclose(q.expr.array(), [math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)],
                               atol=1e-12)
    assert value("atan2(1 m, 1 m)").dim == ANGLE

def test_names_from_the_scope_evaluate_per_draw():
    dims = {"L": LENGTH, "T": Dim.of(s=1)}

    def lookup(node):
        if isinstance(node, ast.Name) and node.name in dims:
            return R(E.Ref(node.name), dims[node.name], ())
        raise KeyError(node)

    r = value("(L, 2 * L, 3 cm) / T^2", Scope(lookup))
    assert r.dim.same(Dim.of(m=1, s=-2)) and r.shape == (3,)
    draws = {"L": np.array([0.5, 1.0, 2.0]), "T": np.array([1.0, 2.0, 4.0])}
    got = np.asarray(jax.vmap(lambda v: E.evaluate(r.expr, v))(draws))
    L, T = draws["L"][:, None], draws["T"][:, None]
    want = np.concatenate([L, 2 * L, np.full_like(L, 0.03)], axis=1) / T ** 2
    np.testing.assert_allclose(got, want, rtol=1e-12)
    with pytest.raises(KeyError):  # the scope's own error passes through
        value("M * 2", Scope(lookup))

def test_mistakes_are_phys_errors():
    with pytest.raises(PhysUnitError, match="cannot add a length"):
        value("1 m + 2 s")
    with pytest.raises(PhysNameError, match="unknown name 'L'"):
        value("2 * L")
    with pytest.raises(PhysNameError, match="unknown function 'sinh'"):
        value("sinh(1)")
