"""The extension table's other rows, tried as a third party would: a prior distribution and an
inference backend, each one module plus one entry point installed at test time, are picked up
by the language and by ``physdsl infer`` with no change to physdsl's files (the effect row:
tests/test_plugin_effect.py)."""
from __future__ import annotations

import numpy as np
import pytest
from plugins import install, looked_at_again

import physdsl
from physdsl.cli import main
from physdsl.infer.base import BACKENDS, get_backend
from physdsl.infer.posterior_data import posterior_draws
from physdsl.syntax.dists import DISTRIBUTIONS

DISTRIBUTION_PLUGIN = '''
import numpyro.distributions as nd
from physdsl.syntax.dists import register_distribution

@register_distribution("wide_normal")
def wide_normal(loc, scale, **options):
    """A normal twice as wide as written (a stand-in for a lab's own prior)."""
    return nd.Normal(loc, 2.0 * scale, **options)
'''

BACKEND_PLUGIN = '''
from physdsl.infer.backends.rmh import RMH
from physdsl.infer.base import register_backend

@register_backend
class DemoRMH(RMH):
    """Random-walk Metropolis under another name: a plug-in sampler."""
    name = "demo_rmh"
'''

SCENE = """\
scene drop {
  world {
    timestep: 10 ms
    duration: 0.5 s
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass ~ wide_normal(1 kg, 0.1 kg)
    position: (0, 0, 1) m
  }
}
"""


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    install(tmp_path, monkeypatch, "demo_prior", DISTRIBUTION_PLUGIN,
            {"physdsl.distributions": "wide_normal = demo_prior"})
    install(tmp_path, monkeypatch, "demo_sampler", BACKEND_PLUGIN,
            {"physdsl.backends": "demo_rmh = demo_sampler"})
    with looked_at_again((DISTRIBUTIONS, BACKENDS), ("demo_prior", "demo_sampler")):
        yield


def test_a_plugin_distribution_is_a_prior_of_the_language(plugins, tmp_path, capsys):
    scene = tmp_path / "drop.phys"
    scene.write_text(SCENE)
    assert main(["lint", str(scene)]) == 0
    draws = physdsl.compile(scene).sample_prior(__import__("jax").random.PRNGKey(0), 4000)
    assert abs(np.std(draws["ball.mass"]) - 0.2) < 0.01  # its own law, not numpyro's normal


def test_a_plugin_backend_samples_through_infer(plugins, tmp_path):
    model = physdsl.compile(SCENE.replace("wide_normal", "normal"))
    idata = physdsl.infer(model, "demo_rmh", chains=2, warmup=200, samples=400, seed=1)
    draws = posterior_draws(idata, ["ball.mass"])["ball.mass"]
    assert type(get_backend("demo_rmh")).__module__ == "demo_sampler"
    assert abs(np.mean(draws) - 1.0) < 0.05  # no data: the prior, normal(1 kg, 0.1 kg)


def test_without_the_plugins_both_names_are_unknown(tmp_path, capsys):
    scene = tmp_path / "drop.phys"
    scene.write_text(SCENE)
    assert main(["lint", str(scene)]) == 2
    assert "wide_normal" in capsys.readouterr().err
    assert "demo_rmh" not in BACKENDS
