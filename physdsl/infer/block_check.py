"""A model check that residual whiteness cannot fool: refit with one time block left out.

A scene fitted to data from another simulator can leave residuals that look like white noise
at the stated level (cart-pole friction: MuJoCo's friction is not the tanh law) while its
mode sits many nats from the truth: the model error is absorbed by the unknowns, differently
in each part of the record. Refits on parts of the data show it. The record is cut into
``BLOCKS`` contiguous time blocks; for each, the mode is refitted without that block
(Levenberg-Marquardt warm-started at the full mode: a few Gauss-Newton steps on the same
compiled function, the block's rows masked out of the data). Where the model is right, a
left-out estimate differs from the full one by what the noise of the block explains:
d_k = theta_(-k) - theta ~ N(0, H_(-k)^-1 - H^-1) (the Hausman variance of nested estimates;
the d_k of different blocks are nearly independent). The check sums the standardised d_k
into a chi-square statistic; only where it rejects at ``LEVEL`` do intervals widen, so with
a right model nothing widens.

How much: a mismatched model's unknowns are not one constant over the record; each part of
it asks for its own value (the pseudo-true value of that block), and the truth is no nearer
to the full fit than those values are to each other. The mean square of an unknown's
standardised departures, E, estimates 1 + tau^2 / (K sigma^2) for K equal blocks (tau^2:
the variance of the blocks' own values, sigma^2: the posterior variance), so the variance
reported is sigma^2 + tau^2 = sigma^2 (1 + K (E - 1)): the spread of what the parts of the
record say (a prediction interval of a random-effects meta-analysis over the blocks), not
just the standard error of their mean (sigma^2 E, the block jackknife's, which covers the
pseudo-true value but not the truth). Standardising per block keeps blocks that barely
inform an unknown (an initial velocity, late in the record) from hiding or faking a
mismatch.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from . import levenberg_marquardt
from .backends.map import best_known_mode, find_mode
from .base import gauss_newton_fn, value_fn
from .threads import thread_map

BLOCKS = 8  # contiguous time blocks, each left out once
# Levenberg-Marquardt steps per refit, warm-started at the full mode: leaving out one block
# of eight moves the mode by about that block's share of the information, which Gauss-Newton
# covers in one or two steps (on the projectile of tests/infer/test_block_check, 3 steps give
# the statistic of 15 to six digits, 2 steps to 0.2%); each step is a forward-mode rollout, and
# 15 of them per block were the largest part of a round's fit on articulated scenes
STEPS = 3
POLISH_STEPS = 15  # steps polishing the draws' mean where no mode was remembered
LEVEL = 0.01  # the check rejects the model when the statistic's p-value is below this
INFO_SHARE = 1e-3  # a direction (or an unknown) counts as informed by a block where leaving
# the block out raises its posterior variance by at least this share of it (a generalised
# eigenvalue of (Hausman variance, posterior covariance), which no scaling of the unknowns
# changes). Below it the block can move the estimate by under 3% of a posterior sd, the size
# of the refit's own inexactness (``STEPS``) and of the round-off in inverting two curvatures:
# such a direction measures those, not the model (on chain_hit a block holding 4.5e-5 of one
# direction's information gave z^2 = 37 and, with the old threshold of 1e-9 relative to the
# largest eigenvalue, p = 7e-108 on a fit whose every block agreed)


def time_edges(model, blocks: int = BLOCKS) -> np.ndarray:
    """Edges of ``blocks`` equal time spans over the measured samples of every observable."""
    ts = [np.asarray(o.obs.times, float)[np.asarray(o.obs.mask).reshape(len(o.obs.times), -1)
                                          .any(axis=1)] for o in model.observed]
    ts = np.concatenate([t for t in ts if t.size]) if ts else np.zeros(0)
    if ts.size == 0:
        return np.zeros(0)
    return np.linspace(ts.min(), ts.max(), blocks + 1)


def without_block(problem, lo: float, hi: float, last: bool):
    """``problem`` with every measured row at times in [lo, hi) ([lo, hi] for the last block)
    masked out (same shapes and dtypes: the compiled functions are reused)."""
    data = dict(problem.data)
    for o in problem.model.observed:
        t = np.asarray(o.obs.times, float)
        inside = (t >= lo) & ((t <= hi) if last else (t < hi))
        d = dict(data[o.obs.name])
        mask = np.asarray(d["mask"])
        d["mask"] = np.where(inside.reshape((-1,) + (1,) * (mask.ndim - 1)), False, mask) \
            .astype(mask.dtype)
        data[o.obs.name] = d
    return problem._replace(data=data)


def full_mode(problem, draws) -> np.ndarray:
    """The full data's mode: the best one the run's mode search remembered on this data
    (``map.remember_modes``), else a Levenberg-Marquardt polish of the draws' mean."""
    best = best_known_mode(problem)
    if best is not None:
        return best
    return find_mode(problem, np.asarray(draws, dtype=float).mean(axis=0), POLISH_STEPS)


