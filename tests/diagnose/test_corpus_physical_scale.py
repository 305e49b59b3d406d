"""Physical scales of joint laws (issue 14 item 3): a joint's load m g L from the bodies it
carries, critical damping 2 m L sqrt(g L), and the judgement of fitted joint damping, joint
friction and contact friction, against values computed by hand from the scenes' numbers."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from physdsl.diagnose import physical_scale as ps
from physdsl.diagnose.candidates import Candidate
from physdsl.diagnose.diagnosis import Ranked
from physdsl.diagnose.edits import with_effect
from physdsl.diagnose.ordering import plausible_first
from physdsl.syntax import load

EXAMPLES = Path(__file__).parents[2] / "examples"
G = 9.81


def _pendulum():
    return load(EXAMPLES / "hidden-effect" / "hinge_viscous" / "naive.phys")


def _by_hand(L: float):
    """The pendulum of hinge_viscous at length L: a 10 g rod whose centre is (L - 4 cm) / 2
    below the hinge and a 300 g bob L below it."""
    m = 0.31
    arm = (0.01 * (L - 0.04) / 2 + 0.3 * L) / m
    return m, arm, m * G * arm, 2 * m * arm * math.sqrt(G * arm)


def test_hinge_load_is_carried_mass_times_g_times_the_arm_to_its_centre():
    scene = _pendulum()
    assert ps.joint_load(scene, "hinge") is None  # the bob's height needs the unknown L
    for L in (0.5, 0.6):
        got = ps.joint_load(scene, "hinge", {"L": L})
        m, arm, load_, bc = _by_hand(L)
        assert got["mass"] == pytest.approx(m) and got["arm"] == pytest.approx(arm, rel=1e-12)
        assert got["load"] == pytest.approx(load_, rel=1e-12)
        assert ps.critical_damping(got) == pytest.approx(bc, rel=1e-12)
    # before any fit the prior's centre serves: L ~ normal(0.5 m, 5 cm)
    assert float(ps.typical_values(scene)["L"]) == pytest.approx(0.5)


def test_chain_hinge_carries_every_link_below_it():
    scene = load(EXAMPLES / "hidden-effect" / "damped_chain" / "naive.phys")
    # hinge2 at 1.0 m carries links 2-4 (centres 0.9, 0.7, 0.5 m, 100 g each): centre 0.3 m below
    got = ps.joint_load(scene, "hinge2")
    assert got["mass"] == pytest.approx(0.3) and got["arm"] == pytest.approx(0.3)
    assert got["load"] == pytest.approx(0.3 * G * 0.3)
    assert ps.joint_load(scene, "hinge4")["load"] == pytest.approx(0.1 * G * 0.1)


def test_slider_load_is_its_weight_and_has_no_critical_damping():
    scene = load(EXAMPLES / "no-effect" / "rail_01" / "naive.phys")
    mass = float(scene.bodies[0].mass.value)
    got = ps.joint_load(scene, "rail")
    assert got["kind"] == "slider" and got["load"] == pytest.approx(mass * G)
    assert ps.critical_damping(got) is None


def test_implausible_joint_strengths_are_flagged():
    scene, values = _pendulum(), {"L": 0.5}
    _, _, load_, bc = _by_hand(0.5)
    friction = ps.judge_joint(scene, "joint_friction", "hinge", 0.06, values)
    assert friction["plausible"] and friction["friction_coefficient"] == pytest.approx(0.06 / load_)
    heavy = ps.judge_joint(scene, "joint_friction", "hinge", 1.6 * load_, values)
    assert not heavy["plausible"] and "physically implausible" in ps.text(heavy)
    light = ps.judge_joint(scene, "joint_damping", "hinge", 0.035, values)
    assert light["plausible"] and light["damping_ratio"] == pytest.approx(0.035 / bc)
    honey = ps.judge_joint(scene, "joint_damping", "hinge", 11 * bc, values)
    assert not honey["plausible"] and "damping ratio 11 of critical" in ps.text(honey)
    assert ps.judge_contact_friction("block,ramp", 0.8)["plausible"]
    assert not ps.judge_contact_friction("block,ramp", 2.0)["plausible"]


def test_joint_law_candidates_get_priors_from_the_joint_load():
    scene = _pendulum()
    _, _, load_, bc = _by_hand(0.5)
    text = with_effect(scene, Candidate("effect", "joint_damping", ("hinge",)))
    assert f"coefficient ~ half_normal({ps.DAMPING_RATIO_PRIOR_SD * bc:.6g})" in text
    text = with_effect(scene, Candidate("effect", "joint_friction", ("hinge",)))
    assert f"torque ~ half_normal({ps.FRICTION_PRIOR_SD * load_:.6g})" in text
    # a shared group takes the widest joint's scale: hinge1 carries 400 g with its centre 0.4 m down
    chain = load(EXAMPLES / "hidden-effect" / "damped_chain" / "naive.phys")
    group = Candidate("effect", "joint_damping", ("hinge1+hinge2+hinge3+hinge4",))
    sd = ps.DAMPING_RATIO_PRIOR_SD * 2 * 0.4 * 0.4 * math.sqrt(G * 0.4)
    assert ps.prior_text(chain, group) == f"~ half_normal({sd:.6g})"


def _tied(effect, tied_with=None):
    return Ranked(rank=1, kind="effect", effect=effect, target="hinge", statistic=100.0,
                  p_value=0.0, dof=1, confirmed=True, tied_with=tied_with)


def test_a_tie_of_joint_laws_goes_to_the_physically_plausible_one():
    """Joint damping fitted at 11x critical (implausible) ties joint friction at a plausible
    coefficient on the same hinge: the friction is named. The judgements are those of
    ``judge_joint`` (keyed by their joint, the target; they name no body)."""
    scene, values = _pendulum(), {"L": 0.5}
    _, _, _, bc = _by_hand(0.5)
    physics = [ps.judge_joint(scene, "joint_damping", "hinge", 11 * bc, values),
               ps.judge_joint(scene, "joint_friction", "hinge", 0.06, values)]
    damping, friction = _tied("joint_damping"), _tied("joint_friction", "joint_damping@hinge")
    winner, ranked = plausible_first(damping, [damping, friction], physics)
    assert winner is friction and ranked == [friction, damping]
    assert damping.tied_with == "joint_friction@hinge" and friction.tied_with is None
    # damping at a plausible ratio keeps its place
    physics[0] = ps.judge_joint(scene, "joint_damping", "hinge", 0.035, values)
    damping, friction = _tied("joint_damping"), _tied("joint_friction", "joint_damping@hinge")
    assert plausible_first(damping, [damping, friction], physics)[0] is damping


def test_an_implausible_winner_yields_to_a_plausible_law_that_predicts_as_well():
    """two_effects_throw, round 1 (measured): linear drag at 10³ × Stokes led by ΔLFO (+215 vs
    +188) while ΔELPD tied (+46.9 vs +47.2); quadratic drag at C_d 0.24 is named instead. A
    rival that predicts clearly worse (ΔELPD beyond the margin) does not take over."""
    linear = Ranked(rank=1, kind="effect", effect="linear_drag", target="bob", statistic=100.0,
                    p_value=0.0, dof=1, confirmed=True, delta_elpd=46.9, delta_lfo=215.2)
    quad = Ranked(rank=2, kind="effect", effect="quadratic_drag", target="bob", statistic=90.0,
                  p_value=0.0, dof=1, confirmed=True, delta_elpd=47.2, delta_lfo=188.1)
    physics = [{"effect": "linear_drag", "target": "bob", "plausible": False},
               {"effect": "quadratic_drag", "target": "bob", "plausible": True}]
    winner, ranked = plausible_first(linear, [linear, quad], physics)
    assert winner is quad and ranked == [quad, linear] and linear.tied_with == "quadratic_drag@bob"
    far = Ranked(rank=2, kind="effect", effect="quadratic_drag", target="bob", statistic=90.0,
                 p_value=0.0, dof=1, confirmed=True, delta_elpd=30.0, delta_lfo=188.1)
    lin2 = Ranked(rank=1, kind="effect", effect="linear_drag", target="bob", statistic=100.0,
                  p_value=0.0, dof=1, confirmed=True, delta_elpd=46.9, delta_lfo=215.2)
    assert plausible_first(lin2, [lin2, far], physics)[0] is lin2
