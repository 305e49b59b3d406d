"""Time stepping: one pure ``step(model, prm, state, t)`` by semi-implicit Euler or RK4.

Forces come from the registered effects; contact-free and compliant-contact accelerations use
the articulated-body algorithm; the LCP contact model needs M (CRBA) and the bias (RNEA).
RK4 is only used without contacts (contacts are non-smooth, so scenes with contact candidates
fall back to semi-implicit Euler; ``Simulator.integrator`` says which one runs).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import contact_stage as cs
from .dynamics import bias_forces, forward_dynamics, mass_matrix
from .effects import EFFECTS, Ctx
from .kinematics import forward_kinematics, integrate_q
from .model import Model


class State(NamedTuple):
    q: jnp.ndarray  # (nq,)
    v: jnp.ndarray  # (nv,)
    contact_force: jnp.ndarray  # (C,) normal force of the last step
    contact_normal: jnp.ndarray  # (C, 3)


def total_gravity(model: Model, prm: dict):
    """Sum of the gravity effects' accelerations (zero without one): buoyancy's g."""
    g = jnp.zeros(3)
    for s in model.sites:
        if s.effect == "gravity":
            g = g + prm["effects"][s.index]["acceleration"]
    return g


def applied_forces(model: Model, prm: dict, kin, state: State, t, t_step):
    """Sum of the generalized forces of every force-stage effect."""
    ctx = Ctx(kin, prm, t, t_step, total_gravity(model, prm), state.contact_force,
              state.contact_normal)
    tau = jnp.zeros(model.nv, dtype=kin.v.dtype)
    for s in model.sites:
        eff = EFFECTS[s.effect]
        if eff.stage == "force":
            tau = tau + eff.force(model, s, prm["effects"][s.index], ctx)
    return tau


def _accel(model, prm, q, v, state, t, t_step):
    """Joint accelerations (ABA), with compliant contact forces if any; and contact outputs."""
    kin = forward_kinematics(model, prm, q, v)
    tau = applied_forces(model, prm, kin, state, t, t_step)
    cf, cn = state.contact_force, state.contact_normal
    if model.ncon:
        con = cs.detect_all(model, prm, kin)
        tau_c, cf = cs.compliant_tau(model, con, mass_matrix(model, kin), v)
        tau = tau + tau_c
        cn = con.normal
    return forward_dynamics(model, kin, tau), cf, cn


def step(model: Model, prm: dict, state: State, t, h):
    """Advance ``state`` from time t by h (one substep)."""
    q, v = state.q, state.v
    if model.ncon and model.contact_model == "lcp":
        kin = forward_kinematics(model, prm, q, v)
        tau = applied_forces(model, prm, kin, state, t, t)
        M = mass_matrix(model, kin)
        v_free = v + h * jnp.linalg.solve(M, tau - bias_forces(model, kin))
        con = cs.detect_all(model, prm, kin)
        v_next, cf = cs.lcp_velocity(model, con, M, v, v_free, h)
        return State(integrate_q(model, q, v_next, h), v_next, cf, con.normal)
    if model.integrator == "rk4" and not model.ncon:
        return _rk4(model, prm, state, t, h)
    a, cf, cn = _accel(model, prm, q, v, state, t, t)
    v_next = v + h * a
    return State(integrate_q(model, q, v_next, h), v_next, cf, cn)


_RK4_C = (0.0, 0.5, 0.5, 1.0)
_RK4_W = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)


def _rk4(model: Model, prm: dict, state: State, t, h):
    """Classic RK4 on (q, v), positions advanced on the manifold by stage velocities (as MuJoCo).

    Stage i evaluates a_i at (q (+) c_i h v_{i-1}, v + c_i h a_{i-1}); the four stages run in a
    scan so the dynamics are traced and compiled once.
    """
    q, v = state.q, state.v

    def stage(carry, cw):
        v_prev, a_prev, v_sum, a_sum = carry
        ci, wi = cw[0], cw[1]
        qi = integrate_q(model, q, v_prev, ci * h)
        vi = v + ci * h * a_prev
        ai, _, _ = _accel(model, prm, qi, vi, state, t + ci * h, t)
        return (vi, ai, v_sum + wi * vi, a_sum + wi * ai), None

    z = jnp.zeros_like(v)
    cw = jnp.array([_RK4_C, _RK4_W], dtype=v.dtype).T
    (_, _, v_avg, a_avg), _ = jax.lax.scan(stage, (v, z, z, z), cw)
    return State(integrate_q(model, q, v_avg, h), v + h * a_avg, state.contact_force,
                 state.contact_normal)
