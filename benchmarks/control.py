"""Issue 17's figures, each from its example (one run each; say the load beside them):

- ``goal_error_m.ball``: the pool shot (examples/control_pool): the push physdsl chooses through
  the ball-ball contact, replayed in MuJoCo; distance of the object ball from its target;
- ``design_error_m.dh_arm``: examples/design_dh_arm: the largest error of the designed link
  lengths against the lengths the targets were computed from;
- ``mpc_success_rate.cartpole`` (swing-up from hanging and a 5 s hold, 8 s runs),
  ``param_error_final``, ``mpc_step_ms``, costs with and without refits:
  examples/control_cartpole/trials.py (MuJoCo plant); ``*.cartpole_balance``: balance only;
- ``mpc_success_rate.double_cartpole`` (``trials.balanced``: never beyond 0.5 rad, within the
  goal's tolerances for the last 2 s of 3; ``_whole_run``: within them throughout),
  ``param_error_after_N_transitions``/``_final``, ``mpc_step_ms``:
  examples/control_double_cartpole/trials.py (14 unknowns, MuJoCo plant);
- ``info_gain_ratio.cart``: examples/experiment_cart/trials.py: random pushes' 90% width of the
  worse-determined unknown over the designed push's (predicted; ``_refit``: measured by
  refitting), and the predicted and refitted shrinkage of that width.

Run: .venv/bin/python benchmarks/control.py [--only ball|dh_arm|cartpole|cartpole_balance|
double_cartpole|experiment_cart] [--seeds N]
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import time
from pathlib import Path

import numpy as np

import physdsl

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _script(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def ball() -> None:
    replay = _script(EXAMPLES / "control_pool" / "mujoco_replay.py")
    t0 = time.perf_counter()
    model = physdsl.compile(EXAMPLES / "control_pool" / "pool.phys")
    _, plan = physdsl.control(model)
    (reach,) = model.scene.goal.terms
    end = replay.replay_in_mujoco(float(plan.values["vx"]), float(plan.values["vy"]), reach.at)
    print(f"goal_error_m.ball_physdsl: {plan.errors[0]:.3g}")
    print(f"goal_error_m.ball: {np.linalg.norm(end[:2] - np.asarray(reach.point[:2])):.3g}")
    print(f"wall_s.ball: {time.perf_counter() - t0:.1f}")


def dh_arm() -> None:
    folder = EXAMPLES / "design_dh_arm"
    truth = json.loads((folder / "truth.json").read_text())["unknowns"]
    t0 = time.perf_counter()
    _, plan = physdsl.control(physdsl.compile(folder / "design_dh_arm.phys"))
    error = max(abs(float(plan.values[k]) - v) for k, v in truth.items())
    print(f"design_error_m.dh_arm: {error:.3g}")
    print(f"target_error_m.dh_arm_physdsl: {max(plan.errors):.3g}")
    print(f"wall_s.dh_arm: {time.perf_counter() - t0:.1f}")


def cartpole(seeds: int, duration: float, swingup: bool = True) -> None:
    trials = _script(EXAMPLES / "control_cartpole" / "trials.py")
    t0 = time.perf_counter()
    figures = trials.swingup_trials(seeds) if swingup else trials.trials(seeds, duration)
    for name, value in figures.items():
        print(f"{name}: {value:.4g}")
    print(f"wall_s.cartpole{'' if swingup else '_balance'}: {time.perf_counter() - t0:.1f}")


def double_cartpole(seeds: int, compare: int | None = None) -> None:
    trials = _script(EXAMPLES / "control_double_cartpole" / "trials.py")
    t0 = time.perf_counter()
    for name, value in trials.trials(seeds, compare=seeds if compare is None else compare
                                     ).items():
        print(f"{name}: {value:.4g}")
    print(f"wall_s.double_cartpole: {time.perf_counter() - t0:.1f}")


def experiment_cart(seeds: int) -> None:
    trials = _script(EXAMPLES / "experiment_cart" / "trials.py")
    t0 = time.perf_counter()
    _, figures = trials.trials(seeds)
    for name, value in figures.items():
        print(f"{name}.cart: {value:.4g}")
    print(f"wall_s.experiment_cart: {time.perf_counter() - t0:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("ball", "dh_arm", "cartpole", "cartpole_balance",
                                           "double_cartpole", "experiment_cart"))
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--duration", type=float, default=3.0, help="balance runs' length, s")
    parser.add_argument("--compare", type=int, default=None,
                        help="double cart-pole: seeds also run without refits (default all)")
    args = parser.parse_args()
    print(f"load_before: {os.getloadavg()[0]:.1f}")
    if args.only in (None, "ball"):
        ball()
    if args.only in (None, "dh_arm"):
        dh_arm()
    if args.only in (None, "cartpole"):
        cartpole(args.seeds, args.duration)
    if args.only in (None, "cartpole_balance"):
        cartpole(args.seeds, args.duration, swingup=False)
    if args.only in (None, "double_cartpole"):
        double_cartpole(args.seeds, args.compare)
    if args.only in (None, "experiment_cart"):
        experiment_cart(min(args.seeds, 4))
    print(f"load_after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
