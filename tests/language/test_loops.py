"""Loops, name templates and aliases: unrolled at resolve time into what one would write by hand."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from physdsl import expr as E
from physdsl.compile import structure_key
from physdsl.errors import PhysError
from physdsl.syntax import format_source, load, loads, parse
from physdsl.syntax.ast import ForLoop, strip_spans

from .conftest import DATA, REPO

LOOPED = """
scene s {
  alias link0 = world
  for i in 1..2 {
    param m{i}: (10 * i) g
    body link{i} { shape: sphere(radius: 1 cm)  mass: m{i}  position: (0, 0, 1 - 0.25 * i) m }
    joint hinge{i}: hinge(link{i - 1} -> link{i}) { axis: (0, 1, 0)  anchor: (0, 0, 1.125 - 0.25 * i) m }
    for j in 0..1 { param k{2 * i + j}: i - j }
  }
  effect linear_drag on link{1 + 1} { coefficient: 0.1 kg/s }
}
"""

EXPLICIT = """
scene s {
  param m1: (10 * 1) g
  body link1 { shape: sphere(radius: 1 cm)  mass: m1  position: (0, 0, 1 - 0.25 * 1) m }
  joint hinge1: hinge(world -> link1) { axis: (0, 1, 0)  anchor: (0, 0, 1.125 - 0.25 * 1) m }
  param k2: 1 - 0
  param k3: 1 - 1
  param m2: (10 * 2) g
  body link2 { shape: sphere(radius: 1 cm)  mass: m2  position: (0, 0, 1 - 0.25 * 2) m }
  joint hinge2: hinge(link1 -> link2) { axis: (0, 1, 0)  anchor: (0, 0, 1.125 - 0.25 * 2) m }
  param k4: 2 - 0
  param k5: 2 - 1
  effect linear_drag on link2 { coefficient: 0.1 kg/s }
}
"""


def test_a_loop_unrolls_into_the_hand_written_scene():
    looped, explicit = loads(LOOPED), loads(EXPLICIT)
    assert [b.name for b in looped.bodies] == ["link1", "link2"]
    assert [(j.name, j.parent, j.child) for j in looped.joints] == [
        ("hinge1", "world", "link1"), ("hinge2", "link1", "link2")]
    assert structure_key(looped) == structure_key(explicit)


def test_the_chain_example_is_the_explicit_chain():
    """examples/ball_chain with loops is the scene its old explicit text (kept as test data) gave."""
    folder = REPO / "examples" / "ball_chain"
    looped = load(folder / "ball_chain.phys")
    explicit = loads((DATA / "ball_chain_explicit.phys").read_text(), "explicit.phys", folder)
    assert len((folder / "ball_chain.phys").read_text().splitlines()) < 40
    # equal but for rounding: 1.1 - 0.2 * 1 is 0.9000000000000001, the old text said 0.9
    assert structure_key(looped) != structure_key(explicit)
    assert structure_key(_rounded(looped)) == structure_key(_rounded(explicit))
    for a, b in zip(looped.observations, explicit.observations, strict=True):
        assert (a.name, a.target) == (b.name, b.target)
        assert np.array_equal(a.times, b.times) and np.array_equal(a.values, b.values)


def _rounded(x):
    """``x`` (a Scene or a part of one) with every constant rounded to 12 decimals."""
    if isinstance(x, E.Const):
        return E.Const(_tup(np.round(np.asarray(x.value, dtype=float), 12).tolist()))
    if isinstance(x, tuple):
        return tuple(_rounded(i) for i in x)
    if isinstance(x, dict):
        return {k: _rounded(v) for k, v in x.items()}
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return dataclasses.replace(x, **{f.name: _rounded(getattr(x, f.name))
                                         for f in dataclasses.fields(x) if f.init})
    return x


def _tup(v):
    return tuple(_tup(i) for i in v) if isinstance(v, list) else v


@pytest.mark.parametrize("text", [LOOPED, EXPLICIT])
def test_loops_print_back_as_loops(text):
    once = format_source(text)
    assert strip_spans(parse(once)) == strip_spans(parse(text))
    assert format_source(once) == once
    if text is LOOPED:
        assert "  for i in 1..2 {\n" in once and "    for j in 0..1 { param k{2 * i + j}: i - j }\n" in once


def test_a_comment_inside_a_loop_stays_there():
    src = "scene s {\n  for i in 1..2 {\n    # the i-th\n    param p{i}: i\n  }\n}\n"
    assert format_source(src) == src
    assert isinstance(parse(src).scene.items[0], ForLoop)


@pytest.mark.parametrize("text, message", [
    ("for i in 1..2 { for i in 1..2 { param p{i}: 1 } }", "the loop variable 'i' is already used"),
    ("body b { mass: 1 kg  shape: sphere(radius: 1 cm) }\n alias b = world",
     "the alias 'b' names something already declared"),
    ("for i in 1..2 { param p{j}: 1 }", "'j' in 'p{j}' is not a loop variable"),
    ("for i in 1..2 { param p{1..2}: 1 }", "a range ('{1..2}') is not a name"),
])
def test_loop_mistakes_are_named(text, message):
    with pytest.raises(PhysError) as ex:
        loads(f"scene s {{\n  {text}\n}}")
    assert message in str(ex.value)


def test_an_error_in_a_loop_names_its_iteration_once():
    text = ("scene s {\n  for i in 1..3 {\n    body b{i} { shape: sphere(radius: 1 cm)  "
            "mass: (i) m }\n  }\n}\n")
    with pytest.raises(PhysError) as ex:
        loads(text)
    assert "(in iteration i = 1 of the loop at line 2)" in str(ex.value)
    assert str(ex.value).count("error:") == 1  # the same mistake in every iteration: said once


@pytest.mark.slow
def test_the_chain_example_rolls_out_as_the_explicit_chain():
    """The same rollout to 1e-12 (positions, orientations, joint angles, contact forces)."""
    from physdsl.physics.simulator import build_simulator

    folder = REPO / "examples" / "ball_chain"
    looped = load(folder / "ball_chain.phys")
    explicit = loads((DATA / "ball_chain_explicit.phys").read_text(), "explicit.phys", folder)
    values = {"m_link": 0.11, "v_ball": 1.5}
    a, b = build_simulator(looped).simulate(values), build_simulator(explicit).simulate(values)
    assert float(np.max(np.asarray(a.contact_force))) > 1.0  # the ball hits the chain
    for field in ("body_pos", "body_quat", "body_vel", "joint_pos", "contact_force"):
        np.testing.assert_allclose(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)),
                                   rtol=1e-12, atol=1e-12)


def test_an_unrolled_module_prints_as_the_hand_written_scene():
    from physdsl.syntax.loops import unroll_module
    from physdsl.syntax.printer import format_module

    text = format_module(unroll_module(parse(LOOPED)))
    assert "for " not in text and "alias" not in text and "{i" not in text
    assert structure_key(loads(text)) == structure_key(loads(EXPLICIT))


def test_export_writes_a_looped_scene_out(tmp_path):
    """A posterior over unknowns inside a loop becomes their fitted priors, one per iteration."""
    from physdsl.export import export
    from physdsl.infer import posterior_data

    src = tmp_path / "chain.phys"
    src.write_text("scene s {\n  world { duration: 0.1 s }\n  for i in 1..2 {\n    body b{i} { "
                   "shape: sphere(radius: 1 cm)  mass ~ log_normal(0, 1)  position: (i, 0, 0) m }\n"
                   "  }\n}\n")
    rng = np.random.default_rng(0)
    post = {"b1.mass": np.exp(rng.normal(0.0, 0.01, (2, 200))),
            "b2.mass": np.exp(rng.normal(1.0, 0.01, (2, 200)))}
    text = export(src, posterior_data.from_dict({"posterior": post}), out_path=tmp_path / "proto.phys")
    (tmp_path / "proto.phys").write_text(text)
    scene = load(tmp_path / "proto.phys")
    priors = {u.name: u.prior for u in scene.unknowns}
    assert set(priors) == {"b1.mass", "b2.mass"}
    medians = {k: float(np.exp(E.evaluate(p.args[0], {}))) for k, p in priors.items()}
    assert abs(medians["b1.mass"] - 1.0) < 0.01 and abs(medians["b2.mass"] - np.e) < 0.03
