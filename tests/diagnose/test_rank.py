"""diagnose() on data simulated by physdsl with one hidden effect switched on.

The naive scene (without the effect) is fitted; ``check`` must flag the misfit, the score
tests must rank the true effect on the true target first among the physical candidates, and
adding it (``edits.with_effect``) and refitting must bring the residuals to the noise with the
true strength inside its 90% interval. Fast cases: quadratic vs linear drag on a steep throw
(speed 12 -> 3 -> 8 m/s, so |v| v and v differ in shape) and joint damping on a pendulum.
"""
from __future__ import annotations

import physdsl

import json

import numpy as np
import pytest

from physdsl.compile import Model
from physdsl.diagnose.edits import load_text, unknown_key, with_effect
from physdsl.diagnose.workflow import check_model

from .conftest import candidate, fit, interval, physical_order


def _row(diag, key):
    return next(r for r in diag.ranking if f"{r.effect}@{r.target}" == key)


def refit_with(f):
    """The naive scene of fitted case ``f`` with its true effect added, fitted and checked."""
    cand = candidate(f.model.scene, f.case)
    new = Model(load_text(f.model.scene, with_effect(f.model.scene, cand)))
    idata = fit(new)
    return new, idata, check_model(new, idata), unknown_key(f.model.scene, cand)


@pytest.fixture(scope="module")
def quadratic(fitted):
    return fitted("quadratic_drag")


@pytest.fixture(scope="module")
def quadratic_refit(quadratic):
    return refit_with(quadratic)


def test_check_flags_the_missing_drag(quadratic):
    rep = quadratic.report
    assert not rep.consistent, rep.text()
    assert rep.rms_sigma > 1.5
    assert rep.flags


def test_score_ranks_quadratic_drag_above_linear_drag(quadratic):
    d = quadratic.diagnosis
    order = physical_order(d)
    assert order[0] == "quadratic_drag@ball", d.table()
    q, lin = _row(d, "quadratic_drag@ball"), _row(d, "linear_drag@ball")
    # same dof, so the statistics compare directly; the gap is far beyond chance (chi2_1)
    assert q.statistic > lin.statistic + 6.0, d.table()
    assert q.z is not None and q.z > 5  # one-sided: the data want a positive coefficient
    assert q.estimate > 0
    # the spin-free ball cannot show a Magnus force: no information, flagged as unseen
    magnus = _row(d, "magnus@ball")
    assert magnus.p_value == 1.0 and "cannot see" in magnus.note


def test_unconfirmed_verdict_names_the_score_winner(quadratic):
    d = quadratic.diagnosis
    assert d.winner is None  # confirm_top=0: nothing refitted
    assert "quadratic_drag on ball" in d.verdict and "not confirmed" in d.verdict, d.verdict
    data = json.loads(json.dumps(d.to_dict()))  # JSON-clean (no NaN, no numpy)
    assert data["ranking"][0]["rank"] == 1
    assert {r["kind"] for r in data["ranking"]} == {"effect", "sensor"}


def test_adding_quadratic_drag_explains_the_data(quadratic, quadratic_refit):
    _, idata, rep, key = quadratic_refit
    assert rep.rms_sigma <= 1.3, rep.text()
    assert rep.rms_sigma < 0.7 * quadratic.report.rms_sigma
    lo, hi = interval(idata, key)
    assert lo <= quadratic.values[key] <= hi, (lo, hi)
    vel = np.asarray(idata.posterior["ball.velocity"].values).reshape(-1, 3)
    q5, q95 = np.quantile(vel, [0.05, 0.95], axis=0)
    truth = quadratic.values["ball.velocity"]
    assert np.all((q5 <= truth) & (truth <= q95)), (q5, q95, truth)


@pytest.mark.slow  # a pendulum's diagnosis (~43 s); ranking: the quadratic-drag tests here
def test_joint_damping_ranks_first_on_a_pendulum(fitted):
    f = fitted("joint_damping")
    assert not f.report.consistent, f.report.text()
    d = f.diagnosis
    order = physical_order(d)
    top = _row(d, order[0])
    damping = _row(d, "joint_damping@hinge")
    # linear drag on the bob of a one-hinge pendulum is exactly joint damping (torque
    # -b L^2 qdot): the two columns are identical and so are their statistics
    assert order[0] in ("joint_damping@hinge", "linear_drag@bob"), d.table()
    assert damping.statistic == pytest.approx(top.statistic, rel=1e-6)
    # Coulomb friction (a square-wave torque) is told apart clearly; quadratic drag on the bob
    # only just ranks below over about 1.4 periods (see docs/diagnosis.md): order, no margin
    friction = _row(d, "joint_friction@hinge")
    assert damping.statistic > friction.statistic + 6.0, d.table()
    assert damping.statistic >= _row(d, "quadratic_drag@bob").statistic, d.table()
    # the pair is marked as acting alike (one refit serves both: the one the table lists first;
    # their equal statistics leave which one that is to rounding); the others are distinct
    drag = _row(d, "linear_drag@bob")
    first = next(r for r in d.ranking if r is damping or r is drag)
    assert {damping.same_as, drag.same_as} == {None, first.key}, d.table()
    assert _row(d, "quadratic_drag@bob").same_as is None and friction.same_as is None


