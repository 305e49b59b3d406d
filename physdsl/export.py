"""Proto-programs: a posterior written back as a .phys program whose priors are the fit.

``export`` turns a scene and its posterior draws into a new scene program: every inferred
unknown's prior becomes a fitted distribution that respects the prior's support. Unknowns
whose unconstrained draws are correlated (|r| >= 0.1) are written jointly as a multivariate
normal in the unconstrained space (numpyro's ``biject_to``): standard-normal params
``proto_zK ~ normal(0, 1)`` and each field an expression ``transform(mean + L_i . z)`` with
the Cholesky factor ``L``. Others get one readable distribution each.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .errors import PhysError, UsageError
from .scene import Prior, Scene, Unknown

CORRELATION_THRESHOLD = 0.1  # below this |r| everywhere, unknowns are written independently


# --------------------------------------------------------------------------------------------
# Supports: which constrained set an unknown lives in, and the bijection to the real line.


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
    from numpyro.distributions import constraints as c

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


def distribution_class(name: str):
    """The numpyro distribution (class or factory) called ``name`` in snake_case."""
    import numpyro.distributions as dist

    key = name.replace("_", "").lower()
    for attr in dir(dist):
        if attr.lower() == key and callable(getattr(dist, attr)):
            return getattr(dist, attr)
    raise PhysError(f"unknown distribution '{name}'")


def prior_support(unknown: Unknown, context: Mapping[str, np.ndarray]) -> Support:
    """The support of ``unknown``'s prior; arguments that depend on other unknowns are
    evaluated at ``context`` (their posterior means), an approximation for dependent bounds."""
    from .expr import evaluate

    prior: Prior = unknown.prior
    cls = distribution_class(prior.dist)
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


# --------------------------------------------------------------------------------------------
# Fitting: independent marginals and correlated blocks in the unconstrained space.


@dataclass(frozen=True)
class Marginal:
    """One unknown written as one distribution: ``dist`` with arguments in SI (per component)."""

    name: str
    shape: tuple[int, ...]
    support: Support
    dist: str  # normal | log_normal | beta | truncated_normal | categorical
    args: Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Block:
    """Correlated unknowns: unconstrained components ``mean + chol @ z``, z standard normal.

    ``components`` lists (unknown name, flat component index) in the order of ``mean``.
    """

    components: tuple[tuple[str, int], ...]
    mean: np.ndarray
    chol: np.ndarray


@dataclass(frozen=True)
class ProtoFit:
    """The fitted joint distribution of the exported unknowns."""

    marginals: tuple[Marginal, ...]
    blocks: tuple[Block, ...]
    supports: Mapping[str, Support]
    shapes: Mapping[str, tuple[int, ...]]


def fit_draws(draws: Mapping[str, np.ndarray], supports: Mapping[str, Support], *,
              widen: float = 1.0, threshold: float = CORRELATION_THRESHOLD) -> ProtoFit:
    """Fit the draws ``{name: (S, *shape)}`` of unknowns with the given supports.

    Continuous components are mapped to the unconstrained space; components whose
    correlation with another unknown's (or another component of the same vector) reaches
    ``threshold`` are grouped (connected components) and fitted as multivariate normals,
    the rest independently. ``widen`` multiplies every unconstrained scale (covariance by
    widen^2); categorical probabilities are tempered as p^(1/widen).
    """
    if widen <= 0:
        raise UsageError(f"--widen must be positive, got {widen}")
    names = list(draws)
    shapes = {n: tuple(np.shape(draws[n])[1:]) for n in names}
    n_draws = {np.shape(draws[n])[0] for n in names}
    if len(n_draws) > 1:
        raise ValueError(f"unknowns have different numbers of draws: {sorted(n_draws)}")
    continuous = [n for n in names if supports[n].kind != "discrete"]
    comps: list[tuple[str, int]] = []
    cols = []
    for n in continuous:
        flat = np.asarray(draws[n], dtype=float).reshape(len(draws[n]), -1)
        y = supports[n].to_unconstrained(flat if shapes[n] else flat[:, 0])
        y = y.reshape(len(flat), -1)
        for i in range(y.shape[1]):
            comps.append((n, i))
            cols.append(y[:, i])
    marginals: list[Marginal] = []
    blocks: list[Block] = []
    if comps:
        y = np.stack(cols, axis=1)
        mean = y.mean(axis=0)
        cov = np.atleast_2d(np.cov(y, rowvar=False))
        groups = _groups(comps, cov, threshold)
        for group in groups:
            members = [comps[i] for i in group]
            unknowns = list(dict.fromkeys(n for n, _ in members))
            if len(members) == 1 or (len(unknowns) == 1 and _max_offdiag(cov, group) < threshold):
                for n in unknowns:
                    idx = [k for k, c in enumerate(comps) if c[0] == n]
                    marginals.append(_fit_marginal(n, shapes[n], supports[n],
                                                   np.asarray(draws[n], dtype=float),
                                                   mean[idx], cov[np.ix_(idx, idx)], widen))
                continue
            sub = cov[np.ix_(group, group)] * widen**2
            blocks.append(Block(tuple(members), mean[group], _cholesky(sub)))
    for n in names:
        if supports[n].kind == "discrete":
            marginals.append(_fit_categorical(n, shapes[n], np.asarray(draws[n]), widen))
    order = {n: k for k, n in enumerate(names)}
    marginals.sort(key=lambda m: order[m.name])
    return ProtoFit(tuple(marginals), tuple(blocks), dict(supports), shapes)


def _groups(comps, cov, threshold) -> list[list[int]]:
    """Connected components of whole unknowns linked by |r| >= threshold (vectors stay whole)."""
    sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    corr = cov / np.outer(sd, sd)
    k = len(comps)
    parent = list(range(k))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(k):
        for j in range(i + 1, k):
            if comps[i][0] == comps[j][0] or abs(corr[i, j]) >= threshold:
                parent[find(i)] = find(j)
    out: dict[int, list[int]] = {}
    for i in range(k):
        out.setdefault(find(i), []).append(i)
    return list(out.values())


def _max_offdiag(cov, group) -> float:
    sub = cov[np.ix_(group, group)]
    sd = np.sqrt(np.maximum(np.diag(sub), 1e-300))
    corr = np.abs(sub / np.outer(sd, sd))
    np.fill_diagonal(corr, 0.0)
    return float(corr.max()) if corr.size else 0.0


def _cholesky(cov: np.ndarray) -> np.ndarray:
    """Cholesky factor, with a tiny diagonal jitter if the sample covariance is singular."""
    jitter = 0.0
    scale = float(np.mean(np.diag(cov))) or 1.0
    for _ in range(8):
        try:
            return np.linalg.cholesky(cov + jitter * np.eye(len(cov)))
        except np.linalg.LinAlgError:
            jitter = max(jitter * 10, 1e-12 * scale)
    raise PhysError("the posterior covariance is not positive definite",
                    hint="the draws may be constant; run inference longer or --free the unknown")


def _fit_marginal(name, shape, support: Support, x, mean, cov, widen) -> Marginal:
    """One readable distribution matched to a continuous unknown's draws (per component)."""
    sd_u = np.sqrt(np.maximum(np.diag(cov), 0.0)) * widen
    sd_u = np.maximum(sd_u, 1e-12 * np.maximum(np.abs(mean), 1.0))
    flat = x.reshape(len(x), -1)
    if support.kind == "real":
        return Marginal(name, shape, support, "normal", {"loc": mean, "scale": sd_u})
    if support.kind == "lower" and np.all(support.low == 0):
        return Marginal(name, shape, support, "log_normal", {"loc": mean, "scale": sd_u})
    if support.kind == "interval" and np.all(support.low == 0) and np.all(support.high == 1):
        m = flat.mean(axis=0)
        v = flat.var(axis=0, ddof=1) * widen**2
        v = np.minimum(v, 0.95 * m * (1 - m))
        v = np.maximum(v, 1e-300)
        k = m * (1 - m) / v - 1
        return Marginal(name, shape, support, "beta",
                        {"concentration1": m * k, "concentration0": (1 - m) * k})
    # shifted or two-sided bounds: a truncated normal fitted by maximum likelihood
    low = support.low if support.kind in ("lower", "interval") else None
    high = support.high if support.kind in ("upper", "interval") else None
    locs, scales = [], []
    for i in range(flat.shape[1]):
        lo = None if low is None else float(np.reshape(low, -1)[i])
        hi = None if high is None else float(np.reshape(high, -1)[i])
        loc, scale = fit_truncated_normal(flat[:, i], lo, hi)
        locs.append(loc)
        scales.append(scale * widen)
    args = {"loc": np.array(locs), "scale": np.array(scales)}
    if low is not None:
        args["low"] = np.reshape(low, -1).astype(float)
    if high is not None:
        args["high"] = np.reshape(high, -1).astype(float)
    return Marginal(name, shape, support, "truncated_normal", args)


