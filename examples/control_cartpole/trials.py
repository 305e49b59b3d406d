"""Adaptive MPC on the MuJoCo cart-pole over seeds: success, parameter error, ms per MPC step,
and the goal's cost with and without refits (for ``benchmarks/control.py`` and the docs).

Each seed tilts the pole by U(-0.08, 0.08) rad from upright and adds N(0, 1e-4) noise to the
plant's observations; success: the pole within the goal's 0.1 rad for the whole run.

    python examples/control_cartpole/trials.py [SEEDS] [DURATION_S]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import physdsl
from physdsl.control import mpc
from physdsl.control.mujoco_plant import MujocoPlant

HERE = Path(__file__).resolve().parent
PLANT_MASS = 0.3  # plant.xml's pole (kg): used to score the estimates, never by the controller


def trials(seeds: int = 10, duration: float = 3.0, noise: float = 1e-4) -> dict[str, float]:
    """The figures, by name (``mpc_success_rate.cartpole`` and friends)."""
    controller = mpc.Controller(physdsl.compile(HERE / "cartpole.phys"))
    held, errors, first_errors, ms, cost = [], [], [], [], {10: [], 0: []}
    for seed in range(seeds):
        tilt = np.random.default_rng(seed).uniform(-0.08, 0.08)
        for every in (10, 0):
            plant = MujocoPlant(str(HERE / "plant.xml"), period=controller.transition.period,
                                initial={"pole_hinge": np.pi + tilt}, seed=seed, noise=noise)
            run = mpc.run(controller.transition.model, plant, duration, refit_every=every,
                          controller=controller)
            cost[every].append(run.cost)
            if every:
                mass = [e["values"]["pole.mass"] for e in run.estimates]
                held.append(run.held())
                first_errors.append(abs(mass[1] - PLANT_MASS) / PLANT_MASS)
                errors.append(abs(mass[-1] - PLANT_MASS) / PLANT_MASS)
                ms.extend(run.step_ms[1:])
    return {"mpc_success_rate.cartpole": float(np.mean(held)),
            "param_error_prior.cartpole": abs(float(controller.transition.physical_values(
                controller.transition.centre[controller.transition.index])["pole.mass"])
                - PLANT_MASS) / PLANT_MASS,
            "param_error_first_refit.cartpole": float(np.median(first_errors)),
            "param_error_final.cartpole": float(np.median(errors)),
            "mpc_step_ms.cartpole": float(np.median(ms)),
            "mpc_step_ms_p90.cartpole": float(np.percentile(ms, 90)),
            "mpc_period_ms.cartpole": 1e3 * controller.transition.period,
            "mpc_cost_refit.cartpole": float(np.mean(cost[10])),
            "mpc_cost_no_refit.cartpole": float(np.mean(cost[0]))}


if __name__ == "__main__":
    args = [float(a) for a in sys.argv[1:3]]
    figures = trials(int(args[0]) if args else 10, args[1] if len(args) > 1 else 3.0)
    for name, value in figures.items():
        print(f"{name} {value:.4g}")
