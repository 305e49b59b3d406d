"""Leave-one-out comparison of fits: PSIS-LOO over every measurement time (the points whose
log-likelihood is constant over the draws set exactly), its reliability in words, and how far
apart two fits' pointwise sums may be and still tie."""
from __future__ import annotations

import warnings

import numpy as np

from ..infer import posterior_data

CONSTANT_LL = 1e-9  # spread of a point's log-likelihood over the draws below which it is constant
ELPD_TIE = 4.0  # differences below this are negligible however small their standard error


def combined_loo(idata):
    """PSIS-LOO over every measurement time of every observation (pointwise values kept)."""
    ll = posterior_data.group(idata, "log_likelihood")
    arrays = [np.asarray(ll[v].values) for v in ll.data_vars]
    stacked = np.concatenate([a.reshape(a.shape[0], a.shape[1], -1) for a in arrays], axis=2)
    with warnings.catch_warnings():  # said in words by loo_reliability, not as a raw warning
        warnings.simplefilter("ignore", UserWarning)
        warnings.simplefilter("ignore", RuntimeWarning)  # constant points, handled below
        loo = posterior_data.loo(stacked)
    return _constant_points_exact(loo, stacked.reshape(-1, stacked.shape[2]))


def _constant_points_exact(loo, ll):
    """PSIS-LOO with the points whose log-likelihood does not vary over the draws set exactly.

    Leaving such a point out changes no importance weight, so its LOO density is its
    log-likelihood itself; PSIS cannot fit a Pareto tail to equal weights and returns NaN
    there (a block that does not rotate: its measured orientation depends on no unknown),
    which would make the whole ELPD NaN."""
    flat = (ll.max(axis=0) - ll.min(axis=0)) < CONSTANT_LL
    if not flat.any():
        return loo
    loo_i = np.asarray(loo.loo_i).copy()
    loo_i[flat] = ll[:, flat].mean(axis=0)
    loo.loo_i = loo_i
    loo.pareto_k = np.where(flat, 0.0, loo.pareto_k)
    loo.elpd_loo = float(loo_i.sum())
    m = ll.max(axis=0)
    lppd = float(np.sum(m + np.log(np.mean(np.exp(ll - m), axis=0))))
    loo.p_loo = lppd - float(loo_i.sum())
    loo.se = float(np.sqrt(loo_i.size * np.var(loo_i)))
    return loo


def loo_reliability(loo) -> str | None:
    """A sentence when PSIS-LOO is unreliable (Pareto k > 0.7 at some points), else None."""
    k = np.asarray(loo.pareto_k)
    bad = int(np.sum(k > 0.7))
    if not bad:
        return None
    return (f"PSIS-LOO is unreliable at {bad} of {k.size} measurements (Pareto k > 0.7): read "
            "ΔELPD as indicative; the leave-future-out comparison does not rely on it")


UNRELIABLE_SHARE = 0.1  # share of points with Pareto k > 0.7 above which a fit's PSIS-LOO is not evidence


def unreliable(loo) -> bool:
    """Whether a fit's PSIS-LOO cannot be read as evidence: Pareto k > 0.7 at more than
    ``UNRELIABLE_SHARE`` of the points. LOO is a harmonic mean over the draws, so draws from an
    approximation wider than the posterior (a Laplace Gaussian around a strength near its off
    value, in log space: a banana it cannot follow) sink it however well the fit itself does."""
    k = np.asarray(loo.pareto_k)
    return bool(k.size and np.mean(k > 0.7) > UNRELIABLE_SHARE)


def sum_se(points: np.ndarray) -> float:
    """Standard error of the sum of pointwise values (as arviz's ``compare``)."""
    return float(np.sqrt(points.size) * points.std())


def tie_margin(pa, pb) -> float:
    """How far apart two fits' summed pointwise scores (ΔELPD or ΔLFO, each against the same
    baseline, ``pa`` and ``pb`` their points) may be and still tie: twice the standard error of
    the summed pointwise differences between them (both are scored on the same points), at
    least ``ELPD_TIE``."""
    if pa is None or pb is None or np.shape(pa) != np.shape(pb):
        return ELPD_TIE
    return max(2.0 * sum_se(np.asarray(pa) - np.asarray(pb)), ELPD_TIE)
