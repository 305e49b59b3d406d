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
from .syntax.loops import unroll_module

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


# --------------------------------------------------------------------------------------------
# Writing a fit as .phys text: distributions for marginals, expressions for blocks (SI + unit).


def number(x: float, sig: int = 6) -> str:
    """A float as short .phys number text with ``sig`` significant digits (no exponent sign noise)."""
    x = float(x)
    if x == 0 or not math.isfinite(x):
        return "0" if x == 0 else repr(x)
    text = f"{x:.{sig}g}"
    if "e" in text:
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def _digits(mean: float, sd: float) -> int:
    """Significant digits so that rounding ``mean`` moves it by well under 1% of ``sd``."""
    if sd <= 0:
        return 12
    ratio = abs(mean) / sd if mean else 1.0
    return int(min(max(math.ceil(math.log10(max(ratio, 1.0))) + 4, 4), 15))


def with_unit(text: str, unit: str, atom: bool = False) -> str:
    """``text`` in SI followed by ``unit`` (nothing for dimensionless ``1``)."""
    if unit in ("", "1"):
        return text
    return f"{text} {unit}" if atom else f"({text}) {unit}"


def _values(arr, shape, fmt) -> str:
    """A scalar or a vector literal (``(a, b, c)``) of flat values ``arr``."""
    items = [fmt(v) for v in np.reshape(arr, -1)]
    return items[0] if not shape else "(" + ", ".join(items) + ")"


def marginal_text(m: Marginal, unit: str) -> str:
    """The distribution call for a marginal, e.g. ``log_normal(-0.5108, 0.0204)``."""
    a = m.args
    if m.dist == "categorical":
        return "categorical(probs: (" + ", ".join(number(p, 6) for p in a["probs"]) + "))"
    if m.dist == "beta":
        return (f"beta({_values(a['concentration1'], m.shape, number)}, "
                f"{_values(a['concentration0'], m.shape, number)})")
    locs, scales = np.reshape(a["loc"], -1), np.reshape(a["scale"], -1)
    digits = max(_digits(lo, s) for lo, s in zip(locs, scales))
    loc = _values(locs, m.shape, lambda v: number(v, digits))
    scale = _values(scales, m.shape, lambda v: number(v, 5))
    if m.dist == "log_normal":  # arguments are of log(value / 1 SI unit): dimensionless
        return f"log_normal({loc}, {scale})"
    if m.dist == "normal":
        return f"normal({with_unit(loc, unit, True)}, {with_unit(scale, unit, True)})"
    if m.dist == "truncated_normal":
        parts = [with_unit(loc, unit, True), with_unit(scale, unit, True)]
        for key in ("low", "high"):
            if key in a:
                parts.append(f"{key}: " + with_unit(_values(a[key], m.shape, lambda v: number(v, 12)),
                                                   unit, True))
        return "truncated_normal(" + ", ".join(parts) + ")"
    raise ValueError(f"no text for distribution {m.dist}")


def transform_text(support: Support, inner: str) -> str:
    """The bijection from the real line onto ``support`` applied to expression text ``inner``."""
    if support.kind == "real":
        return inner
    if support.kind == "lower":
        low = float(support.low)
        return f"exp({inner})" if low == 0 else f"{number(low, 12)} + exp({inner})"
    if support.kind == "upper":
        return f"{number(float(support.high), 12)} - exp({inner})"
    if support.kind == "interval":
        low, high = float(support.low), float(support.high)
        span = f"{number(high - low, 12)} / (1 + exp(-({inner})))"
        return span if low == 0 else f"{number(low, 12)} + {span}"
    raise ValueError(f"no transform for a {support.kind} support")


