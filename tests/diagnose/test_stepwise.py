"""Stepwise selection: group candidates, alternatives from the library, and the refine loop's
second thoughts (a wrong law swapped, a redundant effect dropped) on short physdsl-simulated
throws."""
from __future__ import annotations

import json

import numpy as np
import pytest

from physdsl.compile import Model
from physdsl.diagnose.candidates import Candidate, physics_candidates
from physdsl.diagnose.edits import Draft, load_text, unknown_keys, with_effect
from physdsl.diagnose.refine import refine
from physdsl.diagnose.stepwise import Comparison, alternatives, drop_wins, swap_wins, tied

from .conftest import PENDULUM, load_scene, write_csv

CHAIN = """\
scene chain {
  world {
    timestep: 5 ms
    duration: 1 s
  }
  body l1 { shape: capsule(radius: 1 cm, length: 20 cm)  mass: 100 g  position: (0, 0, 1.4) m }
  body l2 { shape: capsule(radius: 1 cm, length: 20 cm)  mass: 100 g  position: (0, 0, 1.15) m }
  body l3 { shape: capsule(radius: 1 cm, length: 20 cm)  mass: 100 g  position: (0, 0, 0.9) m }
  body l4 { shape: capsule(radius: 1 cm, length: 20 cm)  mass: 100 g  position: (0, 0, 0.65) m }
  joint j1: hinge(world -> l1) { axis: (0, -1, 0)  anchor: (0, 0, 1.525) m  initial ~ normal(40 deg, 5 deg) }
  joint j2: hinge(l1 -> l2) { axis: (0, -1, 0)  anchor: (0, 0, 1.275) m  initial: 0 deg }
  joint j3: hinge(l2 -> l3) { axis: (0, -1, 0)  anchor: (0, 0, 1.025) m  initial: 0 deg }
  joint j4: hinge(l3 -> l4) { axis: (0, -1, 0)  anchor: (0, 0, 0.775) m  initial: 0 deg }
  observe j1.angle from "joints.csv" where joint == "j1" { noise: 3 mrad }
}
"""


def test_a_four_link_chain_has_group_candidates_shared_and_per_joint(tmp_path):
    write_csv(tmp_path / "joints.csv", np.linspace(0, 1, 11), np.zeros((11, 1)), "j1")
    scene = load_scene(tmp_path, CHAIN)
    keys = {c.key for c in physics_candidates(scene)}
    for law in ("joint_damping", "joint_friction", "joint_spring"):
        assert f"{law}@j1+j2+j3+j4" in keys and f"{law}@j1&j2&j3&j4" in keys
        assert {f"{law}@j{i}" for i in range(1, 5)} <= keys
    shared, each = (Candidate("effect", "joint_damping", (t,)) for t in ("j1+j2+j3+j4", "j1&j2&j3&j4"))
    one = load_text(scene, with_effect(scene, shared))
    assert unknown_keys(scene, shared) == ["j1_j2_j3_j4_joint_damping"]
    assert {(e.effect, tuple(e.target)) for e in one.effects if e.effect != "gravity"} == \
        {("joint_damping", (f"j{i}",)) for i in range(1, 5)}
    assert {u.name for u in one.unknowns} == {"j1.initial", "j1_j2_j3_j4_joint_damping"}
    four = load_text(scene, with_effect(scene, each))
    assert {u.name for u in four.unknowns} - {"j1.initial"} == set(unknown_keys(scene, each))
    assert len(unknown_keys(scene, each)) == 4
    # taking a group out restores the scene: its effects and its shared param go
    for cand, grown in ((shared, one), (each, four)):
        back = Draft.of(grown).without_candidate(cand).scene
        assert {e.effect for e in back.effects} == {"gravity"} and {u.name for u in back.unknowns} == {"j1.initial"}
    # a group already partly present is no candidate; a chain of one joint has no group
    part = load_text(scene, with_effect(scene, Candidate("effect", "joint_damping", ("j2",))))
    assert not any(c.joints and c.name == "joint_damping" for c in physics_candidates(part))


