"""Fitting an exported program again on the original data agrees with the first fit (slow)."""
from __future__ import annotations

import physdsl

from pathlib import Path

import numpy as np
import pytest

from physdsl import syntax
from physdsl.compile import compile_scene
from physdsl.export import export
from physdsl.sample import parameter_values

DATA = Path(__file__).resolve().parent / "data"
TOSS = DATA / "toss.phys"


@pytest.mark.slow  # two NUTS fits of the toss (about 80 s CPU, 5-6 min under load)
def test_refit_of_the_exported_program_is_consistent(tmp_path):
    settings = dict(chains=2, warmup=150, samples=200, seed=1, progress=False, max_tree_depth=5,
                    init_steps=100)
    first = physdsl.infer(compile_scene(syntax.load(TOSS)), **settings)
    proto = tmp_path / "proto.phys"
    proto.write_text(export(TOSS, first, out_path=proto))
    scene = syntax.load(proto)
    second = physdsl.infer(compile_scene(scene), **settings)
    draws = {u.name: np.asarray(second.posterior[u.name].values).reshape(-1, *u.shape)
             for u in scene.unknowns}
    module = syntax.parse(proto.read_text(), str(proto))
    again = parameter_values(module, draws, {u.name: u.unit for u in scene.unknowns})
    for name in ("ball.mass", "h0", "ball.velocity", "quadratic_drag@ball.coefficient"):
        a = np.asarray(first.posterior[name].values).reshape(-1, *again[name][0].shape[1:])
        b = again[name][0]
        sd = a.std(0)
        # same place; the data counted twice can only sharpen: by sqrt 2 where the data
        # dominate, less where the prior still counts (measured sd ratios: h0 0.71, velocity
        # 0.81, 0.67, 0.77, drag 0.85, mass 0.94; mass is known only through drag / mass)
        assert np.all(np.abs(a.mean(0) - b.mean(0)) < 2.0 * sd + 1e-12), name
        assert np.all(b.std(0) < 1.1 * sd) and np.all(b.std(0) > 0.55 * sd), name
