"""Inference over many recordings: per-recording and shared unknowns in one posterior (MAP +
Laplace and NUTS), the ``experiment`` dimension, and the pooled drag narrower than one throw's."""
from __future__ import annotations

import numpy as np
import pytest

import physdsl

from .helpers import TRUTH, drag_fit, interval, single, throws

DRAG = TRUTH["coefficient"]


@pytest.mark.slow  # ~23 s; pooled fits: the other tests here and test_backends.py
def test_pooled_map_recovers_drag_narrower_than_one_throw(tmp_path):
    """4 throws (3, 8.4, 14.6, 20 m/s; 0.6 s each): the shared drag's 90% interval covers the
    truth and is >= 3x narrower than the fit of the 8.4 m/s throw alone; every throw's launch
    velocity is its own (its truth within 3.5 posterior sd, sd < 6 cm/s)."""
    picks = ["00", "06", "13", "19"]
    (lo, hi), idata = drag_fit(throws(tmp_path, picks, 0.6))
    assert lo <= DRAG <= hi
    (slo, shi), _ = drag_fit(single(tmp_path, "06"))
    assert slo <= DRAG <= shi
    assert (shi - slo) / (hi - lo) >= 3.0
    v = idata.posterior["ball.velocity"]
    assert v.dims[2] == "experiment" and list(v["experiment"].values) == picks
    draws = np.asarray(v.values).reshape(-1, 4, 3)
    truth = np.array([TRUTH["throws"][p]["velocity"] for p in picks])
    assert np.all(np.abs(draws.mean(axis=0) - truth) <= 3.5 * draws.std(axis=0) + 1e-3)
    assert np.all(draws.std(axis=0) < 0.06)  # each launch pinned by its own throw
    names = set(idata.log_likelihood.data_vars)
    assert names == {f"obs:ball.position[{p}]" for p in picks}


@pytest.mark.slow  # 112 s at load 13 on 2 shared cores (compile + 300 transitions x 2 chains)
def test_pooled_nuts_covers_the_truth(tmp_path):
    """NUTS over 2 throws (11.9 and 15.5 m/s, 0.5 s) samples the shared drag and each throw's launch: its 90%
    interval agrees with MAP + Laplace's (ends within a fifth of the width) and the truth lies
    in its 90% interval (MAP's: 0.0047-0.0063)."""
    scene = throws(tmp_path, ["10", "16"], 0.5)
    (mlo, mhi), _ = drag_fit(scene)
    model = physdsl.compile(scene)
    idata = physdsl.infer(model, backend="nuts", chains=2, warmup=150, samples=150, seed=1,
                          progress=False)
    lo, hi = interval(idata, "quadratic_drag@ball.coefficient")
    assert abs(lo - mlo) < 0.2 * (mhi - mlo) and abs(hi - mhi) < 0.2 * (mhi - mlo)
    assert lo <= DRAG <= hi
    assert idata.posterior["ball.position"].shape == (2, 150, 2, 3)
    z0 = np.asarray(idata.posterior["ball.position"].values)[..., 2].reshape(-1, 2)
    truth = [TRUTH["throws"][p]["position"][2] for p in ("10", "16")]
    assert np.all(np.abs(z0.mean(axis=0) - truth) < 3 * z0.std(axis=0) + 0.005)
    from physdsl.infer.posterior_data import rhat
    assert rhat(np.asarray(idata.posterior["quadratic_drag@ball.coefficient"].values)) < 1.1


@pytest.mark.slow  # ~15 s
def test_check_reports_each_recording_and_the_pool(tmp_path):
    model = physdsl.compile(throws(tmp_path, ["03", "16"], 0.5))
    idata = physdsl.infer(model, backend="map", chains=1, progress=False)
    report = physdsl.check(model, idata)
    names = [o.name for o in report.observables]
    assert names == ["ball.position[03]", "ball.position[16]"]
    assert report.n == sum(o.n for o in report.observables)
    assert 0.7 < report.rms_sigma < 1.3  # the right model: residuals at the noise


def test_concrete_values_roll_out_through_one_compiled_program(tmp_path):
    """The posterior pass's draws reach the pooled rollout with concrete values: three draws
    trace the scene's rollout once (one compiled program), not once per draw as a vmap run op
    by op did (dispatching, and compiling, each of its operations on its own)."""
    import jax

    model = physdsl.compile(throws(tmp_path, ["03", "16"], 0.2))
    draws = model.sample_prior(jax.random.PRNGKey(0), 3)
    before = model.simulator.trace_count
    outs = [model.fit_simulate({k: v[i] for k, v in draws.items()}) for i in range(3)]
    assert model.simulator.trace_count - before == 1
    pos = [np.asarray(o.body_pos) for o in outs]
    assert pos[0].shape[0] == 2 and not np.allclose(pos[0], pos[1])  # both throws, each draw's
