"""Leave-future-out comparison: fit the first ``LFO_FRACTION`` of the recording, score the log
predictive density of every later measurement time."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..infer.output import pointwise_log_likelihood
from .workflow import posterior_draws

LFO_FRACTION = 0.7


def cutoff(model) -> float:
    """The time before which a leave-future-out fit sees the measurements."""
    times = np.concatenate([o.obs.times for o in model.observed])
    return float(times.min() + LFO_FRACTION * (times.max() - times.min()))


def lfo_points(model, idata_cut, cutoff: float) -> np.ndarray:
    """Log predictive density of each measurement time after ``cutoff`` given a fit before it
    (all observations in turn); their sum is the leave-future-out score."""
    draws = posterior_draws(model, idata_cut, max_draws=100)
    ll = pointwise_log_likelihood(model, {k: jnp.asarray(v) for k, v in draws.items()})
    points = []
    for o in model.observed:
        late = o.obs.times > cutoff
        x = np.asarray(ll[o.obs.name][:, late])
        m = x.max(axis=0)
        points.append(m + np.log(np.mean(np.exp(x - m), axis=0)))
    return np.concatenate(points)
