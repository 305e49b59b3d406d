"""A fit compiles its posterior rollout, its Gauss-Newton program and its starts' programs ahead
(``physdsl.ahead``, ``infer.fit_ahead``): each runs the executable compiled
ahead, the jitted functions compile nothing, and the fit equals one with compiling ahead off."""
from __future__ import annotations

import physdsl

import numpy as np

from physdsl import ahead
from physdsl.compile import compile as compile_phys
from physdsl.infer.multistart import CENTRE_DRAWS
from physdsl.infer.problem import model_problem

from .conftest import PROJECTILE_NOISE, PROJECTILE_TRUTH, projectile_text, simulated_scene

TIMES = np.linspace(0.0, 0.4, 9)  # a structure of its own (another duration)
SETTINGS = dict(backend="map", chains=2, warmup=50, samples=50, seed=1, progress=False)


def test_a_fit_runs_the_programs_it_compiled_ahead(tmp_path, monkeypatch):
    monkeypatch.setenv(ahead.ENV, "on")
    model = compile_phys(simulated_scene(tmp_path, projectile_text(), PROJECTILE_TRUTH, TIMES,
                                         PROJECTILE_NOISE, seed=5))
    fit = physdsl.infer(model, **SETTINGS)
    gn = model_problem(model).gauss_newton
    rollout = model.likelihood_simulator._jit
    # and the starts' programs (the prior's centre, the start from the data), queued behind
    # the Gauss-Newton program: the fit compiled them while it waited for that one
    cache = model_problem(model).cache
    centre = cache[("prior-draws", CENTRE_DRAWS)]
    from_data = next(v for k, v in cache.items() if isinstance(k, tuple) and k[0] == "data-start-misfit")
    for program in (gn, rollout, centre, from_data):
        assert len(program._ahead) == 1
        assert program.jitted._cache_size() == 0  # every call ran the executable made ahead
        assert next(iter(program._ahead.values())).compiled is not None

    monkeypatch.setenv(ahead.ENV, "off")
    other = compile_phys(simulated_scene(tmp_path / "off", projectile_text(), PROJECTILE_TRUTH,
                                         np.linspace(0.0, 0.45, 10), PROJECTILE_NOISE, seed=5))
    plain = physdsl.infer(other, **SETTINGS)
    assert model_problem(other).gauss_newton._ahead == {}
    for name in ("ball.velocity", "linear_drag@ball.coefficient"):  # both fits recover the truth
        for f in (fit, plain):
            d = np.asarray(f.posterior[name].values)
            assert np.all(np.abs(d.mean(axis=(0, 1)) - PROJECTILE_TRUTH[name]) < 4 * d.std(axis=(0, 1)))
