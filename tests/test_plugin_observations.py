"""The extension table's observation rows, tried as a third party would: an observation kind
(``height``: a body's z) and a sensor fault (``square_law``: a reading that bends as
``y + k y |y|``), each one module plus one entry point installed at test time, are picked up by
``lint``, by the diagnosis' sensor candidates and by a fit that recovers the true values, with no
change to physdsl's files (the contact-model row: tests/test_plugin_contact.py)."""
from __future__ import annotations

import numpy as np
import pytest
from plugins import install, looked_at_again

import physdsl
from physdsl.cli import main
from physdsl.diagnose.candidates import sensor_candidates
from physdsl.infer.posterior_data import posterior_draws
from physdsl.observe.kinds import OBSERVATION_KINDS
from physdsl.observe.sensor import SENSOR_FAULTS

KIND_PLUGIN = '''
from physdsl.observe.kinds import observation_kind

@observation_kind("height", source="body_pos", columns=("h",), unit="m",
                  marker_source="marker_pos")
def height(track):
    """A body's (or marker's) height: the z of its position track (T, 3) -> (T, 1)."""
    return track[:, 2:3]
'''

FAULT_PLUGIN = '''
import jax.numpy as jnp
from physdsl.observe.sensor import sensor_fault

@sensor_fault("square_law", 0.0, "1")
def square_law(out, k):
    """A sensor whose reading bends: y + k y |y| (k in SI, per unit of the quantity)."""
    return out + k * out * jnp.abs(out)
'''

G, Z0, VZ, K = 9.81, 0.5, 4.0, 0.08  # the truth: launch height and speed, the bend
NOISE = 0.002

SCENE = """\
scene toss {
  world { timestep: 10 ms  duration: 0.8 s  integrator: rk4 }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 0.5) m
    velocity ~ normal((0, 0, 3) m/s, 2 m/s)
  }
  observe ball.height from "height.csv" where body == "ball" {
    noise: 2 mm
    square_law ~ normal(0, 0.2)
  }
}
"""


def write_data(folder) -> None:
    """Heights of a ball tossed straight up, read through the bent sensor, 2 mm noise."""
    t = np.arange(0.0, 0.8001, 0.02)
    z = Z0 + VZ * t - 0.5 * G * t**2
    y = z + K * z * np.abs(z) + np.random.default_rng(3).normal(0.0, NOISE, t.shape)
    rows = "\n".join(f"{a:.4f},ball,{b:.6f}" for a, b in zip(t, y))
    (folder / "height.csv").write_text("t,body,h\n" + rows + "\n")


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    lib = tmp_path / "site"
    lib.mkdir()
    install(lib, monkeypatch, "demo_height", KIND_PLUGIN,
            {"physdsl.observations": "height = demo_height"})
    install(lib, monkeypatch, "demo_bend", FAULT_PLUGIN,
            {"physdsl.sensor_faults": "square_law = demo_bend"})
    with looked_at_again((OBSERVATION_KINDS, SENSOR_FAULTS), ("demo_height", "demo_bend")):
        yield


def test_a_plugin_kind_and_fault_are_linted_and_fitted_back(plugins, tmp_path):
    write_data(tmp_path)
    scene_file = tmp_path / "toss.phys"
    scene_file.write_text(SCENE)
    assert main(["lint", str(scene_file)]) == 0
    scene = physdsl.load(scene_file)
    assert [c.name for c in sensor_candidates(scene) if c.target == ("ball.height",)] == \
        ["delay", "gain", "offset"]  # square_law is in the scene already: no candidate
    idata = physdsl.infer(physdsl.compile(scene), "map", seed=0)
    draws = posterior_draws(idata, ["ball.velocity", "ball.height.square_law"])
    k = np.ravel(draws["ball.height.square_law"])
    vz = np.asarray(draws["ball.velocity"])[..., 2].ravel()
    lo, hi = np.quantile(k, [0.005, 0.995])
    assert lo < K < hi and lo > 0.0, (lo, hi)  # the bend is found, its interval covers it
    assert abs(np.mean(vz) - VZ) < 4 * np.std(vz) and np.std(vz) < 0.02


def test_without_the_plugins_both_names_are_unknown(tmp_path, capsys):
    write_data(tmp_path)
    (tmp_path / "toss.phys").write_text(SCENE)
    assert main(["lint", str(tmp_path / "toss.phys")]) == 2
    err = capsys.readouterr().err
    assert "height" in err
    (tmp_path / "toss.phys").write_text(SCENE.replace("ball.height", "ball.position")
                                        .replace("height.csv", "pos.csv"))
    (tmp_path / "pos.csv").write_text("t,body,x,y,z\n0,ball,0,0,0.5\n")
    assert main(["lint", str(tmp_path / "toss.phys")]) == 2
    assert "square_law" in capsys.readouterr().err
