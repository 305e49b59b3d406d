"""The horizon's terminal cost for a goal that is an equilibrium: the infinite-horizon LQR
cost-to-go ``e^T P e`` of the model linearised there (``P`` the discrete-time algebraic Riccati
solution), so a short horizon still pays for what its last state leaves to the future (a
double pendulum's slow cart drift). ``P`` depends on the physical unknowns: the controller
recomputes it after each refit.

The goal is an equilibrium when every joint has a hold term (its value the coordinate, zero
velocity) and some force keeps it there; ``e`` is the state's difference from it, a hinge's
as the chord ``2 sin(d / 2)`` as in the stage cost (periodic, the same near the goal).

The dynamics are linearised in motion: the mean of the Jacobians at every velocity ``+MOTION``
and ``-MOTION`` (m/s or rad/s). At rest a smoothed Coulomb friction (``tanh(v / 0.01)``) has
a slope of 100x its torque, a damping the moving system never feels: on the double cart-pole
it made the linearised upright look 4x slower to fall (0.05 vs 0.19 growth per period) than it
is. The two offsets cancel the velocity's own first-order effects (Coriolis terms).
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from . import ilqr
from .transition import Transition

NEWTON = 8  # Gauss-Newton steps for the force that holds the equilibrium
RESIDUAL = 1e-7  # largest state change per period (SI) for an equilibrium
MOTION = 0.2  # m/s or rad/s: the velocities the dynamics are linearised at (20x the smoothing)


@dataclass(frozen=True)
class Equilibrium:
    """The goal's state ``x`` (nx,), which coordinates are angles, and a jitted
    ``linearise(z, w) -> (f(x, w) - x, A, B, Q, R, S)`` of the model at unconstrained
    physical unknowns ``z`` and unconstrained force ``w``."""

    x: np.ndarray
    hinge: np.ndarray  # (nx,) bool: coordinate is an angle (its error is a chord)
    linearise: object


def equilibrium(tr: Transition, holds, stage, squash) -> Equilibrium | None:
    """The goal's equilibrium state when every joint has exactly one hold term, else None."""
    values = {}
    for h in holds:
        values.setdefault(h.joint, []).append(h.value)
    if set(values) != set(tr.joints) or any(len(v) != 1 for v in values.values()):
        return None
    n = len(tr.joints)
    x = np.concatenate([[values[j][0] for j in tr.joints], np.zeros(n)])
    hinge = np.concatenate([np.asarray(tr.hinges, bool), np.zeros(n, bool)])
    xs = jnp.asarray(x)

    @jax.jit
    def linearise(z, w):
        prm = tr.params(z)
        f = lambda x, w: tr.step(prm, x, squash(w))  # noqa: E731
        A, B = ilqr.jacobians(f, xs, w, jnp.concatenate([jnp.zeros(n), jnp.full(n, MOTION)]))
        Q = jax.hessian(stage, 0)(xs, w)
        R = jax.hessian(stage, 1)(xs, w)
        S = jax.jacfwd(jax.grad(stage, 0), 1)(xs, w)
        return f(xs, w) - xs, A, B, Q, R, S

    return Equilibrium(x, hinge, linearise)


def error(eq: Equilibrium, x):
    """The state's difference from the equilibrium, a hinge's as its chord."""
    d = x - eq.x
    return jnp.where(eq.hinge, 2.0 * jnp.sin(0.5 * d), d)


def value_matrix(eq: Equilibrium, z, nu: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(P, w*): the Riccati solution of the model at ``z`` linearised at the equilibrium and the
    force w* holding it; None where no force holds it or the pair (A, B) is not stabilisable."""
    w = np.zeros(nu)
    for _ in range(NEWTON):  # the holding force: least squares of the period's state change
        r, A, B, Q, R, S = (np.asarray(a) for a in eq.linearise(z, jnp.asarray(w)))
        if np.max(np.abs(r)) <= RESIDUAL:
            break
        w = w - np.linalg.lstsq(B, r, rcond=None)[0]
    else:
        return None
    try:
        P = scipy.linalg.solve_discrete_are(A, B, Q, R, s=S)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(P)):
        return None
    return 0.5 * (P + P.T), w


def lqr_gain(eq: Equilibrium, z, P, w) -> np.ndarray:
    """The LQR feedback K (nu, nx) of ``P``: w = w* - K e minimises the cost-to-go."""
    _, A, B, _, R, S = (np.asarray(a) for a in eq.linearise(z, jnp.asarray(w)))
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A + S.T)