def block_factors(problem, mode, keep, scale=None, on_block=None) -> dict | None:
    """Per unconstrained coordinate in ``keep``: the widening the block check asks for (>= 1),
    with the statistic; None where no check can be made (no Gauss-Newton function, fewer
    than two informative blocks, a singular curvature). ``mode``: the full data's mode;
    ``scale``: per coordinate, how much wider than the posterior's the intervals are already
    (the sandwich's: residuals above the noise make every departure larger by as much, which
    is no mismatch of the law), so departures are judged against those intervals and the
    factors are relative to them."""
    gn = gauss_newton_fn(problem)
    edges = time_edges(problem.model)
    if gn is None or edges.size < 3:
        return None
    mode = np.asarray(mode, dtype=float)
    _, _, H = gn(mode)
    S = np.ones(len(keep)) if scale is None else np.asarray(scale, dtype=float)
    try:
        cov = np.linalg.inv(np.asarray(H, dtype=float))[np.ix_(keep, keep)]
        Li = np.linalg.inv(np.linalg.cholesky(0.5 * (cov + cov.T) * S[:, None] * S[None, :]))
    except np.linalg.LinAlgError:
        return None
    def refit(k):  # the mode without block k, and its curvature
        sub = without_block(problem, edges[k], edges[k + 1], k == len(edges) - 2)
        gn_sub = _remembered(gauss_newton_fn(sub))
        x = levenberg_marquardt.run(gn_sub, mode, STEPS, value_fn(sub))  # (``find_mode``)
        _, _, Hs = gn_sub(x)  # the refit's last step evaluated it there: not again
        if on_block is not None:
            on_block(1)
        return x, Hs

    z2, stat, dof = [], 0.0, 0
    for x, Hs in thread_map(refit, range(len(edges) - 1)):  # side by side (``threads``)
        try:
            cov_k = np.linalg.inv(np.asarray(Hs, dtype=float))[np.ix_(keep, keep)]
        except np.linalg.LinAlgError:
            continue
        d = (x - mode)[keep]
        D = 0.5 * ((cov_k - cov) + (cov_k - cov).T)  # Hausman: Var(d) to first order
        D = D * S[:, None] * S[None, :]
        # in the posterior's own sd's (scaled by S): eigenvalues are each direction's share
        lam, U = np.linalg.eigh(Li @ D @ Li.T)
        ok = lam > INFO_SHARE
        if not np.any(ok) or not np.all(np.isfinite(d)):
            continue
        proj = U[:, ok].T @ (Li @ d)
        stat += float(np.sum(proj**2 / lam[ok]))
        dof += int(ok.sum())
        var = np.diag(D)
        informed = var > INFO_SHARE * np.maximum(np.diag(cov) * S**2, 1e-300)
        z2.append(np.where(informed, d**2 / np.where(informed, var, 1.0), np.nan))
    if len(z2) < 2 or dof == 0:
        return None
    p = float(chi2.sf(stat, dof))
    Z = np.stack(z2)
    seen = np.isfinite(Z).sum(axis=0)  # blocks that informed each unknown
    excess = np.where(seen > 0, np.nansum(Z, axis=0) / np.maximum(seen, 1), np.nan)
    factors = np.ones(len(keep))
    if p < LEVEL:
        e = np.maximum(np.where(np.isfinite(excess), excess, 1.0), 1.0)
        factors = np.sqrt(1.0 + len(z2) * (e - 1.0))  # sigma^2 + tau^2, tau^2 = K (E - 1) sigma^2
    return {"factors": factors, "statistic": stat, "dof": dof, "p_value": p,
            "blocks": len(z2), "excess": np.where(np.isfinite(excess), excess, 1.0)}


def _remembered(gn):
    """``gn`` that evaluates each point once (keyed by its bytes): the curvature at a refit's
    end is the one its last Levenberg-Marquardt step computed (a rollout with tangents)."""
    seen: dict = {}

    def f(x):
        key = np.asarray(x, dtype=float).tobytes()
        if key not in seen:
            seen[key] = gn(x)
        return seen[key]

    return f


__all__ = ["BLOCKS", "block_factors", "full_mode", "time_edges", "without_block"]
