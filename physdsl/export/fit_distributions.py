"""Fitting a posterior's draws: independent marginals and correlated blocks in the unconstrained space.

Unknowns whose unconstrained draws are correlated (|r| >= 0.1) are fitted jointly as a
multivariate normal (mean and Cholesky factor); the others get one readable distribution
each (normal, log-normal, beta, truncated normal, categorical). ``draw_from_fit`` draws back
from a fit, for checks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import optimize, stats

from ..errors import PhysError, UsageError
from .support import Support

CORRELATION_THRESHOLD = 0.1  # below this |r| everywhere, unknowns are written independently


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


def as_block(fit: ProtoFit, name: str, draws: np.ndarray, widen: float = 1.0) -> ProtoFit:
    """``fit`` with the marginal of ``name`` rewritten as a one-unknown block (same support,
    normal in the unconstrained space): for params whose unit a distribution cannot carry
    (``log_normal``/``beta`` arguments take no unit, and a param takes its unit from them)."""
    support = fit.supports[name]
    flat = np.asarray(draws, dtype=float).reshape(len(draws), -1)
    y = support.to_unconstrained(flat if fit.shapes[name] else flat[:, 0]).reshape(len(flat), -1)
    cov = np.atleast_2d(np.cov(y, rowvar=False)) * widen**2
    block = Block(tuple((name, i) for i in range(y.shape[1])), y.mean(axis=0), _cholesky(cov))
    return ProtoFit(tuple(m for m in fit.marginals if m.name != name), fit.blocks + (block,),
                    fit.supports, fit.shapes)


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


def draw_from_fit(fit: ProtoFit, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` draws of every unknown from ``fit`` (numpy, for checks; sampling scenes goes
    through the exported program instead)."""
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
