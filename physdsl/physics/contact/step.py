"""One velocity-level time step with contact and Coulomb friction, as an LCP.

The formulation of de Avila Belbute-Peres et al. (LCP poster): with contact impulses
lam_n (C,), friction impulses lam_t (C,F) on a polyhedral cone of F directions, and the
sliding speed gamma (C,),

    M v+ = M v_free + Jn^T lam_n + Jt^T lam_t
    a     = Jn v+ - b                   >= 0  _|_  lam_n >= 0    (non-penetration)
    sigma = Jt v+ + E gamma             >= 0  _|_  lam_t >= 0    (friction opposes sliding)
    zeta  = mu lam_n - E^T lam_t        >= 0  _|_  gamma >= 0    (inside the friction cone)

Eliminating v+ = v_free + M^-1 J^T lam leaves a standard LCP in z = (lam_n, lam_t, gamma),
solved by ``lcp.lcp_solve`` and differentiated implicitly there; v+ follows by plain JAX, so
gradients reach M, v_free, Jn, Jt, mu, e, vn_pre and dist. Scenes without any friction effect
pass F = 0 and the LCP holds the normal rows only (C unknowns instead of C (2 + F)).

The normal target b (velocity the contact must separate at, at least):
- impact (``impacts``): the free motion closes the gap within this step, approaching faster
  than half the ``restitution_threshold``. The step is split at the time of impact tau (linear
  in-step velocity, the semi-implicit Euler motion): restitution acts on the normal velocity at
  tau, the free acceleration on the rest of the step, and the gap at the end of the step is the
  one of that split motion (a position correction along the contact normals,
  ``position_velocity``). Without the split the bounce would happen at the start of whichever
  step crosses the surface, so trajectories would jump (by up to |v| h) as parameters move
  the impact across a step boundary, and gradients would miss the impact's timing;
- restitution fades in linearly between half and the whole threshold (resting contacts do not
  bounce, and the change is continuous);
- otherwise b = -dist/h for a gap ahead (speculative contact: may close it, not pass it) and
  b = -baumgarte dist/h for penetration (push out a fraction of the depth per step).
Contacts with active = False, and the friction rows of contacts with mu <= 0, are replaced by
decoupled rows z_i = 0 and contribute nothing (nor any gradient).
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from .. import dense
from .lcp import IP_SETTINGS, IPSettings, lcp_solve_warm


class LCPSettings(NamedTuple):
    """Contact-step settings (static). Velocities in m/s (or rad/s), times in s."""

    restitution_threshold: float = 0.05
    baumgarte: float = 0.2
    solver: IPSettings = IP_SETTINGS


LCP_SETTINGS = LCPSettings()
restitution_threshold = LCP_SETTINGS.restitution_threshold


class Impacts(NamedTuple):
    """Per contact: does it collide within the step, and the split motion's target and end gap."""

    active: jnp.ndarray   # (C,) bool
    target: jnp.ndarray   # (C,) normal velocity at the end of the step
    gap_end: jnp.ndarray  # (C,) gap at the end of the step


def impact_time(vn_pre, vn_free, dist, h):
    """Per contact: (time of contact tau in [0, h], normal velocity there, does the gap close
    within the step); 0 for a gap already closed.

    The normal velocity runs linearly from vn_pre to vn_free over the step; positions follow
    the semi-implicit Euler motion (gap d + h vn_free), so tau = d / -vn_free makes the split
    agree with the unsplit step at both ends of the step (tau = 0 and tau = h).
    """
    closes = dist + h * vn_free < 0
    approach = jnp.where(vn_free < 0, -vn_free, 1.0)
    tau = jnp.clip(jnp.where(closes, dist / approach, 0.0), 0.0, h)
    return tau, vn_pre + (vn_free - vn_pre) / h * tau, closes


def impacts(e, vn_pre, vn_free, dist, h, settings: LCPSettings = LCP_SETTINGS) -> Impacts:
    """Time-of-impact split of one step per contact (see module docstring and ``impact_time``)."""
    tau, v_hit, closes = impact_time(vn_pre, vn_free, dist, h)
    accel = (vn_free - vn_pre) / h
    half = 0.5 * settings.restitution_threshold
    fade = jnp.clip((-v_hit - half) / half, 0.0, 1.0)
    # rebound, then the free acceleration for the rest of the step; a rebound that the
    # acceleration brings back within the step ends resting on the surface (never through it)
    target = jnp.maximum(-e * fade * v_hit + accel * (h - tau), 0.0)
    return Impacts(closes & (v_hit < -half), target, (h - tau) * target)


def normal_target(hit: Impacts, dist, h, settings: LCPSettings = LCP_SETTINGS):
    """Least separating normal velocity b per contact, given its ``impacts`` (module docstring)."""
    gap = jnp.where(dist > 0, -dist / h, -settings.baumgarte * dist / h)
    return jnp.where(hit.active, hit.target, gap)