def test_alternatives_come_from_the_library_same_target_and_sign(tmp_path):
    write_csv(tmp_path / "joints.csv", np.linspace(0, 1, 11), np.zeros((11, 1)), "hinge")
    scene = load_scene(tmp_path, PENDULUM)
    damped = load_text(scene, with_effect(scene, Candidate("effect", "joint_damping", ("hinge",))))
    alts = {c.key for c in alternatives(Draft.of(damped), Candidate("effect", "joint_damping", ("hinge",)))}
    assert alts == {"joint_friction@hinge", "joint_spring@hinge"}
    drag = load_text(scene, with_effect(scene, Candidate("effect", "linear_drag", ("bob",))))
    alts = {c.key for c in alternatives(Draft.of(drag), Candidate("effect", "linear_drag", ("bob",)))}
    assert "quadratic_drag@bob" in alts and "wind@bob" not in alts  # wind: a vector, no sign
    assert all(k.endswith("@bob") for k in alts)


def test_a_steady_push_and_a_wind_stand_for_each_other_once_drag_is_in(tmp_path):
    """Vector laws of one shape and off value are alternatives (no sign to match): with
    quadratic drag on the ball a constant force may be swapped for a wind and back; without
    drag wind is no candidate, so a constant force has no alternative."""
    write_csv(tmp_path / "data.csv", np.linspace(0, 1, 11), np.zeros((11, 3)), "ball")
    scene = load_scene(tmp_path, STEEP)
    push = Candidate("effect", "constant_force", ("ball",))
    pushed = load_text(scene, with_effect(scene, push))
    assert alternatives(Draft.of(pushed), push) == []
    both = load_text(pushed, with_effect(pushed, Candidate("effect", "quadratic_drag", ("ball",))))
    assert {c.key for c in alternatives(Draft.of(both), push)} == {"wind@ball"}
    windy = load_text(scene, with_effect(scene, Candidate("effect", "quadratic_drag", ("ball",)),
                                         Candidate("effect", "wind", ("ball",))))
    assert {c.key for c in alternatives(Draft.of(windy), Candidate("effect", "wind", ("ball",)))} \
        == {"constant_force@ball"}


def test_swap_and_drop_rules():
    # better predictions beyond the margin, evidence agreeing or n/a: swap; evidence against: no
    assert swap_wins(Comparison(50.0, 8.0, 40.0)) and swap_wins(Comparison(50.0, 8.0, None))
    assert not swap_wins(Comparison(50.0, 8.0, -1.0))
    # a tie in ELPD: only strong evidence (> log 10) swaps
    assert swap_wins(Comparison(2.0, 8.0, 3.0)) and not swap_wins(Comparison(2.0, 8.0, 1.0))
    assert not swap_wins(Comparison(2.0, 8.0, None))
    # drop: predictions within the margin and the evidence for the smaller scene
    assert drop_wins(Comparison(-3.0, 8.0, 2.5)) and not drop_wins(Comparison(-3.0, 8.0, -0.5))
    assert not drop_wins(Comparison(-30.0, 8.0, 5.0))
    # a tie (the experiment that would decide is proposed): ΔELPD within the margin, no strong
    # evidence either way
    assert tied(Comparison(3.0, 8.0, -1.0)) and tied(Comparison(-3.0, 8.0, None))
    assert not tied(Comparison(9.0, 8.0, 0.0)) and not tied(Comparison(1.0, 8.0, -3.0))


