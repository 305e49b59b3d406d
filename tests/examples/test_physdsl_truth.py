"""End to end: each example scene, simulated by physdsl at the true unknowns of its truth.json,
reproduces its data to within the stated noise (the data came from MuJoCo). This checks the
examples' geometry conventions and the engine together; slow (one jit compile per scene)."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from conftest import EXAMPLES

SCENES = sorted(p for p in EXAMPLES.glob("*/*.phys"))


def _rms_over_sigma(scene, sim, rollout, obs):
    from physdsl.expr import evaluate

    idx = np.rint(obs.times / sim.model.dt).astype(int)
    if obs.quantity == "position":
        model = np.asarray(rollout.body_pos)[idx, sim.body_names.index(obs.target)]
    elif obs.quantity == "orientation":
        model = np.asarray(rollout.body_quat)[idx, sim.body_names.index(obs.target)]
        model = model * np.sign(np.sum(model * obs.values, axis=1))[:, None]  # q and -q agree
    else:
        model = np.asarray(rollout.joint_pos)[idx, sim.joint_names.index(obs.target)][:, None]
    sigma = float(np.asarray(evaluate(obs.noise.scale, {})))
    return float(np.sqrt(np.mean((model - obs.values) ** 2)) / sigma)


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.parent.name)
def test_physdsl_at_truth_reproduces_the_data(path):
    syntax = pytest.importorskip("physdsl.syntax")
    physics = pytest.importorskip("physdsl.physics")
    scene = syntax.load(path)
    truth = json.loads((path.parent / "truth.json").read_text())
    assert {u.name for u in scene.unknowns} == set(truth["unknowns"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = physics.build_simulator(scene)
        rollout = sim.simulate(truth["unknowns"])
    ratios = {f"{o.target}.{o.quantity}": _rms_over_sigma(scene, sim, rollout, o) for o in scene.observations}
    # 1 ms steps against MuJoCo's finer ones: impacts land up to a step apart, hence 1.5
    assert all(0.8 < r < 1.5 for r in ratios.values()), ratios
