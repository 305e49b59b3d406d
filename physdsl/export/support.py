"""Supports of exported unknowns: the constrained set a prior lives in and its bijection to the
real line (numpyro's ``biject_to``), read from the prior's distribution."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from numpyro.distributions import constraints as c

from ..errors import PhysError
from ..expr import evaluate
from ..scene import Prior, Unknown
from ..syntax.dists import find


@dataclass(frozen=True)
class Support:
    """The set an unknown's values live in, per component (bounds broadcast to its shape).

    kind: real | lower (> low) | upper (< high) | interval (low, high) | discrete (integers
    from 0). The bijection from the real line is numpyro's ``biject_to`` for the same set.
    """

    kind: str
    low: np.ndarray | None = None
    high: np.ndarray | None = None

    def to_unconstrained(self, x: np.ndarray) -> np.ndarray:
        """The inverse bijection, applied componentwise (values on the bound are nudged in)."""
        x = np.asarray(x, dtype=float)
        if self.kind == "real":
            return x
        if self.kind == "lower":
            return np.log(np.maximum(x - self.low, _tiny(self.low)))
        if self.kind == "upper":
            return np.log(np.maximum(self.high - x, _tiny(self.high)))
        if self.kind == "interval":
            u = (x - self.low) / (self.high - self.low)
            u = np.clip(u, 1e-12, 1 - 1e-12)
            return np.log(u) - np.log1p(-u)
        raise ValueError(f"no bijection for a {self.kind} support")

    def from_unconstrained(self, y: np.ndarray) -> np.ndarray:
        """The bijection from the real line onto the support (numpyro's ``biject_to``)."""
        y = np.asarray(y, dtype=float)
        if self.kind == "real":
            return y
        if self.kind == "lower":
            return self.low + np.exp(y)
        if self.kind == "upper":
            return self.high - np.exp(y)
        if self.kind == "interval":
            return self.low + (self.high - self.low) / (1.0 + np.exp(-y))
        raise ValueError(f"no bijection for a {self.kind} support")

    def component(self, i: int) -> "Support":
        """The scalar support of component ``i`` (flat index)."""
        pick = lambda b: None if b is None else np.asarray(b, dtype=float).reshape(-1)[i]  # noqa: E731
        return Support(self.kind, pick(self.low), pick(self.high))


def _tiny(bound) -> float:
    scale = float(np.max(np.abs(bound))) if bound is not None else 1.0
    return 1e-300 + 1e-15 * max(scale, 1.0)


def classify_constraint(constraint, shape: tuple[int, ...]) -> Support:
    """A numpyro constraint as a Support with bounds broadcast to ``shape``."""
    while hasattr(constraint, "base_constraint"):
        constraint = constraint.base_constraint
    bound = lambda b: np.broadcast_to(np.asarray(b, dtype=float), shape).reshape(-1).copy() \
        if shape else np.asarray(float(np.asarray(b)))  # noqa: E731
    name = type(constraint).__name__.lstrip("_")
    if constraint is c.real or name in ("Real", "RealVector"):
        return Support("real")
    if getattr(constraint, "is_discrete", False):
        low = getattr(constraint, "lower_bound", 0)
        if np.any(np.asarray(low) < 0):
            raise ValueError("discrete unknowns below 0 are not supported")
        return Support("discrete")
    has_low = hasattr(constraint, "lower_bound")
    has_high = hasattr(constraint, "upper_bound")
    if has_low and has_high:
        return Support("interval", bound(constraint.lower_bound), bound(constraint.upper_bound))
    if has_low:
        return Support("lower", bound(constraint.lower_bound))
    if has_high:
        return Support("upper", high=bound(constraint.upper_bound))
    raise ValueError(f"support {constraint} has no componentwise bijection")


def prior_support(unknown: Unknown, context: Mapping[str, np.ndarray]) -> Support:
    """The support of ``unknown``'s prior; arguments that depend on other unknowns are
    evaluated at ``context`` (their posterior means), an approximation for dependent bounds."""
    prior: Prior = unknown.prior
    cls = find(prior.dist)
    if cls is None:
        raise PhysError(f"unknown distribution '{prior.dist}'", span=unknown.span)
    args = [np.asarray(evaluate(a, context)) for a in prior.args]
    kwargs = {k: np.asarray(evaluate(v, context)) for k, v in prior.kwargs}
    d = cls(*args, **kwargs)
    if unknown.discrete or getattr(d, "is_discrete", False):
        return Support("discrete")
    try:
        return classify_constraint(d.support, tuple(unknown.shape))
    except ValueError as ex:
        raise PhysError(f"cannot export unknown '{unknown.name}': its prior {prior.dist} has "
                        f"support {d.support}: {ex}", span=unknown.span,
                        hint=f"return it to its prior with --free {unknown.name}") from None
