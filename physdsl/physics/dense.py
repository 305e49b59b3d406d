"""Small dense solves written as plain array operations, with no LAPACK call.

XLA CPU compiles a whole rollout loop into one kernel when the loop holds no custom call
(``xla_flags.py``: its small-while-loop pass); ``jax.scipy.linalg.cho_factor`` and
``jnp.linalg.solve`` are LAPACK custom calls, so a tree's mass-matrix solve kept every chain's
loop running as one thunk per operation. Here the Cholesky factor and both triangular solves are
unrolled over the static size n (n column updates each): O(n^3) flops, as LAPACK, and O(n)
array operations, a few hundred at the tree path's largest size (``tree.TREE_MAX``).
"""
from __future__ import annotations

import jax.numpy as jnp


def cholesky(M):
    """Lower-triangular L with L L^T = M for a symmetric positive definite (n, n) M
    (left-looking: column j from M's column j less the columns before it)."""
    n = M.shape[0]
    rows = jnp.arange(n)
    L = jnp.zeros_like(M)
    for j in range(n):
        s = M[:, j] - L[:, :j] @ L[j, :j] if j else M[:, 0]
        L = L.at[:, j].set(jnp.where(rows >= j, s / jnp.sqrt(s[j]), 0.0))
    return L


def cho_solve(L, b):
    """x with L L^T x = b (b: (n,) or (n, k)), by forward then backward substitution."""
    n = L.shape[0]
    y = jnp.zeros_like(b)
    for i in range(n):
        y = y.at[i].set((b[i] - L[i, :i] @ y[:i]) / L[i, i] if i else b[0] / L[0, 0])
    x = jnp.zeros_like(b)
    for i in reversed(range(n)):
        x = x.at[i].set((y[i] - L[i + 1:, i] @ x[i + 1:]) / L[i, i] if i < n - 1
                        else y[i] / L[i, i])
    return x


def spd_solve(M, b):
    """M^-1 b for a small symmetric positive definite M (a joint-space mass matrix)."""
    return cho_solve(cholesky(M), b)