def test_a_failing_refit_leaves_the_candidate_unconfirmed(quadratic, monkeypatch):
    """A refit the inference cannot finish (here: a Laplace Hessian that is not positive
    definite) is noted on its row; the diagnosis goes on. A candidate acting exactly like a
    better ranked one is not refitted."""
    import copy

    from physdsl.diagnose import confirm, refit_task

    def failing_fit(model, seed=0, start=None):
        raise np.linalg.LinAlgError("Matrix is not positive definite")

    # a candidate's refit runs in refit_task (here or on a worker); confirm fits the baseline
    monkeypatch.setattr(refit_task, "quick_fit", failing_fit)
    monkeypatch.setattr(confirm, "quick_fit", failing_fit)
    d = quadratic.diagnosis
    rows = copy.deepcopy(d.ranking)
    physical = [r for r in rows if r.kind == "effect"]
    physical[1].same_as = f"{physical[0].effect}@{physical[0].target}"  # acts like the first
    confirm.confirm(quadratic.model, quadratic.idata, rows, 2, d.rms_sigma)
    tried = [r for r in rows if r.confirmed is not None]
    # the twin is skipped; nothing explained the misfit, so further candidates were refitted
    assert tried == [physical[0]] + physical[2:2 + 1 + confirm.EXTRA_REFITS]
    for r in tried:
        assert r.confirmed is False and r.note.startswith("refit failed: Matrix is not positive")


def test_refits_stop_at_k_once_one_explains_the_misfit(quadratic, monkeypatch):
    """Past the first k, candidates are refitted only while no refit reached the noise (its
    check consistent)."""
    import copy

    from physdsl.diagnose import confirm

    def refit(model, r, *args):
        r.rms_before, r.rms_after, r.confirmed = 2.0, (1.0 if r is explained else 5.0), True
        r.consistent_after = r is explained  # its check finds no systematic residual

    monkeypatch.setattr(confirm, "refit", refit)
    monkeypatch.setattr(confirm, "quick_fit", lambda model, seed=0, start=None: quadratic.idata)
    monkeypatch.setattr(confirm, "lfo_points", lambda *a: np.zeros(3))
    for first_good, expected in ((0, 2), (3, 4)):
        rows = copy.deepcopy(quadratic.diagnosis.ranking)
        physical = [r for r in rows if r.kind == "effect"]
        explained = physical[first_good]
        lines = []
        confirm.confirm(quadratic.model, quadratic.idata, rows, 2, 2.0, lines.append)
        assert sum(r.confirmed is not None for r in rows) == expected
        # the user hears of each refit as it starts and ends
        refits = [ln for ln in lines if ln.strip().startswith("refit ")]
        assert refits == [f"  refit {i + 1}: with {r.effect} on {r.target}"
                          for i, r in enumerate(physical[:expected])]
        assert sum("RMS 2.00σ → " in ln for ln in lines) == expected


def test_candidates_of_a_contact_scene(tmp_path):
    """Pair effects on the contact pair, body effects on the ball, no damper without a spring,
    nothing already in the scene (its contact friction)."""
    from physdsl.diagnose.candidates import Candidate, physics_candidates, sensor_candidates

    from .conftest import ROLL, load_scene, write_csv

    write_csv(tmp_path / "data.csv", [0.0, 0.1], np.zeros((2, 3)), "ball")
    scene = load_scene(tmp_path, ROLL)
    keys = {c.key for c in physics_candidates(scene)}
    assert {"restitution@floor,ball", "rolling_resistance@floor,ball", "linear_drag@ball",
            "quadratic_drag@ball", "constant_force@ball"} <= keys
    assert not any(k.startswith(("damper@", "contact_friction@", "spring@", "gravity@")) for k in keys)
    # wind is the change of quadratic drag in moving air: proposed only where that drag is
    assert "wind@ball" not in keys
    from physdsl.diagnose.edits import Draft
    dragged = Draft.of(scene).with_candidate(Candidate("effect", "quadratic_drag", ("ball",)))
    assert "wind@ball" in {c.key for c in physics_candidates(dragged.scene)}
    assert {c.key for c in sensor_candidates(scene)} == {
        f"{k}@ball.position" for k in ("offset", "gain", "delay")}


