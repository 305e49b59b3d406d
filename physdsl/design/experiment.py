"""The experiment that would decide between two fitted models: search over what the user can
change (an initial-state field that is an unknown of both scenes, e.g. ``ball.velocity``) for
the setting whose predictions differ most in noise units.

A vector field is varied along its fitted direction (a throw's speed, its direction kept); a
scalar field over its range. Each model is rolled out at its own fitted values with the varied
field set, at the recorded measurement times. The objective is pluggable: a function of the two
predictions and the noise scales returning (score, where); ``max_sigma`` (the default: the
largest |Δ|/σ over times and axes) and ``chi2`` (Σ (Δ/σ)²) are given. The search is a coarse
grid and then a few finer grids around the best point (the objective, a maximum over times,
is not smooth enough for plain gradient steps to be worth their compilation here).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from ..errors import UsageError
from .vary import noise_scales, prior_range, require_unknown  # shared with the information design


@dataclass
class Where:
    observation: str
    axis: str
    t: float


@dataclass
class Proposal:
    """The best setting found and what it separates."""

    field: str
    setting: float  # speed (vector fields) or value (scalars), SI
    recorded: float  # the same at the fitted values
    score: float  # objective at the setting
    recorded_score: float
    where: Where
    objective: str
    label_a: str
    label_b: str
    grid: list

    def text(self) -> str:
        what = "speed" if self.vector else "value"
        unit = "σ" if self.objective == "max_sigma" else " (χ²)"
        return (f"set {self.field} to {what} {self.setting:.3g} (recorded {self.recorded:.3g}): "
                f"{self.label_a} and {self.label_b} then differ by {self.score:.3g}{unit} in "
                f"{self.where.observation} {self.where.axis} at t = {self.where.t:.3g} s "
                f"(recorded: {self.recorded_score:.3g}{unit})")

    vector: bool = True

    def to_dict(self) -> dict:
        return asdict(self)


Objective = Callable[[dict, dict, dict, dict], tuple[float, Where]]


def max_sigma(pa: dict, pb: dict, sigma: dict, times: dict) -> tuple[float, Where]:
    """Largest |Δ|/σ over observations, times and axes, and where it is."""
    best = (-1.0, None)
    for name in pa:
        d = np.abs(np.asarray(pa[name]) - np.asarray(pb[name])) / sigma[name]
        i, a = np.unravel_index(int(np.argmax(d)), d.shape)
        if d[i, a] > best[0]:
            best = (float(d[i, a]), Where(name, sigma[f"{name}:axes"][a], float(times[name][i])))
    return best


def chi2(pa: dict, pb: dict, sigma: dict, times: dict) -> tuple[float, Where]:
    """Σ (Δ/σ)² over observations, times and axes; where: the largest term."""
    total = sum(float(np.sum(((np.asarray(pa[n]) - np.asarray(pb[n])) / sigma[n]) ** 2)) for n in pa)
    return total, max_sigma(pa, pb, sigma, times)[1]


OBJECTIVES = {"max_sigma": max_sigma, "chi2": chi2}


class Pair:
    """Two fitted models and their values; ``predict(field, x)`` sets the field in both."""

    def __init__(self, model_a, values_a, model_b, values_b, field: str):
        require_unknown((model_a, model_b), field)
        self.models, self.values, self.field = (model_a, model_b), (dict(values_a), dict(values_b)), field
        base = np.asarray(values_a[field], float)
        self.vector = base.ndim > 0 and base.size > 1
        self.direction = base / np.linalg.norm(base) if self.vector else None
        self.recorded = float(np.linalg.norm(base)) if self.vector else float(base)
        self.sigma = noise_scales(model_a, values_a)
        self.times = {o.obs.name: o.obs.times for o in model_a.observed}

    def setting(self, x: float):
        return x * self.direction if self.vector else np.asarray(x, float)

    def predict(self, x: float):
        return tuple({k: np.asarray(v) for k, v in m.predict({**vals, self.field: self.setting(x)}).items()}
                     for m, vals in zip(self.models, self.values))


def search(pair: Pair, lo: float, hi: float, objective: Objective = max_sigma, n: int = 9,
           refine: int = 2) -> tuple[float, float, Where, list]:
    """Best x in [lo, hi]: a grid of ``n`` points, then ``refine`` finer grids around the best."""
    grid = []

    def f(x):
        pa, pb = pair.predict(x)
        s, w = objective(pa, pb, pair.sigma, pair.times)
        grid.append((float(x), s))
        return s, w

    xs = np.linspace(lo, hi, n)
    best = max(((x, *f(x)) for x in xs), key=lambda t: t[1])
    step = (hi - lo) / (n - 1)
    for _ in range(refine):
        xs = np.clip(np.linspace(best[0] - step, best[0] + step, 5), lo, hi)
        best = max([best] + [(x, *f(x)) for x in xs if x != best[0]], key=lambda t: t[1])
        step /= 2
    return float(best[0]), float(best[1]), best[2], sorted(grid)


def design(model_a, values_a, model_b, values_b, field: str, rng=None,
           objective: str = "max_sigma", labels=("A", "B")) -> Proposal:
    """The proposal for two fitted models (``values_*``: their fitted values)."""
    if objective not in OBJECTIVES:
        raise UsageError(f"unknown objective '{objective}'", hint=" or ".join(OBJECTIVES))
    pair = Pair(model_a, values_a, model_b, values_b, field)
    lo, hi = rng if rng is not None else prior_range(model_a, field, pair.vector)
    if not hi > lo:
        raise UsageError(f"--range {lo}:{hi}: empty", hint="give LO:HI with LO < HI")
    fn = OBJECTIVES[objective]
    x, score, where, grid = search(pair, lo, hi, fn)
    rec, _ = fn(*pair.predict(pair.recorded), pair.sigma, pair.times)
    return Proposal(field, x, pair.recorded, score, float(rec), where, objective, labels[0],
                    labels[1], grid, pair.vector)


def for_tie(model, a, b) -> Proposal | None:
    """The proposal for two tied diagnosis candidates ``a`` and ``b`` (``diagnosis.Ranked``
    rows refitted with their effect added: ``refit.model``, whose most likely draw is
    ``fitted["point"]``): each refit's model at its values, varying the target's initial
    velocity (a body) or angle (a joint) over its prior range. None where the target has no
    such unknown."""
    field = next((f for f in (f"{a.target}.velocity", f"{a.target}.initial")
                  if f in model.unknown_names), None)
    if field is None or not all(r.refit is not None and "point" in (r.fitted or {}) for r in (a, b)):
        return None
    models = [r.refit.model for r in (a, b)]
    vals = [{k: np.asarray(v) for k, v in r.fitted["point"].items()} for r in (a, b)]
    try:
        return design(models[0], vals[0], models[1], vals[1], field, labels=(a.effect, b.effect))
    except UsageError:
        return None
