"""Rao score tests for missing effects, at the fitted parameters with each candidate switched off.

For Gaussian noise the log-likelihood is -1/2 |r|^2 with standardised residuals
r = (y - f(theta, psi)) / sigma. With J = dr/d(theta, psi) at (theta_hat, psi_off), the score of
a candidate's strength psi is U = -J_psi^T r and the Fisher information is J^T J
(Gauss-Newton). Nuisance parameters theta are projected out:
I_eff = J_psi^T (I - P_theta) J_psi, with P_theta the projection onto J_theta's columns.
T = U^T I_eff^-1 U is chi-square with dim(psi) degrees of freedom under "no such effect";
a scalar strength with a known sign uses the one-sided z = sign * U / sqrt(I_eff).
All candidates are present in one augmented model at their off values (exactly equivalent to
absent), so one forward-mode Jacobian gives every score at once.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree
from scipy import stats
from scipy.special import gammaln

from ..ahead import Program
from ..observe.sensor import SENSOR_FAULTS


@dataclass(frozen=True)
class ScoreResult:
    key: str
    statistic: float  # chi-square statistic T (or z^2 for one-sided)
    z: float | None  # signed one-sided z for scalar strengths with a known sign, else None
    dof: int
    p_value: float
    information: float  # efficient information (trace), 0 when the data cannot see the effect
    estimate: float | None  # one-step estimate of the strength change from off: I_eff^-1 U (scalar)
    log_p: float = 0.0  # natural log of the p-value (ranks candidates whose p underflows to 0)
    # unit vector of the projected column (scalar strengths): candidates whose directions
    # coincide change the predictions alike, so the data cannot tell them apart
    direction: np.ndarray | None = field(default=None, compare=False, repr=False)


def standardized_residuals(model, values, pred=None):
    """All measured residual components divided by their noise scale, as one vector."""
    return model.standardized_residuals(values, model.predict(values) if pred is None else pred)


def jacobian(model, values: dict, nuisance: list[str], tested: list[str]):
    """(r, J_theta, J_psi, predictions) at ``values`` for nuisance and tested unknown names.

    One compiled forward-mode pass gives the residuals, their Jacobian and the predictions
    (compiling the physics is the dominant cost, so nothing else is jitted separately). The
    program takes the values and the data as arguments, so it is compiled once per structure
    and may be compiled ahead, before the fit gives the values (``jacobian_ahead``).
    """
    vals = {u.name: np.asarray(values[u.name], dtype=float) for u in model.unknowns}
    n_theta = sum(int(np.size(vals[k])) for k in nuisance)
    x0 = np.concatenate([np.ravel(vals[k]) for k in [*sorted(nuisance), *sorted(tested)]])
    J, (r, pred) = _program(model, nuisance, tested)(x0, vals, model.data)
    pred = {k: np.asarray(v) for k, v in pred.items()}
    return np.asarray(r), np.asarray(J[:, :n_theta]), np.asarray(J[:, n_theta:]), pred


def jacobian_ahead(model, nuisance: list[str], tested: list[str]) -> None:
    """Start compiling ``jacobian``'s program for ``model`` in the background
    (``physdsl.ahead``): its arguments' types are known from the unknowns' shapes."""
    dtype = jnp.result_type(float)
    vals = {u.name: jax.ShapeDtypeStruct(tuple(u.shape), dtype) for u in model.unknowns}
    size = sum(int(np.prod(vals[k].shape)) for k in [*nuisance, *tested])
    _program(model, nuisance, tested).ahead(jax.ShapeDtypeStruct((size,), dtype), vals,
                                            model.data)


def _program(model, nuisance: list[str], tested: list[str]) -> Program:
    """(x, values, data) -> (dr/dx, (r, predictions)) with x the nuisance then the tested
    unknowns, each group flat in name order (``ravel_pytree``'s), the other values as given;
    compiled once per structure and names."""
    def build():
        def fn(x, values, data):
            theta, unravel_theta = ravel_pytree({k: values[k] for k in nuisance})
            _, unravel_psi = ravel_pytree({k: values[k] for k in tested})

            def r_of(x):
                vals = {**values, **unravel_theta(x[:theta.size]), **unravel_psi(x[theta.size:])}
                pred = model.predict(vals, data=data)
                r = model.standardized_residuals(vals, pred, data)
                return r, (r, pred)

            # forward mode: a handful of unknowns against thousands of residuals (the LCP
            # contact solver's implicit derivative is a custom_jvp, so contact scenes too)
            return jax.jacfwd(r_of, has_aux=True)(x)

        return Program(fn)

    return model.cached(("score-jacobian", tuple(nuisance), tuple(tested)), build)


def project_out(J_theta: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Columns ``cols`` minus their least-squares projection on J_theta's column space."""
    if J_theta.size == 0:
        return cols
    coef, *_ = np.linalg.lstsq(J_theta, cols, rcond=1e-10)
    return cols - J_theta @ coef


def score_test(key: str, r: np.ndarray, cols_eff: np.ndarray, sign: int = 0) -> ScoreResult:
    """Score test of a group of (already projected) columns; ``sign`` for one-sided scalars."""
    U = -cols_eff.T @ r
    info = cols_eff.T @ cols_eff
    dof = cols_eff.shape[1]
    trace = float(np.trace(info))
    scale = float(np.sum(r**2)) + 1.0
    if trace <= 1e-12 * scale:
        return ScoreResult(key, 0.0, None, dof, 1.0, 0.0, None, 0.0)
    if dof == 1:
        i = float(info[0, 0])
        z = float(U[0]) / np.sqrt(i)
        est = float(U[0]) / i
        direction = cols_eff[:, 0] / np.sqrt(i)
        if sign:
            zs = sign * z
            return ScoreResult(key, zs * zs if zs > 0 else 0.0, zs, 1, float(stats.norm.sf(zs)), i, est,
                               float(stats.norm.logsf(zs)), direction)
        return ScoreResult(key, z * z, None, 1, float(stats.chi2.sf(z * z, 1)), i, est,
                           chi2_logsf(z * z, 1), direction)
    w, v = np.linalg.eigh(0.5 * (info + info.T))
    keep = w > 1e-10 * w.max()
    proj = v[:, keep].T @ U
    T = float(np.sum(proj**2 / w[keep]))
    k = int(keep.sum())
    return ScoreResult(key, T, None, k, float(stats.chi2.sf(T, k)), trace, None, chi2_logsf(T, k))


def chi2_logsf(t: float, k: int) -> float:
    """log P(chi2_k > t), finite even where scipy's value underflows (large t: asymptotic series)."""
    v = float(stats.chi2.logsf(t, k))
    if np.isfinite(v):
        return v
    a, x = k / 2.0, t / 2.0
    return float((a - 1) * np.log(x) - x - gammaln(a) + np.log1p((a - 1) / x))


def sensor_columns(model, values, kind: str, obs_name: str, pred=None) -> np.ndarray:
    """dr/d(sensor parameter) columns of the sensor fault ``kind`` at its off value on one
    observation (``pred``: the model's predictions at ``values``, computed if not given): a fault
    on the value by forward-mode derivative of its ``apply`` (an offset: one column per axis, a
    gain: the prediction), a fault on the reading time as a time shift (delay: f'(t))."""
    pred = model.predict(values) if pred is None else pred
    fault = SENSOR_FAULTS[kind]
    cols = []
    for o in model.observed:
        n, k = o.mask.shape
        if model.written_name(o.obs.name) != obs_name:  # (each recording's, pooled)
            cols.append(None)
            continue
        sigma = np.asarray(model.noise_scale(o.obs, values))
        p = np.asarray(pred[o.obs.name])
        m = o.mask.astype(float)
        if fault.on_time:  # delay: y(t) = f(t - tau) -> dr/dtau = f'(t) / sigma
            dp = np.gradient(p, o.obs.times, axis=0)
            blocks = [((dp * m) / sigma).reshape(-1)]
        else:  # dr/dc = -(d apply(p, c) / dc) / sigma at the off value
            off = jnp.full((k,) if fault.per_axis else (), fault.off, dtype=p.dtype)
            d = np.asarray(jax.jacfwd(lambda c: fault.apply(jnp.asarray(p), c))(off))
            d = d if fault.per_axis else d[..., None]
            blocks = [(-(d[..., a] * m) / sigma).reshape(-1) for a in range(d.shape[-1])]
        cols.append(np.stack(blocks, axis=1))
    width = next(c.shape[1] for c in cols if c is not None)
    sizes = [o.mask.size for o in model.observed]
    return np.concatenate([c if c is not None else np.zeros((s, width)) for c, s in zip(cols, sizes)])