def block_texts(block: Block, z_names: Sequence[str], fit: ProtoFit,
                units: Mapping[str, str]) -> dict[str, str]:
    """Value text of every unknown of a correlated block: ``transform(mean + L_i . z)``."""
    comps: dict[str, dict[int, str]] = {}
    for k, (name, i) in enumerate(block.components):
        sd = float(np.sqrt(np.sum(block.chol[k] ** 2)))
        terms = [number(block.mean[k], _digits(block.mean[k], sd))]
        for j in range(k + 1):
            c = float(block.chol[k, j])
            if c == 0.0:
                continue
            sign = "-" if c < 0 else "+"
            terms.append(f"{sign} {number(abs(c), 5)} * {z_names[j]}")
        inner = " ".join(terms)
        comps.setdefault(name, {})[i] = transform_text(fit.supports[name].component(i), inner)
    out = {}
    for name, parts in comps.items():
        shape = fit.shapes[name]
        if shape:
            text = "(" + ", ".join(parts[i] for i in range(int(np.prod(shape)))) + ")"
            out[name] = with_unit(text, units.get(name, "1"), atom=True)
        else:
            out[name] = with_unit(parts[0], units.get(name, "1"))
    return out


# --------------------------------------------------------------------------------------------
# The scene graph as syntax: dropping parts, locating unknowns, rewriting their values.

CONTACT_SUGAR = {"friction": "contact_friction", "restitution": "restitution",
                 "rolling_resistance": "rolling_resistance"}


def _scene_decl(module):
    decl = module.scene
    if decl is None:
        raise PhysError(f"{module.filename}: no scene to export",
                        hint="export reads a scene file: `scene NAME { ... }`")
    return decl


def _with_items(module, decl, items):
    import dataclasses

    new_decl = dataclasses.replace(decl, items=tuple(items))
    return dataclasses.replace(module, items=tuple(new_decl if i is decl else i for i in module.items))


def _walk_exprs(node, found):
    """Every expression node under ``node`` (any AST value), depth first."""
    import dataclasses

    if isinstance(node, tuple):
        for n in node:
            _walk_exprs(n, found)
        return
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        found.append(node)
        for f in dataclasses.fields(node):
            if f.name not in ("span", "unit_span"):
                _walk_exprs(getattr(node, f.name), found)


def _item_label(item) -> str:
    from .syntax import ast as A

    if isinstance(item, A.BodyItem):
        return f"{item.kind} {item.name}"
    if isinstance(item, A.JointItem):
        return f"joint {item.name}"
    if isinstance(item, A.EffectItem):
        return f"effect {item.effect} on {','.join(item.target)}"
    if isinstance(item, A.ContactItem):
        return f"contact {item.a}, {item.b}"
    if isinstance(item, A.ObserveItem):
        return f"observe {item.target}.{item.quantity}"
    if isinstance(item, A.ControlItem):
        return f"control {item.name}"
    if isinstance(item, A.Param):
        return f"param {item.name}"
    if isinstance(item, A.CameraItem):
        return f"camera {item.name}"
    return type(item).__name__


