"""Every effect at its strength's off value is exactly absent, with finite, correct gradients."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.errors import ModelError
from physdsl.physics import build_model, build_simulator
from physdsl.physics.effects import EFFECTS
from physdsl.physics.dynamics import generalized_forces
from physdsl.physics.kinematics import forward_kinematics
from physdsl.physics.params import evaluate_params
from physdsl.scene import Joint
from scenes import c, e, effect, gravity, scene, sphere

TIMES = np.array([0.0, 0.5, 1.0])

# effect -> (target, params with the strength as unknown "s", off value, an "on" value)
CASES = {
    "gravity": ("world", {"acceleration": "s"}, np.zeros(3), np.array([0.1, -0.2, -9.8])),
    "linear_drag": ("ball", {"coefficient": "s"}, 0.0, 0.3),
    "quadratic_drag": ("ball", {"coefficient": "s"}, 0.0, 0.02),
    "wind": ("ball", {"velocity": "s", "coefficient": 0.005}, np.zeros(3), np.array([3.0, 1.0, 0.0])),
    "buoyancy": ("ball", {"fluid_density": "s"}, 0.0, 1000.0),
    "magnus": ("ball", {"coefficient": "s"}, 0.0, 0.01),
    "spring": (("ball", "bob"), {"stiffness": "s", "rest_length": 0.1, "anchor": (0.01, 0.02, 0.03),
                                 "attachment": (0.0, 0.01, 0.0)}, 0.0, 20.0),
    "spring@world": ("ball", {"stiffness": "s", "rest_length": 0.0, "anchor": (0.0, 0.0, 1.0),
                              "attachment": (0.0, 0.0, 0.0)}, 0.0, 20.0),
    "damper": (("ball", "bob"), {"coefficient": "s", "anchor": (0.0, 0.0, 0.0),
                                 "attachment": (0.0, 0.0, 0.05)}, 0.0, 0.5),
    "joint_damping": ("hinge", {"coefficient": "s"}, 0.0, 0.2),
    "joint_friction": ("hinge", {"torque": "s", "smoothing": 0.01}, 0.0, 0.1),
    # torque keeps its default 0: the strength (force) alone cannot switch a torque off
    "constant_force": ("ball", {"force": "s", "torque": (0.0, 0.0, 0.0)}, np.zeros(3), np.array([1.0, 2.0, 3.0])),
    "control_force": ("hinge", {"gain": "s"}, 0.0, 1.0),
    "control_force@body": ("ball", {"gain": "s"}, 0.0, 1.0),
    "rolling_resistance": (("ball", "bob"), {"coefficient": "s"}, 0.0, 0.01),
}


def base(extra=()):
    ball = sphere("ball", 0.1, 0.5, (0.3, 0.1, 1.0), vel=(1.0, -2.0, 0.5), angvel=(3.0, 1.0, -2.0))
    bob = sphere("bob", 0.05, 0.3, (0.0, 0.0, 0.4))
    j = Joint("hinge", "hinge", "world", "bob", axis=c((0, 1, 0)), anchor=c((0, 0, 1.0)),
              initial=e(0.4), initial_velocity=e(1.5))
    return scene([ball, bob], [j], [gravity(), *extra], dt=1e-3, duration=0.02)


def use_for(name):
    target, params, off, on = CASES[name]
    eff = name.split("@")[0]
    tables = {}
    if eff == "control_force":
        vals = np.array([[1.0, 2.0, 3.0]] * 3) if target == "ball" else np.array([0.5, -0.3, 0.2])
        tables = {"times": TIMES, "values": vals}
    return effect(eff, target if isinstance(target, tuple) else target, tables=tables, **params), off, on


def tau_of(scene_, k, values, state):
    model = build_model(scene_)
    prm = evaluate_params(scene_, model, values)
    kin = forward_kinematics(model, prm, prm["q0"], prm["v0"])
    load = EFFECTS[scene_.effects[k].effect].force(model, model.sites[k], prm["effects"][k],
                                                   _ctx(model, prm, kin, state))
    return generalized_forces(model, kin, load)


def _ctx(model, prm, kin, state):
    from physdsl.physics.effects import Ctx
    from physdsl.physics.integrate import total_gravity
    return Ctx(kin, prm, jnp.asarray(0.1), jnp.asarray(0.1), total_gravity(model, prm), *state)


@pytest.mark.parametrize("name", sorted(CASES))
def test_effect_off_is_absent_and_differentiable(name):
    check_effect(name, fd=False)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_effect_gradient_at_off_matches_finite_differences(name):
    check_effect(name, fd=True)


def check_effect(name, fd):
    use, off, on = use_for(name)
    s = base([use])
    k = len(s.effects) - 1
    # a pretend contact of the (ball, bob) pair pressing with 3 N along z, for rolling resistance
    model = build_model(s)
    state = (jnp.full((model.ncon,), 3.0), jnp.tile(jnp.array([0.0, 0.0, 1.0]), (model.ncon, 1)))
    f = jax.jit(lambda x: tau_of(s, k, {"s": x}, state))
    t_off = f(jnp.asarray(off, float))
    assert np.all(np.asarray(t_off) == 0.0)  # exactly absent
    t_on = f(jnp.asarray(on, float))
    if name != "rolling_resistance":  # needs contact rows (none here: no contact pair)
        assert np.abs(np.asarray(t_on)).max() > 1e-6  # and it does something when on
    J = jax.jacfwd(f)(jnp.asarray(off, float))
    assert np.all(np.isfinite(np.asarray(J)))
    if not fd:
        return
    # gradient at the off value matches central finite differences
    x0 = np.asarray(off, float)
    eps = 1e-6 * max(1.0, float(np.abs(on).max()))
    for i in range(x0.size):
        dx = np.zeros(x0.size)
        dx[i] = eps
        dx = dx.reshape(x0.shape)
        fd = (np.asarray(f(jnp.asarray(x0 + dx))) - np.asarray(f(jnp.asarray(x0 - dx)))) / (2 * eps)
        jac_i = np.asarray(J).reshape(model.nv, -1)[:, i]
        np.testing.assert_allclose(jac_i, fd, rtol=1e-6, atol=1e-8)


def test_all_effects_off_equal_no_effects_in_a_rollout():
    uses = [use_for(n) for n in sorted(CASES) if n != "gravity"]
    values = {f"s{i}": jnp.asarray(off, float) for i, (_, off, _) in enumerate(uses)}
    renamed = []
    for i, (u, _, _) in enumerate(uses):
        from physdsl.expr import Ref
        renamed.append(type(u)(u.effect, u.target, {k: (Ref(f"s{i}") if v == Ref("s") else v)
                                                    for k, v in u.params.items()}, u.tables))
    with_off = build_simulator(base(renamed)).simulate(values)
    plain = build_simulator(base()).simulate({})
    np.testing.assert_array_equal(np.asarray(with_off.q), np.asarray(plain.q))
    np.testing.assert_array_equal(np.asarray(with_off.v), np.asarray(plain.v))


def test_wrong_target_is_a_model_error():
    with pytest.raises(ModelError) as err:
        build_model(base([effect("joint_damping", "ball", coefficient=0.1)]))
    assert "joint" in err.value.hint
