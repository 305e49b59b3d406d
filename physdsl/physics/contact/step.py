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
gradients reach M, v_free, Jn, Jt, mu, e, vn_pre and dist.

The normal target b (velocity the contact must separate at, at least):
- restitution: b = -e vn_pre when the contact approaches faster than
  ``restitution_threshold`` and closes within this step (dist + h vn_pre <= 0);
- gap: b = -dist/h for a gap ahead (speculative contact: may close it, not pass it) and
  b = -baumgarte dist/h for penetration (push out a fraction of the depth per step);
- b is the larger of the two when both apply, so restitution never adds the push-out energy.
Contacts with active = False, and the friction rows of contacts with mu <= 0, are replaced by
decoupled rows z_i = 0 and contribute nothing (nor any gradient).
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jax.scipy.linalg import cho_factor, cho_solve

from .lcp import IP_SETTINGS, IPSettings, lcp_solve


class LCPSettings(NamedTuple):
    """Contact-step settings (static). Velocities in m/s (or rad/s), times in s."""

    restitution_threshold: float = 0.05
    baumgarte: float = 0.2
    solver: IPSettings = IP_SETTINGS


LCP_SETTINGS = LCPSettings()
restitution_threshold = LCP_SETTINGS.restitution_threshold


def normal_target(e, vn_pre, dist, h, settings: LCPSettings = LCP_SETTINGS):
    """Least separating normal velocity b per contact (see module docstring)."""
    gap = jnp.where(dist > 0, -dist / h, -settings.baumgarte * dist / h)
    impact = (vn_pre < -settings.restitution_threshold) & (dist + h * vn_pre <= 0)
    return jnp.where(impact, jnp.maximum(-e * vn_pre, gap), gap)


class ContactLCP(NamedTuple):
    """The assembled LCP w = A z + q and what maps its solution back to velocities."""

    A: jnp.ndarray        # (m, m), m = C (2 + F)
    q: jnp.ndarray        # (m,)
    mask: jnp.ndarray     # (m,) bool, rows that take part
    minv_jt: jnp.ndarray  # (n, C + C F): M^-1 [Jn; Jt]^T


def build_lcp(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h,
              settings: LCPSettings = LCP_SETTINGS) -> ContactLCP:
    """Assemble the contact LCP of one step (masked rows decoupled as z_i = 0)."""
    C, F, n = Jt.shape
    active = jnp.asarray(active, bool)
    friction = active & (mu > 0)
    J = jnp.concatenate([Jn, Jt.reshape(C * F, n)], axis=0)
    minv_jt = cho_solve(cho_factor(M), J.T)
    delassus = J @ minv_jt
    E = jnp.kron(jnp.eye(C), jnp.ones((F, 1)))  # (C F, C): sums the directions of a contact
    A = jnp.zeros((2 * C + C * F,) * 2, dtype=delassus.dtype)
    A = A.at[:C + C * F, :C + C * F].set(delassus)
    A = A.at[C:C + C * F, C + C * F:].set(E)
    A = A.at[C + C * F:, :C].set(jnp.diag(mu))
    A = A.at[C + C * F:, C:C + C * F].set(-E.T)
    b = normal_target(e, vn_pre, dist, h, settings)
    q = jnp.concatenate([Jn @ v_free - b, Jt.reshape(C * F, n) @ v_free,
                         jnp.zeros(C, delassus.dtype)])
    mask = jnp.concatenate([active, jnp.repeat(friction, F), friction])
    A = jnp.where(mask[:, None] & mask[None, :], A, 0.0) + jnp.diag(jnp.where(mask, 0.0, 1.0))
    q = jnp.where(mask, q, 1.0)
    return ContactLCP(A, q, mask, minv_jt)


def solve_lcp_step(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h,
                   settings: LCPSettings = LCP_SETTINGS):
    """Velocity after one step with contact: returns (v_next (n,), lam_n (C,), lam_t (C,F)).

    Impulses (N s), not forces: lam_n = f_n h. Shapes: M (n,n) SPD, v_free (n,), Jn (C,n),
    Jt (C,F,n), mu/e/vn_pre/dist/active (C,), h scalar.
    """
    C, F, _ = Jt.shape
    if C == 0:
        return v_free, jnp.zeros((0,), v_free.dtype), jnp.zeros((0, F), v_free.dtype)
    lcp = build_lcp(M, v_free, Jn, Jt, mu, e, vn_pre, dist, active, h, settings)
    z = jnp.where(lcp.mask, lcp_solve(lcp.A, lcp.q, settings.solver), 0.0)
    impulses = z[:C + C * F]
    v_next = v_free + lcp.minv_jt @ impulses
    return v_next, z[:C], z[C:C + C * F].reshape(C, F)