def drop_parts(module, drop: Sequence[str] = (), observe: bool = True, duration: float | None = None,
               source: str | None = None):
    """``module`` without the named parts and everything that depends on them.

    A body (or ground) drops the bodies hanging from it through joints, its joints,
    effects, contacts, controls and observations; ``effect@target`` drops one effect use
    (contact sugar fields included); ``target.quantity`` drops one observation.
    ``observe=False`` drops every observation (then ``duration`` in s, if given, is written
    into the world block when the world has none). Raises a PhysError naming both places
    when something left still refers to a dropped body or joint.
    """
    import dataclasses

    from .syntax import ast as A

    decl = _scene_decl(module)
    items = list(decl.items)
    bodies = {i.name: i for i in items if isinstance(i, A.BodyItem)}
    joints = {i.name: i for i in items if isinstance(i, A.JointItem)}
    effects = [i for i in items if isinstance(i, A.EffectItem)]
    contacts = [i for i in items if isinstance(i, A.ContactItem)]
    observes = [i for i in items if isinstance(i, A.ObserveItem)]

    dead_bodies: set[str] = set()
    dead_effects: set[tuple[str, tuple[str, ...]]] = set()
    dead_sugar: set[tuple[str, str, str]] = set()  # (a, b, field)
    dead_obs: set[tuple[str, str]] = set()
    for name in drop:
        if name in bodies:
            dead_bodies.add(name)
            continue
        if "@" in name:
            eff, _, tgt = name.partition("@")
            target = tuple(t.strip() for t in tgt.split(","))
            hits = [e for e in effects if e.effect == eff and e.target == target]
            sugar = [c for c in contacts if target in ((c.a, c.b), (c.b, c.a))
                     and c.block is not None
                     and any(CONTACT_SUGAR.get(getattr(f, "key", "")) == eff for f in c.block.fields)]
            if hits or sugar:
                dead_effects |= {(e.effect, e.target) for e in hits}
                dead_sugar |= {(c.a, c.b, k) for c in sugar for k, v in CONTACT_SUGAR.items() if v == eff}
                continue
        elif "." in name:
            target, _, quantity = name.partition(".")
            if any(o.target == target and o.quantity == quantity for o in observes):
                dead_obs.add((target, quantity))
                continue
        else:
            hits = [e for e in effects if e.effect == name]
            if len(hits) == 1:
                dead_effects.add((hits[0].effect, hits[0].target))
                continue
        choices = sorted(bodies) + [f"{e.effect}@{','.join(e.target)}" for e in effects] \
            + [f"{o.target}.{o.quantity}" for o in observes]
        raise UsageError(f"--drop {name}: no body, effect or observation of that name in the scene",
                         hint="choose from: " + ", ".join(choices))

    # bodies hanging from dropped bodies go too; so do the joints that hold them
    changed = True
    while changed:
        changed = False
        for j in joints.values():
            if j.parent in dead_bodies and j.child not in dead_bodies:
                dead_bodies.add(j.child)
                changed = True
    dead_joints = {n for n, j in joints.items() if j.child in dead_bodies or j.parent in dead_bodies}
    dead_names = dead_bodies | dead_joints

    kept = []
    removed = []
    for item in items:
        gone = False
        if isinstance(item, A.BodyItem):
            gone = item.name in dead_bodies
        elif isinstance(item, A.JointItem):
            gone = item.name in dead_joints
        elif isinstance(item, A.ContactItem):
            gone = item.a in dead_bodies or item.b in dead_bodies
            if not gone and item.block is not None:
                fields = tuple(f for f in item.block.fields
                               if (item.a, item.b, getattr(f, "key", "")) not in dead_sugar)
                item = dataclasses.replace(item, block=dataclasses.replace(item.block, fields=fields))
        elif isinstance(item, A.EffectItem):
            gone = bool(set(item.target) & dead_names) or (item.effect, item.target) in dead_effects
        elif isinstance(item, A.ControlItem):
            gone = item.target in dead_names
        elif isinstance(item, A.ObserveItem):
            gone = (not observe or item.target in dead_names
                    or (item.target, item.quantity) in dead_obs)
        (removed if gone else kept).append(item)

    errors = []
    declared = {i.name: i for i in removed if isinstance(i, (A.BodyItem, A.JointItem))}
    for item in kept:
        nodes: list = []
        _walk_exprs(item, nodes)
        for node in nodes:
            ref = None
            if isinstance(node, A.Dotted) and node.parts[0] in dead_names:
                ref = node.parts[0]
                text = ".".join(node.parts)
            elif isinstance(node, A.Name) and node.name in dead_names:
                ref = node.name
                text = node.name
            if ref is None:
                continue
            gone = declared[ref]
            where = f" (declared at {gone.span})" if gone.span else ""
            why = "" if ref in drop else f", dropped with {', '.join(drop)}"
            errors.append(PhysError(
                f"'{text}' in {_item_label(item)} refers to {_item_label(gone)}{where}, "
                f"which is dropped{why}",
                span=node.span, source=source,
                hint=f"drop {_item_label(item)} too, or replace '{text}' with a value"))
    if errors:
        from .errors import PhysErrors

        raise errors[0] if len(errors) == 1 else PhysErrors(errors)

    if not observe and duration is not None:
        kept = _ensure_duration(kept, duration)
    return _with_items(module, decl, kept)


def _ensure_duration(items, duration: float):
    """Items with a world block that sets ``duration`` (added when the world has none)."""
    import dataclasses

    from .syntax import ast as A
    from .syntax.parser import parse_field

    field = parse_field(f"duration: {number(duration, 10)} s")
    for k, item in enumerate(items):
        if isinstance(item, A.WorldItem):
            if item.block.get("duration") is None:
                block = dataclasses.replace(item.block, fields=item.block.fields + (field,))
                items[k] = dataclasses.replace(item, block=block)
            return items
    return [A.WorldItem(A.Block((field,)))] + list(items)


