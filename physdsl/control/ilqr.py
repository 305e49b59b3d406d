"""iLQR (iterative linear-quadratic regulator) over a horizon, pure JAX: the plan ``W`` (H, m)
that lowers ``sum_k stage(x_k, w_k) + final(x_H)`` along ``x_{k+1} = f(x_k, w_k)``.

Each iteration linearises ``f`` along the current trajectory (``jacfwd``, one batched
call), takes second-order expansions of the costs, runs the Riccati backward pass, and
rolls the feedback policy forward at several step lengths at once (``vmap``), keeping the
cheapest finite one if it beats the unchanged plan (so the cost never rises, and a step that
overflows is never taken). The whole solve is one
traced function of (x0, W, params): a receding-horizon controller compiles it once and
warm-starts each step from the previous plan shifted by one. Given that plan's trajectory as
well (``guess``), the first iteration linearises along it instead of rolling the plan out
again from the new state, and its forward passes (step length 0 included: the old plan with
the feedback's correction) start from the new state: one sequential rollout per iteration.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

STEP_LENGTHS = (1.0, 0.5, 0.25, 0.1, 0.03)
REGULARISATION = 1e-6  # added to the control Hessian (after shifting it positive definite)


def rollout(f, x0, W):
    """States (H + 1, n) from ``x0`` under the plan ``W`` (H, m)."""
    def body(x, w):
        x1 = f(x, w)
        return x1, x1

    _, xs = jax.lax.scan(body, x0, W)
    return jnp.concatenate([x0[None], xs])


def total_cost(stage, final, X, W):
    return jnp.sum(jax.vmap(stage)(X[:-1], W)) + final(X[-1])


def screen(f, stage, final, x0, W, candidates):
    """The cheapest of the plan ``W`` and the ``candidates`` (C, H, m), rolled out in one batch
    from ``x0``, and its trajectory (a warm start for ``solve``): a local method started where
    the cost is flat or at its top (a pole hanging at rest) has no slope to follow; a candidate
    that already swings gives it one."""
    plans = jnp.concatenate([W[None], candidates])
    Xs = jax.vmap(lambda w: rollout(f, x0, w))(plans)
    costs = jax.vmap(lambda X, w: total_cost(stage, final, X, w))(Xs, plans)
    best = jnp.argmin(jnp.where(jnp.isfinite(costs), costs, jnp.inf))
    return plans[best], Xs[best]


def jacobians(f, x, w, motion=None):
    """(A, B) = the Jacobians of ``f(x, w)`` in one forward-mode pass; with ``motion`` (n,) the
    mean of those at ``x + motion`` and ``x - motion`` (linearised in motion: a smoothed
    Coulomb friction's steep slope at rest is a damping the moving system never feels)."""
    n = x.shape[0]

    def at(x):
        AB = jax.jacfwd(lambda xw: f(xw[:n], xw[n:]))(jnp.concatenate([x, w]))
        return AB[:, :n], AB[:, n:]

    if motion is None:
        return at(x)
    (A1, B1), (A2, B2) = at(x + motion), at(x - motion)
    return 0.5 * (A1 + A2), 0.5 * (B1 + B2)


def _positive(Q):
    """``Q`` with its eigenvalues replaced by their absolute values, plus the regularisation
    (saddle-free Newton): where the cost curves down (a pole hanging at the top of its cost),
    the step still goes downhill with a size set by that curvature, where shifting every
    eigenvalue to ~0 made it huge and saturated the forces."""
    lam, vec = jnp.linalg.eigh(Q)
    return (vec * jnp.abs(lam)) @ vec.T + REGULARISATION * jnp.eye(Q.shape[0], dtype=Q.dtype)


def _backward(f, stage, final, X, W, motion=None):
    """Feedforward steps k (H, m) and gains K (H, m, n) of the Riccati pass; the dynamics'
    Jacobians by ``jacobians`` (with ``motion``: linearised in motion)."""
    A, B = jax.vmap(lambda x, w: jacobians(f, x, w, motion))(X[:-1], W)
    lx = jax.vmap(jax.grad(stage, 0))(X[:-1], W)
    lu = jax.vmap(jax.grad(stage, 1))(X[:-1], W)
    lxx = jax.vmap(jax.hessian(stage, 0))(X[:-1], W)
    luu = jax.vmap(jax.hessian(stage, 1))(X[:-1], W)
    lux = jax.vmap(jax.jacfwd(jax.grad(stage, 1), 0))(X[:-1], W)

    def back(carry, e):
        Vx, Vxx = carry
        A, B, lx, lu, lxx, luu, lux = e
        Qx, Qu = lx + A.T @ Vx, lu + B.T @ Vx
        Qxx, Qux = lxx + A.T @ Vxx @ A, lux + B.T @ Vxx @ A
        Quu = _positive(luu + B.T @ Vxx @ B)
        k = -jnp.linalg.solve(Quu, Qu)
        K = -jnp.linalg.solve(Quu, Qux)
        Vx = Qx + K.T @ Quu @ k + K.T @ Qu + Qux.T @ k
        Vxx = Qxx + K.T @ Quu @ K + K.T @ Qux + Qux.T @ K
        return (Vx, 0.5 * (Vxx + Vxx.T)), (k, K)

    start = (jax.grad(final)(X[-1]), jax.hessian(final)(X[-1]))
    _, (ks, Ks) = jax.lax.scan(back, start, (A, B, lx, lu, lxx, luu, lux), reverse=True)
    return ks, Ks


def _forward(f, x0, X, W, ks, Ks, alpha):
    """The trajectory from ``x0`` and the plan of the feedback policy at step length
    ``alpha`` around the trajectory ``X`` and plan ``W``."""
    def body(x, e):
        xk, wk, k, K = e
        w = wk + alpha * k + K @ (x - xk)
        return f(x, w), (x, w)

    last, (xs, ws) = jax.lax.scan(body, x0, (X[:-1], W, ks, Ks))
    return jnp.concatenate([xs, last[None]]), ws


def solve(f, stage, final, x0, W, iterations: int, guess=None, motion=None):
    """(plan (H, m), trajectory (H + 1, n), cost) after ``iterations`` iLQR iterations from
    the plan ``W``; ``f(x, w)``, ``stage(x, w)`` and ``final(x)`` pure and differentiable.
    ``guess``: a trajectory (H + 1, n) near ``W``'s from ``x0`` (the last plan's, shifted);
    the first iteration then starts from it and keeps its cheapest step, length 0 included.
    ``motion`` (n,): linearise the dynamics in motion (``_backward``): a smoothed Coulomb
    friction's steep slope at rest is a damping the moving system never feels."""
    lengths = jnp.asarray(STEP_LENGTHS, dtype=x0.dtype)

    def step(W, X, x0, lengths):
        ks, Ks = _backward(f, stage, final, X, W, motion)
        Xs, Ws = jax.vmap(lambda a: _forward(f, x0, X, W, ks, Ks, a))(lengths)
        costs = jax.vmap(lambda X, W: total_cost(stage, final, X, W))(Xs, Ws)
        costs = jnp.where(jnp.isfinite(costs) & jnp.all(jnp.isfinite(Ws), axis=(1, 2)),
                          costs, jnp.inf)
        best = jnp.argmin(costs)
        found = jnp.isfinite(costs[best])  # else keep the plan (all steps overflowed)
        return (jnp.where(found, Ws[best], W), jnp.where(found, Xs[best], X),
                jnp.where(found, costs[best], jnp.inf))

    def iteration(carry, _):
        W, X, cost = carry
        Wn, Xn, new = step(W, X, X[0], lengths)
        better = new < cost
        return (jnp.where(better, Wn, W), jnp.where(better, Xn, X),
                jnp.where(better, new, cost)), None

    if guess is None:
        X = rollout(f, x0, W)
        carry = (W, X, total_cost(stage, final, X, W))
    else:  # the first iteration along the guess, from x0; its best step is kept
        W, X, cost = step(W, guess, x0, jnp.concatenate([lengths, jnp.zeros(1, x0.dtype)]))
        carry = (W, X, cost)
        iterations -= 1
    if iterations > 0:
        carry, _ = jax.lax.scan(iteration, carry, None, length=iterations)
    return carry
