"""Simulation-based calibration (Talts et al. 2018) of NUTS on a small scene.

For each of DATASETS datasets: draw the unknowns from the prior, simulate the measurements
(prediction plus the scene's Gaussian noise), fit with ``nuts``, and take the rank of the
true value among RANK_DRAWS thinned posterior draws. If the posterior is right, each rank is
uniform on 0..RANK_DRAWS; a chi-square test over BINS equal bins checks it per unknown.

Every dataset is a new Model of one scene structure, so the physics and the sampler compile
once for all of them (the measurements are an argument of the compiled functions).
"""
from __future__ import annotations

import physdsl

import dataclasses

import jax
import numpy as np
import pytest
from scipy import stats

from physdsl.compile import Model

from .conftest import write_trajectory_csv

SCENE = """\
scene lob {
  world {
    timestep: 10 ms
    duration: 0.5 s
  }
  param vz ~ normal(4 m/s, 0.5 m/s)
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity: (1 m/s, 0 m/s, vz)
    angular_velocity: (0, 0, 0) rad/s
  }
  effect linear_drag on ball { coefficient ~ half_normal(0.5 kg/s) }
  observe ball.position from "data.csv" where body == "ball" { noise: 2 cm }
}
"""
NOISE = 0.02  # m, as in the scene
TIMES = np.linspace(0.0, 0.5, 11)
DATASETS = 100
RANK_DRAWS = 99  # thinned draws per fit: ranks 0..99, 100 values
BINS = 10
FIT = dict(backend="nuts", chains=2, warmup=150, samples=200, progress=False)
THIN = 4  # 2 x 200 draws -> every 4th -> the first 99 (bulk ESS is about a quarter of the draws)
P_MIN = 0.01


def sbc_ranks(model, key, datasets: int) -> dict[str, np.ndarray]:
    """Rank of the truth among RANK_DRAWS thinned draws, per dataset and unknown."""
    truths = model.sample_prior(key, datasets)
    (obs,) = model.scene.observations
    rng = np.random.default_rng(0)
    ranks = {name: np.zeros(datasets, int) for name in model.unknown_names}
    traces = None
    for i in range(datasets):
        values = {k: v[i] for k, v in truths.items()}
        pred = np.asarray(model.predict(values)["ball.position"])
        noisy = pred + rng.normal(0.0, NOISE, pred.shape)
        scene = dataclasses.replace(model.scene, observations=(
            dataclasses.replace(obs, values=noisy, mask=np.ones_like(noisy, bool)),))
        fit = physdsl.infer(Model(scene), seed=i, **FIT)  # a new Model: same structure, its own data
        if i == 0:
            traces = model.simulator.trace_count
        for name in model.unknown_names:
            draws = np.asarray(fit.posterior[name].values).reshape(-1)[::THIN][:RANK_DRAWS]
            assert draws.size == RANK_DRAWS
            ranks[name][i] = int(np.sum(draws < values[name]))
    assert model.simulator.trace_count == traces, "a dataset compiled the physics again"
    return ranks


def bin_counts(ranks: np.ndarray) -> np.ndarray:
    """How many ranks (0..RANK_DRAWS) fall into each of BINS equal bins."""
    return np.bincount(ranks * BINS // (RANK_DRAWS + 1), minlength=BINS)


@pytest.mark.slow
def test_nuts_is_calibrated(tmp_path):
    from physdsl.compile import compile as compile_phys

    (tmp_path / "scene.phys").write_text(SCENE)
    write_trajectory_csv(tmp_path / "data.csv", TIMES, np.zeros((len(TIMES), 3)))
    model = compile_phys(tmp_path / "scene.phys")
    ranks = sbc_ranks(model, jax.random.PRNGKey(2024), DATASETS)
    for name, r in ranks.items():
        counts = bin_counts(r)
        p = float(stats.chisquare(counts).pvalue)
        print(f"SBC {name}: rank counts per bin {counts.tolist()}, chi-square p = {p:.3f}")
        assert p > P_MIN, f"{name}: ranks not uniform (p = {p:.3g}), counts {counts.tolist()}"
