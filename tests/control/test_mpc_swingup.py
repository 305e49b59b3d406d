"""Cart-pole swing-up by adaptive MPC (issue 17 item 3): from hanging at rest the goal's cost has
no slope (the bottom is its top), so the controller screens pumping pushes before each iLQR
solve. MuJoCo is the plant (pole 0.3 kg, +50% on the prior's centre; rail damping 0.4 N s/m,
unknown to the scene). Fast: a short horizon over the first 0.5 s; the full swing-up and 5 s
hold is -m slow and in benchmarks/control.py."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl.control import mpc

mujoco = pytest.importorskip("mujoco")
from physdsl.control.mujoco_plant import MujocoPlant  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_cartpole"
OMEGA0_SQ = 3 * 9.81 / (2 * 0.6)  # the plant's 0.6 m rod about its hinge: g c / (L^2 / 3)


def energy(state: np.ndarray) -> np.ndarray:
    """The pole's energy over its upright value at rest (0 hanging at rest, 1 upright at rest),
    from the angle and angular velocity columns: (1 - cos q) / 2 + w^2 / (4 w0^2)."""
    q, w = state[:, 1], state[:, 3]
    return 0.5 * (1.0 - np.cos(q)) + w ** 2 / (4.0 * OMEGA0_SQ)


def short_horizon(knots: int = 20) -> str:
    """swingup.phys with its first ``knots`` control times (a cheaper compile)."""
    text = (EXAMPLE / "swingup.phys").read_text()
    times = ", ".join(f"{0.02 * k:.2f}" for k in range(knots))
    start = text.index("times: (") + len("times: (")
    text = text[:start] + times + text[text.index(") s", start):]
    return text.replace("1200 ms", f"{20 * knots} ms")


@pytest.mark.slow  # ~40 s; closed-loop MPC runs in tests/control/test_mpc.py
def test_first_half_second_pumps_energy_toward_upright():
    """In 0.5 s of MuJoCo time the MPC lifts the hanging pole's energy to a quarter of upright's
    (unforced it stays at ~1e-4), within the motor's bounds, and the first refits move the
    pole's mass from the prior's centre (0.19 kg) toward the plant's 0.3 kg."""
    model = physdsl.compile(short_horizon())
    plant = MujocoPlant(str(EXAMPLE / "plant.xml"), period=0.02, initial={"pole_hinge": 0.01})
    run = mpc.run(model, plant, 0.5, refit_every=10)
    e = energy(run.states)
    assert e[0] < 1e-3
    assert e[-1] > 0.25, e[-1]
    assert np.all(np.abs(run.forces) <= 10.0 + 1e-9)
    mass = [r["values"]["pole.mass"] for r in run.estimates]
    assert abs(mass[-1] - 0.3) < 0.5 * abs(mass[0] - 0.3)


def test_unforced_pole_stays_down():
    """The energy measure's baseline: the same plant with no force stays near the bottom."""
    plant = MujocoPlant(str(EXAMPLE / "plant.xml"), period=0.02, initial={"pole_hinge": 0.01})
    plant.reset()
    obs = [plant.step({"cart_slider": 0.0}) for _ in range(25)]
    states = np.array([[o.position["cart_slider"], o.position["pole_hinge"],
                        o.velocity["cart_slider"], o.velocity["pole_hinge"]] for o in obs])
    assert np.max(energy(states)) < 1e-3


@pytest.mark.slow
def test_swingup_and_hold_over_seeds():
    """Ten seeds from hanging: the pole is held within 0.1 rad of upright over the last 5 s of
    an 8 s run in at least 9, and the refitted mass and damping end within 10% of the plant's."""
    spec = importlib.util.spec_from_file_location("trials", EXAMPLE / "trials.py")
    trials = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(trials)
    figures = trials.swingup_trials(seeds=10, duration=8.0)
    assert figures["mpc_success_rate.cartpole"] >= 0.9
    assert figures["param_error_final_max.cartpole"] < 0.1
