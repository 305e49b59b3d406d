"""A third-party effect (tests/thirdparty/demo_effect: one module, one entry point) installed
at test time is picked up by ``physdsl lint``, by ``diagnose``'s candidate list and by
``refine``, with no change to physdsl's files.

"Installed" means what pip leaves behind: the module on ``sys.path`` and a ``.dist-info``
whose ``entry_points.txt`` names it under group ``physdsl.effects`` (written from the
plug-in's own pyproject.toml). The data are a tethered throw solved in closed form: under
gravity g and F = -k (x - anchor) each coordinate oscillates about anchor + m g / k.
"""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from plugins import install, looked_at_again

from physdsl.cli import main
from physdsl.diagnose.candidates import Candidate, physics_candidates
from physdsl.physics import build_simulator
from physdsl.physics.effects import EFFECTS
from physdsl.registry import EFFECT_DECLARATIONS
from physdsl.syntax import load

PLUGIN = Path(__file__).parent / "thirdparty" / "demo_effect"
FIT = ("--backend", "map", "--chains", "2", "--warmup", "200", "--samples", "200")
MASS, K, G = 0.2, 0.5, np.array([0.0, 0.0, -9.81])
X0, V0 = np.array([0.0, 0.0, 1.0]), np.array([3.0, 0.0, 12.0])
NOISE = 0.005

SCENE = """\
scene tethered {
  world {
    timestep: 20 ms
    duration: 2 s
    integrator: rk4
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 12) m/s, 2 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
EFFECT  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""
TETHER = "  effect demo_tether on ball { stiffness: 0.5 N/m }\n"


def tethered_throw(t):
    """Closed-form positions (len(t), 3) of the ball on a tether to the origin."""
    w = np.sqrt(K / MASS)
    eq = G * MASS / K
    t = np.asarray(t)[:, None]
    return eq + (X0 - eq) * np.cos(w * t) + V0 / w * np.sin(w * t)


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """The plug-in installed for this test: its module and a .dist-info on sys.path; the
    registries are looked at again, and restored after (other tests see no plug-in)."""
    eps = tomllib.loads((PLUGIN / "pyproject.toml").read_text())["project"]["entry-points"]
    (tmp_path / "site").mkdir()
    install(tmp_path / "site", monkeypatch, "physdsl_demo_effect", None,
            {group: "".join(f"{k} = {v}\n" for k, v in table.items()).rstrip()
             for group, table in eps.items()})
    monkeypatch.syspath_prepend(str(PLUGIN))
    with looked_at_again((EFFECTS, EFFECT_DECLARATIONS), ("physdsl_demo_effect",)):
        yield


@pytest.fixture
def case(tmp_path):
    """data.csv (the tethered throw plus seeded noise), the truth scene and the naive one."""
    t = np.arange(101) * 0.02
    x = tethered_throw(t) + np.random.default_rng(3).normal(0, NOISE, (len(t), 3))
    rows = ["t,body,x,y,z"] + [f"{a:.6f},ball,{p:.10g},{q:.10g},{r:.10g}" for a, (p, q, r)
                               in zip(t, x)]
    (tmp_path / "data.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "truth.phys").write_text(SCENE.replace("EFFECT", TETHER))
    (tmp_path / "naive.phys").write_text(SCENE.replace("EFFECT", ""))
    return tmp_path


def test_lint_refuses_the_effect_until_the_plugin_is_installed(case, capsys):
    assert main(["lint", str(case / "truth.phys")]) == 2
    assert "unknown effect 'demo_tether'" in capsys.readouterr().err


def test_lint_accepts_a_scene_using_the_plugin_effect(installed, case, capsys):
    assert main(["lint", str(case / "truth.phys")]) == 0, capsys.readouterr().err
    assert "ok: scene 'tethered'" in capsys.readouterr().out
    assert EFFECTS.origin("demo_tether") == "physdsl_demo_effect"
    scene = load(case / "truth.phys")
    assert [(e.effect, e.target) for e in scene.effects][1:] == [("demo_tether", ("ball",))]


def test_the_plugin_effect_runs_as_its_closed_form(installed, case):
    """The registered physics is what the scene runs: the rollout of the truth scene is the
    closed-form tethered throw."""
    sim = build_simulator(load(case / "truth.phys"))
    roll = sim.simulate({"ball.velocity": V0})
    ball = sim.body_names.index("ball")
    np.testing.assert_allclose(np.asarray(roll.body_pos)[:, ball], tethered_throw(sim.times),
                               atol=1e-6)


def test_the_plugin_effect_is_a_candidate_of_diagnose(installed, case):
    naive = load(case / "naive.phys")
    assert Candidate("effect", "demo_tether", ("ball",)) in physics_candidates(naive)
    assert "demo_tether" not in {c.name for c in physics_candidates(load(case / "truth.phys"))}


@pytest.mark.slow
def test_diagnose_ranks_the_hidden_plugin_effect_first(installed, case, tmp_path, capsys):
    assert main(["infer", str(case / "naive.phys"), "-o", str(tmp_path / "run"), *FIT]) == 0
    assert main(["diagnose", str(case / "naive.phys"), "--posterior", str(tmp_path / "run"),
                 "-o", str(tmp_path / "diag"), "--confirm", "0"]) == 0, capsys.readouterr().err
    ranking = json.loads((tmp_path / "diag" / "diagnosis.json").read_text())["ranking"]
    assert (ranking[0]["effect"], ranking[0]["target"]) == ("demo_tether", "ball")
    assert ranking[0]["estimate"] > 0  # a pull towards the anchor, as the truth


@pytest.mark.slow
def test_refine_adds_the_hidden_plugin_effect(installed, case, tmp_path, capsys):
    assert main(["refine", str(case / "naive.phys"), "-o", str(tmp_path / "out"),
                 "--max-rounds", "1", "--confirm", "1", *FIT]) == 0, capsys.readouterr().err
    rounds = json.loads((tmp_path / "out" / "refine.json").read_text())["rounds"]
    assert [r["added"] for r in rounds] == [None, {"effect": "demo_tether", "target": "ball"}]
