"""Multistart: starts from the data, the prior's centre and draws; modes grouped into basins."""
import physdsl
import jax
import numpy as np
import pytest

from physdsl.infer.multistart import describe, prior_centre, residual_rms, search, start_points
from physdsl.infer.problem import make_problem, start_position

from .conftest import simulated_scene

# a throw as speed and launch angle: (s, a) and (-s, a + pi) give the same velocity, so the
# log density has two separate modes of the same fit (the priors tell them apart a little)
THROW = """\
scene throw {
  world { timestep: 5 ms  duration: 0.6 s  integrator: rk4 }
  param speed ~ normal(0 m/s, 5 m/s)
  param angle ~ normal(90 deg, 180 deg)
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity: (speed * cos(angle), 0 m/s, speed * sin(angle))
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""
TRUTH = {"speed": 4.0, "angle": np.radians(50.0)}


@pytest.fixture(scope="module")
def throw(tmp_path_factory):
    from physdsl.compile import compile as compile_phys

    scene = simulated_scene(tmp_path_factory.mktemp("throw"), THROW, TRUTH,
                            np.arange(0, 0.6001, 0.02), 0.005, seed=11)
    return make_problem(compile_phys(scene), jax.random.PRNGKey(0), 3)


def test_residual_rms_read_off_the_log_density_equals_the_residuals(throw):
    problem, x = throw
    model = problem.model
    for xi in x:
        values = problem.to_constrained(xi, problem.data)
        r = np.asarray(model.standardized_residuals(values, model.predict(values)))
        n = sum(int(o.mask.sum()) for o in model.observed)
        np.testing.assert_allclose(residual_rms(problem, xi), np.sqrt(np.sum(r**2) / n), rtol=1e-8)


def test_two_mirror_modes_are_two_basins_and_a_repeat_joins_its_own(throw):
    problem, _ = throw
    key = jax.random.PRNGKey(1)
    near = start_position(problem, key, {"speed": 3.5, "angle": np.radians(45.0)})
    again = start_position(problem, key, {"speed": 4.5, "angle": np.radians(55.0)})
    mirror = start_position(problem, key, {"speed": -3.5, "angle": np.radians(225.0)})
    found = search(problem, np.stack([near, mirror, again]), ["a", "b", "c"], 100)
    assert len(found.basins) == 2
    by_start = {s: b for b in found.basins for s in b["starts"]}
    assert by_start["a"] is by_start["c"] and by_start["b"] is not by_start["a"]
    for b in found.basins:  # both fit the data at the noise
        assert 0.7 < b["rms_sigma"] < 1.3
    assert abs(by_start["a"]["values"]["speed"] - 4.0) < 0.1
    assert abs(by_start["b"]["values"]["speed"] + 4.0) < 0.1
    lps = [b["log_density"] for b in found.basins]
    assert lps == sorted(lps, reverse=True)  # best first
    # the mirror is a real share of the posterior (a few units below): its chain stays there
    assert not np.allclose(found.modes[1], found.modes[0])
    assert "basins found: 2 (from 3 starts)" in describe(found.basins)[0]


def test_starts_are_the_data_the_centre_and_prior_draws(throw):
    problem, x = throw
    starts, labels = start_points(problem, x, jax.random.PRNGKey(2))
    assert labels == ["data", "prior centre", "prior draw 1"]
    values = problem.to_constrained(starts[0], problem.data)
    assert abs(float(values["speed"]) - 4.0) < 0.15  # (or -4 at angle + pi: the same throw)
    assert abs(float(values["angle"]) - TRUTH["angle"]) < np.radians(2)
    centre = problem.to_constrained(starts[1], problem.data)
    assert abs(float(centre["speed"])) < 1.0 and abs(float(centre["angle"]) - np.pi / 2) < 0.5
    np.testing.assert_allclose(starts[2], x[0])
    np.testing.assert_allclose(prior_centre(problem, jax.random.PRNGKey(2)), starts[1])


def test_a_map_run_prints_and_saves_its_basins(throw, tmp_path, capsys):
    import json

    problem, _ = throw
    idata = physdsl.infer(problem.model, backend="map", chains=2, warmup=50, samples=10,
                                outdir=tmp_path / "run", progress=True)
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["basins"] == json.loads(idata.attrs["basins"])
    best = run["basins"][0]
    assert "data" in best["starts"] and 0.7 < best["rms_sigma"] < 1.3
    assert abs(best["values"]["speed"] - 4.0) < 0.1
    assert "basins found:" in capsys.readouterr().err


# Two regions of one log density: near 0 a mode (quickly found); beyond 50 a slope whose
# Gauss-Newton matrix is far too stiff, so each step gains 1e-5 (more than a stall's
# ``lm.STALL_GAIN``): a search there crawls its whole budget (a start far from the basin in a
# stiff contact or chaotic rollout)
def _two_regions(x):
    x = np.asarray(x, dtype=float)
    if x[0] < 50.0:
        return -0.5 * float(x @ x), -x, np.eye(1)
    return -1e6 - float(x[0]), -np.ones(1), 1e5 * np.eye(1)


@pytest.mark.parametrize("mode_rms, crawls_to_the_end", [(1.0, False), (3.0, True)])
def test_a_search_far_below_a_mode_that_fits_stops(monkeypatch, mode_rms, crawls_to_the_end):
    """Once one start reaches a mode that fits the data, a start more than MINOR_MODE below it
    stops at the end of the round (the basins list it as stopped); where the mode does not
    fit, it runs its whole budget (it might find a better basin)."""
    from physdsl.infer import multistart as ms

    calls = {"far": 0}

    def gn(x):
        calls["far"] += float(np.asarray(x)[0]) >= 50.0
        return _two_regions(x)

    monkeypatch.setattr(ms, "gauss_newton_fn", lambda problem: gn)
    monkeypatch.setattr(ms, "value_fn", lambda problem: lambda x: _two_regions(x)[0])
    monkeypatch.setattr(ms, "residual_rms", lambda problem, x, lp=None: mode_rms)
    steps = 200
    points, stopped = ms._optimised_all(object(), np.array([[0.7], [80.0]]), steps, None,
                                        ["near", "far"], 0)
    assert abs(points[0, 0]) < 1e-6  # the mode
    assert list(stopped) == [False, crawls_to_the_end is False]
    if crawls_to_the_end:
        assert calls["far"] >= steps  # every step of its budget
        assert points[1, 0] < 80.0
    else:
        assert calls["far"] <= 2 * ms.ROUND_STEPS + 1  # the rounds until the mode was found
