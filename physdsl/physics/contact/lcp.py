"""A primal-dual interior-point solver for the LCP  w = A z + q >= 0, z >= 0, z.w = 0.

An iteration budget (jit-friendly, with an early exit once converged) with Mehrotra
predictor-corrector centering, and an
implicit derivative: ``lcp_solve`` is a ``jax.custom_jvp`` whose tangent rule differentiates
the complementarity conditions at the solution (Amos & Kolter's OptNet / de Avila Belbute-Peres
et al.'s LCP engine) instead of unrolling the iterations; reverse mode transposes that rule.
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
from .. import dense


class IPSettings(NamedTuple):
    """Interior-point settings (static).

    iterations: Newton iterations, always all of them (no early exit, so one jit trace).
    step_fraction: fraction of the step to the boundary of the positive orthant.
    floor: smallest centering target z.w/m, relative to the problem's scale; keeps the
        Newton matrix nonsingular on degenerate problems (a pair with z = w = 0) once converged.
    implicit: differentiate implicitly at the solution (True) or by unrolling (False, for checks).
    tolerance: with ``implicit``, stop early once every complementarity product z_i w_i and
        every residual of w = A z + q is below it (normalised units): the implicit derivative
        does not depend on how the solution was reached, and most contact steps converge in
        a third of the iteration budget.
    warm_shift: a warm start (``lcp_solve_warm``: the last step's solution) is moved this far
        into the interior, relative to its largest entry, before the first iteration.
    restart: a warm start not converged after this many iterations starts again from ones.
    """

    iterations: int = 30
    tolerance: float = 1e-13
    step_fraction: float = 0.99
    floor: float = 1e-14
    implicit: bool = True
    warm_shift: float = 1e-8
    restart: int = 12


IP_SETTINGS = IPSettings()


def _scales(A, q):
    """Scales of z and w so that the normalised problem has entries of order one."""
    a_scale = jnp.maximum(jnp.max(jnp.abs(jnp.diagonal(A))), jnp.max(jnp.abs(A)) * 1e-3)
    a_scale = jnp.maximum(a_scale, jnp.finfo(A.dtype).tiny ** 0.5)
    q_scale = jnp.maximum(jnp.max(jnp.abs(q)), jnp.finfo(q.dtype).tiny ** 0.5)
    return jax.lax.stop_gradient(a_scale), jax.lax.stop_gradient(q_scale)


def _max_step(x, dx, fraction):
    """Largest alpha <= 1 keeping x + alpha dx > 0, shortened by ``fraction``."""
    ratio = jnp.where(dx < 0, -x / jnp.where(dx < 0, dx, -1.0), jnp.inf)
    return jnp.minimum(1.0, fraction * jnp.min(ratio, initial=jnp.inf))


def _interior_point(A, q, settings: IPSettings, warm=None):
    """Solve the LCP; returns (z, w) in the caller's units (unrollable when not implicit).
    ``warm``: a start (z, w) in the caller's units, e.g. the last step's solution; used where
    all its entries are positive (``lcp_solve_warm``), else the iteration starts from ones."""
    m = q.shape[0]
    a_scale, q_scale = _scales(A, q)
    An, qn = A / a_scale, q / q_scale  # z = zn q_scale / a_scale, w = wn q_scale
    floor = max(settings.floor, 1e-2 * float(jnp.finfo(An.dtype).eps))  # float32: 1.2e-9

    def body(_, zw):
        z, w = zw[:2]
        r = An @ z + qn - w
        mu = jnp.dot(z, w) / m
        # Newton on [A z + q - w; z w - target]: [A -I; W Z][dz; dw] = [-r; rhs]
        # ->  (W + Z A) dz = rhs - Z r,  dw = A dz + r. One factorisation, two solves.
        lu = dense.lu_factor(jnp.diag(w) + z[:, None] * An)

        def solve(rhs):
            dz = dense.lu_solve(lu, rhs - z * r)
            return dz, An @ dz + r

        dz_a, dw_a = solve(-z * w)
        alpha_a = jnp.minimum(_max_step(z, dz_a, 1.0), _max_step(w, dw_a, 1.0))
        mu_a = jnp.dot(z + alpha_a * dz_a, w + alpha_a * dw_a) / m
        sigma = jnp.clip(mu_a / jnp.maximum(mu, floor), 0.0, 1.0) ** 3
        target = jnp.maximum(sigma * mu, floor)
        dz, dw = solve(target - z * w - dz_a * dw_a)
        alpha = jnp.minimum(_max_step(z, dz, settings.step_fraction),
                            _max_step(w, dw, settings.step_fraction))
        z_new, w_new = z + alpha * dz, w + alpha * dw
        ok = jnp.all(jnp.isfinite(z_new)) & jnp.all(jnp.isfinite(w_new))
        return jnp.where(ok, z_new, z), jnp.where(ok, w_new, w)  # singular Newton matrix: stay

    ones = jnp.ones_like(qn)
    z0, w0, warmed = ones, ones, jnp.zeros((), bool)
    if warm is not None:  # the last solution, normalised and moved into the interior
        zw, ww = warm[0] * a_scale / q_scale, warm[1] / q_scale
        warmed = jnp.all(zw > 0) & jnp.all(ww > 0)
        z0 = jnp.where(warmed, zw + settings.warm_shift * jnp.max(zw), ones)
        w0 = jnp.where(warmed, ww + settings.warm_shift * jnp.max(ww), ones)
    if not settings.implicit:  # unrolled derivative: a fixed loop reverse mode can run through
        z, w = jax.lax.fori_loop(0, settings.iterations, body, (z0, w0))
        return z * q_scale / a_scale, w * q_scale

    def unfinished(state):
        z, w, i = state
        gap = jnp.max(z * w)
        resid = jnp.max(jnp.abs(An @ z + qn - w))
        return (i < settings.iterations) & ((gap > settings.tolerance) | (resid > settings.tolerance))

    def iterate(state):
        z, w, i = state
        # a warm start that has not converged by ``restart`` starts over from ones
        again = warmed & (i == settings.restart)
        z, w = body(None, (jnp.where(again, ones, z), jnp.where(again, ones, w)))
        return z, w, i + 1

    z, w, _ = jax.lax.while_loop(unfinished, iterate, (z0, w0, jnp.zeros((), jnp.int32)))
    return z * q_scale / a_scale, w * q_scale


@partial(jax.custom_jvp, nondiff_argnums=(3,))
def _lcp_implicit(A, q, warm, settings):
    return _interior_point(A, q, settings, warm)


@_lcp_implicit.defjvp
def _lcp_jvp(settings, primals, tangents):
    # At the solution F = [A z + q - w; z * w] = 0. Eliminating dw gives
    # (Z A + W) dz = -Z (dA z + dq): one linear solve, linear in the tangents, so reverse mode
    # is its transpose (dL/dq = -Z u, dL/dA = -Z u z^T with (Z A + W)^T u = g). The warm
    # start takes no part: the solution does not depend on where the iteration began.
    A, q, warm = primals
    dA, dq, _ = tangents
    z, w = _interior_point(A, q, settings, warm)
    dz = dense.solve(z[:, None] * A + jnp.diag(w), -z * (dA @ z + dq))
    return (z, w), (dz, dA @ z + A @ dz + dq)


def lcp_solve(A, q, settings: IPSettings = IP_SETTINGS):
    """z >= 0 with w = A z + q >= 0 and z.w = 0 (approximately, to the barrier floor)."""
    return lcp_solve_warm(A, q, None, settings)[0]


def lcp_solve_warm(A, q, warm, settings: IPSettings = IP_SETTINGS):
    """(z, w) of ``lcp_solve``, the iteration started from ``warm`` = (z, w) (the last step's
    solution: a resting or rolling contact's LCP changes little from step to step; None or
    any entry not positive: from ones). Where the solution is not unique (a friction pyramid's
    opposite edges both at zero slip) another start may end at another solution with the same
    net impulses; the derivative is taken at the one reached."""
    if q.shape[0] == 0:
        return q, q
    if warm is not None:
        warm = tuple(jax.lax.stop_gradient(x) for x in warm)
    if settings.implicit:
        return _lcp_implicit(A, q, warm, settings)
    return _interior_point(A, q, settings, warm)


def lcp_residual(A, q, z):
    """Natural-map residual max |min(z, A z + q)|: zero exactly at an LCP solution."""
    return jnp.max(jnp.abs(jnp.minimum(z, A @ z + q)), initial=0.0)
