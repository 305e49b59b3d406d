"""Make the many-throws example's recordings: one ball thrown N times at speeds from 3 to
20 m/s with quadratic drag (c = 0.0057 kg/m, a football in air), simulated by physdsl's own
RK4 rollout at 1 ms, sampled at 25 Hz until just before it lands, 1 cm noise per axis.

    python examples/many_throws/make_data.py [--throws 20] [--out examples/many_throws/throws]

Each throw is a folder THROW/trajectory.csv (t, body, x, y, z) and the folder gets
truth.json; the same function makes the tests' and the benchmark's data (``write_throws``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

DRAG = 0.0057  # kg/m
MASS = 0.43  # kg
RATE = 25.0  # samples per second
NOISE = 0.01  # m

SCENE = """scene throw {{
  world {{ timestep: 1 ms  integrator: rk4  duration: {duration} s }}
  body ball {{
    shape: sphere(radius: 11 cm)
    mass: {mass} kg
    position: ({x0}, {y0}, {z0}) m
    velocity: ({vx}, {vy}, {vz}) m/s
  }}
  effect {law} on ball {{ coefficient: {coef} }}
}}
"""


def throw_speeds(n: int, low: float = 3.0, high: float = 20.0) -> np.ndarray:
    """``n`` launch speeds spread evenly from ``low`` to ``high`` m/s."""
    return np.linspace(low, high, n)


def simulate(speed: float, angle: float, start, law: str = "quadratic_drag",
             coef: float = DRAG, mass: float = MASS) -> tuple[np.ndarray, np.ndarray]:
    """(times, positions (N, 3)) of one throw, sampled at RATE until the ball is below 5 cm."""
    import physdsl

    vx, vz = speed * np.cos(angle), speed * np.sin(angle)
    flight = (vz + np.sqrt(vz**2 + 2 * 9.81 * start[2])) / 9.81
    unit = "kg/m" if law == "quadratic_drag" else "kg/s"
    text = SCENE.format(duration=round(flight + 0.1, 3), mass=mass, x0=start[0], y0=start[1],
                        z0=start[2], vx=vx, vy=0.0, vz=vz, law=law, coef=f"{coef} {unit}")
    model = physdsl.compile(text)
    roll = model.simulate({})
    t = np.asarray(roll.t)
    pos = np.asarray(roll.body_pos)[:, 0, :]
    keep = np.arange(0, len(t), int(round(1 / (RATE * (t[1] - t[0])))))
    keep = keep[pos[keep, 2] > 0.05]
    return t[keep], pos[keep]


def write_throws(out: Path, n: int = 20, seed: int = 0, law: str = "quadratic_drag",
                 coef: float = DRAG, speeds=None, max_time: float | None = None) -> dict:
    """Write ``n`` throws under ``out`` (one folder each) and ``truth.json``; the truth."""
    rng = np.random.default_rng(seed)
    speeds = throw_speeds(n) if speeds is None else np.asarray(speeds, dtype=float)
    truth = {"law": law, "coefficient": coef, "mass": MASS, "noise": NOISE, "throws": {}}
    for i, speed in enumerate(speeds):
        angle = np.deg2rad(rng.uniform(35, 55))
        start = (0.0, 0.0, float(np.round(rng.uniform(1.6, 2.0), 3)))
        t, pos = simulate(float(speed), angle, start, law, coef)
        if max_time is not None:
            pos, t = pos[t <= max_time], t[t <= max_time]
        pos = pos + rng.normal(0.0, NOISE, pos.shape)
        name = f"{i:02d}"
        folder = out / name
        folder.mkdir(parents=True, exist_ok=True)
        rows = ["t,body,x,y,z"] + [f"{a:.4f},ball,{p[0]:.5f},{p[1]:.5f},{p[2]:.5f}"
                                   for a, p in zip(t, pos)]
        (folder / "trajectory.csv").write_text("\n".join(rows) + "\n")
        truth["throws"][name] = {"speed": float(speed), "angle_deg": float(np.rad2deg(angle)),
                                 "position": list(start),
                                 "velocity": [float(speed * np.cos(angle)), 0.0,
                                              float(speed * np.sin(angle))]}
    (out / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    return truth


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--throws", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "throws")
    args = ap.parse_args()
    write_throws(args.out, args.throws, args.seed)
