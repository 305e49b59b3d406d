"""physdsl's XLA CPU options (physdsl/xla_flags.py): added to XLA_FLAGS without overriding the
user's own, and in effect in this process: rollout loops compile into one kernel."""
import jax
import numpy as np
import pytest

import physdsl  # noqa: F401  (sets XLA_FLAGS before JAX's backend starts)
from physdsl import xla_flags
from physdsl.physics import build_simulator
from scenes import chain


def test_options_are_added_and_the_users_own_are_kept():
    mine = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=64"
    out = xla_flags.with_options(f"--xla_dump_to=/x {mine}")
    assert out.split().count(mine) == 1
    assert "byte_threshold=1000000000" not in out  # the user's value stands
    assert "--xla_cpu_experimental_ynn_fusion_type=" in out.split()
    assert xla_flags.with_options(out) == out  # applying twice adds nothing


def test_off_adds_nothing():
    env = {"PHYSDSL_XLA_FLAGS": "off", "XLA_FLAGS": "--xla_dump_to=/x"}
    xla_flags.configure(env)
    assert env["XLA_FLAGS"] == "--xla_dump_to=/x"
    env = {}
    xla_flags.configure(env)
    assert set(env["XLA_FLAGS"].split()) == {f"{k}={v}" for k, v in xla_flags.OPTIONS.items()}


@pytest.mark.parametrize("links", [1, 3])
def test_rollout_loops_compile_into_one_kernel(links):
    """XLA's small-call marker in the compiled rollout: the loop was hoisted into one kernel,
    which XLA's default (1 kB) refuses for 2000 recorded steps, and which a LAPACK call in the
    loop (a Cholesky solve of a tree with several dofs: ``dense``) would prevent."""
    sim = build_simulator(chain(links, duration=2.0))
    text = jax.jit(lambda v: sim.simulate(v).body_pos).lower({}).compile().as_text()
    assert "xla_cpu_small_call" in text
    assert "custom-call(" not in text
    z = np.asarray(jax.jit(lambda v: sim.simulate(v).body_pos)({}))
    assert np.all(np.isfinite(z)) and z.shape[0] == 2001
