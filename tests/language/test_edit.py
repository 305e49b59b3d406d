"""Edit helpers: text -> text through the AST, comments kept, result still resolves."""
from __future__ import annotations

import pytest

from physdsl import expr as E
from physdsl.errors import PhysNameError
from physdsl.syntax import loads
from physdsl.syntax.edit import add_effect, remove_item, replace_value

SRC = """# a thrown ball
scene s {
  param m: 200 g  # known mass
  ground floor { normal: (0, 0, 1) }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: m
    velocity: (1, 0, 0) m/s
  }
  contact floor, ball { friction: 0.3 }
  effect linear_drag on ball { coefficient: 0.1 kg/s }
}
"""


def test_add_effect_appends_inside_scene():
    out = add_effect(SRC, "quadratic_drag", "ball", {"coefficient": "~ half_normal(0.01 kg/m)"})
    assert "  effect quadratic_drag on ball { coefficient ~ half_normal(0.01 kg/m) }\n}" in out
    assert out.startswith("# a thrown ball\n") and "# known mass" in out
    s = loads(out)
    assert s.unknown("quadratic_drag@ball.coefficient").unit == "kg/m"
    pair = add_effect(SRC, "rolling_resistance", "floor,ball", {"coefficient": "1 mm"})
    assert "effect rolling_resistance on (floor, ball) { coefficient: 1 mm }" in pair


@pytest.mark.parametrize("path,value,check", [
    ("ball.velocity", "~ normal((1, 0, 0) m/s, 1 m/s)", lambda s: s.body("ball").velocity == E.Ref("ball.velocity")),
    ("ball.shape.radius", "7 cm", lambda s: s.body("ball").shape.size["radius"].value == 0.07),
    ("m", "~ normal(0.2 kg, 10 g)", lambda s: s.body("ball").mass == E.Ref("m")),
    ("linear_drag@ball.coefficient", "0.2 kg/s", lambda s: s.effects[-1].params["coefficient"].value == 0.2),
    ("contact_friction@floor,ball.coefficient", "0.5", lambda s: any(
        e.key == "contact_friction@floor,ball" and e.params["coefficient"].value == 0.5 for e in s.effects)),
    ("ball.position", "(0, 0, 2) m", lambda s: s.body("ball").position.value == (0, 0, 2)),
])
def test_replace_value(path, value, check):
    out = replace_value(SRC, path, value)
    assert check(loads(out))
    assert "# known mass" in out


def test_remove_item():
    out = remove_item(SRC, "effect", "linear_drag@ball")
    assert "linear_drag" not in out
    out = remove_item(out, "contact", "ball, floor")
    assert "contact" not in out and len(loads(out).effects) == 1
    with pytest.raises(PhysNameError):
        remove_item(SRC, "body", "nope")
    with pytest.raises(PhysNameError):
        replace_value(SRC, "nope.mass", "1 kg")
