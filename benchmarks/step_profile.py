"""Where one physics step's time goes, stage by stage (``benchmarks/physics.py --profile``).

Each stage of ``integrate.step`` runs alone over the first ``STEPS`` states of a real rollout
(its inputs computed beforehand, outside the timing), in a ``lax.scan`` that sums its outputs
into the carry (so nothing is hoisted or pruned): kinematics, effects (the applied load),
dynamics (joint accelerations), contact detection and the contact solve (scenes with pairs).
``loop`` is the same scan over the states with no stage (its cost is in every stage's figure),
``step`` the whole step in the rollout's own scan. Microseconds per step, best of 5;
``compile_cpu_s``: CPU seconds to compile the whole-step scan.
"""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from physdsl.physics import contact_stage as cs
from physdsl.physics.integrate import (State, accel, applied_load, joint_mass_matrix, kinematics,
                                       step)

STEPS = 100


def _total(out):
    """Sum of every float leaf of ``out`` (one scalar that depends on all of it)."""
    return sum(jnp.sum(x) for x in jax.tree_util.tree_leaves(out)
               if jnp.issubdtype(jnp.result_type(x), jnp.floating))


def _timed_scan(f, xs):
    """(microseconds per element of ``xs``, compile CPU s) of a scan of ``f`` over ``xs``."""
    def run(xs):
        return jax.lax.scan(lambda acc, x: (acc + 1e-30 * _total(f(x)), None), 0.0, xs)[0]

    t0 = time.process_time()
    fn = jax.jit(run).lower(xs).compile()
    t_c = time.process_time() - t0
    jax.block_until_ready(fn(xs))
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(xs))
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / STEPS, t_c


def profile(sim, values) -> dict:
    """{stage: microseconds per step}, ``step`` (the whole step) and ``compile_cpu_s``."""
    model = sim.model
    prm = sim.params(values)
    roll = sim.simulate(values)
    q, v = roll.q[:STEPS], roll.v[:STEPS]
    C = model.ncon
    h = model.dt / model.substeps
    jac = bool(C)

    def state(q, v):
        return State(q, v, jnp.zeros(C, q.dtype), jnp.zeros((C, 3), q.dtype))

    kin_of = jax.jit(jax.vmap(lambda q, v: kinematics(model, prm, q, v, with_jac=jac)))
    kins = kin_of(q, v)
    loads = jax.jit(jax.vmap(lambda q, v, k: applied_load(model, prm, k, state(q, v), 0.0, 0.0)))(
        q, v, kins)
    out = {"loop": _timed_scan(lambda x: x[0], (q, v))[0],
           "kinematics": _timed_scan(lambda x: kinematics(model, prm, *x, with_jac=jac), (q, v))[0],
           "effects": _timed_scan(lambda x: applied_load(model, prm, x[2], state(x[0], x[1]),
                                                         0.0, 0.0), (q, v, kins))[0],
           "dynamics": _timed_scan(lambda x: accel(model, prm, *x), (kins, loads))[0]}
    if C:
        out["detection"] = _timed_scan(lambda x: cs.detect_all(model, prm, *x), (kins, v))[0]
        out["contact_solve"] = _timed_scan(lambda x: _solve(model, prm, h, *x),
                                           (kins, loads, v))[0]
    whole, t_c = _timed_scan(lambda x: step(model, prm, state(*x), 0.0, h), (q, v))
    out["step"], out["compile_cpu_s"] = whole, t_c
    return out


def _solve(model, prm, h, kin, load, v):
    """The contact model's solve at one state (detection included: its input)."""
    con = cs.detect_all(model, prm, kin, v)
    M = joint_mass_matrix(model, prm, kin) if con.inv_mass is None else None
    if model.contact_model == "compliant":
        return cs.compliant_tau(model, con, M, v)
    v_free = v + h * accel(model, prm, kin, load)
    M = joint_mass_matrix(model, prm, kin)
    return cs.lcp_velocity(model, cs.closing_within(con, v_free, h), M, v, v_free, h)
