"""Progress: warmup and sampling advance their bars once per block of transitions."""
from __future__ import annotations

from contextlib import contextmanager

import jax
import jax.numpy as jnp
import numpy as np

from physdsl.infer.base import Problem
from physdsl.infer.blocks import block_runner, run_blocks


def test_run_blocks_reports_each_block():
    problem = Problem(None, None, 1, None, jnp.zeros(()), {})
    run = block_runner(problem, "count", lambda data, k, c, shared, i: (c + 1.0, c), 100)
    calls = []
    carries, outs = run_blocks(run, problem, jax.random.PRNGKey(0), jnp.zeros(3), 250, 100,
                               on_block=calls.append)
    assert calls == [100, 100, 50]
    assert outs.shape == (3, 250) and np.all(np.asarray(carries) == 250)
    assert np.array_equal(outs[0], np.arange(250.0))


def test_infer_advances_warmup_per_block(projectile_model, monkeypatch):
    from physdsl.infer import run as run_module
    from physdsl.infer.progress import Stages

    advances: dict[str, list[int]] = {}

    class Recording:
        def __init__(self, enabled=True):
            pass

        @contextmanager
        def stage(self, name, total=None, completed=0):
            st = Stages(enabled=False).stage(name, total, completed)
            with st as s:
                original = s.advance

                def advance(n):
                    advances.setdefault(name, []).append(n)
                    original(n)
                s.advance = advance
                yield s

    monkeypatch.setattr(run_module, "Stages", Recording)
    projectile_model.infer(backend="rmh", chains=2, warmup=250, samples=150, block=100, seed=0)
    assert advances["warmup"] == [100, 100, 50]
    assert advances["sampling"] == [100, 50]
