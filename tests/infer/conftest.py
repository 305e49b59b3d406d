"""Shared pieces of the inference tests: tiny scenes, data simulated by physdsl, the CLI runner.

Data are made with physdsl itself: a scene is compiled against placeholder data at the
measurement times, rolled out at known values, and Gaussian noise with a fixed seed is added.
Compiling the physics dominates the cost of these tests, so one Model per scene is shared
by a module (``Problem`` caches compiled stages on it), and the suite's persistent XLA cache
(tests/conftest.py) lets identical computations of separately loaded copies of a scene (e.g.
through the CLI) reuse their executables.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import physdsl  # noqa: F401 - float64

# A ball thrown through air with linear drag: unknown launch velocity and drag coefficient.
PROJECTILE = """\
scene projectile {
  world {
    timestep: 10 ms
    duration: 0.5 s
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  effect linear_drag on ball { coefficient ~ half_normal(0.5 kg/s) }
  observe ball.position from "data.csv" where body == "ball" { noise: NOISE }
}
"""
PROJECTILE_TRUTH = {"ball.velocity": np.array([3.2, 0.4, 4.3]),
                    "linear_drag@ball.coefficient": np.array(0.3)}
PROJECTILE_TIMES = np.linspace(0.0, 0.5, 11)
PROJECTILE_NOISE = 0.01  # m


def write_trajectory_csv(path: Path, times, values, body: str = "ball") -> Path:
    """Write ``t,body,x,y,z`` rows (values (N, 3) in metres)."""
    lines = ["t,body,x,y,z"]
    lines += [f"{t:.6f},{body},{x:.9g},{y:.9g},{z:.9g}" for t, (x, y, z) in zip(times, values)]
    path.write_text("\n".join(lines) + "\n")
    return path


def simulated_scene(folder: Path, text: str, truth: dict, times, noise: float, seed: int,
                    observation: str = "ball.position", data: str = "data.csv") -> Path:
    """Write ``text`` as ``scene.phys`` in ``folder`` with data simulated at ``truth``.

    Returns the scene path. Predictions come from physdsl (placeholder data at ``times``
    first, so the scene compiles), plus N(0, noise^2) per axis from ``seed``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    scene = folder / "scene.phys"
    scene.write_text(text)
    body = observation.split(".")[0]
    write_trajectory_csv(folder / data, times, np.zeros((len(times), 3)), body)
    from physdsl.compile import compile as compile_phys

    model = compile_phys(scene)
    pred = np.asarray(model.predict({k: np.asarray(v) for k, v in truth.items()})[observation])
    noisy = pred + np.random.default_rng(seed).normal(0.0, noise, pred.shape)
    write_trajectory_csv(folder / data, times, noisy, body)
    return scene


def projectile_text(noise: float = PROJECTILE_NOISE) -> str:
    return PROJECTILE.replace("NOISE", f"{noise * 1000:g} mm")


@pytest.fixture(scope="session")
def projectile_scene(tmp_path_factory) -> Path:
    """The projectile scene with data simulated at PROJECTILE_TRUTH (seed 3)."""
    return simulated_scene(tmp_path_factory.mktemp("projectile"), projectile_text(),
                           PROJECTILE_TRUTH, PROJECTILE_TIMES, PROJECTILE_NOISE, seed=3)


@pytest.fixture(scope="session")
def projectile_model(projectile_scene):
    """One compiled Model of the projectile scene, shared so compiled stages are reused."""
    from physdsl.compile import compile as compile_phys

    return compile_phys(projectile_scene)


def run_cli(args, capsys) -> tuple[int, str, str]:
    """Run ``physdsl ARGS`` in-process; (exit code, stdout, stderr)."""
    from physdsl.cli import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def cli(capsys):
    return lambda *args: run_cli(args, capsys)


def interval_contains(draws: np.ndarray, truth, level: float = 0.9) -> np.ndarray:
    """Whether each component of ``truth`` lies in the central ``level`` interval of ``draws``.

    ``draws`` is (chain, draw, *shape); returns a boolean array of ``truth``'s shape.
    """
    flat = np.asarray(draws).reshape(-1, *np.shape(truth))
    lo, hi = np.quantile(flat, [(1 - level) / 2, (1 + level) / 2], axis=0)
    return (lo <= truth) & (truth <= hi)
