"""Leave-future-out comparison: fit the first ``LFO_FRACTION`` of the recording, score the log
predictive density of every later measurement time."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

import jax

from ..compile import PRED_PREFIX
from ..infer.output import pointwise_log_likelihood
from ..infer.posterior_data import group
from .workflow import posterior_draws

LFO_FRACTION = 0.7
MAX_DRAWS = 100  # posterior draws of the cut-off fit that score the later times


def cutoff(model) -> float:
    """The time before which a leave-future-out fit sees the measurements."""
    times = np.concatenate([o.obs.times for o in model.observed])
    return float(times.min() + LFO_FRACTION * (times.max() - times.min()))


def lfo_points(model, idata_cut, cutoff: float) -> np.ndarray:
    """Log predictive density of each measurement time after ``cutoff`` given a fit before it
    (all observations in turn); their sum is the leave-future-out score.

    The cut-off fit's posterior pass predicted every measurement time (its cut is a mask on
    the likelihood, not on the rollout), so the later times are scored from those predictions
    (``idata_cut.posterior_predictive``): no rollout and no compiled rollout of its own
    (a second program per candidate scene that traced and compiled the physics again);
    scored by ``pointwise_log_likelihood`` where the predictions are missing."""
    draws = posterior_draws(model, idata_cut, max_draws=MAX_DRAWS)
    preds = _predictions(model, idata_cut)
    if preds is None:
        ll = pointwise_log_likelihood(model, {k: jnp.asarray(v) for k, v in draws.items()})
    else:
        ll = _scored(model)(draws, preds, model.data)
    points = []
    for o in model.observed:
        late = o.obs.times > cutoff
        x = np.asarray(ll[o.obs.name][:, late])
        m = x.max(axis=0)
        points.append(m + np.log(np.mean(np.exp(x - m), axis=0)))
    return np.concatenate(points)


def _predictions(model, idata_cut) -> dict | None:
    """The cut-off fit's predictions of every observable, thinned as ``posterior_draws`` thins
    the unknowns (same draws): name -> (S, N, K); None where the fit kept none."""
    pp = group(idata_cut, "posterior_predictive")
    out = {}
    for o in model.observed:
        key = PRED_PREFIX + o.obs.name
        if pp is None or key not in pp:
            return None
        arr = np.asarray(pp[key].values)
        arr = arr.reshape(-1, *arr.shape[2:])
        out[o.obs.name] = arr[::max(1, arr.shape[0] // MAX_DRAWS)][:MAX_DRAWS]
    return out


def _scored(model):
    """(draws, predictions, data) -> pointwise log-likelihood per draw: no rollout (one small
    program per scene structure)."""
    def build():
        def one(values, preds, data):
            return model.pointwise_log_likelihood(values, preds, data)
        return jax.jit(jax.vmap(one, in_axes=(0, 0, None)))
    return model.cached("lfo-scored", build)
