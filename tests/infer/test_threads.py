"""Calls spread over threads (infer/threads.py) come back in order and equal to one after
another; the CPU layout of the samplers' chains (a thread a chain) gives the draws of chains
run alone."""
from __future__ import annotations

import numpy as np
import pytest

from physdsl.infer import threads


def test_thread_map_keeps_order_and_raises(monkeypatch):
    monkeypatch.setenv("PHYSDSL_THREADS", "3")
    assert threads.workers() == 3
    assert threads.thread_map(lambda x: x * x, range(10)) == [x * x for x in range(10)]

    def fail(x):
        if x == 4:
            raise ValueError("four")
        return x

    with pytest.raises(ValueError, match="four"):
        threads.thread_map(fail, range(8))


@pytest.mark.parametrize("n, parts", [(10, 3), (2, 4), (0, 2), (7, 1)])
def test_split_cuts_into_consecutive_runs(n, parts):
    runs = threads.split(range(n), parts)
    assert [x for run in runs for x in run] == list(range(n))
    assert len(runs) <= max(1, parts) and all(runs)
    if runs:
        sizes = [len(r) for r in runs]
        assert max(sizes) - min(sizes) <= 1


def test_posterior_pass_from_threads_equals_one_thread(projectile_model, monkeypatch):
    import importlib

    output = importlib.import_module("physdsl.infer.output")
    problem = importlib.import_module("physdsl.infer.problem").model_problem(projectile_model)
    rng = np.random.default_rng(0)
    flat = rng.normal(0.0, 0.3, (40, problem.dim))
    got = {}
    for n in ("1", "2"):
        monkeypatch.setenv("PHYSDSL_THREADS", n)
        got[n] = output.posterior_pass(projectile_model, problem, flat)
    for part in (0, 1):
        for k, v in got["1"][part].items():
            np.testing.assert_array_equal(np.asarray(v), np.asarray(got["2"][part][k]))
