"""Issue 21: the block check (``infer/block_check.py``) sees a model mismatch that white
residuals hide, and leaves intervals alone where the model made the data.

A projectile with linear drag (51 positions over 0.5 s, 2 mm noise): data simulated by the
same scene (right model) and by the scene with quadratic drag instead (wrong law: the fit
is still at ~1.0σ, its residuals look white, and its launch velocity is 9-12 sd off)."""
from __future__ import annotations

import numpy as np
import pytest

import physdsl
from physdsl.compile import compile as compile_phys
from physdsl.infer.backends.map import find_mode
from physdsl.infer.block_check import LEVEL, block_factors
from physdsl.infer.intervals import GROUP, _physical_dims
from physdsl.infer.multistart import residual_rms
from physdsl.infer.problem import model_problem

from .conftest import PROJECTILE, PROJECTILE_TRUTH, simulated_scene

TIMES = np.linspace(0.0, 0.5, 51)
NOISE = 0.002
TEXT = PROJECTILE.replace("NOISE", "2 mm")
QUADRATIC = TEXT.replace("effect linear_drag on ball { coefficient ~ half_normal(0.5 kg/s) }",
                         "effect quadratic_drag on ball { coefficient ~ half_normal(0.5 kg/m) }")
VELOCITY = PROJECTILE_TRUTH["ball.velocity"]


def _fitted(folder, seed, wrong: bool):
    """(problem, mode, physical coordinates) of the linear-drag scene fitted to data made by
    itself or (``wrong``) by the quadratic-drag scene at 0.02 kg/m."""
    if wrong:
        scene = simulated_scene(folder, QUADRATIC, {"ball.velocity": VELOCITY,
                                "quadratic_drag@ball.coefficient": np.array(0.02)},
                                TIMES, NOISE, seed)
        scene.write_text(TEXT)
    else:
        scene = simulated_scene(folder, TEXT, PROJECTILE_TRUTH, TIMES, NOISE, seed)
    model = compile_phys(scene)
    problem = model_problem(model)
    mode = find_mode(problem, np.zeros(problem.dim), 300)
    return problem, mode, _physical_dims(model, problem.dim)


def test_right_model_is_not_widened(tmp_path):
    for seed in range(3):
        problem, mode, keep = _fitted(tmp_path / f"right{seed}", seed, wrong=False)
        found = block_factors(problem, mode, keep)
        assert found["blocks"] == 8 and found["p_value"] >= LEVEL, found
        assert np.all(found["factors"] == 1.0)


def test_mismatch_with_white_residuals_is_seen_and_widens(tmp_path):
    problem, mode, keep = _fitted(tmp_path / "wrong", 0, wrong=True)
    assert residual_rms(problem, mode) < 1.1  # the residuals alone do not tell
    found = block_factors(problem, mode, keep)
    assert found["p_value"] < 1e-6
    assert np.all(found["factors"][[0, 2]] > 3.0)  # vx, vz: the launch in the drag's plane


@pytest.mark.parametrize("wrong", [False, True])
def test_run_intervals_right_model_kept_wrong_model_widened(tmp_path, wrong):
    """Through ``physdsl.infer``: robust within 1.2x of the posterior's width on data the
    model made; on the quadratic-drag data wider than 3x, and nearer the true velocity in
    its own sd units."""
    problem, _, _ = _fitted(tmp_path / "d", 1, wrong=wrong)
    idata = physdsl.infer(problem.model, backend="map", chains=2, samples=300, seed=0,
                          progress=False)
    post = np.asarray(idata.posterior["ball.velocity"].values).reshape(-1, 3)
    rob = np.asarray(getattr(idata, GROUP)["ball.velocity"].values).reshape(-1, 3)
    ratio = rob.std(axis=0) / post.std(axis=0)
    if not wrong:
        assert np.all(ratio < 1.2), ratio
        return
    assert np.all(ratio[[0, 2]] > 3.0), ratio
    z_model = np.abs(post.mean(axis=0) - VELOCITY) / post.std(axis=0)
    z_robust = np.abs(rob.mean(axis=0) - VELOCITY) / rob.std(axis=0)
    assert np.all(z_model[[0, 2]] > 5.0) and np.all(z_robust[[0, 2]] < z_model[[0, 2]] / 3)
