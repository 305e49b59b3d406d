"""The Laplace frame of the gradient samplers (``infer/precondition.py``) and their one trace of
the rollout: the frame's covariance is the inverse curvature at the best start, the affine map
round-trips, and a NUTS warmup traces the scene's rollout no more than once."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from physdsl.infer.base import Settings, gauss_newton_fn, get_backend
from physdsl.infer.precondition import from_frame, laplace_frame, to_frame
from physdsl.infer.problem import model_problem
from physdsl.infer.run import starts

from .conftest import (PROJECTILE_NOISE, PROJECTILE_TIMES, PROJECTILE_TRUTH, projectile_text,
                       simulated_scene)


def test_frame_is_the_inverse_curvature_at_the_best_start(projectile_model):
    problem = model_problem(projectile_model)
    settings = Settings(chains=2, warmup=10, samples=10)
    _, modes = starts(projectile_model, settings, settings.init_steps, [])
    far = np.asarray(modes[0]) + 0.5  # a worse start: the frame must sit at the better one
    shift, scale = laplace_frame(problem, np.stack([far, np.asarray(modes[0])]))
    np.testing.assert_allclose(shift, np.asarray(modes[0]))
    H = np.asarray(gauss_newton_fn(problem)(jnp.asarray(shift))[2])
    np.testing.assert_allclose(scale @ scale.T @ H, np.eye(problem.dim), atol=1e-8)
    xs = np.random.default_rng(0).normal(size=(3, problem.dim))
    np.testing.assert_allclose(from_frame(shift, scale, to_frame(shift, scale, xs)), xs,
                               atol=1e-10)


def test_a_nuts_warmup_traces_the_rollout_once(tmp_path):
    """NUTS evaluates the log density at six places of its tree; the samplers' log density is
    jitted and, for least squares, the Gauss-Newton program the mode search traced: the
    warmup's block traces no rollout of its own (before: six)."""
    from physdsl.compile import compile as compile_phys

    # a structure of its own (5 ms steps), so no other test has compiled its block already
    text = projectile_text().replace("timestep: 10 ms", "timestep: 5 ms")
    model = compile_phys(simulated_scene(tmp_path, text, PROJECTILE_TRUTH, PROJECTILE_TIMES,
                                         PROJECTILE_NOISE, seed=5))
    settings = Settings(chains=2, warmup=3, samples=3)
    problem, positions = starts(model, settings, settings.init_steps, [])
    before = model.simulator.trace_count
    states, _, _ = get_backend("nuts").warmup(problem, positions, jax.random.PRNGKey(0), settings)
    assert np.all(np.isfinite(np.asarray(states.position)))
    assert model.simulator.trace_count == before


def test_chains_side_by_side_or_one_after_another_give_the_same_draws(projectile_model,
                                                                      monkeypatch):
    """The CPU runs each of a block's chains from a thread of its own, an accelerator vmaps
    them (``blocks.chains_side_by_side``): the same keys give the same NUTS draws either way."""
    from physdsl.infer import blocks

    settings = Settings(chains=2, warmup=20, samples=5)
    problem, positions = starts(projectile_model, settings, settings.init_steps, [])
    draws = []
    for side_by_side in (False, True):
        monkeypatch.setattr(blocks, "chains_side_by_side", lambda s=side_by_side: s)
        nuts = get_backend("nuts")
        key = ("layout", side_by_side)  # a block of its own per layout (the cache is shared)
        monkeypatch.setattr(nuts, "name", f"nuts-{key}")
        states, params, _ = nuts.warmup(problem, positions, jax.random.PRNGKey(1), settings)
        draws.append(np.asarray(nuts.sample(problem, states, params, jax.random.PRNGKey(2), 5,
                                            settings)[1]))
    assert draws[0].shape == (2, 5, problem.dim)
    np.testing.assert_allclose(draws[0], draws[1], rtol=1e-9, atol=1e-12)
