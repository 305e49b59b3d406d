"""The rules that keep a learned force honest, on their own: where it is kept, who wins a tie,
where a residual force is put."""
from __future__ import annotations

from types import SimpleNamespace

import physdsl
from physdsl.discover.beyond import (Beyond, learned_helps, library_wins, pointed_target,
                                     verdict)

SCENE = """scene s {
  world { timestep: 10 ms }
  body ball { shape: sphere(radius: 5 cm)  mass: 200 g }
  body bob { shape: sphere(radius: 5 cm)  mass: 1 kg  position: (2, 0, -1) m }
  joint hinge: hinge(world -> bob) { anchor: (2, 0, 0) m  axis: (0, 1, 0) }
}
"""


def _fit(rms):
    return SimpleNamespace(rms=rms)


def test_a_learned_force_is_kept_only_for_a_real_and_evident_gain():
    assert learned_helps(_fit(5.0), _fit(1.0), 100.0, 200.0)
    assert not learned_helps(_fit(5.0), _fit(4.8), 100.0, 200.0)  # RMS falls by less than 10%
    assert not learned_helps(_fit(5.0), _fit(1.0), 100.0, 101.0)  # evidence gain below log 10
    assert learned_helps(_fit(5.0), _fit(1.0), None, 200.0)  # evidence n/a: the RMS decides


def _beyond(library, law_z, proposed=True):
    law = {"terms": ["v_sqrt_speed"], "rms": 1.0, "log_z": law_z, "in_library": False}
    return Beyond("ball", "body", 5.0, 1.0, 0.0, 150.0, proposed, "", library,
                  law if proposed else None)


def test_a_library_effect_that_explains_the_data_wins_ties():
    lib = {"effect": "quadratic_drag@ball", "rms": 1.05, "log_z": 200.0}
    assert verdict(_beyond(lib, 201.0)).startswith("the library's quadratic_drag@ball explains")
    assert "distilled law: v_sqrt_speed" in verdict(_beyond(lib, 210.0))  # clearly better
    worse = {"effect": "quadratic_drag@ball", "rms": 2.7, "log_z": 200.0}  # not at the noise
    assert "distilled law" in verdict(_beyond(worse, 210.0))
    # beside a library winner that leaves systematic residuals the evidence still decides:
    # a law no better than log 10 does not displace it
    assert verdict(_beyond(worse, 190.0)).startswith("the library's quadratic_drag@ball explains")
    assert verdict(_beyond(worse, 201.0)).startswith("the library's quadratic_drag@ball explains")
    # evidence n/a: the law must reach the noise where the library does not
    assert "distilled law" in verdict(_beyond({**worse, "log_z": None}, None))
    assert library_wins({**worse, "rms": 1.1, "log_z": None}, {"rms": 1.0, "log_z": None})
    assert verdict(_beyond(None, 0.0, proposed=False)).startswith("nothing learned is proposed")


def test_the_residual_goes_where_the_check_points():
    scene = physdsl.load(SCENE)
    obs = lambda name, rms: SimpleNamespace(name=name, rms_sigma=rms)  # noqa: E731
    assert pointed_target(scene, SimpleNamespace(observables=[obs("ball.position", 1.1),
                                                              obs("hinge.angle", 9.0)])) == "hinge"
    assert pointed_target(scene, SimpleNamespace(observables=[obs("ball.position", 4.0),
                                                              obs("hinge.angle", 1.0)])) == "ball"
