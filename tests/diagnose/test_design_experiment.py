"""The experiment that decides: linear and quadratic drag fitted to the same slow throw
(physdsl-simulated, quadratic drag true) predict alike at the recorded speed; the proposed
throw speed separates them by >= 5 sigma, and simulating both at it gives that separation."""
from __future__ import annotations

import numpy as np
import pytest

from physdsl.design.experiment import OBJECTIVES, Pair, design

from .conftest import PROJECTILE, fit, load_scene, write_csv

SLOW = PROJECTILE.replace("normal((3, 0, 12) m/s, 2 m/s)", "normal((3, 0, 3) m/s, 2 m/s)").replace(
    "duration: 2 s", "duration: 0.8 s").replace("timestep: 20 ms", "timestep: 10 ms")
TIMES = np.linspace(0.0, 0.8, 41)


def _with(text: str, effect: str, prior: str) -> str:
    return text.replace("  observe", f"  effect {effect} on ball {{ coefficient ~ {prior} }}\n  observe")


@pytest.fixture(scope="module")
def fitted_pair(tmp_path_factory):
    from physdsl.compile import Model
    from physdsl.diagnose.workflow import point_estimate

    folder = tmp_path_factory.mktemp("design")
    write_csv(folder / "data.csv", TIMES, np.zeros((41, 3)), "ball")
    quad = _with(SLOW, "quadratic_drag", "half_normal(0.01 kg/m)")
    lin = _with(SLOW, "linear_drag", "half_normal(0.05 kg/s)")
    truth = {"ball.velocity": np.array([3.0, 0.0, 3.2]),
             "quadratic_drag@ball.coefficient": np.array(4e-3)}
    clean = np.asarray(Model(load_scene(folder, quad, "q.phys")).predict(truth)["ball.position"])
    noisy = clean + np.random.default_rng(1).normal(0, 0.005, clean.shape)
    write_csv(folder / "data.csv", TIMES, noisy, "ball")
    out = []
    for name, text in (("q.phys", quad), ("l.phys", lin)):
        m = Model(load_scene(folder, text, name))
        out.append((m, point_estimate(m, fit(m))))
    return out


def test_proposed_throw_separates_the_laws(fitted_pair):
    (mq, vq), (ml, vl) = fitted_pair
    p = design(ml, vl, mq, vq, "ball.velocity", rng=(1.0, 20.0), labels=("linear", "quadratic"))
    assert p.recorded_score < 3.0  # the recorded throw barely tells them apart
    assert p.score >= 5.0 and p.setting > p.recorded
    # simulate both at the proposed throw: the separation is the reported one
    pair = Pair(ml, vl, mq, vq, "ball.velocity")
    pa, pb = pair.predict(p.setting)
    again, where = OBJECTIVES["max_sigma"](pa, pb, pair.sigma, pair.times)
    assert again == pytest.approx(p.score, rel=1e-9) and where == p.where
    # independently: the largest |Δ|/σ of the two rollouts at that speed
    d = np.abs(pa["ball.position"] - pb["ball.position"]) / 0.005
    assert float(d.max()) == pytest.approx(p.score, rel=1e-9)
    assert "linear and quadratic then differ by" in p.text()
    print(p.text())


def test_cli_usage_errors_before_any_fit(tmp_path, cli):
    write_csv(tmp_path / "data.csv", TIMES, np.zeros((41, 3)), "ball")
    for name, eff in (("q.phys", "quadratic_drag"), ("l.phys", "linear_drag")):
        (tmp_path / name).write_text(_with(SLOW, eff, "half_normal(0.01)"))
    args = ["design-experiment", tmp_path / "l.phys", tmp_path / "q.phys", "-o", tmp_path / "out"]
    code, out, err = cli(*args, "--vary", "ball.mass")
    assert code == 2 and "--vary ball.mass: not an unknown" in err and "Traceback" not in err
    code, out, err = cli(*args, "--vary", "ball.velocity", "--range", "fast")
    assert code == 2 and "expected LO:HI" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_cli_fits_both_and_writes_the_design(tmp_path, cli):
    write_csv(tmp_path / "data.csv", TIMES, np.zeros((41, 3)), "ball")
    from physdsl.compile import Model
    quad = _with(SLOW, "quadratic_drag", "half_normal(0.01 kg/m)")
    truth = {"ball.velocity": np.array([3.0, 0.0, 3.2]),
             "quadratic_drag@ball.coefficient": np.array(4e-3)}
    clean = np.asarray(Model(load_scene(tmp_path, quad, "q.phys")).predict(truth)["ball.position"])
    write_csv(tmp_path / "data.csv", TIMES, clean + np.random.default_rng(1).normal(0, 0.005, clean.shape), "ball")
    (tmp_path / "l.phys").write_text(_with(SLOW, "linear_drag", "half_normal(0.05 kg/s)"))
    code, out, err = cli("design-experiment", tmp_path / "l.phys", tmp_path / "q.phys", "--vary",
                         "ball.velocity", "--range", "1:20", "-o", tmp_path / "out")
    assert code == 0, err
    import json
    p = json.loads((tmp_path / "out" / "design.json").read_text())["proposals"][0]
    assert p["score"] >= 5 and p["setting"] > p["recorded"] and "then differ by" in out
