"""A diagnosis's candidate refits through the executor interface: the same numbers whether a
refit runs here (the default) or as a task that travels to a worker (pickled there and back:
``refit_task.RefitTask`` and its measures), and on a real local process pool (slow)."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import physdsl
from physdsl.batch.executors import InlineExecutor, refits_on
from physdsl.diagnose import refit_task

M, K, V0, X0, G = 0.2, 0.08, np.array([4.0, 0.0, 5.0]), np.array([0.0, 0.0, 1.0]), 9.81
TIMES = np.linspace(0.0, 0.8, 41)
NAIVE = """\
scene toss {
  world { timestep: 10 ms  integrator: rk4  duration: 0.8 s }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((4, 0, 5) m/s, 1 m/s)
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""


def linear_drag_throw(t: np.ndarray) -> np.ndarray:
    """Closed-form flight under gravity and linear drag F = -K v (positions (T, 3))."""
    tau = M / K
    decay = 1.0 - np.exp(-t / tau)
    vt = np.array([0.0, 0.0, -G * tau])  # terminal velocity
    return X0 + np.outer(decay, (V0 - vt) * tau) + np.outer(t, vt)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """The scene without drag fitted to the drag throw (MAP): (model, idata)."""
    root = tmp_path_factory.mktemp("refits")
    x = linear_drag_throw(TIMES) + np.random.default_rng(3).normal(0, 0.005, (len(TIMES), 3))
    (root / "data.csv").write_text("t,body,x,y,z\n" + "".join(
        f"{t:.4f},ball,{a:.6f},{b:.6f},{c:.6f}\n" for t, (a, b, c) in zip(TIMES, x)))
    (root / "scene.phys").write_text(NAIVE)
    model = physdsl.compile(root / "scene.phys")
    return model, physdsl.infer(model, backend="map", chains=1, progress=False)


def refitted(diagnosis) -> dict:
    return {(r.effect, r.target): r for r in diagnosis.ranking if r.delta_elpd is not None}


def travelled(fn, task):
    """A submit that sends ``task`` and the answer through pickle, as a worker's would."""
    future = InlineExecutor().submit(fn, pickle.loads(pickle.dumps(task)))
    return InlineExecutor().submit(pickle.loads, pickle.dumps(future.result()))


@pytest.mark.slow  # ~23 s
def test_refits_as_tasks_give_the_refits_made_here(fitted):
    """The refits' ΔELPD, ΔLFO, RMS, evidence and fitted strength are the same (1e-9) when
    each refit travels as a task; both name the same drag law, which brings the residuals
    from far above the noise to it (a 0.8 s throw at 6.4 m/s barely tells linear from
    quadratic drag, so either may win)."""
    model, idata = fitted
    here = physdsl.diagnose(model, idata, confirm_top=1)
    with refit_task.submitting(travelled):
        there = physdsl.diagnose(model, idata, confirm_top=1)
    a, b = refitted(here), refitted(there)
    assert len(a) >= 1 and a.keys() == b.keys()
    for key in a:
        for name in ("delta_elpd", "delta_lfo", "rms_after", "log_evidence"):
            assert getattr(b[key], name) == pytest.approx(getattr(a[key], name), rel=1e-9), name
        assert b[key].fitted["median"] == pytest.approx(a[key].fitted["median"], rel=1e-9)
        assert b[key].snippet == a[key].snippet and b[key].refit is not None
    assert here.winner.effect == there.winner.effect  # the data's drag, or its quadratic twin
    assert here.winner.effect in ("linear_drag", "quadratic_drag")
    assert here.winner.rms_after < 1.3 < here.winner.rms_before


@pytest.mark.slow  # spawns 2 workers: each imports JAX and compiles its refit
def test_refits_on_a_local_pool_give_the_same_numbers(fitted):
    model, idata = fitted
    here = refitted(physdsl.diagnose(model, idata))
    with refits_on("local", workers=2):
        pool = refitted(physdsl.diagnose(model, idata))
    assert here.keys() == pool.keys()
    for key in here:
        assert pool[key].delta_elpd == pytest.approx(here[key].delta_elpd, rel=1e-6)
        assert pool[key].rms_after == pytest.approx(here[key].rms_after, rel=1e-6)


@pytest.mark.parametrize("args, message", [
    (["diagnose", "scene.phys", "-p", "run", "-o", "diag", "--executor", "dask"],
     "unknown executor 'dask'"),
    (["refine", "scene.phys", "-o", "ref", "--address", "127.0.0.1:6379"],
     "--address goes with --executor ray"),
])
def test_refit_executor_usage_errors_exit_2(tmp_path, monkeypatch, capsys, args, message):
    from physdsl.cli import main
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    assert message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # refused before anything was read or written
