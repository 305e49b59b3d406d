"""Units: SI conversion, dimension algebra and dimension errors."""
from __future__ import annotations

import math

import pytest

from physdsl.syntax.units import ANGLE, LENGTH, Dim, UnitError, parse_unit


@pytest.mark.parametrize("text,scale,si", [
    ("cm", 0.01, "m"), ("mm", 1e-3, "m"), ("km", 1e3, "m"), ("g", 1e-3, "kg"), ("mg", 1e-6, "kg"),
    ("ms", 1e-3, "s"), ("us", 1e-6, "s"), ("min", 60.0, "s"), ("h", 3600.0, "s"),
    ("deg", math.pi / 180, "rad"), ("mrad", 1e-3, "rad"), ("kN", 1e3, "N"), ("Hz", 1.0, "1/s"),
    ("m/s^2", 1.0, "m/s^2"), ("kg/m^3", 1.0, "kg/m^3"), ("g/cm^3", 1000.0, "kg/m^3"),
    ("N*m*s/rad", 1.0, "N*m*s/rad"), ("kg*m^2", 1.0, "kg*m^2"), ("km/h", 1 / 3.6, "m/s"),
    ("N/mm", 1000.0, "N/m"), ("1", 1.0, "1"), ("kPa", 1e3, "kg/m/s^2"),
])
def test_conversion_to_si(text, scale, si):
    s, d = parse_unit(text)
    assert s == pytest.approx(scale, rel=1e-12)
    assert d.si_text() == si


def test_dimension_algebra():
    _, newton = parse_unit("N")
    _, kgms = parse_unit("kg*m/s^2")
    assert newton == kgms
    _, hz = parse_unit("Hz")
    _, rads = parse_unit("rad/s")
    assert hz.same(rads) and hz != rads  # angle is tracked but not compared
    assert (LENGTH ** 2) / LENGTH == LENGTH
    assert ANGLE.is_angle and ANGLE.dimensionless
    assert "velocity" in parse_unit("m/s")[1].name()


@pytest.mark.parametrize("text", ["furlong", "m/", "xyz*m", "kgg"])
def test_unknown_units_raise(text):
    with pytest.raises(UnitError):
        parse_unit(text)


def test_wrong_dimension_is_reported_with_a_hint():
    from physdsl.errors import PhysUnitError
    from physdsl.syntax import loads

    src = "scene s {\n  body b {\n    shape: sphere(radius: 1 cm)\n    mass: 1 kg\n    velocity: (4, 0, 5) kg\n  }\n}\n"
    with pytest.raises(PhysUnitError) as ex:
        loads(src, "thrown.phys")
    text = ex.value.render()
    assert text.startswith("thrown.phys:5:15: error: unit 'kg' is a mass, but 'velocity' needs a velocity (m/s)")
    assert "^^^^^^^^^^^^" in text
    assert "hint: write the velocity in m/s, e.g. (4, 0, 5) m/s" in text


def test_unitless_numbers_are_si():
    from physdsl.syntax import loads

    s = loads("scene s { body b { shape: sphere(radius: 0.1)  mass: 2  position: (0, 0, 1.5) } }")
    b = s.body("b")
    assert b.shape.size["radius"].value == 0.1 and b.mass.value == 2.0
    assert b.position.value == (0.0, 0.0, 1.5)
    assert Dim() == parse_unit("1")[1]
