"""Compiling ahead (``physdsl.ahead``): a Program prepared for some argument types runs the
executable compiled in the background, with the jitted function's results; other types and
tracers take the jitted function; a compile the background thread has not started is taken
back by its caller, and a caller waiting for a running one compiles the queued ones meanwhile
(but those queued as needed later); a process that exits with a compile running ends normally."""
from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import physdsl  # noqa: F401 - float64

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl import ahead

ROOT = Path(__file__).resolve().parent.parent


def _rollout(x, data):
    """A small loop: enough to be a program of its own, cheap to compile."""
    def body(i, s):
        return s * data["a"] + jnp.sin(s) * x
    return jax.lax.fori_loop(0, 50, body, x)


def _fresh():
    """``_rollout`` as a new function (jit shares its executables among jits of one function)."""
    return lambda x, data: _rollout(x, data)


@pytest.fixture
def on(monkeypatch):
    monkeypatch.setenv(ahead.ENV, "on")


def test_a_program_compiled_ahead_runs_that_executable(on):
    prog = ahead.Program(_fresh())
    x, data = jnp.linspace(0.1, 0.5, 4), {"a": jnp.asarray(0.9)}
    prog.ahead(jax.ShapeDtypeStruct((4,), x.dtype), data)
    got = prog(x, data)
    assert prog.jitted._cache_size() == 0  # the jitted function itself never compiled
    np.testing.assert_allclose(got, jax.jit(_rollout)(x, data), rtol=0, atol=0)
    assert prog._cache_size() == 1


def test_other_types_and_tracers_take_the_jitted_function(on):
    prog = ahead.Program(_fresh())
    data = {"a": jnp.asarray(0.9)}
    prog.ahead(jax.ShapeDtypeStruct((4,), jnp.float64), data)
    x3 = jnp.linspace(0.1, 0.5, 3)  # another shape
    np.testing.assert_allclose(prog(x3, data), jax.jit(_rollout)(x3, data), rtol=0, atol=0)
    assert prog.jitted._cache_size() == 1
    x = jnp.linspace(0.1, 0.5, 4)
    outer = jax.jit(lambda x: prog(x, data).sum())  # a tracer: inlined, as jit does
    assert float(outer(x)) == pytest.approx(float(_rollout(x, data).sum()), rel=1e-15)
    g = jax.grad(lambda x: prog(x, data).sum())(x)
    assert np.all(np.isfinite(g))


def test_static_arguments_select_the_executable(on):
    prog = ahead.Program(lambda x, scale: x * (2.0 if scale else 1.0), static_argnums=(1,))
    x = jnp.ones(3)
    prog.ahead(x, True)
    assert np.all(np.asarray(prog(x, True)) == 2.0)
    assert np.all(np.asarray(prog(x, False)) == 1.0)  # another static value: jitted
    assert prog.jitted._cache_size() == 1


def test_off_compiles_nothing_ahead(monkeypatch):
    monkeypatch.setenv(ahead.ENV, "off")
    prog = ahead.Program(_fresh())
    prog.ahead(jnp.ones(4), {"a": jnp.asarray(0.9)})
    assert prog._cache_size() == 0
    prog(jnp.ones(4), {"a": jnp.asarray(0.9)})
    assert prog.jitted._cache_size() == 1


def test_a_queued_compile_is_taken_back_and_a_waiting_caller_compiles_the_next(on, monkeypatch):
    release = threading.Event()
    started = threading.Event()
    real = ahead._compile_unless_exiting

    def slow(lowered):  # the background thread holds the first program until released
        started.set()
        release.wait(30)
        return real(lowered)

    monkeypatch.setattr(ahead, "_compile_unless_exiting", slow)
    data = {"a": jnp.asarray(0.9)}
    first, second, third = (ahead.Program(_fresh()) for _ in range(3))
    for p, n in ((first, 2), (second, 3), (third, 5)):
        p.ahead(jnp.ones(n), data)
    assert started.wait(30)
    # the third is queued behind the others: its caller compiles it rather than wait
    np.testing.assert_allclose(third(jnp.ones(5), data), _rollout(jnp.ones(5), data))
    assert third._ahead[next(iter(third._ahead))].compiled is not None
    # the first is running: its caller compiles the second meanwhile, then takes the first
    threading.Timer(1.0, release.set).start()
    np.testing.assert_allclose(first(jnp.ones(2), data), _rollout(jnp.ones(2), data))
    pending = second._ahead[next(iter(second._ahead))]
    assert pending.future.cancelled() and pending.compiled is not None
    np.testing.assert_allclose(second(jnp.ones(3), data), _rollout(jnp.ones(3), data))


def test_a_waiting_caller_leaves_a_program_queued_for_later_to_the_background(on, monkeypatch):
    release = threading.Event()
    started = threading.Event()
    real = ahead._compile_unless_exiting

    def slow(lowered):  # the background thread holds the first program until released
        if not started.is_set():
            started.set()
            release.wait(30)
        return real(lowered)

    monkeypatch.setattr(ahead, "_compile_unless_exiting", slow)
    data = {"a": jnp.asarray(0.9)}
    first, later = ahead.Program(_fresh()), ahead.Program(_fresh())
    first.ahead(jnp.ones(2), data)
    later.ahead(jnp.ones(3), data, later=True)
    assert started.wait(30)
    threading.Timer(1.0, release.set).start()
    np.testing.assert_allclose(first(jnp.ones(2), data), _rollout(jnp.ones(2), data))
    pending = later._ahead[next(iter(later._ahead))]
    assert not pending.future.cancelled()  # not taken back: the background thread compiles it
    assert pending.future.result(30) is not None
    np.testing.assert_allclose(later(jnp.ones(3), data), _rollout(jnp.ones(3), data))
    assert pending.compiled is not None and later.jitted._cache_size() == 0


def test_a_process_that_exits_while_compiling_ends_normally():
    """XLA aborts a process whose interpreter ends under a running compile; the background
    thread is waited for, and what is still queued is dropped."""
    code = (
        "import jax, jax.numpy as jnp, physdsl\n"
        "from physdsl import ahead\n"
        "f = lambda x: jax.lax.fori_loop(0, 200, lambda i, s: jnp.sin(s) * s + x, x)\n"
        "progs = [ahead.Program(f) for _ in range(4)]\n"
        "[p.ahead(jnp.ones(n + 1)) for n, p in enumerate(progs)]\n"
        "print('exiting')\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, cwd=ROOT, env={**__import__("os").environ,
                                                     ahead.ENV: "on"})
    assert run.returncode == 0, run.stderr[-2000:]
    assert "exiting" in run.stdout
