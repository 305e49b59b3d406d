"""Progress: warmup and sampling advance their bars once per call of the compiled block; the
calls are cut by measured time (``blocks.Pacer``), and the draws do not depend on the cut."""
from __future__ import annotations

import physdsl

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
    assert sum(calls) == 250 and max(calls) <= 100 and calls[0] == 1  # the first call compiles
    assert outs.shape == (3, 250) and np.all(np.asarray(carries) == 250)
    assert np.array_equal(outs[0], np.arange(250.0))


def test_pacer_sizes_calls_by_the_time_per_transition():
    from physdsl.infer.blocks import Pacer

    p = Pacer(target=1.0)
    assert p.next(500, 100) == 1  # unknown cost: one transition
    p.record(1, 30.0)  # the first call: compilation, not timed
    assert p.next(500, 100) == 1
    p.record(1, 0.25)
    assert p.next(500, 100) == 4  # four transitions of 0.25 s: a second
    p.record(4, 0.004)
    assert p.next(500, 100) == 100 and p.next(30, 100) == 30  # capped by the buffer, the rest
    p.record(100, 300.0)  # 3 s a transition (a contact scene): still one per call
    assert p.next(500, 100) == 1


def test_draws_do_not_depend_on_how_the_calls_were_cut():
    """A transition's random numbers depend on its number alone: 250 transitions in calls of
    whatever size, or in two runs of 90 and 160 (a resume), give the same outputs."""
    from physdsl.infer import blocks

    problem = Problem(None, None, 1, None, jnp.zeros(()), {})
    run = block_runner(problem, "noise",
                       lambda data, k, c, shared, i: (c + jax.random.normal(k), c), 100)
    key = jax.random.PRNGKey(3)
    whole = run_blocks(run, problem, key, jnp.zeros(2), 250, 100)
    blocks.pacer_of(run).per = None  # cut differently: calls of one, then by time
    first = run_blocks(run, problem, key, jnp.zeros(2), 90, 100)
    rest = run_blocks(run, problem, key, first[0], 160, 100, offset=90)
    np.testing.assert_array_equal(np.asarray(whole[0]), np.asarray(rest[0]))
    np.testing.assert_array_equal(whole[1], np.concatenate([first[1], rest[1]], axis=1))


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
    physdsl.infer(projectile_model, backend="rmh", chains=2, warmup=250, samples=150, block=100, seed=0)
    assert sum(advances["warmup"]) == 250 and max(advances["warmup"]) <= 100
    assert sum(advances["sampling"]) == 150 and max(advances["sampling"]) <= 100
    assert sum(advances["predictions"]) == 2 * 150
    assert advances["intervals"] == [1] * 8  # the block check's refits, one by one
