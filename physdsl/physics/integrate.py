"""Time stepping: one pure ``step(model, prm, state, t, h)`` by semi-implicit Euler or RK4.

Effects give one summed Load per evaluation. Scenes of free bodies use the Newton-Euler fast
path (``free.py``); others tree kinematics and joint-space dynamics (``dynamics.py``). The LCP contact model
needs the mass matrix (CRBA, or block-diagonal for free bodies) and runs only when some
candidate is within the contact margin or closes its gap within the step (``lax.cond``; under
``vmap`` both branches run).
RK4 is only used without contacts (contacts are non-smooth, so scenes with contact candidates
fall back to semi-implicit Euler; ``Simulator.integrator`` says which one runs). In LCP scenes,
steps with no contact near advance positions by the mean of the old and new velocity (exact
under constant forces: a ball's flight between bounces has no O(h) lag), steps with contacts
by the contact step's position velocity (time-of-impact split, see ``contact.step``).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import contact_stage as cs
from .dynamics import forward_dynamics, generalized_forces, joint_space_accel, mass_matrix
from .effects import EFFECTS, Ctx, zero_load
from .free import free_accel, free_kinematics, free_mass_matrix
from .kinematics import forward_kinematics, integrate_q
from .model import Model


# trees with at most this many dofs: one Cholesky solve; larger: the articulated-body algorithm
JOINT_SPACE_MAX = 24


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


def applied_load(model: Model, prm: dict, kin, state: State, t, t_step):
    """Sum of the Loads of every force-stage effect."""
    ctx = Ctx(kin, prm, t, t_step, total_gravity(model, prm), state.contact_force,
              state.contact_normal)
    load = zero_load(model, kin.com.dtype)
    for s in model.sites:
        eff = EFFECTS[s.effect]
        if eff.stage == "force":
            load = load + eff.force(model, s, prm["effects"][s.index], ctx)
    return load


def kinematics(model: Model, prm: dict, q, v, with_jac: bool = False):
    """Kinematics by the free-body fast path when it applies, else over the tree."""
    if model.free_bodies is not None:
        return free_kinematics(model, prm, q, v, with_jac)
    return forward_kinematics(model, prm, q, v)


def accel(model: Model, prm: dict, kin, load, tau=None):
    """Joint accelerations under ``load`` plus extra generalized forces ``tau``."""
    if model.free_bodies is not None:
        return free_accel(model, prm, kin, load.force, load.torque,
                          load.joint if tau is None else load.joint + tau)
    gen = generalized_forces(model, kin, load)
    gen = gen if tau is None else gen + tau
    if model.nv <= JOINT_SPACE_MAX:
        return joint_space_accel(model, kin, gen)
    return forward_dynamics(model, kin, gen)


def joint_mass_matrix(model: Model, prm: dict, kin):
    """M (nv, nv) at the state of ``kin``."""
    if model.free_bodies is not None:
        return free_mass_matrix(model, prm, kin)
    return mass_matrix(model, kin)


def _accel(model, prm, q, v, state, t, t_step):
    """Accelerations with compliant contact forces if any; and the contact outputs."""
    kin = kinematics(model, prm, q, v, with_jac=bool(model.ncon))
    load = applied_load(model, prm, kin, state, t, t_step)
    cf, cn = state.contact_force, state.contact_normal
    tau = None
    if model.ncon:
        con = cs.detect_all(model, prm, kin)
        M = None if con.inv_mass is not None else joint_mass_matrix(model, prm, kin)
        tau, cf = cs.compliant_tau(model, con, M, v)
        cn = con.normal
    return accel(model, prm, kin, load, tau), cf, cn


def _lcp_step(model, prm, state, t, h):
    q, v = state.q, state.v
    kin = kinematics(model, prm, q, v, with_jac=True)
    load = applied_load(model, prm, kin, state, t, t)
    v_free = v + h * accel(model, prm, kin, load)
    con = cs.closing_within(cs.detect_all(model, prm, kin, v), v_free, h)

    def contact(_):
        return cs.lcp_velocity(model, con, joint_mass_matrix(model, prm, kin), v, v_free, h)

    def apart(_):  # free flight: positions by the trapezoid, exact under constant forces
        return v_free, 0.5 * (v + v_free), jnp.zeros(model.ncon, v.dtype)

    v_next, v_position, cf = jax.lax.cond(jnp.any(con.active), contact, apart, None)
    return State(integrate_q(model, q, v_position, h), v_next, cf, con.normal)


def step(model: Model, prm: dict, state: State, t, h):
    """Advance ``state`` from time t by h (one substep)."""
    if model.ncon and model.contact_model == "lcp":
        return _lcp_step(model, prm, state, t, h)
    if model.integrator == "rk4" and not model.ncon:
        return _rk4(model, prm, state, t, h)
    a, cf, cn = _accel(model, prm, state.q, state.v, state, t, t)
    v_next = state.v + h * a
    return State(integrate_q(model, state.q, v_next, h), v_next, cf, cn)


def _rk4(model: Model, prm: dict, state: State, t, h):
    """Classic RK4 on (q, v), positions advanced on the manifold by stage velocities (as MuJoCo).

    Stage i evaluates a_i at (q (+) c_i h v_{i-1}, v + c_i h a_{i-1}); the four stages are
    unrolled (an inner scan compiles no faster and costs loop overhead in every step).
    """
    q, v = state.q, state.v
    a1, _, _ = _accel(model, prm, q, v, state, t, t)
    v2 = v + 0.5 * h * a1
    a2, _, _ = _accel(model, prm, integrate_q(model, q, v, 0.5 * h), v2, state, t + 0.5 * h, t)
    v3 = v + 0.5 * h * a2
    a3, _, _ = _accel(model, prm, integrate_q(model, q, v2, 0.5 * h), v3, state, t + 0.5 * h, t)
    v4 = v + h * a3
    a4, _, _ = _accel(model, prm, integrate_q(model, q, v3, h), v4, state, t + h, t)
    v_avg = (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
    a_avg = (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
    return State(integrate_q(model, q, v_avg, h), v + h * a_avg, state.contact_force,
                 state.contact_normal)
