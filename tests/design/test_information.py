"""The information design on a short horizon (the search and its files: ``-m slow``, for
the compilation of the gain's gradient): a cart on a damped rail (unknown mass m and
damping c) pushed by a piecewise-constant force. The Fisher matrix through the rollout equals
the one of the closed-form solution of m x'' = u - c x'; the prior belief is the log-normal's
exact Gaussian in log space; the search beats every random push of the same energy and stays
within the bounds and the budget; its files replay the chosen push."""
from __future__ import annotations

import json

import numpy as np
import pytest

import physdsl
from physdsl.design.excite import search
from physdsl.design.information import Z90, belief, fisher, intervals
from physdsl.design.vary import energy, varied

PUSH = "control_force@rail.values"
TIMES = np.round(np.arange(0.0, 1.0 + 1e-9, 0.05), 6)
CONTROL_T = np.arange(5) * 0.2
SCENE = """\
scene cart_short {
  world { timestep: 10 ms  duration: 1 s  integrator: rk4 }
  param m ~ log_normal(0, 0.5)
  param c ~ log_normal(0, 1)
  body cart {
    shape: box(size: (20, 10, 10) cm)
    mass: m
    position: (0, 0, 0.5) m
  }
  joint rail: slider(world -> cart) { axis: (1, 0, 0) }
  effect joint_damping on rail { coefficient: c }
  control push on rail {
    times: (0, 0.2, 0.4, 0.6, 0.8) s
    values ~ uniform(-5 N, 5 N)
  }
  observe rail.angle from "data.csv" where joint == "rail" { noise: 2 mm }
}
"""


def closed_form(m: float, c: float, push, times) -> np.ndarray:
    """x(t) of m x'' = u - c x' from rest, u held over each 0.2 s (exact, interval by interval)."""
    out = []
    for t in times:
        x = v = 0.0
        start = 0.0
        for k, u in enumerate(push):
            end = min(t, CONTROL_T[k + 1] if k + 1 < len(push) else np.inf)
            if end <= start:
                break
            h, vinf = end - start, u / c
            decay = np.exp(-c * h / m)
            x += vinf * h + (v - vinf) * m / c * (1 - decay)
            v = vinf + (v - vinf) * decay
            start = end
        out.append(x)
    return np.asarray(out)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cart")
    (folder / "data.csv").write_text("t,joint,angle\n" + "".join(f"{t},rail,0\n" for t in TIMES))
    (folder / "cart.phys").write_text(SCENE)
    return physdsl.compile(folder / "cart.phys")


@pytest.mark.slow  # ~37 s
def test_fisher_is_the_closed_form_ones(model):
    b = belief(model, (PUSH,))
    push = np.array([3.0, -1.0, 4.0, 0.5, -2.0])
    point = {"m": np.exp(b.centre[b.index][list(b.names).index("m")]),
             "c": np.exp(b.centre[b.index][list(b.names).index("c")])}
    # J by central differences of the closed form in (log c, log m): the flat vector's order
    eps, cols = 1e-6, []
    for name in b.names:
        up, down = dict(point), dict(point)
        up[name] *= np.exp(eps)
        down[name] *= np.exp(-eps)
        cols.append((closed_form(up["m"], up["c"], push, TIMES)
                     - closed_form(down["m"], down["c"], push, TIMES)) / (2 * eps) / 0.002)
    jac = np.stack(cols, axis=1)
    got = np.asarray(fisher(model, b, {PUSH: push}))
    np.testing.assert_allclose(got, jac.T @ jac, rtol=2e-4)
    assert np.linalg.cond(got) > 1  # a real 2x2 information, not a diagonal stub
    assert abs(got[0, 1]) > 1e-3 * np.sqrt(got[0, 0] * got[1, 1])


def test_prior_belief_and_its_intervals(model):
    b = belief(model, (PUSH,))
    assert b.names == ("c", "m") and b.from_posterior == ()
    # log-normal(0, s): its log is normal(0, s), precision 1 / s^2 (the transform's Jacobian in)
    np.testing.assert_allclose(b.precision, np.diag([1.0, 4.0]), atol=1e-9)
    got = intervals(model, b, b.precision)
    mu = b.centre[b.index][1]
    assert got["m"]["lower"][0] == pytest.approx(np.exp(mu - Z90 * 0.5), rel=1e-9)
    assert got["m"]["upper"][0] == pytest.approx(np.exp(mu + Z90 * 0.5), rel=1e-9)


