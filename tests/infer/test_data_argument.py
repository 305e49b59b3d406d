"""Measurements are an argument of the compiled functions, not constants in them: a Model of
the same scene with other data (other values and times, same count) or another ``until``
cut-off reuses every compiled function (nothing is traced again) and still fits its own data."""
from __future__ import annotations

import physdsl

import jax
import numpy as np

from physdsl.compile import Model

from .conftest import PROJECTILE_NOISE, PROJECTILE_TRUTH, projectile_text, simulated_scene

# the recovery tests' nuts settings but shorter: same chains and block, so the same compiles
SETTINGS = dict(backend="nuts", chains=2, warmup=100, samples=100, seed=4, progress=False)
OTHER_TRUTH = {"ball.velocity": np.array([2.6, -0.3, 4.8]),
               "linear_drag@ball.coefficient": np.array(0.15)}
CUTOFF = 0.25  # s: the leave-future-out fit sees 6 of the 11 rows


def _compiled_sizes(model) -> dict:
    return {k: f._cache_size() for k, f in model.compiled.cache.items() if hasattr(f, "_cache_size")}


def test_other_data_and_cutoff_reuse_every_compiled_function(projectile_model, tmp_path):
    from physdsl.compile import compile as compile_phys

    full = physdsl.infer(projectile_model, **SETTINGS)  # compiles what the module has not yet
    sizes = _compiled_sizes(projectile_model)
    tuple_keys = [k[0] for k in sizes if isinstance(k, tuple)]
    # (the posterior pass: draws through the fit's own value function, ``draw-read`` on the
    # scene's one compiled rollout)
    assert "gauss-newton" in sizes and "draw-read" in sizes and "block" in tuple_keys

    times = np.linspace(0.02, 0.5, 11)  # other times: the interpolation weights are data too
    other = compile_phys(simulated_scene(tmp_path, projectile_text(), OTHER_TRUTH, times,
                                         PROJECTILE_NOISE, seed=9))
    cut = Model(projectile_model.scene, until=CUTOFF)
    assert other.compiled is projectile_model.compiled and cut.compiled is projectile_model.compiled
    # (simulating the other data above ran the rollout on its own, eagerly: counted from here)
    traces = projectile_model.simulator.trace_count
    other_fit = physdsl.infer(other, **SETTINGS)
    cut_fit = physdsl.infer(cut, **SETTINGS)

    assert projectile_model.simulator.trace_count == traces, "the rollout was traced again"
    assert _compiled_sizes(projectile_model) == sizes, "a compiled function was compiled again"

    # each fit saw its own data: the other dataset's truth, far from the first one's
    drag = "linear_drag@ball.coefficient"
    d_other = np.asarray(other_fit.posterior[drag].values)
    assert abs(d_other.mean() - 0.15) < 3 * d_other.std() and abs(d_other.mean() - 0.3) > 5 * d_other.std()
    v_other = np.asarray(other_fit.posterior["ball.velocity"].values).reshape(-1, 3)
    assert np.all(np.abs(v_other.mean(0) - OTHER_TRUTH["ball.velocity"]) < 4 * v_other.std(0))
    # the cut-off fit saw the first 0.25 s only: a wider posterior around the same truth
    d_full, d_cut = (np.asarray(f.posterior[drag].values) for f in (full, cut_fit))
    assert d_cut.std() > 1.5 * d_full.std()
    assert abs(d_cut.mean() - PROJECTILE_TRUTH[drag]) < 3 * d_cut.std()


def test_cutoff_log_density_drops_exactly_the_late_rows(projectile_model):
    """log p_full(x) - log p_cut(x) is the log-likelihood of the rows after the cut-off."""
    from physdsl.infer.base import value_and_grad_fn
    from physdsl.infer.output import pointwise_log_likelihood
    from physdsl.infer.problem import model_problem, prior_draws_unconstrained

    cut = Model(projectile_model.scene, until=CUTOFF)
    full_p, cut_p = model_problem(projectile_model), model_problem(cut)
    xs = prior_draws_unconstrained(full_p, jax.random.PRNGKey(3), 8)[:3]
    late = projectile_model.observed[0].obs.times > CUTOFF
    for x in xs:
        diff = float(value_and_grad_fn(full_p)(x)[0]) - float(value_and_grad_fn(cut_p)(x)[0])
        values = {k: v[None] for k, v in full_p.to_constrained(x, full_p.data).items()
                  if k in projectile_model.unknown_names}
        ll = pointwise_log_likelihood(projectile_model, values)["ball.position"][0]
        np.testing.assert_allclose(diff, ll[late].sum(), rtol=1e-10)


def test_a_warmup_over_several_blocks_runs_the_one_compiled_block(projectile_model):
    """Blocks after the first take the carries the compiled block returned; a carry leaf made
    from a Python number (weak-typed) and returned strong-typed is another signature, which
    once compiled the NUTS block a second and a third time."""
    import logging

    physdsl.infer(projectile_model, **SETTINGS)  # compiled now or earlier in this module
    compiled = []

    class Log(logging.Handler):
        def emit(self, record):
            compiled.append(record.getMessage())

    log = Log()
    logging.getLogger("jax").addHandler(log)
    try:
        with jax.log_compiles():
            physdsl.infer(projectile_model, **{**SETTINGS, "warmup": 300})  # three warmup blocks
    finally:
        logging.getLogger("jax").removeHandler(log)
    assert not [m for m in compiled if m.startswith("Compiling jit(chain)")]
