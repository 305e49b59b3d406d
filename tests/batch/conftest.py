"""Shared pieces of the batch tests: eight tiny scenes (a ball tossed at known, different
velocities, position measured with 1 cm noise), one broken scene, the CLI run in a fresh
process, and one local batch of them all that the Ray tests compare against.

Each scene is fitted with MAP + Laplace; rk4 makes the rollout exact for a free fall, so every
fit must land within a few standard deviations of its own scene's velocity (the scenes differ
by more than 100 standard deviations: a job that fitted another scene's data would show).
"""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

TOSS = """\
scene toss {
  world {
    timestep: 10 ms
    integrator: rk4
    duration: 0.5 s
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 10 mm }
}
"""
BROKEN = """\
scene broken {
  body ball { shape: sphere(radius: 5 cm)  mass: 3 parsecs }
}
"""
TIMES = np.linspace(0.0, 0.5, 11)
NOISE = 0.01  # m
N_SCENES = 8
# the jobs' options: MAP + Laplace, few draws (the fit is the same; draws are cheap to save)
FIT = ["--backend", "map", "--chains", "1", "--samples", "20"]

# The CLI in a fresh Python process (as a user runs it; Ray needs its own driver process).
CLI = "import sys; from physdsl.cli import main; sys.exit(main(sys.argv[1:]))"


def truth(i: int) -> np.ndarray:
    """Launch velocity of scene ``i`` (m/s)."""
    return np.array([2.5 + 0.25 * i, 0.1 * i - 0.3, 3.5 + 0.2 * i])


def write_scene(folder: Path, i: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    v = truth(i)
    x = (np.array([0.0, 0.0, 1.0]) + np.outer(TIMES, v) - 0.5 * 9.81 * np.outer(TIMES**2, [0, 0, 1])
         + np.random.default_rng(i).normal(0.0, NOISE, (len(TIMES), 3)))
    rows = [f"{t:.6f},ball,{a:.9g},{b:.9g},{c:.9g}" for t, (a, b, c) in zip(TIMES, x)]
    (folder / "data.csv").write_text("\n".join(["t,body,x,y,z", *rows]) + "\n")
    (folder / "scene.phys").write_text(TOSS)
    return folder / "scene.phys"


@pytest.fixture(scope="session")
def scenes(tmp_path_factory) -> Path:
    """``scenes/toss-0 ... toss-7/scene.phys`` (with data) and ``scenes/broken/scene.phys``."""
    root = tmp_path_factory.mktemp("scenes")
    for i in range(N_SCENES):
        write_scene(root / f"toss-{i}", i)
    (root / "broken").mkdir()
    (root / "broken" / "scene.phys").write_text(BROKEN)
    return root


def run_cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """``physdsl ARGS`` in a new process (the session's compile cache passed on)."""
    return subprocess.run([sys.executable, "-c", CLI, *args], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ), check=False)


def estimates(folder: Path) -> dict[str, tuple[float, float]]:
    """``summary.csv`` of one fit: name -> (mean, sd)."""
    with open(folder / "summary.csv", newline="") as f:
        return {r["name"]: (float(r["mean"]), float(r["sd"])) for r in csv.DictReader(f)}


def summary(out: Path) -> dict:
    return json.loads((out / "batch.json").read_text())


@pytest.fixture(scope="session")
def local_batch(scenes, tmp_path_factory):
    """The local pool (2 workers) on all nine scenes: (OUT, the finished process)."""
    out = tmp_path_factory.mktemp("local") / "out"
    done = run_cli("batch", "infer", "--scenes", str(scenes / "*" / "scene.phys"), "-o", str(out),
                   "--workers", "2", *FIT)
    return out, done