def test_twins_follow_their_representative_and_share_its_rank():
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import tie_twins

    rows = [Ranked(0, "effect", e, t, 1.0, 0.1, 1) for e, t in
            [("linear_drag", "rod"), ("joint_friction", "hinge"), ("joint_damping", "hinge")]]
    rows[2].same_as = "linear_drag@rod"
    out = tie_twins(rows)
    assert [(r.effect, r.rank) for r in out] == [("linear_drag", 1), ("joint_damping", 1),
                                                 ("joint_friction", 2)]


def test_candidates_whose_evidence_ties_the_winner_share_its_rank():
    """Without pointwise values, ΔELPD and ΔLFO both within 4 of the winner's: a tie, sharing
    rank 1; a candidate 14 behind in ΔLFO is ranked after, even with a higher ΔELPD."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import evidence_ties, order_by_evidence, tie_twins

    def row(effect, elpd, lfo):
        r = Ranked(0, "effect", effect, "ball", 1.0, 0.1, 1, confirmed=True)
        r.delta_elpd, r.delta_lfo = elpd, lfo
        return r

    rows = [row("quadratic_drag", 851.8, 2090.6), row("linear_drag", 851.2, 2094.0),
            row("wind", 850.0, 2091.0), row("magnus", 853.0, 2080.0)]
    confirmed = order_by_evidence(rows)
    winner = confirmed[0]
    assert winner.effect == "linear_drag"  # best ΔLFO among the ΔELPD-tied
    ties = evidence_ties(winner, confirmed)
    assert [r.effect for r in ties] == ["wind", "quadratic_drag"]
    for r in ties:
        r.tied_with = "linear_drag@ball"
    out = tie_twins(confirmed)
    assert [(r.effect, r.rank) for r in out] == [("linear_drag", 1), ("wind", 1),
                                                 ("quadratic_drag", 1), ("magnus", 2)]


def test_a_refit_without_evidence_that_outpredicts_the_evidence_leader_goes_first():
    """Where one refit's PSIS-LOO is unreliable the order is by Laplace evidence, but a refit
    whose evidence is n/a and whose reliable ΔELPD beats the leader's beyond the tie margin goes
    first (billiards: sliding friction on the table behind quadratic drag on a ball); within the
    margin, or with an unreliable ΔELPD of its own, it stays behind."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import order_by_evidence

    def row(effect, target, elpd, log_z, reliable):
        r = Ranked(0, "effect", effect, target, 1.0, 0.1, 1, confirmed=True)
        r.delta_elpd, r.log_evidence, r.elpd_reliable = elpd, log_z, reliable
        return r

    drag = row("quadratic_drag", "object", 29594.3, -12254.0, False)
    for elpd, reliable, first in ((39656.8, True, "contact_friction"),
                                  (29596.0, True, "quadratic_drag"),
                                  (39656.8, False, "quadratic_drag")):
        friction = row("contact_friction", "table,*", elpd, None, reliable)
        spin = row("restitution", "cue,object", 37779.3, None, False)
        assert order_by_evidence([drag, spin, friction])[0].effect == first, (elpd, reliable)


def test_a_gap_within_twice_its_standard_error_is_a_tie():
    """ΔLFO 10 apart: a tie where the pointwise differences scatter (se of their sum ~8), an
    order where every point favours the winner alike (se ~0); ΔELPD alike in both."""
    from physdsl.diagnose.diagnosis import Ranked
    from physdsl.diagnose.ordering import evidence_ties, order_by_evidence

    rng = np.random.default_rng(1)

    def row(effect, elpd_points, lfo_points):
        r = Ranked(0, "effect", effect, "ball", 1.0, 0.1, 1, confirmed=True)
        r.elpd_points, r.lfo_points = elpd_points, lfo_points
        r.delta_elpd, r.delta_lfo = float(elpd_points.sum()), float(lfo_points.sum())
        return r

    elpd = rng.normal(1.0, 0.1, 100)
    lfo = np.full(25, 4.0)
    for spread, tie in ((1.6, True), (0.0, False)):
        scatter = rng.normal(0.0, 1.0, 25)
        scatter = spread * (scatter - scatter.mean()) / scatter.std()
        winner = row("linear_drag", elpd, lfo + 0.4)  # 10 ahead in ΔLFO
        other = row("quadratic_drag", elpd + 0.001, lfo + scatter)
        confirmed = order_by_evidence([other, winner])
        assert confirmed[0] is winner
        assert (evidence_ties(winner, confirmed) == [other]) is tie


