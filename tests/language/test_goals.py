"""The ``goal`` block: terms become ``goal.Goal`` values in SI, fmt prints the block back, the
keywords do not take names away, and independent mistakes are all reported (the golden error
files are ``data/broken/goal_*``)."""
from __future__ import annotations

import math

import pytest

from physdsl.errors import PhysError, PhysErrors
from physdsl.goal import Effort, Goal, Hold, Reach
from physdsl.syntax import ast, format_source, load, loads, parse
from physdsl.syntax.ast import strip_spans

from .conftest import DATA

SCENE = """
scene s {
  world { duration: 4 s }
  param v ~ normal(1 m/s, 0.5 m/s)
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity: (v, 0, 0)
  }
  body cart { shape: box(size: (30, 20, 10) cm)  mass: 1 kg }
  body pole { shape: capsule(radius: 1 cm, length: 50 cm)  mass: 100 g }
  joint rail: slider(world -> cart) { axis: (1, 0, 0) }
  joint hinge: hinge(cart -> pole) { axis: (0, 1, 0) }
%s
}
"""


def goal_of(text: str) -> Goal:
    return loads(SCENE % text).goal


def test_every_term_is_a_goal_value_in_si():
    scene = load(DATA / "good" / "goal.phys")
    g = scene.goal
    assert [type(t) for t in g.terms] == [Reach, Reach, Hold, Hold, Effort]
    ball, top, pole, rail, effort = g.terms
    assert (ball.target, ball.at, ball.point, ball.within) == ("ball", 1.0, (0.9, -0.1, 0.03), 0.01)
    assert (top.target, top.at, top.within) == ("top", 1.0, 0.02)  # 1000 ms, 2 * tol
    assert top.point == pytest.approx((0.9, -0.1, 0.06), abs=1e-15)
    assert (pole.joint, pole.start, pole.end, pole.within) == ("pole_hinge", 2.0, 5.0, 0.1)
    assert pole.value == pytest.approx(math.pi, abs=1e-15)  # 180 deg
    assert (rail.joint, rail.value, rail.within) == ("rail", 0.0, 0.1)  # a slider: 10 cm
    assert effort.weight == 1e-3
    assert g.decisions == ("vx", "vy")
    assert g.span.line == 33 and ball.span.line == 34 and effort.span.line == 39


def test_a_scene_without_a_goal_has_none():
    assert loads(SCENE % "").goal is None


def test_bare_numbers_are_si_and_units_convert():
    g = goal_of("goal {\n hinge.angle from 500 ms to 2 -> 1.5 within 2 deg\n"
                " rail.angle from 0 to 3 s -> 250 mm within 0.01\n effort: 2 kN^-2*s^-1 }")
    hinge, rail, effort = g.terms
    assert (hinge.start, hinge.end, hinge.value) == (0.5, 2.0, 1.5)
    assert hinge.within == pytest.approx(math.radians(2), rel=1e-12)
    assert (rail.start, rail.end, rail.value, rail.within) == (0.0, 3.0, 0.25, 0.01)
    assert effort.weight == pytest.approx(2e-6, rel=1e-12)  # 2 per kN^2 s


def test_a_torque_effort_unit_and_a_field_unknown_as_decision():
    text = SCENE.replace("velocity: (v, 0, 0)", "velocity ~ normal((1, 0, 0) m/s, 0.5 m/s)")
    g = loads(text % "goal {\n ball.position at 1 s -> (1, 0, 1) m within 1 cm\n"
                     " effort: 1e-3 N^-2*m^-2*s^-1\n decide: ball.velocity }").goal
    assert g.terms[1] == Effort(1e-3, g.terms[1].span)
    assert g.decisions == ("ball.velocity",)


def test_a_term_after_a_bare_number_is_a_term_not_its_unit():
    m = parse(SCENE % "goal {\n effort: 1e-3\n ball.position at 1 s -> (1, 0, 1) m within 0.01\n"
                      " hinge.angle from 1 to 2 s -> 0 within 0.1\n}")
    goal = next(i for i in m.scene.items if isinstance(i, ast.GoalItem))
    assert [type(t) for t in goal.terms] == [ast.GoalField, ast.ReachTerm, ast.HoldTerm]
    assert strip_spans(goal.terms[0]) == ast.GoalField("effort", (ast.Num("1e-3"),))
    assert strip_spans(goal.terms[2].start) == ast.Num("1")


def test_goal_words_stay_free_as_names():
    text = SCENE.replace("body cart", "body goal").replace("world -> cart", "world -> goal") \
        .replace("cart -> pole", "goal -> pole")
    g = loads(text % "param at: 1 s\n param to: 3 s\n param within: 2 cm\n"
                     " goal {\n goal.position at at -> (1, 0, 0.5) m within within\n"
                     " hinge.angle from at to to -> 0 within 1 deg\n}").goal
    assert (g.terms[0].target, g.terms[0].at, g.terms[0].within) == ("goal", 1.0, 0.02)
    assert (g.terms[1].start, g.terms[1].end) == (1.0, 3.0)


def test_fmt_writes_the_canonical_block_and_keeps_the_tree():
    src = SCENE % ("  goal{ball.position at 1 s->(1,0,1) m within 1 cm   # there\n"
                   "effort:1e-3 decide:v\n\n hinge.angle from 1 s to 2*1.5 s -> -(90) deg within 2 deg}")
    out = format_source(src)
    assert out.endswith(
        "  goal {\n"
        "    ball.position at 1 s -> (1, 0, 1) m within 1 cm  # there\n"
        "    effort: 1e-3\n"
        "    decide: v\n"
        "\n"
        "    hinge.angle from 1 s to 2 * 1.5 s -> -90 deg within 2 deg\n"
        "  }\n"
        "}\n")
    assert format_source(out) == out
    assert strip_spans(parse(out)) == strip_spans(parse(src))


def test_independent_goal_mistakes_are_all_reported():
    with pytest.raises(PhysErrors) as info:
        goal_of("goal {\n ball.position at 1 kg -> (1, 0, 1) m within 1 cm\n"
                " hinge.angle from 1 s to 2 s -> 1 m within 1 deg\n decide: w\n}")
    messages = [e.message for e in info.value.errors]
    assert len(messages) == 3
    assert "the time after 'at' is a time (s)" in messages[0]
    assert "held at is an angle (rad)" in messages[1]
    assert "unknown name 'w'" in messages[2]
    assert [e.span.line for e in info.value.errors] == [16, 17, 18]


def test_an_unknown_in_a_goal_is_refused_with_a_decide_hint():
    with pytest.raises(PhysError) as info:
        goal_of("goal { hinge.angle from 1 s to 2 s -> v * 1 s/m within 1 deg }")
    assert "depends on the unknown 'v'" in info.value.message
    assert "decide: v" in info.value.hint
