"""Traced programs kept on disk (physdsl/traces.py) through ``ahead.Program``: a Program with an
identity is exported once and later Programs of that identity load it instead of tracing; the
loaded program computes the same numbers as ``jax.jit``; a changed argument type or
environment is another entry; a damaged entry is traced again; a program that cannot be
exported runs as ``jax.jit`` does. A new Program object stands for a new process (its
in-memory state is empty; the disk is all it shares). Nothing here is timed."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl import ahead, traces
from physdsl.ahead import Program, ProgramCache, build_once


class Pair(NamedTuple):
    a: jnp.ndarray
    b: jnp.ndarray | None


def _fn(x, data, scale):
    """A pytree in (with a static ``scale``), a pytree out with a None leaf and a NamedTuple."""
    y = jnp.sin(x) * data["w"] + scale
    return {"sum": jnp.sum(y), "pair": Pair(y, None), "n": data["n"] * 2}


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setattr(traces, "folder", lambda: tmp_path / "traces")
    return tmp_path / "traces"


def _args(n=5):
    x = jnp.linspace(0.0, 1.0, n)
    return x, {"w": jnp.arange(n, dtype=float), "n": jnp.int32(3)}, 0.5


def _counts():
    return dict(traces.COUNTS)


def _delta(before):
    return {k: traces.COUNTS[k] - before[k] for k in before}


def test_a_second_program_of_one_identity_loads_and_computes_what_jit_does(folder):
    x, data, scale = _args()
    reference = jax.jit(_fn, static_argnums=(2,))(x, data, scale)
    before = _counts()
    first = Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before) == {"loaded": 0, "exported": 1, "not_exportable": 0}
    assert len(list(folder.glob("*.trace"))) == 1
    before = _counts()
    second = Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before) == {"loaded": 1, "exported": 0, "not_exportable": 0}
    for out in (first, second):
        assert out["pair"].b is None and isinstance(out["pair"], Pair)
        assert jax.tree_util.tree_structure(out) == jax.tree_util.tree_structure(reference)
        for got, want in zip(jax.tree_util.tree_leaves(out), jax.tree_util.tree_leaves(reference)):
            np.testing.assert_array_equal(got, want)


def test_other_argument_types_static_values_and_environment_are_other_entries(folder, monkeypatch):
    x, data, scale = _args()
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    Program(_fn, static_argnums=(2,), identity="test/fn")(*_args(7))  # another shape
    out = Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, 1.5)  # another static
    np.testing.assert_allclose(out["sum"], jnp.sum(jnp.sin(x) * data["w"] + 1.5))
    Program(_fn, static_argnums=(2,), identity="test/other")(x, data, scale)  # another name
    assert len(list(folder.glob("*.trace"))) == 4
    monkeypatch.setenv("PHYSDSL_SOME_OPTION", "1")  # may decide a trace: part of the key
    before = _counts()
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before)["exported"] == 1 and len(list(folder.glob("*.trace"))) == 5
    monkeypatch.setenv("PHYSDSL_THREADS", "1")  # decides nothing traced: not part of it
    before = _counts()
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before)["loaded"] == 1


def test_a_damaged_entry_is_traced_again_and_replaced(folder):
    x, data, scale = _args()
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    (entry,) = folder.glob("*.trace")
    entry.write_bytes(entry.read_bytes()[:100])
    before = _counts()
    out = Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before) == {"loaded": 0, "exported": 1, "not_exportable": 0}
    np.testing.assert_allclose(out["sum"], jnp.sum(jnp.sin(x) * data["w"] + scale))
    before = _counts()
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert _delta(before)["loaded"] == 1


def test_a_program_with_a_host_callback_runs_as_jit_does(folder):
    seen = []

    def noisy(x):
        jax.debug.callback(lambda v: seen.append(float(v)), x[0])
        return 2.0 * x

    before = _counts()
    out = Program(noisy, identity="test/noisy")(jnp.ones(3))
    assert _delta(before)["not_exportable"] == 1 and not list(folder.glob("*.trace"))
    np.testing.assert_array_equal(out, 2.0 * np.ones(3))
    assert seen == [1.0]


def test_without_identity_or_with_the_cache_off_nothing_is_kept(folder, monkeypatch):
    x, data, scale = _args()
    Program(_fn, static_argnums=(2,))(x, data, scale)
    assert not folder.exists()
    monkeypatch.setattr(traces, "folder", lambda: None)
    Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert not folder.exists()


def test_compiled_ahead_the_stored_program_is_what_runs(folder, monkeypatch):
    monkeypatch.setenv(ahead.ENV, "on")
    x, data, scale = _args()

    def fn(*args):  # (jax.jit's count is per function: _fn's holds other tests' compiles)
        return _fn(*args)

    Program(fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    program = Program(fn, static_argnums=(2,), identity="test/fn")
    before = _counts()
    program.ahead(jax.ShapeDtypeStruct(x.shape, x.dtype), data, scale)
    assert _delta(before)["loaded"] == 1
    out = program(x, data, scale)
    assert program.jitted._cache_size() == 0  # neither traced nor compiled by jit
    np.testing.assert_allclose(out["sum"], jnp.sum(jnp.sin(x) * data["w"] + scale))


def test_a_structure_cache_names_its_programs_by_structure_and_key():
    cache = ProgramCache("abc")
    made = build_once(cache, ("gauss-newton", 3), lambda: Program(jnp.sin))
    assert made.identity == "abc/('gauss-newton', 3)"
    assert build_once(cache, ("gauss-newton", 3), lambda: 1 / 0) is made  # built once
    odd = build_once(cache, ("x", object()), lambda: Program(jnp.sin))  # no stable name
    assert odd.identity is None
    assert build_once({}, "plain dict", lambda: Program(jnp.sin)).identity is None


def test_a_plugin_without_a_source_file_keeps_nothing(folder, monkeypatch):
    """A registry entry from a module with no file (its code could change unseen by the key):
    programs are traced as jit does, nothing is written."""
    from physdsl.registry import Registry

    monkeypatch.setitem(Registry.instances[0]._origin, "ghost", "a_module_never_imported")
    x, data, scale = _args()
    out = Program(_fn, static_argnums=(2,), identity="test/fn")(x, data, scale)
    assert not folder.exists()
    np.testing.assert_allclose(out["sum"], jnp.sum(jnp.sin(x) * data["w"] + scale))
