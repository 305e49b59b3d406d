"""Time stepping: one pure ``step(model, prm, state, t)`` by semi-implicit Euler or RK4.

Forces come from the registered effects; contact-free and compliant-contact accelerations use
the articulated-body algorithm; the LCP contact model needs M (CRBA) and the bias (RNEA).
RK4 is only used without contacts (contacts are non-smooth, so scenes with contact candidates
fall back to semi-implicit Euler; ``Simulator.integrator`` says which one runs).
"""
from __future__ import annotations

from typing import NamedTuple

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
        a1, _, _ = _accel(model, prm, q, v, state, t, t)
        v2 = v + 0.5 * h * a1
        a2, _, _ = _accel(model, prm, integrate_q(model, q, v, 0.5 * h), v2, state, t + 0.5 * h, t)
        v3 = v + 0.5 * h * a2
        a3, _, _ = _accel(model, prm, integrate_q(model, q, v2, 0.5 * h), v3, state, t + 0.5 * h, t)
        v4 = v + h * a3
        a4, _, _ = _accel(model, prm, integrate_q(model, q, v3, h), v4, state, t + h, t)
        v_next = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        q_next = integrate_q(model, q, (v + 2 * v2 + 2 * v3 + v4) / 6.0, h)
        return State(q_next, v_next, state.contact_force, state.contact_normal)
    a, cf, cn = _accel(model, prm, q, v, state, t, t)
    v_next = v + h * a
    return State(integrate_q(model, q, v_next, h), v_next, cf, cn)