def test_a_posterior_wider_than_its_prior_is_flagged(quadratic):
    """Laplace draws with a floored curvature (variance ~1e10) are no posterior: flagged, and
    the good fit is not."""
    from physdsl.infer.fit import wider_than_prior

    assert wider_than_prior(quadratic.model, quadratic.idata) == []
    broken = quadratic.idata.copy()
    v = broken.posterior["ball.velocity"]
    broken.posterior["ball.velocity"] = v + 1e5 * (v - v.mean(("chain", "draw")))
    assert wider_than_prior(quadratic.model, broken) == ["ball.velocity"]


def test_where_laplace_fails_metropolis_starts_at_the_same_modes(quadratic, monkeypatch):
    """The fallback samples from the modes MAP found (found once), not from fresh prior draws:
    both backends get the same start positions, the second chain included."""
    from physdsl.infer import fit
    from physdsl.infer.backends import map as map_backend

    def no_laplace(problem, mode):
        raise map_backend.LaplaceError("not strictly concave (test)")

    monkeypatch.setattr(map_backend, "laplace_sqrt", no_laplace)
    model = quadratic.model
    calls = []
    real_infer = fit.infer

    def spy(model, **kwargs):
        calls.append((kwargs["backend"], np.asarray(kwargs["positions"])))
        return real_infer(model, **kwargs)

    monkeypatch.setattr(fit, "infer", spy)
    idata = fit.fit_with_fallback(model, "map", chains=2, warmup=60, samples=20, seed=1,
                                   progress=False)
    assert [b for b, _ in calls] == ["map", "rmh"]
    np.testing.assert_array_equal(calls[0][1], calls[1][1])
    assert "random-walk Metropolis" in idata.attrs["fit_note"]
    # both chains sit at the fitted velocity (posterior sd ~ mm/s; the prior's is 2 m/s)
    mode = quadratic.idata.posterior["ball.velocity"].values.mean(axis=(0, 1))
    for chain in idata.posterior["ball.velocity"].values:
        assert np.max(np.abs(chain.mean(axis=0) - mode)) < 0.05


def test_infer_starts_at_given_positions(quadratic):
    """``positions`` replaces the prior draws and their optimisation: a few Metropolis steps
    from a far point stay near it; a wrong shape is a usage error."""
    from physdsl.errors import UsageError
    from physdsl.infer.problem import model_problem

    model = quadratic.model
    dim = model_problem(model).dim
    far = np.tile(np.linspace(5.0, 6.0, dim), (2, 1))
    idata = physdsl.infer(model, backend="rmh", positions=far, chains=2, warmup=1, samples=2,
                        progress=False)
    v = idata.posterior["ball.velocity"].values[:, 0]
    assert np.all(v > 4.0)  # the prior is normal((3, 0, 12), 2): (x, y) ~ 5-6 only from the start
    with pytest.raises(UsageError, match="start positions"):
        physdsl.infer(model, backend="rmh", positions=far[:1], chains=2, warmup=1, samples=1,
                    progress=False)


def test_refine_starts_the_next_round_where_the_refit_ended(quadratic, quadratic_refit,
                                                            monkeypatch, tmp_path):
    """Round 1's fit starts at round 0's fit plus the winner's fitted strength (from the prior,
    billiards' second round settled at 7.85σ where the diagnosis's refit had reached 0.97σ)."""
    import dataclasses

    from physdsl.diagnose import refine as refine_module
    from physdsl.diagnose.refine import refine
    from physdsl.diagnose.workflow import point_estimate

    new_model, new_idata, _, key = quadratic_refit
    starts = []

    def fit(model, backend, **settings):
        starts.append(dict(settings["start"]))
        return quadratic.idata if not starts[1:] else new_idata

    winner = dataclasses.replace(_row(quadratic.diagnosis, "quadratic_drag@ball"), confirmed=True,
                                 fitted={"name": key, "median": 4e-4}, snippet="effect ...")
    diag = dataclasses.replace(quadratic.diagnosis, winner=winner, verdict="missing effect")
    monkeypatch.setattr(refine_module, "fit_with_fallback", fit)
    monkeypatch.setattr(refine_module, "diagnose", lambda *a, **k: diag)
    scene = next(quadratic.folder.glob("naive.phys"))
    rounds = refine(scene, tmp_path / "out", max_rounds=2, echo=lambda *_: None)
    assert [r.added for r in rounds] == [None, {"effect": "quadratic_drag", "target": "ball"}]
    assert starts[0] == {}
    expected = {k: np.asarray(v).tolist() for k, v in point_estimate(quadratic.model,
                                                                     quadratic.idata).items()}
    assert starts[1] == {**expected, key: 4e-4}