def _set_field(block, key: str, value, create: bool):
    """``block`` (possibly None) with field ``key`` set to ``value``; None if absent and not ``create``."""
    import dataclasses

    from .syntax import ast as A

    if block is None:
        return A.Block((A.Field(key, value),)) if create else None
    for k, f in enumerate(block.fields):
        if isinstance(f, A.Field) and f.key == key:
            fields = list(block.fields)
            fields[k] = dataclasses.replace(f, value=value)
            return dataclasses.replace(block, fields=tuple(fields))
    if not create:
        return None
    return dataclasses.replace(block, fields=block.fields + (A.Field(key, value),))


def set_unknown(module, name: str, value):
    """``module`` with the unknown called ``name`` given ``value`` (an ast Dist or expression).

    Names follow docs/language.md: ``param``, ``body.field``, ``joint.field``,
    ``effect@target.param`` (contact sugar included; a parameter that only had its library
    default prior gets a field), ``target.quantity.noise``.
    """
    import dataclasses

    from .syntax import ast as A

    decl = _scene_decl(module)
    items = list(decl.items)

    def done(k, item):
        items[k] = item
        return _with_items(module, decl, items)

    if "@" in name:
        head, _, param = name.rpartition(".")
        eff, _, tgt = head.partition("@")
        target = tuple(tgt.split(","))
        for k, item in enumerate(items):
            if isinstance(item, A.EffectItem) and item.effect == eff and item.target == target:
                return done(k, dataclasses.replace(item, block=_set_field(item.block, param, value, True)))
        for k, item in enumerate(items):
            if isinstance(item, A.ContactItem) and target in ((item.a, item.b), (item.b, item.a)):
                for key, e in CONTACT_SUGAR.items():
                    block = _set_field(item.block, key, value, False) if e == eff else None
                    if block is not None:
                        return done(k, dataclasses.replace(item, block=block))
            if isinstance(item, A.ControlItem) and eff == "control_force" and target == (item.target,):
                block = _set_field(item.block, param, value, False)
                if block is not None:
                    return done(k, dataclasses.replace(item, block=block))
    else:
        parts = name.split(".")
        for k, item in enumerate(items):
            if len(parts) == 1 and isinstance(item, A.Param) and item.name == name:
                return done(k, dataclasses.replace(item, value=value))
            if len(parts) == 2 and isinstance(item, (A.BodyItem, A.JointItem)) \
                    and item.name == parts[0]:
                block = _set_field(item.block, parts[1], value, False)
                if block is not None:
                    return done(k, dataclasses.replace(item, block=block))
            if len(parts) == 3 and isinstance(item, A.ObserveItem) \
                    and (item.target, item.quantity) == tuple(parts[:2]):
                block = _set_field(item.block, parts[2], value, False)
                if block is not None:
                    return done(k, dataclasses.replace(item, block=block))
    raise PhysError(f"cannot find where unknown '{name}' is written in the scene",
                    hint=f"return it to its prior with --free {name}")


def add_params(module, params: Sequence[tuple[str, str]]):
    """``module`` with ``param NAME ~ DIST`` items (text) placed first in the scene, after world."""
    from .syntax import ast as A
    from .syntax.parser import parse_field

    decl = _scene_decl(module)
    new = [A.Param(n, parse_field(f"x ~ {d}").value) for n, d in params]
    items = list(decl.items)
    at = next((k + 1 for k, i in enumerate(items) if isinstance(i, A.WorldItem)), 0)
    return _with_items(module, decl, items[:at] + new + items[at:])


