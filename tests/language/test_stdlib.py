"""The standard library declares exactly the effects of the table in docs/language.md."""
from __future__ import annotations

import pytest

from physdsl import expr as E
from physdsl.syntax import loads
from physdsl.syntax.units import parse_unit

# effect -> (acts_on, {param: (unit, shape, default or None, off or None, strength)})
TABLE = {
    "gravity": ("world", {"acceleration": ("m/s^2", (3,), (0, 0, -9.81), 0.0, True)}),
    "linear_drag": ("body", {"coefficient": ("kg/s", (), None, 0.0, True)}),
    "quadratic_drag": ("body", {"coefficient": ("kg/m", (), None, 0.0, True)}),
    "wind": ("body", {"velocity": ("m/s", (3,), None, 0.0, True),
                      "coefficient": ("kg/m", (), 0.005, None, False)}),
    "buoyancy": ("body", {"fluid_density": ("kg/m^3", (), None, 0.0, True)}),
    "magnus": ("body", {"coefficient": ("kg", (), None, 0.0, True)}),
    "spring": ("body|pair", {"stiffness": ("N/m", (), None, 0.0, True),
                             "rest_length": ("m", (), 0.0, None, False),
                             "anchor": ("m", (3,), (0, 0, 0), None, False),
                             "attachment": ("m", (3,), (0, 0, 0), None, False)}),
    "damper": ("body|pair", {"coefficient": ("N*s/m", (), None, 0.0, True),
                             "anchor": ("m", (3,), (0, 0, 0), None, False),
                             "attachment": ("m", (3,), (0, 0, 0), None, False)}),
    "joint_damping": ("joint", {"coefficient": ("N*m*s/rad", (), None, 0.0, True)}),
    "joint_friction": ("joint", {"torque": ("N*m", (), None, 0.0, True),
                                 "smoothing": ("rad/s", (), 0.01, None, False)}),
    "joint_spring": ("joint", {"stiffness": ("N*m/rad", (), None, 0.0, True),
                               "rest": ("rad", (), 0.0, None, False)}),
    "contact_friction": ("pair", {"coefficient": ("1", (), None, 0.0, True)}),
    "restitution": ("pair", {"coefficient": ("1", (), 1.0, 1.0, True)}),
    "rolling_resistance": ("pair", {"coefficient": ("m", (), None, 0.0, True)}),
    "constant_force": ("body", {"force": ("N", (3,), None, 0.0, True),
                                "torque": ("N*m", (3,), (0, 0, 0), None, False)}),
    "control_force": ("body|joint", {"gain": ("1", (), 1.0, 0.0, True)}),
}


@pytest.fixture(scope="module")
def library():
    return loads("scene s {}").effect_library


def test_every_effect_of_the_table(library):
    assert set(TABLE) <= set(library)
    for name, (acts_on, params) in TABLE.items():
        decl = library[name]
        assert decl.acts_on == acts_on and decl.doc
        assert [p.name for p in decl.params] == list(params)
        for pname, (unit, shape, default, off, strength) in params.items():
            p = decl.param(pname)
            assert parse_unit(p.unit)[1] == parse_unit(unit)[1], (name, pname)
            assert p.shape == shape and p.strength == strength and p.off == off
            if default is None:
                assert p.default is None and p.prior is not None  # left out -> unknown with prior
            else:
                assert E.constant_value(p.default) == pytest.approx(default)
        s = decl.strength
        assert s is not None
        if s.prior is not None and s.sign == 1:
            assert s.prior.dist in ("half_normal", "log_normal", "exponential", "gamma")
    assert library["restitution"].strength.sign == -1


def test_slider_units_for_joint_effects():
    src = """scene s {
      body c { shape: box(size: (1, 1, 1) m)  mass: 1 kg }
      joint rail: slider(world -> c) { axis: (1, 0, 0) }
      effect joint_damping on rail { coefficient: 2 N*s/m }
      effect joint_friction on rail { torque: 1 N  smoothing: 0.1 m/s }
    }"""
    s = loads(src)
    assert {e.key for e in s.effects} >= {"joint_damping@rail", "joint_friction@rail"}


def test_effect_import_of_stdlib_file_is_harmless():
    s = loads('import "effects/quadratic_drag.phys"\nimport "effects/drag.phys"\nscene s {}')
    assert "quadratic_drag" in s.effect_library


def test_materials_library(tmp_path):
    (tmp_path / "s.phys").write_text('import "materials.phys"\nscene s { body b { shape: sphere(radius: 1 cm)  density: steel_density } }')
    from physdsl.syntax import load
    assert load(tmp_path / "s.phys").body("b").density.value == 7850.0


def test_gravity_default_and_unknown():
    s = loads("scene s {}")
    assert s.effects[0].params["acceleration"].value == (0.0, 0.0, -9.81)
    s = loads("scene s { world { gravity ~ normal((0, 0, -9.8) m/s^2, 0.1 m/s^2) } }")
    u = s.unknown("gravity@world.acceleration")
    assert u.shape == (3,) and u.unit == "m/s^2"
