"""Material-level candidates: a pair effect on every contact pair of one fixed body with ONE
shared coefficient (a table's cloth has one friction coefficient, not one per ball)."""
from __future__ import annotations

import numpy as np
import pytest

from .conftest import load_scene, write_csv

# Two balls sliding without spin on a floor, apart (they never touch); ball a's velocity unknown.
TWO_BALLS = """\
scene two_balls {
  world {
    timestep: 10 ms
    duration: 0.4 s
  }
  ground floor { normal: (0, 0, 1)  point: (0, 0, 0) m }
  body a {
    shape: sphere(radius: 3 cm)
    mass: 200 g
    position: (0, 0, 3) cm
    velocity ~ normal((1.5, 0, 0) m/s, 0.3 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  body b {
    shape: sphere(radius: 3 cm)
    mass: 300 g
    position: (0, 0.5, 0.03) m
    velocity: (0.6, 0.8, 0) m/s
    angular_velocity: (0, 0, 0) rad/s
  }
%s
  observe a.position from "a.csv" where body == "a" { noise: 2 mm }
  observe b.position from "b.csv" where body == "b" { noise: 2 mm }
}
"""
TIMES = np.linspace(0.0, 0.4, 21)


def _scene(folder, extra: str = "", name: str = "scene.phys"):
    for body in ("a", "b"):
        if not (folder / f"{body}.csv").exists():
            write_csv(folder / f"{body}.csv", TIMES, np.zeros((len(TIMES), 3)), body)
    return load_scene(folder, TWO_BALLS % extra, name)


def _material(scene, effect: str, fixed: str = "floor"):
    from physdsl.diagnose.candidates import physics_candidates

    return next(c for c in physics_candidates(scene) if c.key == f"{effect}@{fixed},*")


def test_material_candidates_where_pairs_share_a_fixed_body(tmp_path):
    from physdsl.diagnose.candidates import material_pairs, physics_candidates

    scene = _scene(tmp_path)
    keys = {c.key for c in physics_candidates(scene)}
    assert {"contact_friction@floor,*", "restitution@floor,*", "rolling_resistance@floor,*"} <= keys
    assert {"contact_friction@floor,a", "contact_friction@floor,b", "contact_friction@a,b"} <= keys
    assert not any(k.startswith("damper@") or k.endswith("@a,*") for k in keys)
    assert material_pairs(scene, "contact_friction", "floor") == [("floor", "a"), ("floor", "b")]
    # friction already on one of the two pairs: one pair left, no shared coefficient to propose
    partial = _scene(tmp_path, "  contact floor, b { friction: 0.3 }", "partial.phys")
    keys = {c.key for c in physics_candidates(partial)}
    assert "contact_friction@floor,*" not in keys and "contact_friction@floor,a" in keys
    assert "restitution@floor,*" in keys


def test_material_candidate_is_one_param_and_one_effect_per_pair(tmp_path):
    """Printed with the language's printer: ``param floor_contact_friction ~ prior`` and the
    effect on each pair with that param as its coefficient; the scene gains ONE unknown."""
    from physdsl.compile import Model
    from physdsl.diagnose.edits import load_text, unknown_key, with_effect

    scene = _scene(tmp_path)
    cand = _material(scene, "contact_friction")
    new = load_text(scene, with_effect(scene, cand))
    added = {u.name for u in Model(new).unknowns} - {u.name for u in Model(scene).unknowns}
    assert added == {"floor_contact_friction"} == {unknown_key(scene, cand)}
    uses = [e for e in new.effects if e.effect == "contact_friction"]
    assert sorted(e.target for e in uses) == [("floor", "a"), ("floor", "b")]
    # the shared param's name is taken: the candidate cannot be written, and says so
    from physdsl.diagnose.edits import Draft
    from physdsl.diagnose.screening import expressible
    from physdsl.errors import PhysNameError

    taken = _scene(tmp_path, "  param floor_contact_friction: 0.3", "taken.phys")
    with pytest.raises(PhysNameError):
        with_effect(taken, _material(taken, "contact_friction"))
    assert not expressible(Draft.of(taken), _material(taken, "contact_friction"))


