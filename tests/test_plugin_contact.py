"""The extension table's contact-model row, tried as a third party would: a contact model
(``elastic``: a touching, closing contact has its normal velocity reversed, whatever the scene's
restitution) in one module plus one entry point installed at test time is accepted by ``lint``
(``world { contact: elastic }``) and steps the rollout: a ball dropped on the floor bounces back
to the height it fell from, where the built-in LCP at the scene's restitution 0.5 reaches
e^2 = 1/4 of it."""
from __future__ import annotations

import numpy as np
import pytest
from plugins import install, looked_at_again

import physdsl
from physdsl.cli import main
from physdsl.registry import CONTACT_MODELS

CONTACT_PLUGIN = '''
import jax.numpy as jnp
from physdsl.physics import contact_stage as cs
from physdsl.physics.contact_models import contact_model
from physdsl.physics.integrate import State, accel, applied_load, joint_mass_matrix, kinematics
from physdsl.physics.kinematics import integrate_q

@contact_model("elastic")
def elastic(model, prm, state, t, h, forward_only=False):
    """Semi-implicit Euler; a penetrating, closing contact gets the impulse that reverses its
    normal velocity, lam = -2 vn / (Jn M^-1 Jn^T): restitution 1, energy kept."""
    kin = kinematics(model, prm, state.q, state.v, with_jac=True)
    v = state.v + h * accel(model, prm, kin, applied_load(model, prm, kin, state, t, t))
    con = cs.detect_all(model, prm, kin)
    minv_jt = jnp.linalg.solve(joint_mass_matrix(model, prm, kin), con.Jn.T)  # (nv, C)
    vn = con.Jn @ v
    hit = con.active & (con.dist <= 0) & (vn < 0)
    lam = jnp.where(hit, -2.0 * vn / jnp.sum(con.Jn * minv_jt.T, -1), 0.0)
    v = v + minv_jt @ lam
    return State(integrate_q(model, state.q, v, h), v, lam / h, con.normal)
'''

DROP = 1.0  # m from the ball's lowest point to the floor

SCENE = f"""\
scene drop {{
  world {{ timestep: 1 ms  duration: 1.2 s  contact: elastic }}
  ground floor {{
    normal: (0, 0, 1)
    point: (0, 0, 0) m
  }}
  body ball {{
    shape: sphere(radius: 5 cm)
    mass: 60 g
    position: (0, 0, {DROP + 0.05}) m
  }}
  contact floor, ball {{ restitution: 0.5 }}
}}
"""


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    install(tmp_path, monkeypatch, "demo_contact", CONTACT_PLUGIN,
            {"physdsl.contact_models": "elastic = demo_contact"})
    with looked_at_again((CONTACT_MODELS,), ("demo_contact",)):
        yield


def apex_after_bounce(text: str) -> float:
    """The ball's lowest point at its highest after the first floor contact (m)."""
    z = np.asarray(physdsl.compile(text).simulate({}).body_pos)[:, -1, 2] - 0.05
    first = int(np.argmax(np.diff(z) > 0))  # the first step that goes up
    return float(z[first:].max())


def test_a_plugin_contact_model_bounces_to_its_analytic_height(plugin, tmp_path):
    (tmp_path / "drop.phys").write_text(SCENE)
    assert main(["lint", str(tmp_path / "drop.phys")]) == 0
    assert "elastic" in CONTACT_MODELS.names()
    assert apex_after_bounce(SCENE) == pytest.approx(DROP, abs=0.01)  # energy kept
    # the built-in LCP honours restitution 0.5: (1/2)^2 of the drop
    assert apex_after_bounce(SCENE.replace("elastic", "lcp")) == pytest.approx(DROP / 4, abs=0.02)


def test_without_the_plugin_the_contact_model_is_unknown(tmp_path, capsys):
    (tmp_path / "drop.phys").write_text(SCENE)
    assert main(["lint", str(tmp_path / "drop.phys")]) == 2
    err = capsys.readouterr().err
    assert "unknown contact 'elastic'" in err and "lcp" in err


def test_the_builtin_names_the_language_knows_are_the_ones_physics_registers():
    """``registry.CONTACT_MODELS`` names its built-ins without importing physics (the language
    checks ``world { contact }`` by them); each is registered by the module named for it."""
    assert {n: CONTACT_MODELS.origin(n) for n in CONTACT_MODELS} == CONTACT_MODELS.builtins
