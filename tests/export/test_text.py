"""Writing a fit as .phys text: snippets parse, expressions evaluate to the fitted transform."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from physdsl.errors import PhysError, UsageError
from physdsl.export import (Support, block_texts, drop_parts, fit_draws, marginal_text, number,
                            set_unknown, snippet)
from physdsl.sample import expression_value
from physdsl.syntax import ast as A
from physdsl.syntax.parser import parse, parse_field
from physdsl.syntax.units import parse_unit

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
POS = Support("lower", np.asarray(0.0))
REAL = Support("real")


def _draws(seed=0, n=4000):
    rng = np.random.default_rng(seed)
    y = rng.multivariate_normal([np.log(0.6), 0.7, 0.2, -1.0, 0.5],
                                [[0.01, -0.006, 0, 0, 0], [-0.006, 0.01, 0, 0, 0],
                                 [0, 0, 0.04, 0.01, 0], [0, 0, 0.01, 0.04, 0], [0, 0, 0, 0, 0.09]], n)
    return {"L": np.exp(y[:, 0]), "hinge.initial": y[:, 1], "ball.velocity": y[:, 2:5],
            "mu": 2.0 / (1 + np.exp(-y[:, 4]))}


def test_number_text_parses_back_exactly_enough():
    for x in (0.0, 1.0, -0.51082562, 1.234e-7, 6.02e23, -3.5e-12):
        text = number(x, 8)
        assert "e+" not in text
        assert abs(float(text) - x) <= 1e-7 * abs(x)


def test_block_expressions_evaluate_to_the_fitted_transform():
    draws = _draws()
    sup = {"L": POS, "hinge.initial": REAL, "ball.velocity": REAL,
           "mu": Support("interval", np.asarray(0.0), np.asarray(2.0))}
    draws["mu"] = draws["mu"] * 0 + 2.0 / (1 + np.exp(-(0.3 * draws["hinge.initial"] + 0.1)))
    fit = fit_draws(draws, sup)
    assert len(fit.blocks) == 2
    units = {"L": "m", "hinge.initial": "rad", "ball.velocity": "m/s", "mu": "1"}
    zs = {}
    rng = np.random.default_rng(1)
    for b, prefix in zip(fit.blocks, ("a", "b")):
        z_names = [f"{prefix}{k}" for k in range(len(b.mean))]
        z = rng.standard_normal(len(b.mean))
        env = {n: (np.asarray(v), parse_unit("m/m")[1]) for n, v in zip(z_names, z)}
        y = b.mean + b.chol @ z
        for name, text in block_texts(b, z_names, fit, units).items():
            value, dim = expression_value(parse_field(f"x: {text}").value, env)
            idx = [k for k, (n, _) in enumerate(b.components) if n == name]
            want = np.array([fit.supports[name].component(i).from_unconstrained(y[k])
                             for k, (_, i) in zip(idx, [b.components[k] for k in idx])])
            np.testing.assert_allclose(np.reshape(value, -1), want, rtol=1e-4, atol=1e-4)  # << sd
            assert dim.si_text() == parse_unit(units[name] if units[name] != "1" else "m/m")[1].si_text()
            zs[name] = value
    assert set(zs) == set(draws)


@pytest.mark.parametrize("dist,support,unit", [
    ("normal", REAL, "m/s"), ("log_normal", POS, "kg"),
    ("beta", Support("interval", np.asarray(0.0), np.asarray(1.0)), "1"),
    ("truncated_normal", Support("interval", np.asarray(0.1), np.asarray(0.4)), "kg"),
])
def test_marginal_text_parses_as_the_distribution(dist, support, unit):
    rng = np.random.default_rng(2)
    x = support.from_unconstrained(rng.normal(0.1, 0.3, 3000))
    fit = fit_draws({"q": x}, {"q": support})
    (m,) = fit.marginals
    assert m.dist == dist
    node = parse_field(f"x ~ {marginal_text(m, unit)}").value
    assert isinstance(node, A.Dist) and node.name == dist


def _pendulum():
    path = EXAMPLES / "pendulum" / "pendulum.phys"
    return parse(path.read_text(), str(path)), path.read_text()


def _names(module):
    return {(type(i).__name__, getattr(i, "name", None) or getattr(i, "target", None))
            for i in module.scene.items}


def test_drop_body_removes_its_joint_effect_observation():
    module, _ = _pendulum()
    out = drop_parts(module, ["bob"])
    names = _names(out)
    assert ("BodyItem", "bob") not in names and ("JointItem", "weld") not in names
    assert ("ObserveItem", "bob") not in names
    assert ("ObserveItem", "hinge") in names and ("BodyItem", "rod") in names


def test_drop_parent_drops_the_bodies_hanging_from_it():
    module, _ = _pendulum()
    out = drop_parts(module, ["rod"])
    kinds = {type(i).__name__ for i in out.scene.items}
    assert not kinds & {"BodyItem", "JointItem", "EffectItem", "ObserveItem"}


def test_drop_effect_and_observation_and_no_observe():
    module, _ = _pendulum()
    out = drop_parts(module, ["joint_damping@hinge", "hinge.angle"])
    names = _names(out)
    assert ("EffectItem", ("hinge",)) not in names
    assert ("ObserveItem", "hinge") not in names and ("ObserveItem", "bob") in names
    gen = drop_parts(module, [], observe=False, duration=10.0)
    assert not any(isinstance(i, A.ObserveItem) for i in gen.scene.items)
    world = next(i for i in gen.scene.items if isinstance(i, A.WorldItem))
    assert world.block.get("duration") is not None


def test_drop_reports_a_reference_that_remains_naming_both_places():
    _, text = _pendulum()
    text = text.replace("  joint weld", "  body marker {\n    shape: sphere(radius: 1 cm)\n"
                        "    mass: 1 g\n    position: bob.position + (0, 0, 0.1) m\n  }\n  joint weld")
    module = parse(text, "pendulum.phys")
    with pytest.raises(PhysError) as err:
        drop_parts(module, ["bob"], source=text)
    msg = err.value.render()
    assert "bob.position" in msg and "body marker" in msg and "body bob" in msg
    assert "pendulum.phys:" in msg  # the place of the reference and of the declaration
    assert msg.count("pendulum.phys:") >= 2


def test_drop_unknown_name_is_a_usage_error():
    module, _ = _pendulum()
    with pytest.raises(UsageError, match="no body, effect or observation"):
        drop_parts(module, ["nothing"])


def test_set_unknown_finds_params_fields_effects_and_noise():
    module, _ = _pendulum()
    value = snippet("x ~ log_normal(-0.5, 0.1)")
    for name in ("L", "hinge.initial", "joint_damping@hinge.coefficient"):
        module = set_unknown(module, name, value)
    items = module.scene.items
    assert next(i for i in items if isinstance(i, A.Param) and i.name == "L").value == value
    hinge = next(i for i in items if isinstance(i, A.JointItem) and i.name == "hinge")
    assert hinge.block.get("initial").value == value
    eff = next(i for i in items if isinstance(i, A.EffectItem))
    assert eff.block.get("coefficient").value == value
    module = set_unknown(module, "bob.position.noise", snippet("x: 3 mm"))
    with pytest.raises(PhysError, match="cannot find"):
        set_unknown(module, "bob.nothing", value)
