"""numpyro distributions by snake_case name: lookup, argument names, constraints, shapes.

The language accepts any numpyro distribution (registered in ``DISTRIBUTIONS``, with those of
plug-ins: entry-point group ``physdsl.distributions``); this module answers, without sampling,
which class a name means, how its arguments bind, whether constant arguments satisfy the
distribution's constraints, and the shape and support of a draw.
"""
from __future__ import annotations

import inspect

import numpy as np
import numpyro.distributions as nd
from numpyro.distributions import constraints as C

from ..registry import Registry

# arguments that are plain numbers whatever the unknown's unit (shapes, exponents, probabilities)
DIMLESS_ARGS = {"concentration", "concentration0", "concentration1", "df", "probs", "logits",
                "total_count", "skewness", "tailweight", "eta", "dimension", "num_categories",
                "alpha", "sharpness", "gate", "temperature", "asymmetry", "quantile"}
# ... and those that are plain numbers in one distribution only (beta_proportion's mean is in (0, 1))
DIMLESS_OF = {"beta_proportion": {"mean"}}
# distributions whose loc/scale live in log space (so they take no unit); log_uniform is not
# one: its low and high bound the value itself and carry its unit (its support is [low, high])
LOG_SPACE = {"log_normal", "hurdle_log_normal"}
# argument -> power of the unknown's dimension it carries (default 1), and per-distribution
# exceptions (inverse_gamma's rate scales the value: 1 / Gamma(concentration, rate))
ARG_POWER = {"rate": -1, "covariance_matrix": 2, "precision_matrix": -2}
POWER_OF = {"inverse_gamma": {"rate": 1}}
_NOT_DISTS = {"Distribution", "ExpandedDistribution", "TransformedDistribution", "Independent",
              "MaskedDistribution", "FoldedDistribution", "ImproperUniform", "Unit",
              "DiscreteUniform_"}


def unit_power(dist: str, arg: str) -> float | None:
    """The power of the unknown's dimension that ``dist``'s argument ``arg`` carries (1: the
    unknown's own unit, -1 its inverse); None when the argument is a plain number."""
    if dist in LOG_SPACE or arg in DIMLESS_ARGS or arg in DIMLESS_OF.get(dist, ()):
        return None
    return POWER_OF.get(dist, {}).get(arg, ARG_POWER.get(arg, 1))


def snake(name: str) -> str:
    out = []
    for i, ch in enumerate(name):
        if ch.isupper() and i and (not name[i - 1].isupper() or
                                   (i + 1 < len(name) and name[i + 1].islower())):
            out.append("_")
        out.append(ch.lower())
    return "".join(out)


DISTRIBUTIONS: Registry[object] = Registry("physdsl.distributions", "distribution")


def register_distribution(name: str):
    """Decorator: make a numpyro-style distribution class or factory available to ``~`` as
    ``name`` (a plug-in's module, named by an entry point of group ``physdsl.distributions``)."""
    def deco(obj):
        return DISTRIBUTIONS.add(name, obj, obj.__module__)
    return deco


def _numpyro_distributions():
    """numpyro's distribution classes and factory functions, by snake_case name."""
    for attr in dir(nd):
        obj = getattr(nd, attr)
        if attr.startswith("_") or attr in _NOT_DISTS or not attr[0].isupper():
            continue
        if isinstance(obj, type) and issubclass(obj, nd.Distribution):
            yield snake(attr), obj
        elif inspect.isfunction(obj) and obj.__module__.startswith("numpyro.distributions"):
            yield snake(attr), obj


for _name, _obj in _numpyro_distributions():
    DISTRIBUTIONS.add(_name, _obj, "numpyro.distributions")


def catalogue() -> Registry:
    """snake_case name -> numpyro class or factory function (and plug-ins')."""
    return DISTRIBUTIONS


def find(name: str):
    """The class/factory for a snake_case name, or None."""
    cat = catalogue()
    if name in cat:
        return cat[name]
    squashed = name.replace("_", "")
    for key, obj in cat.items():
        if key.replace("_", "") == squashed:
            return obj
    return None


def arg_names(obj) -> tuple[list[str], list[str]]:
    """(positional-or-keyword names, keyword-only names), without validate_args."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return [], []
    pos, kw = [], []
    for p in sig.parameters.values():
        if p.name in ("self", "validate_args") or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        (kw if p.kind == p.KEYWORD_ONLY else pos).append(p.name)
    return pos, kw


def required_args(obj) -> list[str]:
    sig = inspect.signature(obj)
    return [p.name for p in sig.parameters.values()
            if p.default is p.empty and p.name not in ("self", "validate_args")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def arg_constraints(obj, given: set[str]) -> dict:
    """Constraints of the arguments, looking through factories such as Categorical."""
    if isinstance(obj, type):
        return dict(getattr(obj, "arg_constraints", {}))
    name = obj.__name__
    for suffix, arg in (("Probs", "probs"), ("Logits", "logits")):
        cls = getattr(nd, name + suffix, None)
        if cls is not None and arg in given:
            return dict(getattr(cls, "arg_constraints", {}))
    if name == "TruncatedNormal":
        return {"scale": C.positive}
    return {}


def constraint_words(c) -> str:
    """A constraint in words: 'positive', 'in [0, 1]', 'greater than 2', ..."""
    kind = type(c).__name__.lstrip("_")
    lb, ub = getattr(c, "lower_bound", None), getattr(c, "upper_bound", None)
    if kind == "Positive":
        return "positive"
    if kind == "Nonnegative" or (kind == "GreaterThanEq" and lb == 0):
        return "zero or positive"
    if kind in ("UnitInterval",):
        return "in [0, 1]"
    if kind in ("Interval", "OpenInterval", "IntegerInterval") and lb is not None:
        return f"in [{lb:g}, {ub:g}]"
    if kind == "GreaterThan":
        return f"greater than {lb:g}"
    if kind == "GreaterThanEq":
        return f"at least {lb:g}"
    if kind == "LessThan":
        return f"less than {ub:g}"
    if kind in ("Real", "RealVector", "RealMatrix"):
        return "real"
    return snake(kind).replace("_", " ")


def satisfies(c, value: np.ndarray) -> bool | None:
    """Whether a constant value meets a constraint (None when it cannot be told)."""
    kind = type(c).__name__.lstrip("_")
    if kind in ("Dependent",):
        return None
    try:
        ok = np.asarray(c(np.asarray(value, dtype=float)))
        return bool(np.all(ok))
    except Exception:  # noqa: BLE001 - shape mismatches etc.: cannot tell
        return None


def draw_info(obj, args: list, kwargs: dict) -> tuple[tuple[int, ...] | None, bool, str]:
    """(shape of one draw, discrete?, support in words) from example argument arrays."""
    try:
        d = obj(*[np.asarray(a, dtype=float) for a in args],
                **{k: np.asarray(v, dtype=float) for k, v in kwargs.items()}, validate_args=False)
        shape = tuple(int(s) for s in (d.batch_shape + d.event_shape))
        support = d.support
        return shape, bool(getattr(support, "is_discrete", False)), constraint_words(support)
    except Exception:  # noqa: BLE001
        return None, False, "?"