def rebase_paths(module, src_dir: Path, out_dir: Path):
    """``module`` with every relative file name (imports found beside the scene, data files,
    meshes) rewritten relative to ``out_dir`` so the program still finds them there."""
    import dataclasses
    import os

    from .syntax import ast as A

    src_dir, out_dir = Path(src_dir).resolve(), Path(out_dir).resolve()
    if src_dir == out_dir:
        return module

    def moved(p: str | None, must_exist: bool = False) -> str | None:
        if p is None or os.path.isabs(p) or (must_exist and not (src_dir / p).exists()):
            return p
        return Path(os.path.relpath(src_dir / p, out_dir)).as_posix()

    def fix(node):
        if isinstance(node, tuple):
            return tuple(fix(n) for n in node)
        if isinstance(node, A.Call) and node.func == "mesh":
            return dataclasses.replace(node, args=tuple(
                dataclasses.replace(a, value=A.Str(moved(a.value.value), a.value.span))
                if isinstance(a.value, A.Str) else a for a in node.args))
        if isinstance(node, A.ObserveItem):
            return dataclasses.replace(node, file=moved(node.file), times=moved(node.times))
        if isinstance(node, A.ControlItem):
            return dataclasses.replace(node, file=moved(node.file))
        if isinstance(node, A.Import):
            return dataclasses.replace(node, path=moved(node.path, must_exist=True))
        if dataclasses.is_dataclass(node) and not isinstance(node, type):
            changes = {f.name: fix(getattr(node, f.name)) for f in dataclasses.fields(node)
                       if f.name not in ("span", "unit_span", "comments")}
            return dataclasses.replace(node, **changes)
        return node

    return fix(module)


# --------------------------------------------------------------------------------------------
# The whole export: posterior -> fit -> program text.


def posterior_draws(idata, names: Sequence[str]) -> dict[str, np.ndarray]:
    """Flattened posterior draws ``{name: (chains * draws, *shape)}`` of the named unknowns."""
    post = idata.posterior
    out = {}
    for n in names:
        arr = np.asarray(post[n].values, dtype=float)
        out[n] = arr.reshape(-1, *arr.shape[2:])
    return out


def fit_quality(idata, names: Sequence[str]) -> tuple[float, float]:
    """(max r-hat, min bulk ESS) over the named unknowns' components (nan when undefined)."""
    import warnings

    from .infer import posterior_data

    if not names:
        return float("nan"), float("nan")
    post = posterior_data.group(idata, "posterior")
    r, e = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n in names:
            arr = np.asarray(post[n].values, dtype=float)
            for x in np.moveaxis(arr.reshape(*arr.shape[:2], -1), 2, 0):  # (chain, draw) each
                r.append(posterior_data.rhat(x))
                e.append(posterior_data.ess(x, method="bulk"))
    r_max = float(np.nanmax(r)) if np.any(np.isfinite(r)) else float("nan")
    e_min = float(np.nanmin(e)) if np.any(np.isfinite(e)) else float("nan")
    return r_max, e_min


def _z_prefix(scene: Scene, source: str) -> str:
    prefix = "proto_z"
    while prefix in source or any(u.name.startswith(prefix) for u in scene.unknowns):
        prefix = "proto_" + prefix
    return prefix


def _header(scene_path: Path, run: Mapping, fit: ProtoFit, quality, n_draws: int,
            free, drop, widen, observe, z_names) -> list[str]:
    from .version import __version__

    lines = [f"proto-program exported by physdsl {__version__} from {run.get('scene') or scene_path}"]
    if run.get("scene_sha256"):
        lines.append(f"scene sha256 {run['scene_sha256']}")
    for f, h in (run.get("data_sha256") or {}).items():
        lines.append(f"data {Path(f).name} sha256 {h}")
    chains = f"backend {run.get('backend', '?')}, seed {run.get('seed', '?')}, {n_draws} draws"
    r_max, e_min = quality
    lines.append(f"posterior: {chains}; r-hat max {r_max:.3f}, ESS min {e_min:.0f}")
    if fit.blocks:
        names = list(dict.fromkeys(n for b in fit.blocks for n, _ in b.components))
        lines.append(f"correlated (multivariate normal, unconstrained space, {z_names[0]}.."
                     f"{z_names[-1]}): {', '.join(names)}")
    if fit.marginals:
        lines.append("independent: " + ", ".join(f"{m.name} {m.dist}" for m in fit.marginals))
    opts = []
    if free:
        opts.append("free " + ", ".join(free))
    if drop:
        opts.append("dropped " + ", ".join(drop))
    if widen != 1.0:
        opts.append(f"widened x{widen:g}")
    if not observe:
        opts.append("no observations (a pure generator)")
    if opts:
        lines.append("; ".join(opts))
    return ["# " + line for line in lines]