def test_score_tests_run_the_program_compiled_ahead(quadratic):
    """``refine`` starts compiling the score tests' program before the round's fit
    (``screening.score_ahead``); ``score_all`` then runs that executable, with the same scores."""
    from physdsl.diagnose.screening import score_ahead, score_all

    aug = score_ahead(quadratic.model)
    assert aug is not None
    (key, program), = [(k, f) for k, f in aug.compiled.cache.items()
                       if isinstance(k, tuple) and k[0] == "score-jacobian"]
    jitted_before = program.jitted._cache_size()
    assert len(program._ahead) == 1
    scored = score_all(quadratic.model, quadratic.idata)
    assert program.jitted._cache_size() == jitted_before  # nothing compiled where it was called
    assert next(iter(program._ahead.values())).compiled is not None
    for cand, res in scored:
        row = _row(quadratic.diagnosis, cand.key)
        assert res.statistic == pytest.approx(row.statistic, rel=1e-9, abs=1e-12), cand.key


def test_confirm_compiles_the_refits_it_will_make_ahead(quadratic):
    """``confirm`` starts compiling its sure refits' fit programs before the baseline
    (``confirm.refits_ahead``); the refit's own Model of the same scene runs them."""
    import jax.numpy as jnp

    from physdsl.diagnose.confirm import refits_ahead, sure_refits
    from physdsl.diagnose.edits import Draft
    from physdsl.infer.problem import model_problem

    ranked = quadratic.diagnosis.ranking
    first = next(r for r in ranked if not r.same_as)
    draft = Draft.of(quadratic.model.scene)
    picks = sure_refits(ranked, 2, first)
    models = refits_ahead(draft, picks)
    assert len(models) == len(picks) >= 2
    for r, held in zip(picks, models):
        again = Model(draft.with_candidate(r.candidate).scene)  # as ``refit`` builds it
        assert again.compiled is held.compiled
        problem = model_problem(again)
        gn = problem.gauss_newton
        assert len(gn._ahead) == 1
        jitted_before = gn.jitted._cache_size()  # (an earlier test may have fitted this scene)
        value, grad, _ = gn(jnp.zeros(problem.dim), problem.data)
        assert gn.jitted._cache_size() == jitted_before, r.effect  # the executable made ahead ran
        assert next(iter(gn._ahead.values())).compiled is not None and np.isfinite(float(value))


@pytest.mark.parametrize("explained_by, prepared", [
    (1, []),  # the first refit explains (the second is sure): no extra needed, none prepared
    (2, ["c"]),  # the second (last sure) explains: the first extra was prepared in vain
    (4, ["c", "d"]),  # nothing explains before the last: each extra prepared a refit ahead
    (None, ["c", "d"]),
])
def test_confirm_prepares_an_extra_refit_while_the_one_before_runs(monkeypatch, explained_by,
                                                                     prepared):
    """With k = 2 sure refits and ``EXTRA_REFITS`` more while nothing explains the misfit: once a
    refit has left the misfit unexplained, each refit from the k-th on has the next distinct
    effect's programs prepared ahead (``refits_ahead``) while it runs, up to the budget."""
    from physdsl.diagnose import confirm as cf
    from physdsl.diagnose.diagnosis import Ranked

    ranked = [Ranked(i + 1, "effect", name, "x", 1.0, 0.0, 1) for i, name in enumerate("abcdef")]
    ranked.insert(2, Ranked(9, "effect", "twin", "x", 1.0, 0.0, 1, same_as="b@x"))
    asked, refitted = [], []

    def refit_row(base, r, ahead, label, echo):
        refitted.append(r.effect)
        r.consistent_after = len(refitted) == explained_by

    monkeypatch.setattr(cf, "refits_ahead", lambda draft, rows: asked.append(
        [r.effect for r in rows]) or [])
    monkeypatch.setattr(cf, "Baseline", lambda *args: None)
    monkeypatch.setattr(cf, "doubtful_twin", lambda r, ranked: False)
    monkeypatch.setattr(cf, "_refit_row", refit_row)
    cf.confirm(None, None, ranked, 2, 30.0, draft=object())
    assert asked[0] == ["a", "b"]  # the sure refits, at the start
    assert asked[1:] == [[p] for p in prepared]
    assert refitted == ["a", "b", "c", "d"][:max(explained_by or 4, 2)]