def test_where_psis_loo_is_unreliable_the_evidence_decides():
    """A fit whose PSIS-LOO is unreliable (draws of an approximation wider than the posterior)
    has a meaningless ELPD: ΔELPD -3864 with the RMS falling 1.00σ -> 0.97σ was measured on
    the double pendulum (Coulomb friction added beside damping on the elbow, whose damping then
    sits near zero). The Laplace evidence decides instead; with it n/a, ΔELPD as before."""
    assert swap_wins(Comparison(-3864.0, 870.0, 22.0, loo_ok=False))
    assert not swap_wins(Comparison(+3864.0, 870.0, 1.0, loo_ok=False))  # evidence not strong
    assert drop_wins(Comparison(-3864.0, 870.0, 0.5, loo_ok=False))
    assert not drop_wins(Comparison(+3864.0, 870.0, -2.0, loo_ok=False))
    assert tied(Comparison(-3864.0, 870.0, 1.0, loo_ok=False))
    assert not tied(Comparison(1.0, 870.0, 5.0, loo_ok=False))
    assert not swap_wins(Comparison(-3864.0, 870.0, None, loo_ok=False))
    # unreliable PSIS-LOO and the evidence n/a: nothing can be read, so nothing changes. The
    # double pendulum's round 2 (LOO unreliable at 363 of 603 points) swapping the shoulder's
    # damping for a spring raised the RMS 0.97σ -> 1.89σ, Δlog Z n/a, and "won" on ΔELPD +2543.9
    assert not swap_wins(Comparison(2543.9, 905.3, None, loo_ok=False))
    assert not drop_wins(Comparison(3893.6, 869.4, None, loo_ok=False))
    assert not tied(Comparison(1.0, 870.0, None, loo_ok=False))
    assert "no evidence either way" in Comparison(2543.9, 905.3, None, loo_ok=False).text()


def test_a_refit_is_confirmed_near_the_noise_on_the_check_not_an_rms_cut():
    """``refit_task.confirmed``: at 1.00σ with systematic residuals (runs test), a refit can only
    lower the RMS a little (0.97σ); far from the noise it must take a tenth of the excess; where
    its PSIS-LOO is unreliable, strong Laplace evidence stands in for ΔELPD."""
    from physdsl.diagnose.refit_task import confirmed

    good = {"elpd_reliable": True, "delta_elpd": 40.0, "delta_elpd_se": 8.0, "delta_lfo": 9.0,
            "log_evidence": 4447.0, "rms_before": 1.00, "rms_after": 0.97}
    assert confirmed(good)
    assert not confirmed({**good, "rms_after": 1.01})
    assert confirmed({**good, "rms_before": 7.14, "rms_after": 6.4})
    assert not confirmed({**good, "rms_before": 7.14, "rms_after": 6.6})
    assert not confirmed({**good, "delta_lfo": -1.0})
    wild = {**good, "elpd_reliable": False, "delta_elpd": -3864.0, "delta_elpd_se": 434.0}
    assert confirmed(wild, base_log_z=4425.0)  # Δlog Z +22
    assert not confirmed(wild, base_log_z=4446.0) and not confirmed(wild, base_log_z=None)
    # evidence n/a on one side: leave-future-out decides, beyond twice its standard error
    steady = np.full(60, 0.5)  # ΔLFO +30, every future point a little better: se ~0
    assert confirmed({**wild, "lfo_points": steady, "delta_lfo": 30.0}, base_log_z=None)
    assert confirmed({**wild, "lfo_points": steady, "delta_lfo": 30.0, "log_evidence": None},
                     base_log_z=4425.0)
    rng = np.random.default_rng(3)
    noisy = rng.normal(0.0, 3.0, 60)
    noisy += 0.5 - noisy.mean()  # the same ΔLFO +30, scattered: se ~23
    assert not confirmed({**wild, "lfo_points": noisy, "delta_lfo": 30.0}, base_log_z=None)


