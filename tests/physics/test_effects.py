"""Every effect at its strength's off value is exactly absent, with finite, correct gradients."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.errors import ModelError
from physdsl.expr import Ref
from physdsl.physics import build_model, build_simulator
from physdsl.physics.dynamics import generalized_forces
from physdsl.physics.effects import EFFECTS, Ctx
from physdsl.physics.integrate import total_gravity
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
    "joint_spring": ("hinge", {"stiffness": "s", "rest": 0.1}, 0.0, 2.0),
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


NAMES = sorted(CASES)


def uses_with_own_strengths():
    """(use, off, on) of every case, the strength of case i renamed to the unknown ``s{i}``."""
    out = []
    for i, name in enumerate(NAMES):
        use, off, on = use_for(name)
        params = {k: (Ref(f"s{i}") if v == Ref("s") else v) for k, v in use.params.items()}
        out.append((dataclasses.replace(use, params=params), off, on))
    return out


class AllEffects:
    """Every case in one scene (after the base gravity), compiled once: ``taus(values)`` is the
    (cases, nv) generalized force of each case's effect alone at the initial state."""

    def __init__(self):
        uses = uses_with_own_strengths()
        s = base([u for u, _, _ in uses])
        model = build_model(s)
        # a pretend contact of the (ball, bob) pair pressing with 3 N along z, for rolling resistance
        state = (jnp.full((model.ncon,), 3.0), jnp.tile(jnp.array([0.0, 0.0, 1.0]), (model.ncon, 1)))

        def taus(values):
            prm = evaluate_params(s, model, values)
            kin = forward_kinematics(model, prm, prm["q0"], prm["v0"])
            ctx = Ctx(kin, prm, jnp.asarray(0.1), jnp.asarray(0.1), total_gravity(model, prm), *state)
            return jnp.stack([
                generalized_forces(model, kin, EFFECTS[u.effect].force(
                    model, model.sites[1 + i], prm["effects"][1 + i], ctx))
                for i, (u, _, _) in enumerate(uses)])

        self.nv = model.nv
        self.taus = jax.jit(taus)
        self.off = {f"s{i}": jnp.asarray(off, float) for i, (_, off, _) in enumerate(uses)}
        self.on = {f"s{i}": jnp.asarray(on, float) for i, (_, _, on) in enumerate(uses)}
        self.at_off = np.asarray(self.taus(self.off))
        self.jac = jax.jit(jax.jacfwd(taus))(self.off)


@pytest.fixture(scope="module")
def all_effects():
    return AllEffects()


@pytest.mark.parametrize("name", NAMES)
def test_effect_off_is_absent_and_differentiable(all_effects, name):
    i, ae = NAMES.index(name), all_effects
    assert np.all(ae.at_off[i] == 0.0)  # exactly absent
    t_on = np.asarray(ae.taus({**ae.off, f"s{i}": ae.on[f"s{i}"]}))[i]
    if name != "rolling_resistance":  # needs contact rows (none here: no contact pair)
        assert np.abs(t_on).max() > 1e-6  # and it does something when on
    assert all(np.all(np.isfinite(np.asarray(j))) for j in ae.jac.values())


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_effect_gradient_at_off_matches_finite_differences(all_effects, name):
    """d(tau)/d(strength) at the off value against central finite differences."""
    i, ae = NAMES.index(name), all_effects
    key = f"s{i}"
    x0 = np.asarray(ae.off[key])
    eps = 1e-6 * max(1.0, float(np.abs(np.asarray(ae.on[key])).max()))
    jac = np.asarray(ae.jac[key][i]).reshape(ae.nv, -1)
    for k in range(x0.size):
        dx = np.zeros(x0.size)
        dx[k] = eps
        dx = dx.reshape(x0.shape)
        up = np.asarray(ae.taus({**ae.off, key: jnp.asarray(x0 + dx)}))[i]
        dn = np.asarray(ae.taus({**ae.off, key: jnp.asarray(x0 - dx)}))[i]
        np.testing.assert_allclose(jac[:, k], (up - dn) / (2 * eps), rtol=1e-6, atol=1e-8)


def test_all_effects_off_equal_no_effects_in_a_rollout():
    cases = [(i, u, off) for i, (n, (u, off, _)) in enumerate(zip(NAMES, uses_with_own_strengths()))
             if n != "gravity"]
    values = {f"s{i}": jnp.asarray(off, float) for i, _, off in cases}
    with_off = build_simulator(base([u for _, u, _ in cases])).simulate(values)
    plain = build_simulator(base()).simulate({})
    np.testing.assert_array_equal(np.asarray(with_off.q), np.asarray(plain.q))
    np.testing.assert_array_equal(np.asarray(with_off.v), np.asarray(plain.v))


def test_wrong_target_is_a_model_error():
    with pytest.raises(ModelError) as err:
        build_model(base([effect("joint_damping", "ball", coefficient=0.1)]))
    assert "joint" in err.value.hint


def test_quadratic_drag_derivative_rule_matches_finite_differences_and_is_zero_at_rest():
    from physdsl.physics.effects.quadratic_drag import speed_times

    v = jnp.array([[3.0, -1.5, 0.7], [0.2, 0.1, -4.0]])
    dv = jnp.array([[0.3, 0.8, -0.5], [-1.0, 0.4, 0.2]])
    _, tangent = jax.jvp(speed_times, (v,), (dv,))
    eps = 1e-6
    fd = (speed_times(v + eps * dv) - speed_times(v - eps * dv)) / (2 * eps)
    np.testing.assert_allclose(tangent, fd, rtol=1e-8, atol=1e-9)
    # |v| v = 0 at rest, and so is its derivative (a guard-free norm would give NaN here)
    out, tangent0 = jax.jvp(speed_times, (jnp.zeros((1, 3)),), (dv[:1],))
    assert np.all(out == 0.0) and np.all(tangent0 == 0.0)
    np.testing.assert_allclose(jax.jacfwd(lambda x: speed_times(x).sum())(v),
                               jax.jacrev(lambda x: speed_times(x).sum())(v), rtol=1e-12)