@pytest.mark.slow  # compiling the gain's gradient (forward over forward mode): ~90 s of CPU
def test_search_beats_random_pushes_within_bounds_and_budget(model, tmp_path):
    item = (varied(model, "rail"),)  # the control on the rail, by its target
    assert item[0].field == PUSH and np.all(item[0].upper == 5.0)
    b = belief(model, (PUSH,))
    d = search(model, b, item, restarts=2, random=6, steps=25, seed=1)
    push = np.asarray(d.settings[PUSH])
    assert np.all(np.abs(push) <= 5.0 + 1e-12)
    assert d.energy <= d.budget * (1 + 1e-9)
    assert float(energy(model, item, {PUSH: push})) == pytest.approx(d.energy, rel=1e-9)
    assert d.gain >= max(d.starts) - 1e-9 and d.gain > d.random_gain
    # the after-intervals are the Fisher's: recomputed independently from the chosen push
    after = intervals(model, b, b.precision + np.asarray(fisher(model, b, {PUSH: push})))
    for n in b.names:
        assert after[n]["width"][0] == pytest.approx(d.after[n]["width"][0], rel=1e-6)
        assert d.after[n]["width"][0] < d.before[n]["width"][0]
    text = d.text()
    assert "worse-determined" in text and "90% interval width" in text


@pytest.mark.slow  # the same compilation (shared when run with the test above)
def test_files_replay_the_chosen_push(model, tmp_path):
    out = tmp_path / "exp"
    d = physdsl.design_experiment(model, None, ["rail"], restarts=1, random=2, steps=5,
                                  outdir=out)
    table = np.loadtxt(out / "control_rail.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1], np.ravel(d.settings[PUSH]), rtol=1e-10, atol=1e-12)
    planned = physdsl.compile(out / "experiment.phys", allowed_paths=[model.scene.path.parent])
    assert PUSH not in planned.unknown_names
    values = {"m": 1.3, "c": 0.7}
    np.testing.assert_allclose(np.asarray(planned.predict(values)["rail.angle"]),
                               np.asarray(model.predict({**values, PUSH: d.settings[PUSH]})["rail.angle"]),
                               atol=1e-12)
    report = json.loads((out / "design.json").read_text())
    assert report["criterion"] == "d_optimal" and set(report["unknowns"]) == {"c", "m"}
    assert report["unknowns"]["m"]["after"]["width"][0] == pytest.approx(d.after["m"]["width"][0])
    assert (out / "design.txt").read_text().strip() == d.text()
    with pytest.raises(physdsl.errors.UsageError, match="not empty"):
        physdsl.design_experiment(model, None, ["rail"], outdir=out)


def test_cli_usage_errors(model, tmp_path, capsys):
    from physdsl.cli import main

    scene = model.scene.path
    for vary, message in (("cart.mass", "not an unknown"), ("m", "no range")):
        code = main(["design-experiment", str(scene), "--vary", vary, "-o", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow  # compiles the gain's gradient for this scene (~90 s of CPU)
def test_an_initial_state_within_its_range(tmp_path):
    """Varying the rail's initial speed (the push known): the choice stays within --range, and
    a faster start, which the damping slows visibly, teaches more than the mean random one."""
    (tmp_path / "data.csv").write_text("t,joint,angle\n" + "".join(f"{t},rail,0\n" for t in TIMES))
    text = SCENE.replace("values ~ uniform(-5 N, 5 N)", "values: (1, 0, 0, 0, 0) N").replace(
        "axis: (1, 0, 0) }", "axis: (1, 0, 0)  initial_velocity ~ normal(0 m/s, 1 m/s) }")
    (tmp_path / "cart.phys").write_text(text)
    model = physdsl.compile(tmp_path / "cart.phys")
    d = physdsl.design_experiment(model, None, ["rail.initial_velocity"], rng=(-0.5, 1.5),
                                  restarts=2, random=6, steps=25)
    v0 = float(np.ravel(d.settings["rail.initial_velocity"])[0])
    assert -0.5 <= v0 <= 1.5 and d.energy is None and d.budget is None
    assert d.gain > d.random_gain and v0 > 1.0  # the larger speed allowed
    assert set(d.before) == {"c", "m"}