def test_add_effect_cli_takes_a_material_target(tmp_path, cli):
    _scene(tmp_path)
    code, out, err = cli("add-effect", tmp_path / "scene.phys", "rolling_resistance", "on",
                         "floor,*", "-o", tmp_path / "new.phys")
    assert code == 0, err
    from physdsl.syntax import load

    new = load(tmp_path / "new.phys")
    assert sorted(e.target for e in new.effects if e.effect == "rolling_resistance") == [
        ("floor", "a"), ("floor", "b")]


def test_a_material_twin_represents_its_per_pair_twin():
    """Where one pair's column is the material candidate's (the other pair cannot be seen),
    the material candidate represents the group; the others follow it with its rank."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import mark_twins, tie_twins

    rows = [Ranked(0, "effect", e, t, s, 0.1, 1) for e, t, s in
            [("contact_friction", "floor,a", 9.0), ("contact_friction", "floor,*", 8.9),
             ("linear_drag", "a", 5.0), ("contact_friction", "floor,b", 0.0)]]
    d = np.array([1.0, 0.0])
    mark_twins(rows, {"contact_friction@floor,a": d, "contact_friction@floor,*": d,
                      "linear_drag@a": np.array([0.6, 0.8])})
    assert rows[1].same_as is None and rows[0].same_as == "contact_friction@floor,*"
    out = tie_twins(rows)
    assert [(r.target, r.rank) for r in out] == [("floor,*", 1), ("floor,a", 1), ("a", 2),
                                                 ("floor,b", 3)]


def test_material_score_column_is_the_sum_of_the_pair_columns(tmp_path, monkeypatch):
    """score_all tests the material candidate on the sum of its pairs' columns (the derivative
    with respect to one shared coefficient), projected like every other column."""
    from physdsl.compile import Model
    from physdsl.diagnose import screening
    from physdsl.diagnose.score import project_out, score_test

    model = Model(_scene(tmp_path))
    rng = np.random.default_rng(3)
    n = 2 * 3 * len(TIMES)
    r, J_theta = rng.normal(size=n), rng.normal(size=(n, 3))
    got = {}

    def fake_jacobian(aug, values, nuisance, tested):
        got["tested"] = tested
        got["values"] = {k: values[k] for k in tested}
        got["J_psi"] = rng.normal(size=(n, sum(int(np.prod(aug.scene.unknown(k).shape))
                                               for k in tested)))
        return r, J_theta, got["J_psi"], {}

    monkeypatch.setattr(screening, "jacobian", fake_jacobian)
    monkeypatch.setattr(screening, "sensor_candidates", lambda scene: [])
    monkeypatch.setattr(screening, "point_estimate",
                        lambda m, idata: {"a.velocity": np.array([1.5, 0.0, 0.0])})
    scores = {c.key: s for c, s in screening.score_all(model, None)}
    assert not any(k.endswith(",*.coefficient") for k in got["tested"])  # not in the scene itself
    offset, cols = 0, {}
    for k in sorted(got["tested"]):
        width = 3 if k.startswith(("wind@", "constant_force@")) else 1
        cols[k] = got["J_psi"][:, offset: offset + width]
        offset += width
    summed = cols["contact_friction@floor,a.coefficient"] + cols["contact_friction@floor,b.coefficient"]
    want = score_test("x", r, project_out(J_theta, summed), 1)
    assert scores["contact_friction@floor,*"].z == pytest.approx(want.z, rel=1e-12)
    # one-sided strengths are tested just inside their physical side (see tested_value)
    assert 0 < got["values"]["contact_friction@floor,a.coefficient"] < 1e-4
    assert 1 - 1e-4 < got["values"]["restitution@floor,a.coefficient"] < 1


@pytest.fixture(scope="module")
def shared_friction(tmp_path_factory):
    """Data of the two balls with one friction coefficient 0.15 on both floor pairs, and the
    score tests of the frictionless scene at the true values."""
    from physdsl.compile import Model
    from physdsl.diagnose import screening
    from physdsl.diagnose.edits import with_effect

    folder = tmp_path_factory.mktemp("material")
    truth = _scene(folder, name="placeholder.phys")
    truth = load_scene(folder, with_effect(truth, _material(truth, "contact_friction")),
                       "truth.phys")
    values = {"a.velocity": np.array([1.4, 0.1, 0.0]), "floor_contact_friction": np.asarray(0.15)}
    pred = Model(truth).predict(values)
    rng = np.random.default_rng(11)
    for body in ("a", "b"):
        clean = np.asarray(pred[f"{body}.position"])
        write_csv(folder / f"{body}.csv", TIMES, clean + rng.normal(0, 0.002, clean.shape), body)
    model = Model(load_scene(folder, TWO_BALLS % "", "naive.phys"))
    at = {"a.velocity": values["a.velocity"]}
    mp = pytest.MonkeyPatch()
    mp.setattr(screening, "point_estimate", lambda m, idata: {k: np.asarray(v) for k, v in at.items()})
    try:
        scored = screening.score_all(model, None)
    finally:
        mp.undo()
    return model, at, {c.key: s for c, s in scored}


@pytest.mark.slow
def test_shared_friction_outscores_each_pair_and_its_column_is_the_derivative(shared_friction):
    """On data with one friction coefficient on both pairs, the material candidate outscores
    each per-pair one (it explains both balls), and its score equals that of a
    finite-difference column of the residuals with respect to the one shared coefficient, in
    the scene ``with_effect`` writes (the LCP's own derivative, not a copy of the sum).
    (About 60 s: three compiled contact rollouts and one forward-mode Jacobian.)"""
    import jax.numpy as jnp

    from physdsl.compile import Model
    from physdsl.diagnose.edits import load_text, with_effect
    from physdsl.diagnose.screening import tested_value
    from physdsl.diagnose.score import jacobian, project_out, score_test, standardized_residuals

    model, at, scores = shared_friction
    best = scores["contact_friction@floor,*"]
    assert best.z > 10
    for pair in ("floor,a", "floor,b"):
        assert scores[f"contact_friction@{pair}"].statistic < best.statistic
    scene = model.scene
    shared = Model(load_text(scene, with_effect(scene, _material(scene, "contact_friction"))))
    mu0, h = tested_value(scene.effect_library["contact_friction"]), 1e-4

    def res(mu):
        vals = {k: jnp.asarray(v) for k, v in at.items()}
        vals["floor_contact_friction"] = jnp.asarray(mu)
        return np.asarray(standardized_residuals(shared, vals))

    r0 = res(mu0)
    col = ((res(mu0 + h) - r0) / h)[:, None]
    _, J_theta, _, _ = jacobian(model, {k: np.asarray(v) for k, v in at.items()}, ["a.velocity"], [])
    fd = score_test("fd", r0, project_out(J_theta, col), 1)
    assert fd.z == pytest.approx(best.z, rel=1e-3)
    assert fd.estimate == pytest.approx(best.estimate, rel=1e-3)


def test_a_strength_far_outside_its_prior_is_not_proposed(tmp_path):
    """A candidate whose one-step estimate lies > 1000 prior sds from off barely moves the
    predictions (rolling resistance on a nearly frictionless table); a plausible one passes."""
    from physdsl.diagnose.candidates import Candidate
    from physdsl.diagnose.screening import IMPLAUSIBLE, prior_sd, prior_sds_needed
    from physdsl.diagnose.score import ScoreResult

    scene = _scene(tmp_path)
    cand = Candidate("effect", "rolling_resistance", ("floor", "a"))
    sd = prior_sd(scene.effect_library["rolling_resistance"].strength.prior)
    assert sd == pytest.approx(1e-3 * np.sqrt(1 - 2 / np.pi))  # half_normal(1 mm)

    def res(est):
        return ScoreResult("k", 100.0, 10.0, 1, 1e-23, 1.0, est, -52.0)

    assert prior_sds_needed(scene, cand, res(5 * sd)) is None
    assert prior_sds_needed(scene, cand, res(2 * IMPLAUSIBLE * sd)) == pytest.approx(2 * IMPLAUSIBLE)
    assert prior_sds_needed(scene, Candidate("effect", "wind", ("a",)), res(None)) is None
