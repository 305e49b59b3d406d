"""Small dense solves written as plain array operations, with no LAPACK call.

XLA CPU compiles a whole rollout loop into one kernel when the loop holds no custom call
(``xla_flags.py``: its small-while-loop pass); ``jax.scipy.linalg.cho_factor``, ``lu_factor``
and ``jnp.linalg.solve`` are LAPACK custom calls, so a solve inside a step kept the whole
loop running as one thunk per operation.
- ``spd_solve`` (a tree's mass matrix): the Cholesky factor and both triangular solves
  unrolled over the static size n: O(n^3) flops, as LAPACK, and O(n) array operations, a few
  hundred at the tree path's largest size (``tree.TREE_MAX``).
- ``solve`` (the contact solver's Newton matrices, which are not symmetric, and its other
  small systems): LU with partial pivoting and the two substitutions each as a loop over the
  n rows, one small body each, so the interior-point iteration that holds them compiles no
  larger than with LAPACK's calls (measured in ``docs/physics.md``, "Seventh pass").
"""
from __future__ import annotations

import jax
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


def lu_factor(A):
    """(LU, perm): P A = L U by Gaussian elimination with partial pivoting, L unit lower
    (below the diagonal of LU) and U upper, ``perm`` the rows of A in P A's order. A loop
    over the n columns (one small body, so the Newton step that holds it compiles quickly)
    for the contact solver's Newton matrices, which are not symmetric. Rows are not moved
    while eliminating (a pivot row is only marked used; one gather orders them at the end):
    a column costs a row read, a rank-1 update and a column write."""
    n = A.shape[0]
    rows = jnp.arange(n)

    def column(k, state):
        A, free, perm = state
        col = A[:, k]
        p = jnp.argmax(jnp.where(free, jnp.abs(col), -1.0))
        free = free.at[p].set(False)
        pivot = col[p]
        low = jnp.where(free, col / jnp.where(pivot != 0, pivot, 1.0), 0.0)
        A = A - low[:, None] * jnp.where(rows > k, A[p], 0.0)[None, :]
        return A.at[:, k].set(jnp.where(free, low, col)), free, perm.at[k].set(p)

    A, _, perm = jax.lax.fori_loop(0, n, column, (A, jnp.ones(n, bool), rows))
    return A[perm], perm


def lu_solve(lu, b):
    """x with A x = b (b: (n,) or (n, k)) from ``lu_factor(A)``: forward then backward
    substitution, a loop over the rows each."""
    LU, perm = lu
    n = LU.shape[0]
    rows = jnp.arange(n)
    lower = jnp.where(rows[:, None] > rows[None, :], LU, 0.0)
    upper = jnp.where(rows[:, None] < rows[None, :], LU, 0.0)
    diag = jnp.diagonal(LU)

    def forward(i, y):
        return y.at[i].set(y[i] - lower[i] @ y)

    def backward(j, x):
        i = n - 1 - j
        return x.at[i].set((x[i] - upper[i] @ x) / diag[i])

    y = jax.lax.fori_loop(0, n, forward, b[perm])
    return jax.lax.fori_loop(0, n, backward, y)


def solve(A, b):
    """A^-1 b for a small square A (general: partial pivoting)."""
    return lu_solve(lu_factor(A), b)
