"""Stepwise selection end to end (slow): a double pendulum with two hidden effects of two laws,
viscous damping in the shoulder and Coulomb friction in the elbow; ``refine`` from the naive
scene must find both, law and target, and end at the noise."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from physdsl.compile import Model
from physdsl.diagnose.candidates import Candidate
from physdsl.diagnose.edits import load_text, with_effect
from physdsl.diagnose.refine import refine
from physdsl.syntax import load

from .conftest import load_scene

pytestmark = pytest.mark.slow

DOUBLE = """\
scene double {
  world {
    timestep: 2 ms
    duration: 4 s
    integrator: rk4
  }
  body link1 { shape: capsule(radius: 2 cm, length: 40 cm)  mass: 400 g  position: (0, 0, 1.3) m }
  body link2 { shape: capsule(radius: 1.5 cm, length: 30 cm)  mass: 300 g  position: (0, 0, 0.95) m }
  joint shoulder: hinge(world -> link1) {
    axis: (0, -1, 0)
    anchor: (0, 0, 1.5) m
    initial ~ normal(50 deg, 5 deg)
    initial_velocity: 0 rad/s
  }
  joint elbow: hinge(link1 -> link2) {
    axis: (0, -1, 0)
    anchor: (0, 0, 1.1) m
    initial ~ normal(-30 deg, 5 deg)
    initial_velocity: 0 rad/s
  }
  observe shoulder.angle from "joints.csv" where joint == "shoulder" { noise: 5 mrad }
  observe elbow.angle from "joints.csv" where joint == "elbow" { noise: 5 mrad }
  observe link2.position from "bob.csv" where body == "link2" { noise: 2 mm }
}
"""


def _write(folder, times, pred):
    rows = ["t,joint,angle"]
    for name in ("shoulder", "elbow"):
        rows += [f"{t:.6f},{name},{a:.10g}" for t, (a,) in zip(times, pred[f"{name}.angle"])]
    (folder / "joints.csv").write_text("\n".join(rows) + "\n")
    rows = ["t,body,x,y,z"] + [f"{t:.6f},link2,{x:.10g},{y:.10g},{z:.10g}"
                               for t, (x, y, z) in zip(times, pred["link2.position"])]
    (folder / "bob.csv").write_text("\n".join(rows) + "\n")


def test_refine_finds_damping_in_one_hinge_and_friction_in_the_other(tmp_path):
    times = np.linspace(0.0, 4.0, 201)
    _write(tmp_path, times, {"shoulder.angle": np.zeros((201, 1)), "elbow.angle": np.zeros((201, 1)),
                             "link2.position": np.zeros((201, 3))})
    naive = load_scene(tmp_path, DOUBLE, "naive.phys")
    text = with_effect(naive, Candidate("effect", "joint_damping", ("shoulder",)),
                       Candidate("effect", "joint_friction", ("elbow",)))
    truth = Model(load_text(naive, text))
    values = {"shoulder.initial": np.radians(50.0), "elbow.initial": np.radians(-30.0),
              "joint_damping@shoulder.coefficient": 0.004, "joint_friction@elbow.torque": 0.002}
    pred = {k: np.asarray(v) for k, v in truth.predict(values).items()}
    rng = np.random.default_rng(21)
    noisy = {"shoulder.angle": pred["shoulder.angle"] + rng.normal(0, 0.005, (201, 1)),
             "elbow.angle": pred["elbow.angle"] + rng.normal(0, 0.005, (201, 1)),
             "link2.position": pred["link2.position"] + rng.normal(0, 0.002, (201, 3))}
    _write(tmp_path, times, noisy)
    rounds = refine(tmp_path / "naive.phys", tmp_path / "out", max_rounds=4, confirm_top=2,
                    warmup=200, samples=64, echo=print)
    final = load(rounds[-1].scene)
    found = {(e.effect, tuple(e.target)) for e in final.effects} - {("gravity", ("world",))}
    history = [(r.action, r.added, r.replaced, round(r.rms_sigma, 3)) for r in rounds]
    # both laws, each on its hinge, and nothing else (the round-0 damping on the elbow dropped)
    assert found == {("joint_damping", ("shoulder",)), ("joint_friction", ("elbow",))}, history
    assert rounds[-1].rms_sigma <= 1.2 and rounds[-1].consistent, history
    with (Path(rounds[-1].scene).parent / "fit" / "summary.csv").open() as f:
        summary = {r["name"]: r for r in csv.DictReader(f)}
    for key, value in values.items():  # the truth inside every 90% interval
        assert float(summary[key]["q5"]) <= value <= float(summary[key]["q95"]), (key, summary[key])