# a steep throw: 20 m/s up, 2 m/s at the top, hidden quadratic drag; linear drag cannot bend the
# trajectory alike at both speeds
STEEP = """\
scene steep {
  world {
    timestep: 20 ms
    duration: 3 s
    integrator: rk4
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((2, 0, 20) m/s, 2 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""


@pytest.fixture(scope="module")
def steep(tmp_path_factory):
    """Data of the steep throw with quadratic drag c = 1e-3 kg/m, and the naive scene."""
    folder = tmp_path_factory.mktemp("steep")
    times = np.linspace(0.0, 3.0, 61)
    write_csv(folder / "data.csv", times, np.zeros((61, 3)), "ball")
    naive = load_scene(folder, STEEP, "naive.phys")
    quad = Candidate("effect", "quadratic_drag", ("ball",))
    truth = Model(load_text(naive, with_effect(naive, quad)))
    pred = np.asarray(truth.predict({"ball.velocity": np.array([2.0, 0.0, 20.0]),
                                     "quadratic_drag@ball.coefficient": np.asarray(1e-3)})["ball.position"])
    speed = np.linalg.norm(np.gradient(pred, times, axis=0), axis=1)
    assert speed.max() > 18 and speed.min() < 3  # the speeds span 2-20 m/s
    write_csv(folder / "data.csv", times, pred + np.random.default_rng(11).normal(0, 0.005, pred.shape), "ball")
    return folder, load_scene(folder, STEEP, "naive.phys")


def _start(folder, naive, *effects) -> str:
    text = with_effect(naive, *(Candidate("effect", name, ("ball",)) for name in effects))
    (folder / "start.phys").write_text(text)
    return folder / "start.phys"


@pytest.mark.slow  # six fits of a 3 s throw: 73 CPU s
def test_the_loop_swaps_a_wrong_drag_law(steep, tmp_path):
    folder, naive = steep
    scene = _start(folder, naive, "linear_drag")
    rounds = refine(scene, tmp_path / "out", max_rounds=1, warmup=100, samples=64,
                    revise=("linear_drag@ball",), echo=print)
    r0, r1 = rounds
    assert r0.action is None and r0.added is None
    assert r1.action == "swapped", [r.verdict for r in rounds]
    assert r1.added == {"effect": "quadratic_drag", "target": "ball"}
    assert r1.replaced == {"effect": "linear_drag", "target": "ball"}
    assert r1.rms_sigma < r0.rms_sigma and r1.elpd > r0.elpd
    assert r1.log_evidence is not None and r0.log_evidence is not None and r1.log_evidence > r0.log_evidence
    data = json.loads((tmp_path / "out" / "refine.json").read_text())
    assert [r["action"] for r in data["rounds"]] == [None, "swapped"]
    assert data["rounds"][1]["replaced"] == r1.replaced and data["rounds"][1]["added"] == r1.added
    assert {"scene", "rms_sigma", "elpd", "added"} <= set(data["rounds"][0])


@pytest.mark.slow
def test_the_loop_drops_an_effect_whose_evidence_vanished(steep, tmp_path):
    folder, naive = steep
    scene = _start(folder, naive, "quadratic_drag", "linear_drag")
    rounds = refine(scene, tmp_path / "out", max_rounds=1, warmup=100, samples=64,
                    revise=("linear_drag@ball",), echo=print)
    r1 = rounds[1]
    assert r1.action == "dropped", [r.verdict for r in rounds]
    assert r1.replaced == {"effect": "linear_drag", "target": "ball"} and r1.added is None
    from physdsl.syntax import load

    left = load(r1.scene)
    assert {(e.effect, tuple(e.target)) for e in left.effects if e.effect != "gravity"} == \
        {("quadratic_drag", ("ball",))}
    # the drop costs no fit: with both drags the fit reaches 0.901σ (the multistart's data
    # starts; it once stopped in a poor basin at 3.15σ), without the linear one 0.908σ;
    # where both evidences exist they agree
    assert r1.consistent and r1.rms_sigma < rounds[0].rms_sigma + 0.05
    assert rounds[0].log_evidence is None or r1.log_evidence > rounds[0].log_evidence


def test_strong_evidence_breaks_a_tie_in_elpd_not_a_clear_win():
    """Among candidates tied in ΔELPD the ΔLFO leader wins unless another's Laplace evidence
    is stronger by more than log 10; a candidate ahead in ΔELPD beyond the margin stays first."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import order_by_evidence

    def row(effect, elpd, lfo, log_z):
        r = Ranked(0, "effect", effect, "ball", 1.0, 0.1, 1, confirmed=True)
        r.delta_elpd, r.delta_lfo, r.log_evidence = elpd, lfo, log_z
        return r

    tie = [row("linear_drag", 851.2, 2094.0, 300.0), row("quadratic_drag", 851.8, 2090.6, 301.0)]
    assert order_by_evidence(tie)[0].effect == "linear_drag"  # 1 nat: not strong
    tie[1].log_evidence = 303.0
    assert order_by_evidence(tie)[0].effect == "quadratic_drag"  # 3 nats > log 10
    tie[1].log_evidence = None
    assert order_by_evidence(tie)[0].effect == "linear_drag"  # n/a: ΔLFO decides
    clear = [row("linear_drag", 900.0, 2094.0, 300.0), row("quadratic_drag", 851.8, 2090.6, 310.0)]
    assert order_by_evidence(clear)[0].effect == "linear_drag"


