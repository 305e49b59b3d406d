"""Distribution arguments and units: what the resolver accepts agrees with what numpyro means
and with the support that lint prints.

An argument that carries the unknown's unit to the power p must scale like it: if X ~ D(a)
then k X ~ D(a with that argument times k^p), i.e. log p_k(k x) = log p(x) - log k. Plain
numbers (shapes, exponents, probabilities) and log-space arguments stay unchanged.
"""
from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.errors import PhysUnitError
from physdsl.syntax import dists, loads, unknowns_rows

# circular: the value is an angle modulo 2π, so no scaling identity holds (its loc is in rad)
NOT_SCALABLE = {"von_mises"}
# arguments given when the distribution has no constraint to pick a value from
PLAIN = {"low": 0.5, "high": 2.5, "loc": 0.6}


def _value(arg: str, c) -> float | None:
    """A valid example value of an argument from its constraint (None: cannot tell)."""
    if arg in PLAIN:
        return PLAIN[arg]
    if c is None:
        return None
    kind = type(c).__name__.lstrip("_")
    if kind in ("Positive", "Nonnegative", "GreaterThan", "GreaterThanEq"):
        return float(getattr(c, "lower_bound", 0) or 0) + 1.7
    if kind == "UnitInterval":
        return 0.3
    if kind in ("Interval", "OpenInterval"):
        return float(c.lower_bound + c.upper_bound) / 2
    if kind == "Real":
        return 0.6
    return None


def _example(name: str):
    """(distribution, its example arguments) for a continuous scalar one, else None."""
    obj = dists.catalogue()[name]
    pos, kw = dists.arg_names(obj)
    cons = dists.arg_constraints(obj, set(pos + kw))
    required = set(dists.required_args(obj))
    params = inspect.signature(obj).parameters
    args = {}
    for a in pos + kw:
        default = params[a].default
        numeric = isinstance(default, (int, float)) and not isinstance(default, bool)
        if a in cons or a in required or a in PLAIN or numeric:
            v = _value(a, cons.get(a))
            if v is None and not numeric:
                return None
            args[a] = v if v is not None else float(default) + 0.5
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = obj(**{a: np.float64(v) for a, v in args.items()})
    except (TypeError, ValueError, AssertionError):  # needs other arguments (e.g. integers)
        return None
    if getattr(d.support, "is_discrete", False) or d.event_shape != () or d.batch_shape != ():
        return None
    return d, args


def _points(d) -> np.ndarray:
    """Points inside the support where the density is finite (a hurdle's zero excluded)."""
    x = np.linspace(0.55, 4.0, 12)
    x = x[np.asarray(d.support(x), bool) & np.isfinite(np.asarray(d.log_prob(x)))]
    assert len(x) >= 3
    return x


CONTINUOUS = {n: ex for n in sorted(dists.catalogue()) if (ex := _example(n)) is not None}
WITH_UNIT = sorted(n for n, (_, args) in CONTINUOUS.items()
                   if any(dists.unit_power(n, a) is not None for a in args))


def test_the_catalogue_is_covered():
    """The scaling test sees the distributions people write (a numpyro change would show)."""
    for name in ("normal", "half_normal", "uniform", "log_uniform", "student_t", "cauchy",
                 "exponential", "gamma", "inverse_gamma", "weibull", "pareto", "laplace",
                 "truncated_normal", "half_cauchy"):
        assert name in WITH_UNIT, name
    assert "log_normal" in CONTINUOUS and "log_normal" not in WITH_UNIT


@pytest.mark.parametrize("name", [n for n in WITH_UNIT if n not in NOT_SCALABLE])
def test_unit_powers_mean_what_numpyro_means(name):
    d, args = CONTINUOUS[name]
    x = _points(d)
    k = 3.0
    scaled = {a: v * k ** p if (p := dists.unit_power(name, a)) is not None else v
              for a, v in args.items()}
    dk = dists.catalogue()[name](**{a: np.float64(v) for a, v in scaled.items()})
    np.testing.assert_allclose(np.asarray(dk.log_prob(k * x)),
                               np.asarray(d.log_prob(x)) - np.log(k), atol=1e-8)


def test_log_normal_lives_in_log_space():
    """log_normal's loc takes no unit because it shifts by log k when the value scales by k."""
    k = 3.0
    d, _ = CONTINUOUS["log_normal"]
    x = _points(d)
    dk = dists.catalogue()["log_normal"](d.loc + np.log(k), d.scale)
    np.testing.assert_allclose(np.asarray(dk.log_prob(k * x)),
                               np.asarray(d.log_prob(x)) - np.log(k), atol=1e-8)


def _mass(prior: str):
    src = f"scene s {{ body b {{ shape: sphere(radius: 1 cm)  mass ~ {prior} }} }}"
    return loads(src, "s.phys")


def _in_grams(name: str) -> str:
    """``name``'s example prior with every unit-carrying argument written in grams."""
    _, args = CONTINUOUS[name]
    parts = []
    for a, v in args.items():
        p = dists.unit_power(name, a)
        text = f"{v * 1000.0 ** p:g}" if p is not None else f"{v:g}"
        unit = "" if p is None else " g" if p == 1 else f" g^{p:g}"
        parts.append(f"{a}: {text}{unit}")
    return f"{name}({', '.join(parts)})"


@pytest.mark.parametrize("name", WITH_UNIT)
def test_lint_support_is_the_distribution_of_the_arguments_in_si(name):
    """A prior written in grams resolves, and lint's support is numpyro's for the SI values."""
    d, _ = CONTINUOUS[name]
    rows = {r[0]: r for r in unknowns_rows(_mass(_in_grams(name)))}
    assert rows["b.mass"][2] == dists.constraint_words(d.support)
    assert rows["b.mass"][4] == "kg"


def test_log_uniform_bounds_carry_the_unit_and_lint_shows_them_in_si():
    rows = {r[0]: r for r in unknowns_rows(_mass("log_uniform(10 g, 1 kg)"))}
    assert rows["b.mass"][2] == "in [0.01, 1]" and rows["b.mass"][4] == "kg"
    # plain numbers are the unknown's SI unit: the same support
    rows = {r[0]: r for r in unknowns_rows(_mass("log_uniform(0.01, 1)"))}
    assert rows["b.mass"][2] == "in [0.01, 1]"
    with pytest.raises(PhysUnitError) as ex:
        _mass("log_uniform(1 s, 2 s)")
    assert ex.value.message == "log_uniform's 'low' is a time (s), but the value needs a mass (kg)"


WITH_PLAIN = sorted(n for n, (_, args) in CONTINUOUS.items()
                    if any(dists.unit_power(n, a) is None for a in args))


@pytest.mark.parametrize("name", WITH_PLAIN)
def test_plain_arguments_refuse_a_unit_in_words(name):
    """Every argument the resolver calls a plain number says so when given a unit."""
    _, args = CONTINUOUS[name]
    a = next(a for a in args if dists.unit_power(name, a) is None)
    given = ", ".join(f"{b}: {v:g}{' kg' if b == a else ''}" for b, v in args.items())
    with pytest.raises(PhysUnitError) as ex:
        _mass(f"{name}({given})")
    why = "lives in log space" if name in dists.LOG_SPACE else "is a plain number"
    assert ex.value.message == f"{name}'s '{a}' {why}; it takes no unit"


def test_signatures_still_bind():
    """Every example binds by keyword (numpyro renaming an argument would show here)."""
    for name, (_, args) in CONTINUOUS.items():
        inspect.signature(dists.catalogue()[name]).bind(**args)