def fit_truncated_normal(x: np.ndarray, low: float | None, high: float | None) -> tuple[float, float]:
    """Maximum-likelihood (loc, scale) of a normal truncated to (low, high)."""
    from scipy import optimize, stats

    x = np.asarray(x, dtype=float)
    m, s = float(x.mean()), float(x.std(ddof=1)) or 1e-12
    a_lo = -np.inf if low is None else low
    a_hi = np.inf if high is None else high

    def nll(theta):
        loc, scale = theta[0] * s + m, s * math.exp(theta[1])
        return -float(np.sum(stats.truncnorm.logpdf(x, (a_lo - loc) / scale,
                                                    (a_hi - loc) / scale, loc, scale)))

    best = optimize.minimize(nll, np.zeros(2), method="Nelder-Mead",
                             options={"xatol": 1e-6, "fatol": 1e-8, "maxiter": 2000})
    return float(best.x[0] * s + m), float(s * math.exp(best.x[1]))


def _fit_categorical(name, shape, x, widen) -> Marginal:
    if shape:
        raise PhysError(f"cannot export discrete vector unknown '{name}'",
                        hint=f"return it to its prior with --free {name}")
    values = np.rint(np.asarray(x, dtype=float).reshape(-1)).astype(int)
    if values.min() < 0:
        raise PhysError(f"cannot export discrete unknown '{name}' with negative values")
    counts = np.bincount(values).astype(float)
    p = counts / counts.sum()
    p = np.where(p > 0, p ** (1.0 / widen), 0.0)
    return Marginal(name, shape, Support("discrete"), "categorical", {"probs": p / p.sum()})


