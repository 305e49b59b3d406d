"""Per-recording control files from the manifest: ``control push on ball from throws.push
column (fx, fy, fz)`` reads each recording's force table from the file its row names; the
rollout of every recording follows its own pushes (analytic), and a pooled fit recovers the
shared mass through them. Located errors (manifest row and column, the control file's row
and column): the golden files ``data/exp_control_*``."""
from __future__ import annotations

import numpy as np
import pytest

import physdsl

from .helpers import interval

MASS, G, X0 = 0.5, np.array([0.0, 0.0, -9.81]), np.array([0.0, 0.0, 1.0])
# per recording: the control table (times, forces N) and the true launch velocity
PUSHES = {
    "a": ([0.0, 0.3], [[2.0, 0.0, 0.0], [-1.0, 0.0, 1.0]], [1.0, 0.0, 2.0]),
    "b": ([0.2], [[0.0, 3.0, 0.0]], [2.0, 0.5, 1.5]),
    "c": ([0.0, 0.1, 0.4], [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, -2.0, 2.0]], [0.5, 0.0, 3.0]),
}
TIMES = np.round(np.arange(0.0, 0.601, 0.02), 10)
SCENE = """scene pushed {
  world { timestep: 10 ms  integrator: rk4 }
  experiments runs from "runs.csv"
  body ball {
    shape: sphere(radius: 5 cm)
    mass ~ half_normal(2 kg)
    position: (0, 0, 1) m
    velocity ~ per_experiment normal((1, 0, 2) m/s, 2 m/s)
  }
  control push on ball from runs.push column (fx, fy, fz)
  observe ball.position from "trajectory.csv" where body == "ball" { noise: 2 mm }
}
"""


def exact(knots, forces, v0, t):
    """Position at ``t`` under gravity and the zero-order-hold force table (piecewise
    constant acceleration, integrated in closed form)."""
    edges = [0.0] + [k for k in knots if 0.0 < k < t] + [t]
    x, v = X0.copy(), np.array(v0, dtype=float)
    for lo, hi in zip(edges[:-1], edges[1:]):
        on = [f for k, f in zip(knots, forces) if k <= lo + 1e-12]
        a = G + (np.array(on[-1]) if on else 0.0) / MASS
        dt = hi - lo
        x, v = x + v * dt + 0.5 * a * dt ** 2, v + a * dt
    return x


def write_runs(tmp, noise=0.002, seed=1):
    """The manifest (name, folder, push), each run's push.csv and noisy trajectory.csv."""
    rng = np.random.default_rng(seed)
    rows = ["name,folder,push"]
    for name, (knots, forces, v0) in PUSHES.items():
        folder = tmp / "runs" / name
        folder.mkdir(parents=True)
        (folder / "push.csv").write_text("t,fx,fy,fz\n" + "".join(
            f"{k},{f[0]},{f[1]},{f[2]}\n" for k, f in zip(knots, forces)))
        pos = np.array([exact(knots, forces, v0, t) for t in TIMES])
        pos += rng.normal(0, noise, pos.shape) if noise else 0.0
        (folder / "trajectory.csv").write_text("t,body,x,y,z\n" + "".join(
            f"{t:.2f},ball,{p[0]:.6f},{p[1]:.6f},{p[2]:.6f}\n" for t, p in zip(TIMES, pos)))
        rows.append(f"{name},runs/{name},runs/{name}/push.csv")
    (tmp / "runs.csv").write_text("\n".join(rows) + "\n")
    (tmp / "scene.phys").write_text(SCENE)
    return tmp / "scene.phys"


def test_each_recording_rolls_out_under_its_own_control_file(tmp_path):
    """The rollout of recording r at the true mass and launches is the closed-form trajectory
    under r's own force table (to 1e-9 m); the tables differ, so a swap would not match."""
    model = physdsl.compile(write_runs(tmp_path, noise=0.0))
    assert model.recording_names == ("a", "b", "c")
    v0 = np.array([PUSHES[r][2] for r in model.recording_names])
    roll = model.simulate({"ball.mass": np.array(MASS), "ball.velocity": v0})
    t = np.asarray(roll.t) if roll.t.ndim == 1 else np.asarray(roll.t)[0]
    for i, (name, (knots, forces, v)) in enumerate(PUSHES.items()):
        steps = [int(np.argmin(np.abs(t - s))) for s in TIMES]
        got = np.asarray(roll.body_pos)[i, steps, 0]
        want = np.array([exact(knots, forces, v, s) for s in TIMES])
        np.testing.assert_allclose(got, want, atol=1e-9, err_msg=name)
    first = np.asarray(roll.body_pos)[:, -1, 0]
    assert np.min(np.abs(first[0] - first[1])) > 0.01  # the recordings' pushes differ


# a pooled fit (~35 s); pooled fits: tests/experiments/test_pooled.py, test_backends.py
@pytest.mark.slow
def test_pooled_fit_recovers_the_shared_mass_through_the_controls(tmp_path):
    """MAP + Laplace over 3 runs (0.6 s, 2 mm noise): the shared mass's 90% interval covers
    0.5 kg and is within 3% of it; each run's launch velocity within 2 cm/s of its truth."""
    model = physdsl.compile(write_runs(tmp_path))
    idata = physdsl.infer(model, backend="map", chains=1, progress=False, seed=0)
    lo, hi = interval(idata, "ball.mass")
    assert lo <= MASS <= hi and hi - lo < 0.03 * MASS
    v = np.asarray(idata.posterior["ball.velocity"].values).reshape(-1, 3, 3).mean(axis=0)
    np.testing.assert_allclose(v, [PUSHES[r][2] for r in ("a", "b", "c")], atol=0.02)


def test_format_keeps_the_manifest_column_source():
    from physdsl.syntax.parser import parse
    from physdsl.syntax.printer import format_module
    assert format_module(parse(SCENE), SCENE) == SCENE
    item = [i for i in parse(SCENE).items[0].items if type(i).__name__ == "ControlItem"][0]
    assert (item.setting, item.file, item.columns) == ("runs.push", None, ("fx", "fy", "fz"))
