"""Shared helpers for the MuJoCo data generators: MJCF skeleton, rollout, noise, CSV, truth.

Each generator builds its MJCF from a ``truth`` dict (so tests can rebuild and re-simulate it
from ``truth.json``), integrates at a small timestep, samples at 100 Hz, adds Gaussian noise
with a fixed seed and writes long-format CSVs next to the example's .phys file.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Callable

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
RATE_HZ = 100.0


def mjcf(body_xml: str, *, timestep: float, integrator: str = "RK4", contact: str = "",
         extra_world: str = "") -> str:
    """A MuJoCo model with gravity -9.81 z, no default collisions (contacts only via pairs)."""
    return f"""<mujoco model="scene">
  <option timestep="{timestep}" integrator="{integrator}" cone="elliptic" gravity="0 0 -9.81"/>
  <default><geom contype="0" conaffinity="0"/><site size="0.005"/></default>
  <worldbody>
    {extra_world}
    {body_xml}
  </worldbody>
  <contact>{contact}</contact>
</mujoco>
"""


def rollout(model: mujoco.MjModel, data: mujoco.MjData, duration: float,
            record: Callable[[mujoco.MjData], dict[str, np.ndarray]],
            before_step: Callable[[mujoco.MjData], None] | None = None,
            rate_hz: float = RATE_HZ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Step the model; ``record(data)`` at every sample time t = k / rate_hz (k = 0, 1, ...)."""
    every = int(round(1.0 / (rate_hz * model.opt.timestep)))
    if abs(every * model.opt.timestep * rate_hz - 1.0) > 1e-9:
        raise ValueError("timestep must divide the sample period")
    n = int(round(duration * rate_hz)) + 1
    mujoco.mj_forward(model, data)
    rows: list[dict[str, np.ndarray]] = []
    for k in range(n):
        rows.append({key: np.array(v, dtype=float) for key, v in record(data).items()})
        if k == n - 1:
            break
        for _ in range(every):
            if before_step is not None:
                before_step(data)
            mujoco.mj_step(model, data)
    times = np.arange(n) / rate_hz
    return times, {key: np.stack([r[key] for r in rows]) for key in rows[0]}


def add_noise(series: dict[str, np.ndarray], sigma: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Independent Gaussian noise of standard deviation ``sigma`` on every value."""
    return {k: v + rng.normal(0.0, sigma, size=v.shape) for k, v in series.items()}


def write_positions(path: Path, times: np.ndarray, series: dict[str, np.ndarray]) -> None:
    """Long format ``t,body,x,y,z``: one row per body per sample."""
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["t", "body", "x", "y", "z"])
        for i, t in enumerate(times):
            for body, xyz in series.items():
                w.writerow([f"{t:.6f}", body, *(f"{c:.5f}" for c in xyz[i])])


def write_angles(path: Path, times: np.ndarray, series: dict[str, np.ndarray]) -> None:
    """Long format ``t,joint,angle`` (rad for hinges, m for sliders)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["t", "joint", "angle"])
        for i, t in enumerate(times):
            for joint, q in series.items():
                w.writerow([f"{t:.6f}", joint, f"{float(q[i]):.6f}"])


def read_long(path: Path, key: str, columns: tuple[str, ...]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Read a long-format CSV back: sample times and, per ``key`` value, an (N, D) array."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    names = list(dict.fromkeys(r[key] for r in rows))
    out = {n: np.array([[float(r[c]) for c in columns] for r in rows if r[key] == n]) for n in names}
    times = np.array([float(r["t"]) for r in rows if r[key] == names[0]])
    return times, out


def write_truth(path: Path, truth: dict) -> None:
    path.write_text(json.dumps(truth, indent=2) + "\n")


def load_truth(path: Path) -> dict:
    return json.loads(path.read_text())


def write_angle_example(name: str, truth: dict, simulate) -> None:
    """Simulate ``truth`` and write joints.csv, trajectory.csv (noisy) and truth.json for ``name``."""
    out = EXAMPLES / name
    out.mkdir(parents=True, exist_ok=True)
    t, angles, positions = simulate(truth)
    rng = np.random.default_rng(truth["noise"]["seed"])
    write_angles(out / "joints.csv", t, add_noise(angles, truth["noise"]["sigma_angle_rad"], rng))
    write_positions(out / "trajectory.csv", t, add_noise(positions, truth["noise"]["sigma_position_m"], rng))
    write_truth(out / "truth.json", truth)


def write_recording(out: Path, truth: dict, times: np.ndarray, angles: dict[str, np.ndarray],
                    positions: dict[str, np.ndarray]) -> None:
    """Noisy trajectory.csv (positions first), joints.csv (where there are joints) and truth.json."""
    rng = np.random.default_rng(truth["noise"]["seed"])
    write_positions(out / "trajectory.csv", times, add_noise(positions, truth["noise"]["sigma_position_m"], rng))
    if angles:
        write_angles(out / "joints.csv", times, add_noise(angles, truth["noise"]["sigma_angle_rad"], rng))
    write_truth(out / "truth.json", truth)