def test_refine_revise_names_an_effect_the_scene_lacks(tmp_path, capsys):
    from .conftest import run_cli

    write_csv(tmp_path / "joints.csv", np.linspace(0, 1, 11), np.zeros((11, 1)), "hinge")
    load_scene(tmp_path, PENDULUM, "naive.phys")
    code, _, err = run_cli(["refine", tmp_path / "naive.phys", "-o", tmp_path / "out", "--revise",
                            "linear_drag@bob"], capsys)
    assert code == 2 and "--revise linear_drag@bob" in err and "EFFECT@TARGET" in err
    assert "Traceback" not in err and not (tmp_path / "out").exists()


def test_a_confirmed_group_with_a_strength_per_joint_brings_its_shared_strength_to_a_refit():
    """``confirm.shared_siblings``: damping per hinge confirmed, the same law with one shared
    strength (not refitted: the refits stopped once one explained the misfit) is refitted too,
    so the evidence can prefer one strength for four where the hinges are damped alike."""
    from physdsl.diagnose.confirm import shared_siblings
    from physdsl.diagnose.diagnosis import Ranked

    def row(name, target, **kw):
        c = Candidate("effect", name, (target,))
        return Ranked(1, "effect", name, target, 10.0, 1e-9, 4, -20.0, 3.0, 0.01, candidate=c, **kw)

    each = row("joint_damping", "h1&h2&h3&h4", confirmed=True)
    shared = row("joint_damping", "h1+h2+h3+h4")
    other_law = row("joint_friction", "h1+h2+h3+h4")
    assert shared_siblings([each, row("joint_friction", "h1&h2&h3&h4"), shared, other_law]) == [shared]
    assert shared_siblings([row("joint_damping", "h1&h2&h3&h4", confirmed=False), shared]) == []
    shared.confirmed = True  # refitted already (ranked before the refits stopped)
    assert shared_siblings([each, shared]) == []


