"""HMC and RMH on a pooled scene: three pushed runs (per-recording control files and launch
velocities from the manifest, a per-recording launch height, one shared mass); each backend's
90% interval of the shared mass covers its truth and every run's height lands on its own."""
from __future__ import annotations

import numpy as np
import pytest

import physdsl

from .helpers import interval
from .test_controls import MASS, PUSHES, SCENE, write_runs

KNOWN_LAUNCH = SCENE.replace(
    "    position: (0, 0, 1) m\n    velocity ~ per_experiment normal((1, 0, 2) m/s, 2 m/s)\n",
    "    position: (0, 0, z0)\n    velocity: (runs.vx, runs.vy, runs.vz)\n").replace(
    "  body ball {", "  param z0 ~ per_experiment normal(1 m, 5 cm)\n  body ball {")


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    root = tmp_path_factory.mktemp("pooled_backends")
    write_runs(root)
    lines = (root / "runs.csv").read_text().splitlines()
    lines = [lines[0] + ",vx [m/s],vy [m/s],vz [m/s]"] + [
        row + "," + ",".join(str(v) for v in PUSHES[row.split(",")[0]][2]) for row in lines[1:]]
    (root / "runs.csv").write_text("\n".join(lines) + "\n")
    (root / "scene.phys").write_text(KNOWN_LAUNCH)
    return physdsl.compile(root / "scene.phys")


@pytest.mark.parametrize("backend, settings", [
    # HMC: 37 s CPU in a fresh process, 33 s of it compiling its programs (4.8 s once compiled)
    pytest.param("hmc", dict(warmup=100, samples=150, integration_steps=8),
                 marks=pytest.mark.slow),
    ("rmh", dict(warmup=1500, samples=1500)),
])
def test_backend_covers_the_shared_mass_on_a_pooled_scene(model, backend, settings):
    idata = physdsl.infer(model, backend=backend, chains=2, seed=2, progress=False, **settings)
    lo, hi = interval(idata, "ball.mass")
    assert lo <= MASS <= hi and hi - lo < 0.05 * MASS
    z0 = idata.posterior["z0"]
    assert z0.dims[2] == "experiment" and list(z0["experiment"].values) == ["a", "b", "c"]
    z = np.asarray(z0.values).reshape(-1, 3)
    assert np.all(np.abs(z.mean(axis=0) - 1.0) < 4 * z.std(axis=0) + 1e-4)
    assert np.all(z.std(axis=0) < 0.005)  # each run's height pinned by its own data