# --------------------------------------------------------------------------------------------
# Drawing from a fit (used by tests and to check an export against its posterior).


def draw_from_fit(fit: ProtoFit, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` draws of every unknown from ``fit`` (numpy, for checks; sampling scenes goes
    through the exported program instead)."""
    from scipy import stats

    rng = np.random.default_rng(seed)
    out: dict[str, np.ndarray] = {}
    for m in fit.marginals:
        size = (n, *m.shape)
        a = {k: np.reshape(v, m.shape) for k, v in m.args.items()} if m.dist != "categorical" else {}
        if m.dist == "normal":
            out[m.name] = rng.normal(a["loc"], a["scale"], size)
        elif m.dist == "log_normal":
            out[m.name] = np.exp(rng.normal(a["loc"], a["scale"], size))
        elif m.dist == "beta":
            out[m.name] = rng.beta(a["concentration1"], a["concentration0"], size)
        elif m.dist == "truncated_normal":
            lo = a.get("low", -np.inf)
            hi = a.get("high", np.inf)
            out[m.name] = stats.truncnorm.rvs((lo - a["loc"]) / a["scale"],
                                              (hi - a["loc"]) / a["scale"], a["loc"], a["scale"],
                                              size=size, random_state=rng)
        elif m.dist == "categorical":
            out[m.name] = rng.choice(len(m.args["probs"]), size=size, p=m.args["probs"])
    for b in fit.blocks:
        z = rng.standard_normal((n, len(b.mean)))
        y = b.mean + z @ b.chol.T
        for k, (name, i) in enumerate(b.components):
            shape = fit.shapes[name]
            arr = out.setdefault(name, np.zeros((n, int(np.prod(shape)) if shape else 1)))
            arr[:, i] = fit.supports[name].component(i).from_unconstrained(y[:, k])
    for name in list(out):
        if out[name].ndim == 2 and not fit.shapes[name] and out[name].shape[1] == 1:
            out[name] = out[name][:, 0]
        elif fit.shapes[name]:
            out[name] = out[name].reshape(n, *fit.shapes[name])
    return out
