"""Adaptive MPC on the MuJoCo cart-pole over seeds: success, parameter error, ms per MPC step,
and the goal's cost with and without refits (for ``benchmarks/control.py`` and the docs).

Balance (``trials``, cartpole.phys): each seed tilts the pole by U(-0.08, 0.08) rad from
upright and adds N(0, 1e-4) noise to the plant's observations; success: the pole within the
goal's 0.1 rad for the whole run. Swing-up (``swingup_trials``, swingup.phys): each seed starts
the pole hanging, U(-0.05, 0.05) rad off; success: the pole within 0.1 rad of upright over the
run's last ``HOLD`` s.

    python examples/control_cartpole/trials.py [SEEDS] [DURATION_S] [balance|swingup]
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
PLANT_DAMPING = 0.4  # plant.xml's rail (N s/m): the same
HOLD = 5.0  # s: a swing-up succeeds when the pole stays within tolerance over the last HOLD s


def trials(seeds: int = 10, duration: float = 3.0, noise: float = 1e-4) -> dict[str, float]:
    """Balance figures, by name (``mpc_success_rate.cartpole_balance`` and friends)."""
    controller = mpc.Controller(physdsl.compile(HERE / "cartpole.phys"))
    held, errors, first_errors, ms, cpu, cost = [], [], [], [], [], {10: [], 0: []}
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
                ms.extend(run.step_ms[1:]), cpu.extend(run.step_cpu_ms[1:])
    return {"mpc_success_rate.cartpole_balance": float(np.mean(held)),
            "param_error_prior.cartpole_balance": abs(float(
                controller.transition.physical_values(controller.transition.centre[
                    controller.transition.index])["pole.mass"]) - PLANT_MASS) / PLANT_MASS,
            "param_error_first_refit.cartpole_balance": float(np.median(first_errors)),
            "param_error_final.cartpole_balance": float(np.median(errors)),
            "mpc_step_ms.cartpole_balance": float(np.median(ms)),
            "mpc_step_ms_p90.cartpole_balance": float(np.percentile(ms, 90)),
            "mpc_step_cpu_ms.cartpole_balance": float(np.median(cpu)),
            "mpc_period_ms.cartpole_balance": 1e3 * controller.transition.period,
            "mpc_cost_refit.cartpole_balance": float(np.mean(cost[10])),
            "mpc_cost_no_refit.cartpole_balance": float(np.mean(cost[0]))}


def _upright_since(run: mpc.MpcResult, tolerance: float) -> float:
    """The time from which the pole stays within ``tolerance`` of upright to the run's end."""
    angle = run.states[:, run.joints.index("pole_hinge")]
    miss = np.abs(np.mod(angle, 2 * np.pi) - np.pi) > tolerance
    if miss[-1]:
        return float("inf")  # not upright at the end
    return float(run.times[np.flatnonzero(miss)[-1] + 1]) if miss.any() else 0.0


def swingup_trials(seeds: int = 10, duration: float = 8.0, noise: float = 1e-4,
                   every: int = 10, first: int = 0, compare: int | None = None
                   ) -> dict[str, float]:
    """Swing-up and balance from hanging, seeds ``first`` on, with refits every ``every``
    periods and, for the first ``compare`` of them (all by default), without."""
    controller = mpc.Controller(physdsl.compile(HERE / "swingup.phys"))
    tr = controller.transition
    (tolerance,) = [h.within for h in controller.holds if h.joint == "pole_hinge"]
    held, up, errors, ms, cpu, cost, held_fixed = [], [], [], [], [], {every: [], 0: []}, []
    compare = seeds if compare is None else compare
    for seed in range(first, first + seeds):
        tilt = np.random.default_rng(seed).uniform(-0.05, 0.05)
        for k in ((every, 0) if seed < first + compare else (every,)):
            plant = MujocoPlant(str(HERE / "plant.xml"), period=tr.period,
                                initial={"pole_hinge": tilt}, seed=seed, noise=noise)
            run = mpc.run(tr.model, plant, duration, refit_every=k, controller=controller)
            since = _upright_since(run, tolerance)
            ok = since <= duration - HOLD + 1e-9
            cost[k].append(run.cost)
            if not k:
                held_fixed.append(ok)
                print(f"seed {seed} without refits: upright from {since:.2f} s, held {ok}, "
                      f"cost {run.cost:.1f}", flush=True)
                continue
            held.append(ok), up.append(since), ms.extend(run.step_ms[1:])
            cpu.extend(run.step_cpu_ms[1:])
            final = run.estimates[-1]["values"]
            errors.append(max(abs(final["pole.mass"] - PLANT_MASS) / PLANT_MASS, abs(
                final["joint_damping@cart_slider.coefficient"] - PLANT_DAMPING) / PLANT_DAMPING))
            print(f"seed {seed}: upright from {since:.2f} s, held {ok}, cost {run.cost:.1f}, "
                  f"{np.median(run.step_ms[1:]):.0f} ms per step "
                  f"({np.median(run.step_cpu_ms[1:]):.0f} ms CPU), mass "
                  f"{final['pole.mass']:.4f} kg, damping "
                  f"{final['joint_damping@cart_slider.coefficient']:.4f} N s/m", flush=True)
    return {"mpc_success_rate.cartpole": float(np.mean(held)),
            "mpc_success_rate_no_refit.cartpole": float(np.mean(held_fixed or [np.nan])),
            "swingup_time_s_median.cartpole": float(np.median(up)),
            "param_error_final.cartpole": float(np.median(errors)),
            "param_error_final_max.cartpole": float(np.max(errors)),
            "mpc_step_ms.cartpole": float(np.median(ms)),
            "mpc_step_ms_p90.cartpole": float(np.percentile(ms, 90)),
            "mpc_step_cpu_ms.cartpole": float(np.median(cpu)),
            "mpc_period_ms.cartpole": 1e3 * tr.period,
            "mpc_cost_refit.cartpole": float(np.mean(cost[every])),
            "mpc_cost_no_refit.cartpole": float(np.mean(cost[0] or [np.nan]))}


if __name__ == "__main__":
    args = [float(a) for a in sys.argv[1:3]]
    which = swingup_trials if sys.argv[3:] == ["swingup"] else trials
    figures = which(int(args[0]) if args else 10, args[1] if len(args) > 1 else (
        8.0 if which is swingup_trials else 3.0))
    for name, value in figures.items():
        print(f"{name} {value:.4g}")
