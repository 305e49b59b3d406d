"""refine adds a sensor fault as a term of the scene: a hinge encoder with a constant offset
(the bob's tracked positions unbiased), physdsl-simulated. The loop writes ``offset`` into the
encoder's observe block, ends at the noise and adds no physical effect."""
from __future__ import annotations

import json

import numpy as np
import pytest

from .conftest import PENDULUM, write_csv

SCENE = PENDULUM.replace(
    "  observe hinge.angle",
    '  observe bob.position from "bob.csv" where body == "bob" { noise: 2 mm }\n  observe hinge.angle')
TIMES = np.linspace(0.0, 2.0, 101)
OFFSET = 0.03  # rad: 10 noise sigmas of the encoder


@pytest.mark.slow
def test_refine_adds_the_encoder_offset_and_no_effect(tmp_path):
    from physdsl.compile import Model
    from physdsl.diagnose.refine import refine
    from physdsl.syntax import load

    data = tmp_path / "data"
    data.mkdir()
    write_csv(data / "joints.csv", TIMES, np.zeros((101, 1)), "hinge")
    write_csv(data / "bob.csv", TIMES, np.zeros((101, 3)), "bob")
    (data / "naive.phys").write_text(SCENE)
    pred = Model(load(data / "naive.phys")).predict({"hinge.initial": np.array(0.7)})
    rng = np.random.default_rng(11)
    write_csv(data / "joints.csv", TIMES, np.asarray(pred["hinge.angle"]) + OFFSET
              + rng.normal(0, 0.003, (101, 1)), "hinge")
    write_csv(data / "bob.csv", TIMES, np.asarray(pred["bob.position"])
              + rng.normal(0, 0.002, (101, 3)), "bob")
    rounds = refine(data / "naive.phys", tmp_path / "out", max_rounds=2, confirm_top=1,
                    echo=lambda line: None)
    summary = json.loads((tmp_path / "out" / "refine.json").read_text())
    added = [r["added"] for r in summary["rounds"] if r["added"]]
    assert added == [{"effect": "offset", "target": "hinge.angle"}], summary
    assert rounds[-1].rms_sigma <= 1.2
    final = load(rounds[-1].scene)
    assert [e.effect for e in final.effects] == ["gravity"]  # no physical effect added
    assert "offset ~ normal" in final.source