def test_refits_with_unreliable_psis_loo_are_ordered_by_their_evidence():
    """Round 1 of the double pendulum: friction on the elbow alone (log Z +2.8 over friction on
    both hinges, P 0.94) must lead, although its unreliable ΔELPD (-3864) is below the other's
    (-3833); the two are not tied (a Bayes factor above 10)."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import evidence_ties, order_by_evidence

    def row(target, elpd, lfo, z):
        return Ranked(1, "effect", "joint_friction", target, 60.0, 1e-14, 1, -32.0, 7.0, 0.001,
                      confirmed=True, delta_elpd=elpd, delta_lfo=lfo, log_evidence=z,
                      elpd_points=np.full(603, elpd / 603), lfo_points=np.full(181, lfo / 181),
                      elpd_reliable=False, candidate=Candidate("effect", "joint_friction", (target,)))

    both, elbow = row("shoulder+elbow", -3832.8, 6.2, 4444.4), row("elbow", -3864.2, 8.9, 4447.2)
    assert order_by_evidence([both, elbow]) == [elbow, both]
    assert evidence_ties(elbow, [elbow, both]) == []
    both.log_evidence = 4446.0  # within a Bayes factor of 10: tied
    assert evidence_ties(elbow, [elbow, both]) == [both]


def test_a_swapped_in_law_starts_at_its_off_value_beside_the_current_fit(tmp_path, monkeypatch):
    """A swap's refit starts where its scene nests the one without the law it replaces: every
    other unknown at the current fit, the new law's strength a hair inside its physical side,
    so the mode is searched from there alone (``quick_fit`` warm). Started from a prior draw of
    the new strength instead, the double pendulum's swap of the shoulder's damping for Coulomb
    friction ran the whole multistart (422 s) and ended at 55.2σ, far worse than the same scene
    without either law (1.86σ), which it contains."""
    from physdsl.diagnose import stepwise
    from physdsl.errors import ModelError

    write_csv(tmp_path / "joints.csv", np.linspace(0, 1, 11), np.zeros((11, 1)), "hinge")
    scene = load_scene(tmp_path, PENDULUM)
    damping = Candidate("effect", "joint_damping", ("hinge",))
    damped = load_text(scene, with_effect(scene, damping))
    fitted = {"hinge.initial": np.asarray(0.7), "joint_damping@hinge.coefficient": np.asarray(0.01)}
    monkeypatch.setattr(stepwise, "point_estimate", lambda model, idata: dict(fitted))
    starts = {}

    def record(model, start=None, **_):
        law = next((e.effect for e in model.scene.effects if e.effect != "gravity"), None)
        starts[law] = (set(model.unknown_names), dict(start))
        raise ModelError("recorded")  # a refit failure: reexamine goes on to the next

    monkeypatch.setattr(stepwise, "quick_fit", record)
    current = stepwise.Judged(Model(damped), None, None, None, None)
    act, lines, _ = stepwise.reexamine(current, Draft.of(damped), [damping])
    assert act is None and len(lines) == 3  # drop, swap to friction, swap to a spring
    assert starts[None] == ({"hinge.initial"}, {"hinge.initial": fitted["hinge.initial"]})
    for law in ("joint_friction", "joint_spring"):
        key, = unknown_keys(scene, Candidate("effect", law, ("hinge",)))
        names, start = starts[law]
        assert set(start) == names == {"hinge.initial", key}, (law, names, start)
        assert start["hinge.initial"] == fitted["hinge.initial"] and 0.0 < start[key] <= 1e-3


def test_a_swap_never_rests_on_the_priors_alone():
    """Two laws that reach the same best fit differ in Laplace evidence only by their priors'
    Occam factors. two_effects_throw (MuJoCo, drag + a steady push): with drag in, `wind`
    refitted at 0.9316σ against the constant force's 0.9322σ (Δχ² 0.3 over 273 residuals),
    PSIS-LOO unreliable, Δlog Z +6.1, and the force (1 N per axis, a generic prior) was
    swapped out; with a 0.1 N prior the two log Z were equal. Such a swap is a tie: the current
    law stays and the experiment that would decide is proposed."""
    by_priors = Comparison(-148.2, 53.8, 6.1, loo_ok=False, d_fit=0.15)
    assert not swap_wins(by_priors) and tied(by_priors)
    assert not swap_wins(Comparison(2.0, 8.0, 3.0, d_fit=-0.4)) and tied(Comparison(2.0, 8.0, 3.0, d_fit=-0.4))
    # where the data prefer the new law (a better best fit), the evidence decides as before
    assert swap_wins(Comparison(-148.2, 53.8, 6.1, loo_ok=False, d_fit=4.0))
    assert swap_wins(Comparison(2.0, 8.0, 3.0, d_fit=2.5))
    # predicting better beyond the margin is the data speaking, whatever the best fits
    assert swap_wins(Comparison(50.0, 8.0, 40.0, d_fit=0.5))
