"""The distilled-law dictionary: every term's coefficient unit times the term's unit is a force
(torque in a hinge), and the ``distilled_law`` physics matches analytic motion and the library."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import physdsl
from physdsl.discover.phys_text import law_scene_text
from physdsl.discover.terms import TERMS, coefficient_unit, terms_for
from physdsl.physics.simulator import build_simulator
from physdsl.syntax.units import parse_unit

FORCE = {"body": "N", "hinge": "N*m", "slider": "N"}


@pytest.mark.parametrize("kind", ["body", "hinge", "slider"])
def test_every_term_times_its_coefficient_is_a_force(kind):
    force = parse_unit(FORCE[kind])[1]
    for t in terms_for(kind):
        term_unit = t.unit[1] if kind == "slider" else t.unit[0]
        c = parse_unit(coefficient_unit(t, kind))[1]
        u = parse_unit(term_unit)[1]
        assert tuple(a + b for a, b in zip(c.exps, u.exps)) == tuple(force.exps), (kind, t.name)


BALL = """scene s {
  world { timestep: 5 ms  integrator: rk4 }
  body ball { shape: sphere(radius: 5 cm)  mass: 200 g  position: (0, 0, 1) m  velocity: (3, 0, 4) m/s }
}
"""


def test_a_linear_law_follows_the_analytic_solution():
    """F = -b v under gravity: v(t) = (v0 + g m/b) e^(-b t/m) - g m/b along z, v0 e^(-bt/m) in x."""
    b, m, g = 0.05, 0.2, 9.81
    text = law_scene_text(BALL, "ball", "body", ["v"], values={"v": -b})
    scene = physdsl.load(text)
    assert scene.effects[-1].effect == "distilled_law"
    roll = build_simulator(scene).simulate({})
    t = np.asarray(roll.t)
    k = b / m
    x = 3.0 / k * (1 - np.exp(-k * t))
    z = 1.0 + (4.0 + g / k) / k * (1 - np.exp(-k * t)) - g / k * t
    pos = np.asarray(roll.body_pos)[:, 0]
    np.testing.assert_allclose(pos[:, 0], x, atol=1e-8)
    np.testing.assert_allclose(pos[:, 2], z, atol=1e-8)


def test_the_speed_squared_term_is_the_library_quadratic_drag():
    c = 0.01
    law = build_simulator(physdsl.load(
        law_scene_text(BALL, "ball", "body", ["v_speed"], values={"v_speed": -c}))).simulate({})
    lib = build_simulator(physdsl.load(BALL.replace(
        "\n}\n", f"\n  effect quadratic_drag on ball {{ coefficient: {c} kg/m }}\n}}\n"))).simulate({})
    np.testing.assert_allclose(np.asarray(law.q), np.asarray(lib.q), atol=1e-12)


def test_a_law_with_unknown_coefficients_has_units_priors_and_an_off_value():
    text = law_scene_text(BALL, "ball", "body", ["v_sqrt_speed", "d_inv2"], center=(0, 0, -1),
                          priors={"v_sqrt_speed": (0.0, 0.05), "d_inv2": (0.0, 0.1)})
    scene = physdsl.load(text)
    decl = scene.effect_library["distilled_law"]
    by = {p.name: p for p in decl.params}
    assert by["v_sqrt_speed"].off == 0.0 and by["d_inv2"].off == 0.0
    assert decl.strength.name == "v_sqrt_speed"  # what add-effect gives an unknown
    units = {u.name: u.unit for u in scene.unknowns}
    assert units == {"distilled_law@ball.v_sqrt_speed": "kg/s",
                     "distilled_law@ball.d_inv2": "m^3*kg/s^2"}  # N s/m and N m^2 in SI
    np.testing.assert_allclose(np.asarray(scene.effects[-1].params["center"].array()), (0, 0, -1))
    assert physdsl.format_source(physdsl.format_source(text)) == physdsl.format_source(text)
    assert set(TERMS) >= set(by) - {"center"}


def test_a_law_file_is_ready_for_add_effect(tmp_path):
    """law.phys (the declaration alone) imported by a scene: add-effect puts the law on the
    body, its first term an unknown with the law's prior."""
    from physdsl.discover.phys_text import declaration

    (tmp_path / "law.phys").write_text(declaration("body", ["v_sqrt_speed"],
                                                   {"v_sqrt_speed": (0.0, 0.06)}))
    (tmp_path / "scene.phys").write_text('import "law.phys"\n' + BALL)
    scene = physdsl.load(tmp_path / "scene.phys")
    new = physdsl.add_effect(scene, "distilled_law", "ball")
    assert "effect distilled_law on ball" in new.source
    assert [u.name for u in new.unknowns] == ["distilled_law@ball.v_sqrt_speed"]
