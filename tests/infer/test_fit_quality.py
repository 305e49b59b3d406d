"""Fit quality, printed and saved by every `infer`: the check's own numbers (residual RMS in
noise units overall and per observable, worst window, verdict), and a warning in words where
the fit is far from the data; the posterior pass gives the same results one draw at a time or vmapped."""
from __future__ import annotations

import physdsl

import json

import numpy as np
import pytest


@pytest.fixture(scope="module")
def good(projectile_model):
    return physdsl.infer(projectile_model, backend="map", chains=2, warmup=100, samples=20, seed=1,
                                  progress=False)


def _shifted(model, idata, name: str, delta: float):
    """``idata``'s draws with the unconstrained coordinate ``name`` moved by ``delta``."""
    from physdsl.infer.backends.map import coordinate_names
    from physdsl.infer.base import Settings
    from physdsl.infer.output import build_inference_data
    from physdsl.infer.problem import model_problem
    from numpyro.infer.util import unconstrain_fn
    from jax.flatten_util import ravel_pytree

    problem = model_problem(model)
    post = idata.posterior
    values = {u.name: np.asarray(post[u.name].values[0, 0]) for u in model.unknowns}
    x = np.array(ravel_pytree(unconstrain_fn(model.prior_values, (), {}, values))[0])
    x[coordinate_names(problem).index(name)] += delta
    return build_inference_data(model, problem, x[None, None, :], {}, Settings())


def test_fit_quality_is_the_checks_numbers(projectile_model, good):
    from physdsl.diagnose.workflow import check_model
    from physdsl.diagnose.quality import fit_quality

    q = fit_quality(projectile_model, good)
    report = check_model(projectile_model, good)
    assert q["rms_sigma"] == report.rms_sigma
    assert q["observables"] == {"ball.position": report.observables[0].rms_sigma}
    worst = max(report.observables[0].windows, key=lambda w: w.rms_sigma)
    assert q["worst_window"]["rms_sigma"] == worst.rms_sigma
    assert q["worst_window"]["label"] == worst.label
    assert 0.5 < q["rms_sigma"] < 1.5 and q["consistent"] and q["warnings"] == []
    (start,) = q["starts"]
    assert start["observable"] == "ball.position" and start["sigma"] < 5


def test_a_fit_far_from_the_data_is_said_to_describe_a_wrong_model(projectile_model, good):
    from physdsl.diagnose.quality import fit_quality, fit_quality_lines

    off = _shifted(projectile_model, good, "ball.velocity[0]", 0.5)  # 0.5 m/s too fast
    q = fit_quality(projectile_model, off)
    assert q["rms_sigma"] > 3 and not q["consistent"]
    (w,) = q["warnings"]
    assert "far from the data" in w and "model that does not fit" in w
    lines = fit_quality_lines(q)
    assert lines[0].startswith("fit: residual RMS") and "ball.position" in lines[0]
    assert lines[-1].startswith("  check: ") and q["verdict"] in lines[-1]


def test_a_start_far_from_the_first_samples_is_flagged(projectile_model, good):
    from dataclasses import replace

    from physdsl.diagnose.workflow import observable_fits
    from physdsl.diagnose.quality import FAR_START, start_agreement

    fits = observable_fits(projectile_model, good)
    (near,) = start_agreement(projectile_model, fits)
    moved = [replace(f, point=f.point + np.array([0.0, 0.0, 0.1])) for f in fits]  # 10 cm up
    (far,) = start_agreement(projectile_model, moved)
    assert near["sigma"] < FAR_START < far["sigma"]
    assert far["fitted"].startswith("(") and far["fitted"].endswith(" m")


def test_posterior_pass_one_by_one_equals_vmapped(projectile_model, good, monkeypatch):
    """The pass through the fit's own value function (one draw a call, the scene's one
    compiled rollout) gives the vmapped pass's numbers, also where it hands the draws left to
    the vmapped pass (long rollouts: ``vmap_after``) in calls of ``PASS_CHUNK``; and that
    value function is the log density."""
    import jax
    from physdsl.infer import output
    from physdsl.infer.base import value_fn
    from physdsl.infer.problem import model_problem

    problem = model_problem(projectile_model)
    rng = np.random.default_rng(0)
    centre = np.array([3.2, 0.4, 4.3, np.log(0.3)])  # velocity, log drag (the flat order)
    flat = centre + rng.normal(0.0, 0.05, (20, problem.dim))
    seen = []
    one_by_one = output.posterior_pass(projectile_model, problem, flat, on_chunk=seen.append)
    assert sum(seen) == 20 and seen[:2] == [1, 1]  # the first two calls time a draw
    vmapped = output.posterior_pass(projectile_model, problem._replace(draw=None), flat)
    # a contact-free scene whose loop is one kernel (physdsl's XLA options) is never vmapped
    monkeypatch.setattr(output.xla_flags, "in_effect", lambda: True)
    assert output.vmap_after(projectile_model) == np.inf
    monkeypatch.setattr(output.xla_flags, "in_effect", lambda: False)  # as without the options
    monkeypatch.setattr(output, "VMAP_AFTER_S", 0.0)  # every rollout counts as long
    monkeypatch.setattr(output, "VMAP_AFTER_FREE_S", 0.0)
    monkeypatch.setattr(output, "PASS_CHUNK", 7)
    mixed_seen = []
    mixed = output.posterior_pass(projectile_model, problem, flat, on_chunk=mixed_seen.append)
    # the first two time a draw; the vmapped chunks run on threads and report as they finish
    assert mixed_seen[:2] == [1, 1] and sorted(mixed_seen[2:]) == [4, 7, 7]
    assert set(one_by_one[0]) == set(vmapped[0]) == {"ball.velocity", "linear_drag@ball.coefficient",
                                                      "pred:ball.position"}
    leaves = [jax.tree_util.tree_leaves(t) for t in (one_by_one, vmapped, mixed)]
    for a, b, c in zip(*leaves):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(c, b, rtol=1e-10, atol=1e-12)
    value = value_fn(problem)
    for x in flat[:3]:
        np.testing.assert_allclose(float(value(x)), float(problem.logdensity(x, problem.data)),
                                   rtol=1e-12)


def test_infer_prints_and_saves_the_fit_quality(projectile_scene, cli, tmp_path):
    out = tmp_path / "run"
    code, stdout, err = cli("infer", projectile_scene, "-o", out, "--backend", "map",
                            "--chains", "2", "--warmup", "100", "--samples", "20")
    assert code == 0, err
    assert "fit: residual RMS" in stdout and "check: " in stdout
    for stage in ("compile", "optimise", "laplace", "sampling", "predictions", "intervals",
                  "fit quality"):
        assert f"{stage}: done in" in err  # progress of every stage on stderr
    q = json.loads((out / "run.json").read_text())["fit_quality"]
    assert 0.5 < q["rms_sigma"] < 1.5 and q["verdict"]


def test_a_failing_quality_check_does_not_lose_the_fit(good, monkeypatch):
    from physdsl.diagnose.quality import fit_quality_lines
    from physdsl.infer import run
    from physdsl.infer.progress import Stages

    def broken(model, idata):
        raise ValueError("no trajectory")

    idata = good.copy()
    q = run._fit_quality(broken, None, idata, Stages(enabled=False))["fit_quality"]
    assert q == {"error": "ValueError: no trajectory", "warnings": []}
    assert fit_quality_lines(q) == ["fit: quality not computed (ValueError: no trajectory)"]
    assert "fit_quality" in idata.attrs
