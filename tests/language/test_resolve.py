"""Resolver: every construct of the all-constructs fixture lands in the Scene as documented."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl import expr as E
from physdsl.errors import (PhysError, PhysErrors, PhysImportError, PhysNameError,
                            PhysStructureError, PhysTypeError)
from physdsl.syntax import load, loads, unknowns_table

from .conftest import DATA

GOOD = DATA / "good" / "all_constructs.phys"


@pytest.fixture(scope="module")
def scene():
    return load(GOOD)


def val(e, **values):
    return np.asarray(E.evaluate(e, values))


def test_world(scene):
    w = scene.world
    assert (w.timestep, w.duration, w.substeps, w.integrator, w.contact_model) == \
        (0.002, 0.2, 2, "rk4", "compliant")
    g = next(e for e in scene.effects if e.effect == "gravity")
    assert g.target == ("world",) and g.params["acceleration"].value == (0.0, 0.0, -9.8)


def test_bodies_in_si(scene):
    cart, pole, ball = scene.body("cart"), scene.body("pole"), scene.body("ball")
    assert cart.shape.kind == "box" and cart.shape.size["size"].value == pytest.approx((0.3, 0.2, 0.1))
    assert cart.density.value == 7850.0  # from the imported library param
    L = 0.55
    assert float(val(pole.shape.size["length"], L=L)) == pytest.approx(L - 0.08)
    assert val(pole.position, L=L) == pytest.approx([0, 0, 0.1 + L / 2])
    assert pole.material.ambient.value == 0.3 and pole.color.value == (0.2, 0.4, 0.6)
    assert ball.inertia.value == pytest.approx((2 * 0.4 * 0.057 * 0.04**2,) * 3)
    assert ball.position.value == pytest.approx((1.0, 0.0, math.sqrt(2) * 0.5))
    q = val(ball.orientation)
    assert q == pytest.approx([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)])
    assert ball.velocity == E.Ref("ball.velocity")
    floor = scene.body("floor")
    assert floor.fixed and floor.shape.kind == "plane" and floor.shape.size["normal"].value == (0, 0, 1)
    part = scene.body("part")
    assert part.shape.kind == "mesh" and part.shape.mesh_path.name == "tri.obj"
    assert scene.body("drum").fixed


def test_joints(scene):
    rail, tilt = scene.joint("rail"), scene.joint("tilt")
    assert (rail.kind, rail.parent, rail.child) == ("slider", "world", "cart")
    assert rail.limits[0].value == -1.0 and rail.limits[1].value == 1.0
    assert rail.initial_velocity.value == 0.1
    assert tilt.initial == E.Ref("tilt.initial")
    assert tilt.dh.alpha.value == pytest.approx(math.pi / 2) and tilt.dh.d.value == 0.1


def test_contact_pairs(scene):
    pairs = set(scene.contact_pairs)
    # fixed first; part has collide: false; cart-pole joined; floor-drum both fixed
    assert ("floor", "ball") in pairs and ("floor", "cart") in pairs and ("drum", "ball") in pairs
    assert not any("part" in p for p in pairs)
    assert ("cart", "pole") not in pairs and ("pole", "cart") not in pairs
    assert ("floor", "drum") not in pairs and ("drum", "floor") not in pairs
    for a, b in scene.contact_pairs:
        assert not scene.body(b).fixed or scene.body(a).fixed


def test_effects_and_defaults(scene):
    eff = {e.key: e for e in scene.effects}
    assert eff["contact_friction@floor,ball"].params["coefficient"] == \
        E.Binary("*", E.Const(0.3), E.Ref("mu"))
    assert eff["restitution@floor,ball"].params["coefficient"].value == 0.8
    assert eff["linear_drag@ball"].params["coefficient"] == E.Ref("linear_drag@ball.coefficient")
    spring = eff["spring@drum,ball"]
    assert spring.params["rest_length"].value == 0.5 and spring.params["anchor"].value == (0, 0, 0)
    assert set(spring.params) == {"stiffness", "rest_length", "anchor", "attachment"}
    assert eff["wind@ball"].params["coefficient"].value == 0.005
    assert eff["joint_damping@rail"].params["coefficient"].value == 0.2
    assert "pulse" in scene.effect_library and "magnus" in scene.effect_library
    assert len(scene.effect_library) >= 16
    for use in scene.effects:
        decl = scene.effect_library[use.effect]
        assert {p.name for p in decl.params} <= set(use.params)


def test_controls(scene):
    eff = {e.key: e for e in scene.effects}
    push = eff["control_force@cart"]
    assert push.tables["times"].tolist() == [0.0, 0.5] and push.tables["values"].shape == (2, 3)
    motor = eff["control_force@tilt"]
    assert motor.tables["values"].tolist() == [0.5, 0.25] and motor.params["gain"].value == 2.0
    guess = eff["control_force@rail"]
    assert guess.params["values"] == E.Ref("control_force@rail.values")
    assert scene.unknown("control_force@rail.values").shape == (3,)
    assert "values" not in guess.tables and len(guess.tables["times"]) == 3


def test_unknowns(scene):
    u = {x.name: x for x in scene.unknowns}
    assert u["L"].unit == "m" and u["L"].prior.args == (E.Const(0.6), E.Const(0.05))
    assert set(u["L"].used_in) == {"pole.shape.length", "pole.position"}
    assert u["ball.velocity"].shape == (3,) and u["ball.velocity"].unit == "m/s"
    assert u["offset"].shape == (3,)
    assert u["which"].discrete and not u["L"].discrete
    assert u["tilt.initial"].unit == "rad"
    assert u["tilt.initial"].prior.args[0].value == pytest.approx(math.radians(5))
    assert u["cart.orientation.noise"].unit == "1"
    assert u["quadratic_drag@ball.coefficient"].unit == "kg/m"
    assert u["rolling_resistance@floor,ball.coefficient"].prior.args[0].value == pytest.approx(1e-3)
    table = unknowns_table(scene)
    assert "quadratic_drag@ball.coefficient" in table and "half_normal(0.01)" in table


def test_observations(scene):
    obs = {(o.name, o.file.name): o for o in scene.observations}
    pos = obs[("ball.position", "traj.csv")]
    assert pos.times.tolist() == [0.0, 0.1, 0.2] and pos.values.shape == (3, 3)
    assert pos.mask.tolist() == [[True] * 3, [True, False, True], [True] * 3]
    assert pos.noise.scale.value == 0.002 and pos.columns == ("x", "y", "z")
    ori = obs[("cart.orientation", "traj.csv")]
    assert ori.noise.kind == "student_t" and ori.noise.df.value == 5.0 and ori.dim == 4
    ang = obs[("tilt.angle", "joints.csv")]
    assert ang.values[:, 0].tolist() == [0.1, 0.12] and ang.noise.scale.value == 0.003
    img = [o for o in scene.observations if o.quantity == "image"]
    assert [len(o.frames) for o in img] == [3, 3]
    assert img[0].times.tolist() == [0.0, 0.05, 0.1]
    assert img[1].times == pytest.approx([0.0, 0.05, 0.1])
    cam = scene.cameras[0]
    assert cam.size == (32, 24) and cam.fov.value == pytest.approx(math.radians(40))
    assert scene.light.diffuse.value == (0.8, 0.8, 0.8)


def test_gradients_flow_through_resolved_expressions(scene):
    import jax

    pole = scene.body("pole")
    f = lambda L: E.evaluate(pole.position, {"L": L})[2]  # noqa: E731
    assert float(jax.grad(f)(0.6)) == pytest.approx(0.5)


# ---- errors ----------------------------------------------------------------------------------

def err(src: str, tmp_path: Path | None = None, cls=PhysError) -> PhysError:
    with pytest.raises(cls) as ex:
        if tmp_path is not None:
            (tmp_path / "s.phys").write_text(src)
            load(tmp_path / "s.phys")
        else:
            loads(src, "s.phys")
    return ex.value


BALL = "body ball { shape: sphere(radius: 1 cm)  mass: 1 kg }"


def test_close_matches_for_names():
    e = err(f"scene s {{ param radius: 1 cm  body b {{ shape: sphere(radius: radiuss)  mass: 1 kg }} }}",
            cls=PhysNameError)
    assert "did you mean 'radius'" in e.message


def test_user_import_cycle_and_missing(tmp_path):
    (tmp_path / "a.phys").write_text('import "b.phys"\n')
    (tmp_path / "b.phys").write_text('import "a.phys"\n')
    e = err(f'import "a.phys"\nscene s {{ {BALL} }}', tmp_path, PhysImportError)
    assert "cyclic import" in e.message and "a.phys -> b.phys -> a.phys" in e.message
    e = err(f'import "nope.phys"\nscene s {{ {BALL} }}', tmp_path, PhysImportError)
    assert "cannot find import" in e.message


def test_stdlib_import_and_diamond(tmp_path):
    (tmp_path / "x.phys").write_text('import "effects/drag.phys"\nparam g0: 1 m\n')
    (tmp_path / "y.phys").write_text('import "x.phys"\nimport "effects/linear_drag.phys"\n')
    (tmp_path / "s.phys").write_text(
        f'import "x.phys"\nimport "y.phys"\nscene s {{ {BALL} effect linear_drag on ball {{ coefficient: g0 * 1 kg/m/s }} }}')
    s = load(tmp_path / "s.phys")
    assert s.effects[-1].params["coefficient"].value == 1.0


def test_joint_structure_errors():
    two = "body a { shape: sphere(radius: 1 cm)  mass: 1 kg } body b { shape: sphere(radius: 1 cm)  mass: 1 kg }"
    e = err(f"scene s {{ {two} joint j1: hinge(a -> b) {{ axis: (0, 1, 0) }} "
            "joint j2: hinge(b -> a) { axis: (0, 1, 0) } }", cls=PhysStructureError)
    assert "cycle" in e.message
    e = err(f"scene s {{ {two} joint j: ball(world -> world) }}", cls=PhysNameError)
    assert "unknown child 'world'" in e.message


@pytest.mark.parametrize("dist,words", [
    ("half_normal(-1)", "must be positive"),
    ("normal(1, 0)", "must be positive"),
    ("gamma(2 kg, 1)", "plain number"),
    ("beta(0.5, -2)", "must be positive"),
    ("categorical(prob: (0.5, 0.5))", "no argument 'prob'"),
    ("normal_dist(0, 1)", "unknown distribution"),
    ("log_normal(1 kg, 0.1)", "log space"),
    ("normal(1 kg, 0.1 kg, 3)", "at most 2"),
    ("student_t(loc: 1)", "needs argument 'df'"),
])
def test_distribution_checks(dist, words):
    e = err(f"scene s {{ body b {{ shape: sphere(radius: 1 cm)  mass ~ {dist} }} }}")
    assert words in e.message


def test_prior_shape_must_fit_field():
    e = err("scene s { body b { shape: sphere(radius: 1 cm)  mass: 1 kg  velocity ~ normal((1, 2) m/s, 1 m/s) } }",
            cls=PhysTypeError)
    assert "needs 3 numbers" in e.message


def test_errors_are_collected():
    e = err("scene s { body b { shape: sphere(radius: 1 kg)  mass: 1 m } body c { mas: 1 } }",
            cls=PhysErrors)
    assert len(e.errors) >= 3


def test_data_errors_name_file_row_column(tmp_path):
    (tmp_path / "d.csv").write_text("t,body,x,y,z\n0,b,0,0,0\n0.1,b,0,zz,0\n")
    e = err(f"scene s {{ body b {{ shape: sphere(radius: 1 cm)  mass: 1 kg }} "
            'observe b.position from "d.csv" where body == "b" { noise: 1 mm } }', tmp_path,
            physdsl.DataError)
    assert (e.row, e.column) == (3, "y") and e.file.endswith("d.csv")
