"""physdsl's XLA CPU options (physdsl/xla_flags.py): added to XLA_FLAGS without
overriding the user's own, and with them rollout loops compile into one kernel."""
import os
import subprocess
import sys
from pathlib import Path

import physdsl  # noqa: F401
from physdsl import xla_flags
from physdsl.physics import build_simulator, tree
from scenes import chain


def test_options_are_added_and_the_users_own_are_kept():
    mine = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=64"
    out = xla_flags.with_options(f"--xla_dump_to=/x {mine}")
    assert out.split().count(mine) == 1
    assert "byte_threshold=1000000000" not in out  # the user's value stands
    assert "--xla_cpu_experimental_ynn_fusion_type=" in out.split()
    assert xla_flags.with_options(out) == out  # applying twice adds nothing


def test_options_are_on_unless_turned_off(monkeypatch):
    monkeypatch.setattr(xla_flags, "backend_started", lambda: False)  # as at import physdsl
    env = {"XLA_FLAGS": "--xla_dump_to=/x", "PHYSDSL_XLA_FLAGS": "off"}
    xla_flags.configure(env)
    assert env["XLA_FLAGS"] == "--xla_dump_to=/x" and not xla_flags.in_effect(env)
    for env in ({}, {"PHYSDSL_XLA_FLAGS": "on"}):
        xla_flags.configure(env)
        assert set(env["XLA_FLAGS"].split()) == {f"{k}={v}"
                                                 for k, v in xla_flags.OPTIONS.items()}
        assert xla_flags.in_effect(env)


HOISTED = """
import jax, physdsl
from physdsl.physics import build_simulator
from scenes import chain
for links in (1, 8):
    sim = build_simulator(chain(links, duration=2.0))
    text = jax.jit(lambda v: sim.simulate(v).body_pos).lower({}).compile().as_text()
    print(links, "xla_cpu_small_call" in text, "custom-call(" in text)
"""


def test_with_the_options_rollout_loops_compile_into_one_kernel():
    """XLA's small-call marker in the compiled rollout: the loop was hoisted into one kernel,
    which XLA's default (1 kB) refuses for 2000 recorded steps, and which a LAPACK call in the
    loop (the tree path's Cholesky solve at 8 dofs: ``dense``) would prevent. Each setting in a
    process of its own: the options act only before JAX starts."""
    here = str(Path(__file__).parent)
    out = {}
    for on in ("on", "off"):
        env = {**os.environ, "PHYSDSL_XLA_FLAGS": on, "PHYSDSL_CACHE_DIR": "off",
               "PYTHONPATH": os.pathsep.join([here, os.environ.get("PYTHONPATH", "")])}
        env.pop("XLA_FLAGS", None)
        run = subprocess.run([sys.executable, "-c", HOISTED], env=env, capture_output=True,
                             text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
        out[on] = run.stdout.splitlines()[:2]
    assert out["on"] == ["1 True False", "8 True False"]
    assert out["off"][1] == "8 False True"  # LAPACK's Cholesky in the loop, a call per operation


def test_small_contact_free_trees_take_the_recursive_path(monkeypatch):
    """At most ``tree.RECURSIVE_MAX`` dofs and no contact: the recursive algorithms, where the
    loop is one kernel; the vectorised tree path above that size, or without the options."""
    few, many = build_simulator(chain(2)).model, build_simulator(chain(3)).model
    monkeypatch.setattr(xla_flags, "in_effect", lambda: True)
    assert not tree.applies(few) and tree.applies(many)
    monkeypatch.setattr(xla_flags, "in_effect", lambda: False)
    assert tree.applies(few)


def test_options_are_not_claimed_once_jax_has_started():
    """After JAX's backend started (a user computed before ``import physdsl``), XLA reads no
    more flags: ``configure`` leaves XLA_FLAGS alone, so ``in_effect`` stays true to the
    compiled programs."""
    import jax.numpy as jnp
    jnp.zeros(1).block_until_ready()
    assert xla_flags.backend_started()
    env = {}
    xla_flags.configure(env)
    assert env == {}
