"""MAP keeps its mode: where the Laplace step fails (a direction the data cannot see), `infer
--backend map` still writes the mode, names the unknowns along the flat direction, exits 1,
and its hint (`--fallback rmh`) samples the posterior instead."""
from __future__ import annotations

import json

import numpy as np
import pytest

from .conftest import PROJECTILE_TIMES, simulated_scene

# the release height split into a table's height and the ball's height above it, both
# unknown with priors far wider than anything the data say: only their sum is seen
SPLIT = """\
scene split_height {
  world {
    timestep: 10 ms
    duration: 0.5 s
  }
  param table ~ normal(0.7 m, 100 km)
  param above ~ normal(0.3 m, 100 km)
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, table + above)
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 1 cm }
}
"""
TRUTH = {"table": np.array(0.7), "above": np.array(0.3), "ball.velocity": np.array([3.2, 0.4, 4.3])}
RUN = ("--backend", "map", "--chains", "2", "--warmup", "60", "--samples", "20")


@pytest.fixture(scope="module")
def split_scene(tmp_path_factory):
    return simulated_scene(tmp_path_factory.mktemp("split"), SPLIT, TRUTH, PROJECTILE_TIMES,
                           0.01, seed=2)


def test_map_writes_the_mode_and_names_the_flat_direction(split_scene, cli, tmp_path):
    from physdsl.infer import posterior_data

    out = tmp_path / "run"
    code, stdout, err = cli("infer", split_scene, "-o", out, *RUN)
    assert code == 1, err
    assert "not strictly concave" in err and "1 of 5 directions" in err
    flat_line = err[err.index("Flat or not concave along"):].splitlines()[0]
    assert "table" in flat_line and "above" in flat_line and "velocity" not in flat_line
    assert "--fallback rmh" in err
    assert "Traceback" not in err and "internal error" not in err

    run = json.loads((out / "run.json").read_text())
    assert run["laplace"] == "failed"
    (direction,) = run["laplace_directions"]
    weights = {c["name"]: c["weight"] for c in direction["components"]}
    assert set(weights) == {"table", "above"}
    assert weights["table"] == pytest.approx(-weights["above"], rel=1e-3)  # table - above
    assert run["fit_quality"]["rms_sigma"] < 1.5  # the mode itself fits the data

    post = posterior_data.group(posterior_data.read(out / "posterior.nc"), "posterior")
    assert post.sizes["chain"] == 1 and post.sizes["draw"] == 1  # the mode, a single draw
    height = float(post["table"].values.ravel()[0] + post["above"].values.ravel()[0])
    assert height == pytest.approx(1.0, abs=0.02)
    np.testing.assert_allclose(post["ball.velocity"].values.reshape(3), TRUTH["ball.velocity"],
                               atol=0.1)
    assert (out / "summary.csv").read_text().count("\n") == 1 + 5  # header + 5 components
    assert "fit: residual RMS" in stdout  # the mode's fit quality is printed too


@pytest.mark.slow  # a second fit (MAP, then random-walk Metropolis): about a minute
def test_fallback_rmh_samples_from_the_mode(split_scene, cli, tmp_path):
    from physdsl.infer import posterior_data

    out = tmp_path / "run"
    code, _, err = cli("infer", split_scene, "-o", out, *RUN, "--fallback", "rmh")
    assert code == 0, err
    assert "random-walk Metropolis" in err
    post = posterior_data.group(posterior_data.read(out / "posterior.nc"), "posterior")
    assert post.sizes["draw"] == 20
    height = (post["table"] + post["above"]).values
    assert np.all(np.abs(height - 1.0) < 0.05)  # every draw keeps the seen sum
    assert "laplace" not in json.loads((out / "run.json").read_text())


def test_fallback_goes_with_map_only(split_scene, cli, tmp_path):
    code, _, err = cli("infer", split_scene, "-o", tmp_path / "run", "--backend", "nuts",
                       "--fallback", "rmh")
    assert code == 2 and "--fallback rmh goes with --backend map" in err
