"""Levenberg-Marquardt on a log density whose curvature the Gauss-Newton matrix describes, as
``init`` / ``step`` over a small state (blackjax's shape), so a caller can advance several
searches side by side and stop one between steps (``multistart``); ``run`` is the whole search.

Steps solve (H + lam diag(H)) d = gradient (Marquardt's scaling: every unknown in its own
units). The damping follows the gain ratio rho = actual / predicted gain of each step
(Nielsen's update, as in Madsen, Nielsen & Tingleff 2004, "Methods for non-linear least
squares problems", alg. 3.16, and levmar/optimistix): a step taken shrinks lam by
max(1/3, 1 - (2 rho - 1)^3), a step refused grows it by nu = 2, 4, 8, ... So a run of
refusals is undone at once by good steps (a fixed shrink factor left lam large and the
steps short for tens of iterations).

Converged when the full Gauss-Newton step would gain less than ``GAIN_TOL`` (its predicted
gain g^T H^-1 g / 2: the gradient measured in the metric of the information, which does not
depend on the damping or on the unknowns' units), or when the point no longer moves (a step
within rounding of x, or ``STALL`` steps each gaining less than ``STALL_GAIN`` where the
quadratic model failed, rho < ``STALL_RHO``, with no step gaining more in between: a kink or
rounding noise, where the prediction never comes true; a block sliding on a ramp with
friction predicted 0.03-0.05 nats a full step for hundreds of steps that gained 1e-7 to 1e-6
each). A small gain of one damped step is not convergence, nor are tiny gains that the model
predicted (a search leaving a heavy damping behind: its steps grow threefold each).

Trajectory fits are badly scaled (a start position seen to a millimetre beside a mass seen to
tens of percent) and their log density bends at every contact; L-BFGS there rebuilds its
curvature from steps, loses it at each kink and crawls (hundreds of rollouts). H from the
rollout's Jacobian knows every scale at once: tens of steps.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

GAIN_TOL = 1e-9  # log-density units (nats): a gain below this has no statistical meaning
STALL = 5  # steps gaining less than STALL_GAIN, as the model did not predict: stalled (a kink)
STALL_GAIN = 1e-6  # nats: five such steps move the log density by less than 5e-6 nats
STALL_RHO = 0.5  # a step gaining less than this share of its predicted gain: the model failed
LAM_MIN, LAM_MAX = 1e-12, 1e16  # damping bounds: below, a Gauss-Newton step; above, none


class LMState(NamedTuple):
    """One search between steps: the point, its log density, gradient and Gauss-Newton matrix,
    the damping, the steps in a row that gained nothing, the steps taken, and whether the
    search has ended (converged, stalled, or nowhere left to go)."""

    x: np.ndarray
    value: float
    grad: np.ndarray
    H: np.ndarray
    lam: float = 1e-3
    stalled: int = 0
    steps: int = 0
    done: bool = False


def init(gn, x0) -> LMState:
    """The search at ``x0``; ``gn``: x -> (log p, gradient, H). Ended at once where the log
    density is not finite there."""
    x = np.asarray(x0, dtype=float)
    v, g, H = evaluate(gn, x)
    return LMState(x, v, g, H, done=not np.isfinite(v))


def step(gn, state: LMState, value=None) -> LMState:
    """One Levenberg-Marquardt step from ``state`` (the state as it is where it has ended).
    ``value``: x -> log p, cheaper (no tangents) for trial points after a refusal, which are
    often refused again where the log density jumps (a contact that switches between
    neighbouring parameter values)."""
    if state.done:
        return state
    x, v, g, H, lam = state.x, state.value, state.grad, state.H, state.lam
    ended = state._replace(done=True)
    if newton_gain(H, g) <= GAIN_TOL:
        return ended  # at the mode: a full Gauss-Newton step would gain nothing that matters
    scale = np.maximum(np.diag(H), 1e-12 * max(float(np.max(np.abs(np.diag(H)))), 1e-300))
    nu = 2.0
    while lam <= LAM_MAX:
        d = solve(H + lam * np.diag(scale), g)
        if d is None:
            lam, nu = lam * nu, nu * 2.0
            continue
        if np.max(np.abs(d)) <= 1e-14 * (1.0 + np.max(np.abs(x))):
            return ended  # the step is lost in rounding: nowhere left to go
        predicted = float(g @ d - 0.5 * d @ H @ d)  # > 0: H + lam D is positive definite
        # the first trial in full (most are taken); after a refusal, values first
        vn = float(value(jnp.asarray(x + d))) if value is not None and nu > 2.0 else None
        if vn is None or (np.isfinite(vn) and vn > v):
            vn, g_new, H_new = evaluate(gn, x + d)
        rho = (vn - v) / max(predicted, 1e-300) if np.isfinite(vn) else -np.inf
        if rho > 0:
            lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LAM_MIN)
            tiny = vn - v <= STALL_GAIN
            stalled = state.stalled + (rho < STALL_RHO) if tiny else 0
            return LMState(x + d, vn, g_new, H_new, lam, stalled, state.steps + 1,
                           stalled >= STALL)
        lam, nu = lam * nu, nu * 2.0
    return ended  # no step raises it: against an edge, or a jump at the point itself


def run(gn, x0, steps: int = 300, value=None) -> np.ndarray:
    """The best point found from ``x0`` within ``steps`` steps (see the module's docstring)."""
    state = init(gn, x0)
    while not state.done and state.steps < steps:
        state = step(gn, state, value)
    return state.x


def newton_gain(H, g) -> float:
    """The gain g^T H^-1 g / 2 that the full Gauss-Newton step predicts (inf where H is
    singular): the gradient's size in the metric of the information."""
    d = solve(H, g)
    return float("inf") if d is None else 0.5 * float(g @ d)


def solve(A, b):
    """A^-1 b by Cholesky (A symmetric positive definite), None where it is not."""
    try:
        L = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return None
    d = np.linalg.solve(L.T, np.linalg.solve(L, b))
    return d if np.all(np.isfinite(d)) else None


def evaluate(gn, x):
    """(log p, gradient, H) at ``x`` as host numbers."""
    v, g, H = gn(jnp.asarray(x))
    return float(v), np.asarray(g, dtype=float), np.asarray(H, dtype=float)
