"""A steady push on a body has contact laws as alternatives where the body touches something
(``diagnose/contact_sources.py``): rolling resistance and sliding friction on the pairs the
fitted rollout shows in contact, none on a pair never touched, none in free flight."""
from __future__ import annotations

import numpy as np

from physdsl.compile import Model
from physdsl.diagnose.candidates import Candidate
from physdsl.diagnose.contact_sources import touching
from physdsl.diagnose.edits import Draft, load_text, with_effect
from physdsl.diagnose.stepwise import alternatives, sources_unexamined

from .conftest import load_scene, write_csv

# a ball rolling along the floor; a wall it never reaches is a contact pair of the scene too
ROLLING = """\
scene rolling {
  world {
    timestep: 5 ms
    duration: 0.3 s
  }
  ground floor { normal: (0, 0, 1)  point: (0, 0, 0) m }
  ground wall { normal: (-1, 0, 0)  point: (5, 0, 0) m }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, HEIGHT)
    velocity ~ normal((1.5, 0, VZ) m/s, 0.3 m/s)
    angular_velocity: (0, 30, 0) rad/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 2 mm }
}
"""
PUSH = Candidate("effect", "constant_force", ("ball",))
CONTACT_LAWS = {"rolling_resistance", "contact_friction"}


def _pushed(tmp_path, height: str, vz: float):
    """The scene with a constant force on the ball, and the pairs its rollout touches."""
    write_csv(tmp_path / "data.csv", np.linspace(0, 0.3, 7), np.zeros((7, 3)), "ball")
    scene = load_scene(tmp_path, ROLLING.replace("HEIGHT", height).replace("VZ", str(vz)))
    pushed = load_text(scene, with_effect(scene, PUSH))
    model = Model(pushed)
    values = {u: np.zeros(3) for u in model.unknown_names}
    values["ball.velocity"] = np.array([1.5, 0.0, vz])
    draft = Draft.of(pushed)
    # added by the loop: re-examined next round where it touches something (the diagnosis
    # that chose it ranked the contact laws at other targets)
    return draft, touching(model, values), sources_unexamined(draft, PUSH, model, values)


def test_a_push_on_a_rolling_ball_has_the_contact_laws_of_its_touched_pair(tmp_path):
    draft, touched, due = _pushed(tmp_path, "5 cm", 0.0)
    assert touched == {frozenset(("floor", "ball"))}  # on the floor, never at the wall
    assert due
    keys = {c.key for c in alternatives(draft, PUSH, touched=touched)}
    assert {f"{law}@floor,ball" for law in CONTACT_LAWS} <= keys
    assert not any("wall" in k for k in keys)  # a pair never touched cannot make the force
    assert "restitution@floor,ball" not in keys  # acts at impacts only (off at 1, not 0)
    # without the fit's contacts every pair of the ball counts, and with two of them the
    # law on all of the ball's pairs with one coefficient (its surface) is offered too
    keys = {c.key for c in alternatives(draft, PUSH)}
    assert {f"{law}@{p}" for law in CONTACT_LAWS for p in ("floor,ball", "wall,ball", "ball,*")} <= keys
    assert not any(k.startswith(("damper", "restitution")) for k in keys)  # no spring, no impact law
    # the ball-wide law is one shared param on both pairs; taking the push out keeps the rest
    wide = Candidate("effect", "rolling_resistance", ("ball", "*"))
    bare = draft.without_candidate(PUSH)
    both = bare.with_candidate(wide).scene
    assert {tuple(e.target) for e in both.effects if e.effect == "rolling_resistance"} == \
        {("floor", "ball"), ("wall", "ball")}
    assert "ball_rolling_resistance" in {u.name for u in both.unknowns}
    assert not any(e.effect == "constant_force" for e in both.effects)


def test_a_push_in_free_flight_has_no_contact_alternative(tmp_path):
    draft, touched, due = _pushed(tmp_path, "2 m", 3.0)  # thrown up, lands long after 0.3 s
    assert touched == set() and not due
    assert not any(c.name in CONTACT_LAWS for c in alternatives(draft, PUSH, touched=touched))
