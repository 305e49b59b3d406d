"""Time stepping: one pure ``step(model, prm, state, t, h)`` by semi-implicit Euler or RK4.

Effects give one summed Load per evaluation. Scenes of free bodies use the Newton-Euler fast
path (``free.py``); jointed trees the vectorised kinematics and dynamics of ``tree.py`` (the
recursive ones of ``kinematics.py``/``dynamics.py`` above ``tree.TREE_MAX`` dofs). The LCP contact model
needs the mass matrix (CRBA, or block-diagonal for free bodies) and runs only when some
candidate is within the contact margin or closes its gap within the step (``lax.cond``; under
``vmap`` both branches run).
A scene with contacts keeps its integrator between contacts: each step with no contact near
is the integrator's step without contact forces (RK4; or semi-implicit Euler with positions
by the mean of the old and new velocity, exact under constant forces), a step with a
contact near is the velocity-level contact step (LCP with its time-of-impact split, see
``contact.step``; compliant: semi-implicit Euler with the penalty forces). So a contact that
never comes near leaves an RK4 rollout exactly as it is without the contact pair. A step in
which a gap closes (none closed already) is split there: the scene's integrator up to it, then
the LCP step from the configuration at impact (its normals and lever arms; taken at the
step's start they are off by O(h): a ball at 3 m/s 1 ms from a 4.5 cm capsule-sphere contact
hits it along a normal up to ~4 degrees from the one at the step's start).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import contact_stage as cs
from . import tree, welds
from . import contact as cm
from .contact_models import CONTACT_MODELS, contact_model
from .dynamics import forward_dynamics, generalized_forces, mass_matrix
from .effects import EFFECTS, Ctx, zero_load
from .free import free_accel, free_kinematics, free_mass_matrix
from .kinematics import forward_kinematics, integrate_q
from .structure import PhysicsModel


IMPACT_GAP = 1e-3  # fraction of a step: contacts closing nearer its start or end than this are
# left to the LCP step's own time-of-impact split (no advance; no remainder of near-zero length)


class State(NamedTuple):
    q: jnp.ndarray  # (nq,)
    v: jnp.ndarray  # (nv,)
    contact_force: jnp.ndarray  # (C,) normal force of the last step
    contact_normal: jnp.ndarray  # (C, 3)
    # LCP scenes: (z, w) of the last contact step's LCP, the next one's warm start (zeros:
    # none, after a step with no contact near); None elsewhere
    lcp_warm: tuple | None = None


def start_state(model: PhysicsModel, q, v) -> State:
    """The state at (q, v) before any step: no contact force, no warm start yet."""
    C = model.ncon
    warm = None
    if C and model.contact_model == "lcp":
        warm = (jnp.zeros(cs.lcp_rows(model), q.dtype),) * 2
    return State(q, v, jnp.zeros(C, q.dtype), jnp.zeros((C, 3), q.dtype), warm)


def total_gravity(model: PhysicsModel, prm: dict):
    """Sum of the gravity effects' accelerations (zero without one): buoyancy's g."""
    g = jnp.zeros(3)
    for s in model.sites:
        if s.effect == "gravity":
            g = g + prm["effects"][s.index]["acceleration"]
    return g


def applied_load(model: PhysicsModel, prm: dict, kin, state: State, t, t_step):
    """Sum of the Loads of every force-stage effect."""
    ctx = Ctx(kin, prm, t, t_step, total_gravity(model, prm), state.contact_force,
              state.contact_normal)
    load = zero_load(model, kin.com.dtype)
    for s in model.sites:
        eff = EFFECTS[s.effect]
        if eff.stage == "force":
            load = load + eff.force(model, s, prm["effects"][s.index], ctx)
    return load


def kinematics(model: PhysicsModel, prm: dict, q, v, with_jac: bool = False):
    """Kinematics by the free-body fast path when it applies, else over the tree (over its core
    bodies where bodies are welded to moving ones: ``welds``)."""
    if model.free_bodies is not None:
        return free_kinematics(model, prm, q, v, with_jac)
    fused = welds.fuse(model)
    if fused is None:
        return _tree_kinematics(model, prm, q, v)
    return welds.expand(fused, prm, _tree_kinematics(fused.core, prm["core"], q, v))


def _tree_kinematics(model: PhysicsModel, prm: dict, q, v):
    if tree.applies(model):
        return tree.tree_kinematics(model, prm, q, v)
    return forward_kinematics(model, prm, q, v)


def accel(model: PhysicsModel, prm: dict, kin, load, tau=None):
    """Joint accelerations under ``load`` plus extra generalized forces ``tau``."""
    if model.free_bodies is not None:
        return free_accel(model, prm, kin, load.force, load.torque,
                          load.joint if tau is None else load.joint + tau)
    if kin.core is not None:
        fused = welds.fuse(model)
        model, kin, load = fused.core, kin.core, welds.core_load(fused, kin, load)
    if tree.applies(model):
        return tree.tree_accel(model, kin, load, tau)
    gen = generalized_forces(model, kin, load)
    gen = gen if tau is None else gen + tau
    return forward_dynamics(model, kin, gen)


def joint_mass_matrix(model: PhysicsModel, prm: dict, kin):
    """M (nv, nv) at the state of ``kin``."""
    if model.free_bodies is not None:
        return free_mass_matrix(model, prm, kin)
    if kin.core is not None:
        model, kin = welds.fuse(model).core, kin.core
    if tree.applies(model):
        return tree.tree_mass_matrix(model, kin)
    return mass_matrix(model, kin)


def _accel(model, prm, q, v, state, t, t_step):
    """Accelerations at (q, v) under the applied loads alone (no contact forces)."""
    kin = kinematics(model, prm, q, v)
    return accel(model, prm, kin, applied_load(model, prm, kin, state, t, t_step))


def _flight(model, prm, state, t, h, a1, v_free):
    """The step of the scene's integrator with no contact near: RK4 (its first stage ``a1`` given),
    or, under semi-implicit Euler, positions by the trapezoid of v and ``v_free`` (exact under
    constant forces: a ball's flight between bounces has no O(h) lag)."""
    if model.integrator == "rk4":
        return _rk4(model, prm, state, t, h, a1)
    return state._replace(q=integrate_q(model, state.q, 0.5 * (state.v + v_free), h), v=v_free)


def either(near, contact, apart, operand, forward_only: bool):
    """``contact(operand)`` where ``near``, else ``apart(operand)``: ``lax.cond``; with
    ``forward_only``, a while loop of at most one trip over ``contact`` after ``apart``. Under
    ``vmap`` (chains) a cond with a batched predicate runs both branches every time; the loop
    runs ``contact`` only where some member needs it, so a contact that never comes near costs
    its detection alone. The operand passes a barrier tied to the loop's flag, or XLA would
    hoist ``contact`` (invariant in the loop) out of the loop and run it always. A while loop
    has no reverse-mode derivative: only where differentiated in forward mode
    (``simulator.forward_mode``)."""
    if not forward_only:
        return jax.lax.cond(near, contact, apart, operand)

    def body(c):
        _, x = jax.lax.optimization_barrier((c[0], operand))
        return jnp.zeros_like(near), contact(x)

    return jax.lax.while_loop(lambda c: c[0], body, (near, apart(operand)))[1]


@contact_model("lcp")
def _lcp_step(model, prm, state, t, h, forward_only=False):
    """The LCP contact step where some candidate is within reach (``cs.closing_within``), else
    the scene's integrator without contact forces (``_flight``), by ``either``."""
    q, v = state.q, state.v
    kin = kinematics(model, prm, q, v, with_jac=True)
    load = applied_load(model, prm, kin, state, t, t)
    a = accel(model, prm, kin, load)
    v_free = v + h * a
    con = cs.closing_within(cs.detect_all(model, prm, kin, v), v_free, h)

    def lcp(o, t0, hh):
        """The LCP step of length ``hh`` from time ``t0`` and the state and contacts of ``o``.
        RK4 scenes: the LCP's impulse first, then RK4 over the step (exactly RK4 where the
        impulse is zero, as while a ball leaves a link within the contact margin), then the
        impact's position correction; else the LCP's semi-implicit Euler step itself."""
        prm, q, v, kin, con, v_free = o
        v_next, v_position, cf, solution = cs.lcp_velocity(
            model, con, joint_mass_matrix(model, prm, kin), v, v_free, hh, state.lcp_warm)
        if model.integrator == "rk4":
            s = _rk4(model, prm, state._replace(q=q, v=v + (v_next - v_free)), t0, hh)
            q_next, v_next = integrate_q(model, s.q, v_position - v_next, hh), s.v
        else:
            q_next = integrate_q(model, q, v_position, hh)
        # the start only: no derivative flows through it (nor a tangent carried for it)
        warm = None if state.lcp_warm is None else tuple(jax.lax.stop_gradient(x)
                                                         for x in solution)
        return State(q_next, v_next, cf * (hh / h), con.normal, warm)

    # The scene's integrator up to the first time a gap closes (tau), or over the whole step
    # where no contact is near (tau = h): one copy of it, outside the branch, for both (the
    # contact branch used to hold a second copy). Unsplit where some contact is closed
    # already (it may carry a load and friction that a contact-free advance would drop).
    near = jnp.any(con.active)
    tau, _, closes = cm.impact_time(con.Jn @ v, con.Jn @ v_free, con.dist, h)
    closes = closes & con.active
    tau = jnp.minimum(jnp.min(jnp.where(closes, tau, h), initial=h), (1.0 - IMPACT_GAP) * h)
    split = jnp.any(closes) & (tau > IMPACT_GAP * h) & ~jnp.any(con.active & (con.dist <= 0))
    # (an advance by 0 where a contact is near and the step is not split: the same step)
    tau = jnp.where(near, jnp.where(split, tau, 0.0), h)
    s = _flight(model, prm, state, t, tau, a, v + tau * a)

    def contact(o):
        """The LCP step for the rest of the step from the state at the first impact: the
        impulse acts along the normals and lever arms of the bodies where they touch. An
        unsplit step starts where this step does (tau = 0): its kinematics, free velocity and
        contacts are those above, not computed again (a resting or rolling contact's every
        step; only an impact's split step needs them at tau)."""
        s, tau = o

        def at_impact(s):
            kin2 = kinematics(model, prm, s.q, s.v, with_jac=True)
            a2 = accel(model, prm, kin2, applied_load(model, prm, kin2, s, t + tau, t))
            v_free2 = s.v + (h - tau) * a2
            return kin2, cs.closing_within(cs.detect_all(model, prm, kin2, s.v), v_free2,
                                           h - tau), v_free2

        kin2, con2, v_free2 = jax.lax.cond(split, at_impact, lambda s: (kin, con, v_free), s)
        return lcp((prm, s.q, s.v, kin2, con2, v_free2), t + tau, h - tau)

    def apart(o):
        warm = state.lcp_warm
        cold = None if warm is None else tuple(jnp.zeros_like(x) for x in warm)
        return State(o[0].q, o[0].v, jnp.zeros(model.ncon, v.dtype), con.normal, cold)

    return either(near, contact, apart, (s, tau), forward_only)


@contact_model("compliant")
def _compliant_step(model, prm, state, t, h, forward_only=False):
    """Semi-implicit Euler with penalty contact forces where some candidate is within the
    contact margin; else (RK4 scenes) RK4 without contact forces, which are zero there."""
    q, v = state.q, state.v
    kin = kinematics(model, prm, q, v, with_jac=True)
    load = applied_load(model, prm, kin, state, t, t)
    con = cs.detect_all(model, prm, kin)

    def contact(o):
        prm, q, v, kin, con, load = o
        if con.inv_mass is not None:  # free bodies: forces on the bodies, no contact Jacobian
            extra, cf = cs.compliant_load(model, kin, con, h)
            v_next = v + h * accel(model, prm, kin, load + extra)
        else:
            tau, cf = cs.compliant_tau(model, con, joint_mass_matrix(model, prm, kin), v, h)
            v_next = v + h * accel(model, prm, kin, load, tau)
        return State(integrate_q(model, q, v_next, h), v_next, cf, con.normal)

    operand = (prm, q, v, kin, con, load)
    if model.integrator != "rk4":
        return contact(operand)

    def apart(o):
        s = _rk4(model, prm, state, t, h, accel(model, prm, kin, load))
        return State(s.q, s.v, jnp.zeros(model.ncon, v.dtype), con.normal)

    return either(jnp.any(con.active), contact, apart, operand, forward_only)


def step(model: PhysicsModel, prm: dict, state: State, t, h, forward_only: bool = False):
    """Advance ``state`` from time t by h (one substep); ``forward_only``: the rollout is
    differentiated in forward mode alone (contact steps skipped under vmap, ``either``)."""
    if model.ncon:
        return CONTACT_MODELS[model.contact_model](model, prm, state, t, h, forward_only)
    if model.integrator == "rk4":
        return _rk4(model, prm, state, t, h)
    v_next = state.v + h * _accel(model, prm, state.q, state.v, state, t, t)
    return state._replace(q=integrate_q(model, state.q, v_next, h), v=v_next)


def _rk4(model: PhysicsModel, prm: dict, state: State, t, h, a1=None):
    """Classic RK4 on (q, v), positions advanced on the manifold by stage velocities (as MuJoCo);
    contact forces take no part (``step`` calls it only with no contact near).

    Stage i evaluates a_i at (q (+) c_i h v_{i-1}, v + c_i h a_{i-1}); the four stages are
    unrolled (an inner scan compiles no faster and costs loop overhead in every step). ``a1``:
    the first stage when the caller has it already.
    """
    q, v = state.q, state.v
    if a1 is None:
        a1 = _accel(model, prm, q, v, state, t, t)
    v2 = v + 0.5 * h * a1
    a2 = _accel(model, prm, integrate_q(model, q, v, 0.5 * h), v2, state, t + 0.5 * h, t)
    v3 = v + 0.5 * h * a2
    a3 = _accel(model, prm, integrate_q(model, q, v2, 0.5 * h), v3, state, t + 0.5 * h, t)
    v4 = v + h * a3
    a4 = _accel(model, prm, integrate_q(model, q, v3, h), v4, state, t + h, t)
    v_avg = (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
    a_avg = (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
    return state._replace(q=integrate_q(model, q, v_avg, h), v=v + h * a_avg)
