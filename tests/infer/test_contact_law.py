"""The contact law's error term (``physdsl/infer/contact_law.py``): an unknown that only an
impact informs gets intervals that cover the truth when the data come from a slightly
different contact law, and scenes without contacts keep their intervals bit for bit."""
from __future__ import annotations

import physdsl

import json

import numpy as np
import pytest

from jax.flatten_util import ravel_pytree
from numpyro.infer.util import unconstrain_fn

from physdsl.compile import compile as compile_phys
from physdsl.infer import contact_law, intervals
from physdsl.infer.backends.map import find_mode
from physdsl.infer.base import gauss_newton_fn
from physdsl.infer.problem import model_problem

from .conftest import interval_contains, write_trajectory_csv

Z90 = 1.6448536269514722

# Ball a (known mass and speed) hits ball b at rest head-on, in free space; only b is
# tracked, so b's mass is informed by the impact alone (its speed after it) and a wrong
# rebound is absorbed into the mass, leaving white residuals.
COLLISION = """\
scene collision {
  world {
    timestep: 5 ms
    duration: 0.6 s
    gravity: (0, 0, 0) m/s^2
  }
  param xb ~ normal(0.4 m, 1 cm)
  body a {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 0) m
    velocity: (1, 0, 0) m/s
  }
  body b {
    shape: sphere(radius: 5 cm)
    mass ~ uniform(100 g, 600 g)
    position: (xb, 0 m, 0 m)
    velocity: (0, 0, 0) m/s
  }
CONTACT
  observe b.position from "data.csv" where body == "b" { noise: 1 mm }
}
"""
TRUTH = {"xb": np.array(0.4), "b.mass": np.array(0.3)}
TIMES = np.linspace(0.0, 0.6, 61)
E_TRUE = 0.96  # the data's law: restitution 0.96 where the scene says elastic (1)


@pytest.fixture(scope="module")
def collision(tmp_path_factory):
    """(the elastic scene's Model, data made with restitution ``E_TRUE``, 1 mm noise)."""
    folder = tmp_path_factory.mktemp("collision")
    write_trajectory_csv(folder / "data.csv", TIMES, np.zeros((TIMES.size, 3)), "b")
    made = folder / "made.phys"
    made.write_text(COLLISION.replace("CONTACT", f"  contact a, b {{ restitution: {E_TRUE} }}"))
    pred = np.asarray(compile_phys(made).predict(TRUTH)["b.position"])
    noisy = pred + np.random.default_rng(5).normal(0.0, 1e-3, pred.shape)
    write_trajectory_csv(folder / "data.csv", TIMES, noisy, "b")
    scene = folder / "scene.phys"
    scene.write_text(COLLISION.replace("CONTACT", ""))
    return compile_phys(scene)


def test_the_term_covers_what_the_impact_informs(collision):
    """At the mode of the elastic scene: the true mass is many posterior sd away, and within
    1.645 sd of the posterior with the term (unconstrained coordinates, names sorted: b.mass,
    xb); the data cannot tell the rebound from the mass, so eta keeps its prior width."""
    problem = model_problem(collision)
    truth = np.asarray(ravel_pytree(unconstrain_fn(collision.prior_values, (), {}, TRUTH))[0])
    mode = find_mode(problem, truth, 40)
    plain = np.linalg.inv(np.asarray(gauss_newton_fn(problem)(mode)[2]))
    found = contact_law.marginal_covariance(collision, problem, mode)
    robust = plain + found["cov"]
    z_plain = np.abs(truth - mode) / np.sqrt(np.diag(plain))
    z_robust = np.abs(truth - mode) / np.sqrt(np.diag(robust))
    assert z_plain[0] > 3 * Z90 and z_robust[0] < Z90, (z_plain, z_robust)
    assert found["pairs"] == ["a,b"] and found["eta_sd"][0] > 0.9 * contact_law.WIDTH
    assert np.all(np.linalg.eigvalsh(found["cov"]) > -1e-12 * np.abs(found["cov"]).max())


def test_a_fit_with_robust_intervals_compiles_the_term_ahead(collision, monkeypatch):
    """``fit_ahead.compile_ahead(robust=True)`` queues the term's rollout program, and the term
    runs that executable (``physdsl.ahead``); a fit without robust intervals does not queue it."""
    from physdsl import ahead
    from physdsl.infer.fit_ahead import compile_ahead

    monkeypatch.setenv(ahead.ENV, "on")
    problem = model_problem(collision)
    key = ("contact-law-residuals", ("contact_law:a,b",))
    compile_ahead(problem, starts=False)
    assert key not in problem.cache or not problem.cache[key]._ahead
    compile_ahead(problem, starts=False, robust=True)
    (pending,) = problem.cache[key]._ahead.values()
    truth = np.asarray(ravel_pytree(unconstrain_fn(collision.prior_values, (), {}, TRUTH))[0])
    assert contact_law.marginal_covariance(collision, problem, truth)["pairs"] == ["a,b"]
    assert pending.called and pending.compiled is not None


