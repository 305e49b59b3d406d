"""Generate examples/hidden-effect/sliding_ball (physdsl-simulated): two hidden contact effects.

A ball is launched along a level floor without spin. Sliding friction (mu) decelerates it
and spins it up until it rolls (at 5/7 of the launch speed, after 2 v0 / (7 mu g)); from then
on only rolling resistance (mu_r) slows it, at 5 mu_r g / (7 r). The naive scene has a
frictionless floor, so the ball glides at its launch speed. Both effects are needed: friction
alone leaves a ball that rolls on for ever, rolling resistance alone cannot act on a ball
that slides on a frictionless floor. The data are the naive scene with both effects added by
the diagnosis's own edits (``with_effect``), rolled out at the truth, plus seeded noise.

Usage: python tools/make_data/sliding_ball.py
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
FOLDER = ROOT / "examples" / "hidden-effect" / "sliding_ball"
RATE_HZ, DURATION, NOISE, SEED = 50.0, 2.0, 0.002, 1403
MU, MU_R, V0, RADIUS = 0.15, 0.001, 3.0, 0.05

NAIVE = f"""\
# A ball is rolled out by hand along a level floor (it leaves the hand without spin) and
# tracked from above at {RATE_HZ:.0f} Hz for {DURATION:.0f} s (trajectory.csv, {NOISE * 1000:.0f} mm noise per axis).
# First model: the floor is frictionless and nothing else slows the ball.
# Unknown: the launch speed and where the ball left the hand.
scene sliding_ball {{
  world {{ timestep: 5 ms  duration: {DURATION:.0f} s }}
  param x0 ~ normal(0 m, 2 cm)
  param v0 ~ normal(3 m/s, 0.5 m/s)
  ground floor {{ normal: (0, 0, 1)  point: (0, 0, 0) m }}
  body ball {{
    shape: sphere(radius: {RADIUS * 100:.0f} cm)
    mass: 200 g
    position: (x0, 0 m, {RADIUS * 100:.0f} cm)
    velocity: (v0, 0 m/s, 0 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }}
  observe ball.position from "trajectory.csv" where body == "ball" {{ noise: {NOISE * 1000:.0f} mm }}
}}
"""

README = (
    "# sliding_ball: the ball slides, then rolls, then slows (physdsl-simulated)\n\n"
    f"A ball launched without spin at {V0} m/s along a level floor. `naive.phys` has a frictionless floor: "
    "the ball glides at its launch speed.\n"
    f"Two effects are hidden on the ball-floor pair: sliding friction mu = {MU} (it decelerates the ball at "
    f"mu g and spins it up until it rolls, at 5/7 of the launch speed after {2 * V0 / (7 * MU * 9.81):.2f} s) and "
    f"rolling resistance mu_r = {MU_R * 1000:.0f} mm (the rolling ball then decelerates at 5 mu_r g / (7 r) = "
    f"{5 * MU_R * 9.81 / (7 * RADIUS):.3f} m/s^2).\n"
    "Rolling resistance cannot act on a ball sliding on a frictionless floor, so `refine` must find the "
    "friction first. Made by `tools/make_data/sliding_ball.py` (physdsl, 5 ms steps).\n")


def main() -> None:
    sys.path.insert(0, str(ROOT))
    from physdsl.compile import Model
    from physdsl.diagnose.candidates import Candidate
    from physdsl.diagnose.edits import load_text, with_effect
    from physdsl.syntax import format_source, load

    FOLDER.mkdir(parents=True, exist_ok=True)
    times = np.arange(int(round(DURATION * RATE_HZ)) + 1) / RATE_HZ
    _write(FOLDER / "trajectory.csv", times, np.zeros((times.size, 3)))
    naive_path = FOLDER / "naive.phys"
    naive_path.write_text(format_source(NAIVE, str(naive_path)))
    scene = load(naive_path)
    for effect in ("contact_friction", "rolling_resistance"):
        scene = load_text(scene, with_effect(scene, Candidate("effect", effect, ("floor", "ball"))))
    truth = {"x0": 0.0, "v0": V0, "contact_friction@floor,ball.coefficient": MU,
             "rolling_resistance@floor,ball.coefficient": MU_R}
    pred = np.asarray(Model(scene).predict({k: np.asarray(v) for k, v in truth.items()})["ball.position"])
    noisy = pred + np.random.default_rng(SEED).normal(0.0, NOISE, pred.shape)
    _write(FOLDER / "trajectory.csv", times, noisy)
    (FOLDER / "README.md").write_text(README)
    (FOLDER / "truth.json").write_text(json.dumps({
        "hidden_effect": {"effect": "contact_friction", "target": "floor,ball",
                          "law": "sliding friction mu N opposing the slip of the contact point"},
        "also_hidden": [{"effect": "rolling_resistance", "target": "floor,ball",
                         "law": "a torque mu_r N opposing the ball's rolling"}],
        "parameters": truth, "naive_unknowns": ["x0", "v0"],
        "source": "physdsl-simulated (tools/make_data/sliding_ball.py)",
        "noise": {"sigma_position_m": NOISE, "rate_hz": RATE_HZ, "seed": SEED},
        "physical_parameters": {"rolls_from_s": 2 * V0 / (7 * MU * 9.81),
                                "rolling_deceleration_m_s2": 5 * MU_R * 9.81 / (7 * RADIUS)},
    }, indent=2) + "\n")
    print(f"naive - truth: max |dx| {np.abs(pred[:, 0] - (V0 * times)).max():.3f} m; "
          f"speed at the end {(pred[-1, 0] - pred[-2, 0]) * RATE_HZ:.3f} m/s; "
          f"5/7 v0 - decel (t - t_roll) = {5 / 7 * V0 - 5 * MU_R * 9.81 / (7 * RADIUS) * (DURATION - 2 * V0 / (7 * MU * 9.81)):.3f}")
    assert math.isfinite(float(noisy.sum()))


def _write(path: Path, times: np.ndarray, xyz: np.ndarray) -> None:
    rows = ["t,body,x,y,z"] + [f"{t:.6f},ball,{a:.6f},{b:.6f},{c:.6f}" for t, (a, b, c) in zip(times, xyz)]
    path.write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
