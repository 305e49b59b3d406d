"""The small solves of physics/dense.py (unrolled Cholesky, looped LU) against LAPACK's, and
their derivatives against finite differences, in float64."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.physics import dense


def _spd(n, seed):
    """A random symmetric positive definite (n, n) matrix, condition number ~1e3."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (q * np.geomspace(1e-3, 1.0, n)) @ q.T


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_factor_and_solve_equal_lapack(n):
    M = _spd(n, n)
    L = np.asarray(dense.cholesky(jnp.asarray(M)))
    np.testing.assert_allclose(L, np.linalg.cholesky(M), rtol=0, atol=1e-12)
    assert np.all(np.triu(L, 1) == 0.0)
    b = np.random.default_rng(1).normal(size=(n, 3))
    for rhs in (b[:, 0], b):  # a vector and a matrix of right-hand sides
        x = np.asarray(dense.spd_solve(jnp.asarray(M), jnp.asarray(rhs)))
        np.testing.assert_allclose(M @ x, rhs, rtol=0, atol=1e-10)
        np.testing.assert_allclose(x, np.linalg.solve(M, rhs), rtol=1e-9)


def _general(n, seed):
    """A random non-symmetric (n, n) matrix, well away from singular."""
    return np.random.default_rng(seed).normal(size=(n, n)) + 3 * np.eye(n)


@pytest.mark.parametrize("solve,matrix", [(dense.spd_solve, _spd), (dense.solve, _general)])
def test_derivative_matches_finite_differences(solve, matrix):
    """d/dt of A(t)^-1 b(t) (forward mode, as rollouts differentiate; through the pivoting
    loop for ``dense.solve``) against central differences."""
    A0, dA = matrix(4, 7), matrix(4, 8)
    b0, db = np.arange(1.0, 5.0), np.array([0.5, -1.0, 0.25, 2.0])

    def f(t):
        return solve(jnp.asarray(A0) + t * dA, jnp.asarray(b0) + t * db)

    _, tangent = jax.jvp(f, (0.0,), (1.0,))
    h = 1e-6
    fd = (np.asarray(f(h)) - np.asarray(f(-h))) / (2 * h)
    np.testing.assert_allclose(np.asarray(tangent), fd, rtol=1e-6)


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_general_solve_equals_lapack_and_pivots(n):
    """``dense.solve`` (LU with partial pivoting) on a non-symmetric matrix whose first pivot
    is zero (no solve without row exchanges) against numpy's, a vector and a matrix of
    right-hand sides."""
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n)) + n * np.eye(n)
    if n > 1:
        A[0, 0] = 0.0
    b = rng.normal(size=(n, 3))
    for rhs in (b[:, 0], b):
        x = np.asarray(jax.jit(dense.solve)(jnp.asarray(A), jnp.asarray(rhs)))
        np.testing.assert_allclose(A @ x, rhs, rtol=0, atol=1e-11)
        np.testing.assert_allclose(x, np.linalg.solve(A, rhs), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("n", [3, 8, 24])
def test_lu_factors_are_lapacks_partial_pivoting(n):
    """``lu_factor``'s (LU, perm): A[perm] = L U with the pivot rows LAPACK's partial pivoting
    chooses (the largest remaining entry of each column), on a matrix that needs an exchange
    at nearly every column; the contact solver's Newton matrices are 24 x 24."""
    import scipy.linalg

    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n))[rng.permutation(n)]
    LU, perm = (np.asarray(a) for a in jax.jit(dense.lu_factor)(jnp.asarray(A)))
    L, U = np.tril(LU, -1) + np.eye(n), np.triu(LU)
    np.testing.assert_allclose(L @ U, A[perm], rtol=0, atol=1e-12)
    P, L_ref, U_ref = scipy.linalg.lu(A)  # A = P L U
    np.testing.assert_array_equal(perm, np.argmax(P, axis=0))
    np.testing.assert_allclose(L, L_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(U, U_ref, rtol=0, atol=1e-12)