@pytest.mark.slow
def test_an_impact_informed_unknown_is_covered_under_another_contact_law(collision):
    """The same through ``infer``: the robust intervals name the term and cover the mass."""
    idata = physdsl.infer(collision, backend="map", chains=2, samples=200, seed=1, progress=False)
    robust = getattr(idata, intervals.GROUP)
    plain = interval_contains(idata.posterior["b.mass"].values, 0.3)
    assert not plain  # the elastic law's posterior excludes the true mass
    assert interval_contains(robust["b.mass"].values, 0.3)
    assert contact_law.METHOD in robust.attrs["method"]
    found = json.loads(robust.attrs["contact_law"])
    assert found["pairs"] == ["a,b"] and found["widened"]
    # the data cannot tell the rebound from the mass: eta keeps (nearly) its prior width
    assert found["eta_sd"][0] > 0.5 * contact_law.WIDTH
    sd = lambda ds, k: float(np.std(np.asarray(ds[k].values)))  # noqa: E731
    assert sd(robust, "b.mass") > 5 * sd(idata.posterior, "b.mass")
    assert "contact law" in intervals.describe(idata)


def test_contact_free_scene_never_computes_the_term(projectile_model, monkeypatch):
    """No contact pair: the term is not computed at all, so the intervals are those without
    it, bit for bit."""
    def called(*args, **kwargs):
        raise AssertionError("contact_law.marginal_covariance called on a contact-free scene")

    monkeypatch.setattr(contact_law, "marginal_covariance", called)
    idata = physdsl.infer(projectile_model, backend="map", chains=2, samples=200, seed=2,
                          progress=False)
    robust = getattr(idata, intervals.GROUP)
    assert json.loads(robust.attrs["contact_law"]) == {"note": "not run"}
    assert "contact law" not in robust.attrs["method"]


def test_augmented_scene_scales_only_fixed_restitutions(collision):
    """A pair whose restitution is an unknown fits its own rebound: no nuisance there."""
    scene = collision.scene
    assert contact_law.nuisance_pairs(scene) == [("a", "b")]
    aug = contact_law.augmented_scene(scene, [("a", "b")])
    uses = [u for u in aug.effects if u.effect == "restitution"]
    assert len(uses) == 1 and contact_law.scale_name(("a", "b")) in \
        contact_law.references(uses[0].params["coefficient"])


@pytest.mark.slow  # two CLI fits (~37 s); the term itself: the tests above
def test_a_pair_that_never_impacts_leaves_the_intervals_as_they_are(tmp_path):
    """A pair with a fixed restitution that does not impact within the record (a sliding
    block's floor, a ball rolling on a ramp) has no rebound to be wrong: the term is zero and
    the intervals are those without it (it had raised KeyError 'width' and ended the fit)."""
    xb = 2.0  # ball a covers 0.6 m in 0.6 s: it never reaches b
    truth = {"xb": np.array(xb), "b.mass": np.array(0.3)}
    write_trajectory_csv(tmp_path / "data.csv", TIMES, np.zeros((TIMES.size, 3)), "b")
    text = COLLISION.replace("CONTACT", "  contact a, b { restitution: 1 }").replace(
        "normal(0.4 m, 1 cm)", f"normal({xb} m, 1 cm)")
    made = tmp_path / "made.phys"
    made.write_text(text)
    pred = np.asarray(compile_phys(made).predict(truth)["b.position"])
    noisy = pred + np.random.default_rng(3).normal(0.0, 1e-3, pred.shape)
    write_trajectory_csv(tmp_path / "data.csv", TIMES, noisy, "b")
    model = compile_phys(made)
    assert contact_law.nuisance_pairs(model.scene) == [("a", "b")]
    idata = physdsl.infer(model, backend="map", chains=2, samples=200, seed=1, progress=False)
    robust = getattr(idata, intervals.GROUP)
    found = json.loads(robust.attrs["contact_law"])
    assert found["pairs"] == [] and not found["widened"]
    assert "contact law" not in robust.attrs["method"]
    assert interval_contains(robust["xb"].values, xb)