class ContactLCP(NamedTuple):
    """The assembled LCP w = A z + q and what maps its solution back to velocities."""

    A: jnp.ndarray        # (m, m), m = C (2 + F), or C without friction (F = 0)
    q: jnp.ndarray        # (m,)
    mask: jnp.ndarray     # (m,) bool, rows that take part
    minv_jt: jnp.ndarray  # (n, C + C F): M^-1 [Jn; Jt]^T
    delassus: jnp.ndarray  # (C + C F, C + C F): [Jn; Jt] M^-1 [Jn; Jt]^T
    hit: Impacts           # the step's impacts (targets and end gaps)


def build_lcp(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h,
              settings: LCPSettings = LCP_SETTINGS) -> ContactLCP:
    """Assemble the contact LCP of one step (masked rows decoupled as z_i = 0)."""
    C, F, n = Jt.shape
    active = jnp.asarray(active, bool)
    J = jnp.concatenate([Jn, Jt.reshape(C * F, n)], axis=0)
    minv_jt = dense.solve(M, J.T)
    delassus = J @ minv_jt
    hit = impacts(e, vn_pre, Jn @ v_free, dist, h, settings)
    b = normal_target(hit, dist, h, settings)
    if F == 0:
        A, q, mask = delassus, Jn @ v_free - b, active
    else:
        friction = active & (mu > 0)
        E = jnp.kron(jnp.eye(C), jnp.ones((F, 1)))  # (C F, C): sums the directions of a contact
        A = jnp.zeros((2 * C + C * F,) * 2, dtype=delassus.dtype)
        A = A.at[:C + C * F, :C + C * F].set(delassus)
        A = A.at[C:C + C * F, C + C * F:].set(E)
        A = A.at[C + C * F:, :C].set(jnp.diag(mu))
        A = A.at[C + C * F:, C:C + C * F].set(-E.T)
        q = jnp.concatenate([Jn @ v_free - b, Jt.reshape(C * F, n) @ v_free,
                             jnp.zeros(C, delassus.dtype)])
        mask = jnp.concatenate([active, jnp.repeat(friction, F), friction])
    A = jnp.where(mask[:, None] & mask[None, :], A, 0.0) + jnp.diag(jnp.where(mask, 0.0, 1.0))
    q = jnp.where(mask, q, 1.0)
    return ContactLCP(A, q, mask, minv_jt, delassus, hit)


class ContactStep(NamedTuple):
    """Result of one contact step."""

    v: jnp.ndarray           # (n,) velocity after the step
    lam_n: jnp.ndarray       # (C,) normal impulses (N s)
    lam_t: jnp.ndarray       # (C, F) friction impulses along the cone edges
    v_position: jnp.ndarray  # (n,) velocity that advances positions (v plus impact corrections)
    solution: tuple  # (z, w) of the LCP: the next step's warm start (``lcp_solve_warm``)


def position_velocity(lcp: ContactLCP, v_next, Jn, dist, active, h):
    """Velocity for the position update: ``v_next`` plus the impulse-free correction along the
    normals of impacting contacts that puts their end-of-step gap where the split motion has it.

    Solves D c = (gap_end - dist)/h - vn+ on impact rows (D = Jn M^-1 Jn^T, regularised for
    redundant contacts such as the corners of a box landing flat).
    """
    C = Jn.shape[0]
    hit = lcp.hit
    rows = hit.active & jnp.asarray(active, bool)
    want = jnp.where(rows, (hit.gap_end - dist) / h - Jn @ v_next, 0.0)
    D = lcp.delassus[:C, :C]
    ridge = 1e-12 * jnp.max(jnp.abs(jnp.diagonal(D))) + jnp.finfo(D.dtype).tiny
    D = jnp.where(rows[:, None] & rows[None, :], D, 0.0) + jnp.diag(jnp.where(rows, ridge, 1.0))
    c = dense.solve(D, want)
    return v_next + lcp.minv_jt[:, :C] @ jnp.where(rows, c, 0.0)


def lcp_size(C: int, F: int) -> int:
    """Rows of a step's LCP with C contacts and F friction directions each (``build_lcp``)."""
    return C * (2 + F) if F else C


def solve_lcp_step(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h,
                   settings: LCPSettings = LCP_SETTINGS, warm=None) -> ContactStep:
    """One contact step: velocity, impulses and the position-update velocity.

    Impulses (N s), not forces: lam_n = f_n h. Shapes: M (n,n) SPD, v_free (n,), Jn (C,n),
    Jt (C,F,n) (F = 0: frictionless), mu/e/vn_pre/dist/active (C,), h scalar. ``warm``: the
    last step's ``solution`` (the solver starts there, ``lcp_solve_warm``), or None.
    """
    C, F, _ = Jt.shape
    if C == 0:
        empty = jnp.zeros((0,), v_free.dtype)
        return ContactStep(v_free, empty, jnp.zeros((0, F), v_free.dtype), v_free,
                           (empty, empty))
    lcp = build_lcp(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h, settings)
    solution = lcp_solve_warm(lcp.A, lcp.q, warm, settings.solver)
    z = jnp.where(lcp.mask, solution[0], 0.0)
    v_next = v_free + lcp.minv_jt @ z[:C + C * F]
    v_pos = position_velocity(lcp, v_next, Jn, dist, active, h)
    return ContactStep(v_next, z[:C], z[C:C + C * F].reshape(C, F), v_pos, solution)
