"""Laplace evidence: the marginal likelihood p(y | scene) of a fitted scene, and posterior model
probabilities of competing scenes.

log p(y) ≈ log p(y, x*) + d/2 log 2π − ½ log det H at the mode x* of the log density in the
fit's unconstrained space (the integral is the same in any parametrisation; the log density
there carries the transform's Jacobian), H its negative Hessian: the Gauss-Newton curvature
the mode search already uses where the likelihood is least squares with known noise (exact for
a linear-Gaussian model), else central differences of the gradient (``laplace_sqrt``). Unlike
ΔELPD it counts complexity: a strength the prior makes implausible, or one the data leave
unconstrained, costs its Occam factor. Where the fit's Laplace step failed (a kink at the mode)
or H is not positive definite, or the mode search stopped where a Newton step would still gain
more than ``MODE_SLACK`` (not a mode), the evidence is ``None`` ("n/a"), never a wrong number.
"""
from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from ..infer.backends.map import LaplaceError, best_known_mode, find_mode, laplace_sqrt
from ..infer.levenberg_marquardt import newton_gain
from ..infer.base import gauss_newton_fn, value_and_grad_fn
from ..infer.problem import model_problem, start_position
from .workflow import noise_unknowns, point_estimate

STRONG = math.log(10.0)  # Δlog Z of strong evidence (Jeffreys: a Bayes factor above 10)


def laplace_log_evidence(model, idata=None, *, values: dict | None = None) -> float | None:
    """Laplace log marginal likelihood of ``model`` at the mode of its fit: the best mode the
    fit remembered on this Model's data (``remember_modes``), else the mode found from the
    most likely posterior draw of ``idata`` (or from constrained ``values``); None where
    Laplace is unreliable."""
    if idata is not None and idata.attrs.get("fit_note"):
        return None  # the fit's own Laplace step failed there: no Gaussian describes the mode
    problem = model_problem(model)
    # the fit's own best mode where it remembered one (a MAP fit's: searching again from its
    # best draw cost rolling_ball's refine 64 s, a kink's stalled steps each time)
    x = best_known_mode(problem) if values is None else None
    if x is None:
        start = values if values is not None else point_estimate(model, idata)
        x = find_mode(problem, start_position(problem, jax.random.PRNGKey(0), start), steps=50)
    gn = gauss_newton_fn(problem) if not noise_unknowns(model) else None
    if gn is not None:
        v, g, H = (np.asarray(a, dtype=float) for a in gn(jnp.asarray(x)))
    else:
        v, g = (np.asarray(a, dtype=float) for a in value_and_grad_fn(problem)(jnp.asarray(x)))
        try:
            S = laplace_sqrt(problem, x)  # S S^T = H^-1
        except LaplaceError:
            return None
        H = np.linalg.inv(S @ S.T)
    if not newton_gain(H, g) <= MODE_SLACK:
        return None  # the mode search stopped short of a mode (a kink, an edge): no Laplace
    return quadratic_log_evidence(float(v), g, H)


MODE_SLACK = 1.0  # log-density units a Newton step may still gain at a point taken as the mode


def quadratic_log_evidence(v: float, g: np.ndarray, H: np.ndarray) -> float | None:
    """log ∫ exp(v + gᵀu − ½ uᵀHu) du: the Laplace evidence from a point near the mode (the
    gradient term corrects a mode found to finite precision; exact for a quadratic log
    density). None unless H is symmetric positive definite and every number finite."""
    H = 0.5 * (H + H.T)
    if not (np.isfinite(v) and np.all(np.isfinite(g)) and np.all(np.isfinite(H))):
        return None
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    w = np.linalg.solve(L, g)
    logdet = 2.0 * float(np.sum(np.log(np.diag(L))))
    return float(v + 0.5 * w @ w + 0.5 * g.size * math.log(2 * math.pi) - 0.5 * logdet)


def model_probabilities(log_evidence: dict) -> dict:
    """Posterior model probabilities under equal prior odds: the softmax of the log evidences
    (name -> log Z); a model whose evidence is None ("n/a") gets None and is left out."""
    known = {k: v for k, v in log_evidence.items() if v is not None and np.isfinite(v)}
    if not known:
        return {k: None for k in log_evidence}
    top = max(known.values())
    w = {k: math.exp(v - top) for k, v in known.items()}
    total = sum(w.values())
    return {k: (w[k] / total if k in w else None) for k in log_evidence}
