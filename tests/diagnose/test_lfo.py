"""Leave-future-out scores (``diagnose/lfo.py``) read off the cut-off fit's own predictions
equal those of a fresh rollout of every draw (the way they were computed before): same draws,
same log predictive density per later measurement time."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from physdsl.compile import Model
from physdsl.diagnose.lfo import MAX_DRAWS, cutoff, lfo_points
from physdsl.diagnose.workflow import posterior_draws
from physdsl.infer.output import pointwise_log_likelihood

from .conftest import CASES, fit, make_case


def test_lfo_from_the_fits_predictions_equals_a_rollout_of_each_draw(tmp_path):
    naive, _ = make_case(tmp_path, CASES["quadratic_drag"])
    model = Model(naive)
    cut = cutoff(model)
    idata_cut = fit(Model(naive, until=cut))
    points = lfo_points(model, idata_cut, cut)
    draws = posterior_draws(model, idata_cut, max_draws=MAX_DRAWS)
    ll = pointwise_log_likelihood(model, {k: jnp.asarray(v) for k, v in draws.items()})
    late = model.observed[0].obs.times > cut
    x = np.asarray(ll[model.observed[0].obs.name][:, late])
    m = x.max(axis=0)
    expected = m + np.log(np.mean(np.exp(x - m), axis=0))
    assert points.shape == expected.shape == (int(late.sum()),)
    np.testing.assert_allclose(points, expected, rtol=1e-9, atol=1e-9)
    # the later times are predicted worse than noise alone would allow: the drag is missing
    assert points.sum() < -10.0
