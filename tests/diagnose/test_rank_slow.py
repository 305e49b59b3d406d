"""The whole diagnosis on every hidden-effect case, sensor faults and no fault at all (slow).

Each case: data simulated by physdsl with one effect on, the naive scene fitted, ``diagnose``
with one confirmation refit. The true effect (or one exactly equivalent to it, see
``EQUIVALENT``) must lead the score ranking among physical candidates, be confirmed as the
winner, bring the residual RMS to within 1.3 noise units, and its fitted strength's 90%
interval must hold the truth.
"""
from __future__ import annotations

import numpy as np
import pytest

from .conftest import CASES, EQUIVALENT, fit_case, physical_order

pytestmark = pytest.mark.slow

PHYSICAL = ["quadratic_drag", "linear_drag", "wind", "joint_damping", "joint_friction",
            "joint_spring", "restitution", "contact_friction", "rolling_resistance", "damper"]


def _row(diag, key):
    return next(r for r in diag.ranking if f"{r.effect}@{r.target}" == key)


@pytest.mark.parametrize("name", PHYSICAL)
def test_hidden_effect_is_found_confirmed_and_fitted(fitted, name):
    f = fitted(name, 1)
    case = f.case
    assert not f.report.consistent, f.report.text()
    d = f.diagnosis
    ok = {case.key} | EQUIVALENT.get(name, set())
    top = _row(d, physical_order(d)[0])
    true = _row(d, case.key)
    assert f"{top.effect}@{top.target}" in ok or true.statistic == pytest.approx(
        top.statistic, rel=1e-6), d.table()
    assert d.winner is not None, d.verdict + "\n" + d.table()
    assert f"{d.winner.effect}@{d.winner.target}" in ok, d.table()
    assert d.winner.rms_after <= 1.3, d.table()
    if f"{d.winner.effect}@{d.winner.target}" == case.key and np.ndim(case.strength) == 0:
        assert d.winner.fitted["q5"] <= case.strength <= d.winner.fitted["q95"], d.winner.fitted


def test_linear_drag_ranks_above_quadratic_drag(fitted):
    d = fitted("linear_drag").diagnosis
    assert physical_order(d)[0] == "linear_drag@ball", d.table()
    assert _row(d, "linear_drag@ball").statistic > _row(d, "quadratic_drag@ball").statistic + 6


def test_sensor_offset_is_not_wind(tmp_path):
    """A constant offset on a throw whose launch point is known: a sensor fault, not wind."""
    f = fit_case(tmp_path, CASES["quadratic_drag"], 0,
                 extra={"quadratic_drag@ball.coefficient": 0.0},
                 offset={"ball.position": (0.03, -0.02, 0.04)})
    assert not f.report.consistent
    d = f.diagnosis
    top = d.ranking[0]
    assert (top.kind, top.effect, top.target) == ("sensor", "offset", "ball.position"), d.table()
    assert "sensor fault" in d.verdict and "offset" in d.verdict and "wind" not in d.verdict


def test_sensor_delay(tmp_path):
    """The tracker reports the state of 40 ms ago: a sensor delay."""
    f = fit_case(tmp_path, CASES["quadratic_drag"], 0,
                 extra={"quadratic_drag@ball.coefficient": 0.0}, delay=0.04)
    d = f.diagnosis
    top = d.ranking[0]
    assert (top.kind, top.effect) == ("sensor", "delay"), d.table()
    assert "delay" in d.verdict


def test_no_hidden_effect_rarely_invents_one(tmp_path):
    """20 datasets of the steep throw without any effect: diagnose names a missing effect or a
    sensor fault in few of them (the Bonferroni-corrected level is 5% per dataset)."""
    invented = []
    for seed in range(20):
        case = CASES["quadratic_drag"]
        case = type(case)(**{**case.__dict__, "seed": 100 + seed})
        f = fit_case(tmp_path / f"s{seed}", case, 0, extra={"quadratic_drag@ball.coefficient": 0.0})
        d = f.diagnosis
        if any(r.p_value < 0.05 / len(d.ranking) for r in d.ranking):
            invented.append((seed, d.verdict))
        else:
            assert not d.verdict.startswith(("missing effect", "most likely", "the misfit looks"))
    # Binomial(20, 0.05): P(more than 3) = 1.6%
    assert len(invented) <= 3, invented