def export(scene_path: str | Path, idata, *, free: Sequence[str] = (), drop: Sequence[str] = (),
           widen: float = 1.0, observe: bool = True, out_path: str | Path | None = None,
           run: Mapping | None = None) -> str:
    """A .phys program whose priors are the posterior ``idata`` fitted, as text.

    ``free``: unknowns that keep their original prior; ``drop``: bodies, effects
    (``effect@target``) or observations (``target.quantity``) removed with what depends on
    them; ``widen``: factor on every unconstrained scale; ``observe=False``: no observe
    blocks (a pure generator). ``out_path``: where the text will be written (relative file
    names are rewritten to work from there; default: beside the scene). ``run``: the run's
    run.json contents, for the header. The text parses, resolves and is ``fmt``-stable.
    """
    from . import syntax

    scene_path = Path(scene_path)
    source = scene_path.read_text(encoding="utf-8")
    scene = syntax.loads(source, filename=str(scene_path), base_dir=scene_path.parent)
    run = dict(run or {})
    run.setdefault("scene", str(scene_path))
    posterior_vars = set(idata.posterior.data_vars)
    names = {u.name for u in scene.unknowns}
    bad = [f for f in free if f not in names]
    if bad:
        raise UsageError(f"--free {bad[0]}: no unknown of that name in {scene_path}",
                         hint="unknowns: " + ", ".join(sorted(names)))
    module = unroll_module(syntax.parse(source, str(scene_path)))  # loops written out
    module = drop_parts(module, drop, observe, duration=scene.duration, source=source)
    reduced = syntax.loads(print_module(module, source), filename=str(scene_path),
                           base_dir=scene_path.parent)
    targets = [u for u in reduced.unknowns if u.name in posterior_vars and u.name not in free]
    draws = posterior_draws(idata, [u.name for u in targets])
    for u in targets:
        if tuple(draws[u.name].shape[1:]) != tuple(u.shape):
            raise PhysError(f"posterior of '{u.name}' has shape {draws[u.name].shape[1:]}, the "
                            f"scene says {tuple(u.shape)}", span=u.span,
                            hint="export with the scene the posterior was fitted to")
    means = {n: d.mean(axis=0) for n, d in draws.items()}
    supports = {u.name: prior_support(u, means) for u in targets}
    fit = fit_draws(draws, supports, widen=widen)
    units = {u.name: u.unit for u in targets}
    for m in fit.marginals:
        if "." not in m.name and units[m.name] not in ("", "1") and m.dist in ("log_normal", "beta"):
            fit = as_block(fit, m.name, draws[m.name], widen)
    z_prefix = _z_prefix(scene, source)
    n_z = sum(len(b.mean) for b in fit.blocks)
    z_names = [f"{z_prefix}{k + 1}" for k in range(n_z)]
    k = 0
    for b in fit.blocks:
        texts = block_texts(b, z_names[k:k + len(b.mean)], fit, units)
        k += len(b.mean)
        for name, text in texts.items():
            module = set_unknown(module, name, _snippet(f"x: {text}"))
    for m in fit.marginals:
        module = set_unknown(module, m.name, _snippet(f"x ~ {marginal_text(m, units[m.name])}"))
    if z_names:
        module = add_params(module, [(z, "normal(0, 1)") for z in z_names])
    header = _header(scene_path, run, fit, fit_quality(idata, [u.name for u in targets]),
                     len(next(iter(draws.values()))) if draws else 0, free, drop, widen,
                     observe, z_names)
    # the program must resolve (checked where its files are now, before they are rebased)
    syntax.loads(print_module(module, source), filename=str(scene_path), base_dir=scene_path.parent)
    out_dir = Path(out_path).parent if out_path is not None else scene_path.parent
    module = rebase_paths(module, scene_path.parent, out_dir)
    return syntax.format_source("\n".join(header) + "\n\n" + print_module(module, source))


def print_module(module, source: str) -> str:
    """Text of an (edited) module through the language's printer; comments of ``source``
    stay where they were."""
    from .syntax.printer import format_module

    return format_module(module, source)


def _snippet(text: str):
    """The value (expression or Dist) of a one-field snippet ``key: value`` / ``key ~ dist``."""
    from .syntax.ast import strip_spans
    from .syntax.parser import parse_field

    return strip_spans(parse_field(text).value)

