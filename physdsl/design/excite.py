"""The excitation that teaches the most: the settings of the ``--vary`` fields (control
sequences within their bounds and an energy budget, initial states within a range) that
maximise the D-optimal information gain (``information.gain``), by gradient ascent (Adam,
forward-mode derivatives through the rollout) from a few random starts, all started at once.

The comparison is random excitations of the same energy: uniform draws within the bounds,
each control sequence scaled to the budget (then clipped to its bounds). The budget defaults
to the median energy of such draws, so a random push is a typical one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..compile import Model
from .information import Belief, fisher, intervals
from .vary import Varied, energy

BUDGET_DRAWS = 256
BATCH = 4  # rows per compiled call: random excitations and restarts run in chunks of it


@dataclass
class InfoDesign:
    """The chosen excitation and what it, and random ones of the same energy, would teach."""

    fields: tuple[str, ...]
    settings: dict  # field -> chosen value (SI)
    gain: float  # log det(P0 + F) - log det P0 at the choice
    energy: float | None  # ∫u² dt of the chosen controls (None: no control varied)
    budget: float | None
    before: dict  # unknown -> 90% interval (lower, upper, width per component)
    after: dict
    random_after: dict  # unknown -> mean width per component over the random excitations
    random_gain: float  # mean over the random excitations
    random_energy: float | None
    starts: list = field(default_factory=list)  # each start's final gain
    units: dict = field(default_factory=dict)
    criterion: str = "d_optimal"

    def widths(self, which: str) -> dict[str, float]:
        """Each unknown's largest 90% width over its components (``before``/``after``/``random``)."""
        src = self.random_after if which == "random" else getattr(self, which)
        return {n: float(np.max(v if which == "random" else v["width"])) for n, v in src.items()}

    def worst(self) -> str:
        """The worse-determined unknown: the largest 90% width relative to its interval's centre
        (the width itself for an unknown centred at 0)."""
        def rel(name):
            b = self.before[name]
            mid = np.abs((np.asarray(b["lower"]) + np.asarray(b["upper"])) / 2)
            w = np.asarray(b["width"])
            return float(np.max(np.where(mid > 0, w / np.where(mid > 0, mid, 1), w)))

        return max(self.before, key=rel)

    def ratio(self, name: str | None = None) -> float:
        """Random excitations' mean 90% width of ``name`` (default the worse-determined) over
        the chosen excitation's: how many times narrower the choice leaves it."""
        name = name or self.worst()
        return self.widths("random")[name] / self.widths("after")[name]

    def text(self) -> str:
        """The report in words: one line per learned unknown, then the comparison."""
        lines = [f"excitation of {', '.join(self.fields)} (D-optimal, expected entropy reduction "
                 f"{0.5 * self.gain:.3g} nats; random of the same energy: {0.5 * self.random_gain:.3g})"]
        if self.budget is not None:
            lines.append(f"energy ∫u² dt: {self.energy:.4g} (budget {self.budget:.4g}; "
                         f"random {self.random_energy:.4g})")
        before, after, rnd = self.widths("before"), self.widths("after"), self.widths("random")
        for n in self.before:
            u = "" if self.units.get(n) in (None, "1") else f" {self.units[n]}"
            lines.append(f"{n}: 90% interval width {before[n]:.4g} -> {after[n]:.4g}{u} "
                         f"({before[n] / after[n]:.3g}x narrower; random: {rnd[n]:.4g})")
        w = self.worst()
        lines.append(f"worse-determined: {w}; the chosen excitation leaves it {self.ratio(w):.3g}x "
                     "narrower than random ones of the same energy")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"criterion": self.criterion, "fields": list(self.fields),
                "settings": {k: np.asarray(v).tolist() for k, v in self.settings.items()},
                "gain_logdet": self.gain, "entropy_reduction_nats": 0.5 * self.gain,
                "energy": self.energy, "budget": self.budget,
                "unknowns": {n: {"unit": self.units.get(n), "before": self.before[n],
                                 "after": self.after[n], "random_width": self.random_after[n]}
                             for n in self.before},
                "random": {"gain_logdet": self.random_gain, "energy": self.random_energy},
                "worst": self.worst(), "info_gain_ratio": self.ratio(), "starts": self.starts}


class Excitation:
    """The ``--vary`` fields as one free vector: settings within bounds, controls scaled down
    to the energy budget; ``evaluate`` gives gain, its gradient and the Fisher matrix."""

    def __init__(self, model: Model, b: Belief, items: tuple[Varied, ...], budget: float | None):
        self.model, self.belief, self.items, self.budget = model, b, items, budget
        self.cuts = np.cumsum([v.size for v in items])[:-1]
        key = ("info-design", b.index.tobytes(), budget is None,
               tuple((v.field, v.lower.tobytes(), v.upper.tobytes()) for v in items))
        # compiled once per scene structure and excitation: belief, budget and data are arguments
        self._evaluate = model.cached(key, self._build)

    def _build(self):
        names, index, items = self.belief.names, self.belief.index, self.items

        def objective(w, centre, precision, budget, data):
            b = Belief(names, index, centre, precision, ())
            s = self.settings(w, budget)
            f = fisher(self.model, b, s, data)
            g = jnp.linalg.slogdet(precision + f)[1] - jnp.linalg.slogdet(precision)[1]
            return g, (g, f, energy(self.model, items, s))

        return jax.jit(jax.vmap(jax.jacfwd(objective, has_aux=True), in_axes=(0,) + (None,) * 4))

    def evaluate(self, w):
        """(gradient of the gain, (gain, Fisher matrix, energy)) at each row of ``w``; rows are
        padded to a multiple of BATCH so that every call reuses one compiled program."""
        b, w = self.belief, np.atleast_2d(np.asarray(w, float))
        n = len(w)
        padded = np.concatenate([w, np.repeat(w[:1], -n % BATCH, axis=0)])
        args = (jnp.asarray(b.centre), jnp.asarray(b.precision),
                jnp.asarray(self.budget if self.budget is not None else 0.0), self.model.data)
        chunks = [self._evaluate(jnp.asarray(padded[i:i + BATCH]), *args)
                  for i in range(0, len(padded), BATCH)]
        return jax.tree_util.tree_map(lambda *a: jnp.concatenate(a)[:n], *chunks)

    def settings(self, w, budget=None) -> dict:
        """The setting of each field at free coordinates ``w``, controls scaled down to the
        budget (default this excitation's)."""
        budget = self.budget if budget is None else budget
        parts = jnp.split(jnp.asarray(w), self.cuts) if len(self.items) > 1 else [jnp.asarray(w)]
        out = {v.field: v.value(p) for v, p in zip(self.items, parts)}
        if self.budget is not None:
            e = energy(self.model, self.items, out)
            s = jnp.minimum(1.0, jnp.sqrt(budget / jnp.maximum(e, 1e-300)))
            out = {v.field: out[v.field] * s if v.control else out[v.field] for v in self.items}
        return out

    def free(self, settings: dict) -> np.ndarray:
        return np.concatenate([v.free(settings[v.field]) for v in self.items])


def default_budget(model: Model, items, rng: np.random.Generator) -> float | None:
    """The median ∫u² dt of uniform draws of the varied controls (None: none varied)."""
    if not any(v.control for v in items):
        return None
    draws = [energy(model, items, {v.field: v.draw(rng) for v in items}) for _ in range(BUDGET_DRAWS)]
    return float(np.median(np.asarray(draws)))


def random_settings(model: Model, items, budget, rng: np.random.Generator) -> dict:
    """A uniform draw within the bounds, its controls scaled to the budget, then clipped."""
    s = {v.field: v.draw(rng) for v in items}
    if budget is not None:
        scale = float(np.sqrt(budget / max(float(energy(model, items, s)), 1e-300)))
        s = {v.field: np.clip(s[v.field] * scale, v.lower, v.upper) if v.control else s[v.field]
             for v in items}
    return s


def _adam(ex: Excitation, starts: np.ndarray, steps: int, lr: float) -> tuple[np.ndarray, np.ndarray]:
    """Gradient ascent on the gain from every start at once; (best w per start, its gain)."""
    opt = optax.adam(lr)
    w = jnp.asarray(starts)
    state = opt.init(w)
    best_w, best_g = np.array(starts), np.full(len(starts), -np.inf)
    for _ in range(steps + 1):
        grad, (g, _, _) = ex.evaluate(w)
        g = np.asarray(g)
        better = np.isfinite(g) & (g > best_g)
        best_w[better], best_g[better] = np.asarray(w)[better], g[better]
        updates, state = opt.update(-jnp.nan_to_num(grad), state)
        w = optax.apply_updates(w, updates)
    return best_w, best_g


def search(model: Model, b: Belief, items: tuple[Varied, ...], *, budget: float | None = None,
           restarts: int = 4, random: int = 8, steps: int = 60, lr: float = 0.3,
           seed: int = 0) -> InfoDesign:
    """The most informative excitation of ``items`` for belief ``b``, against ``random``
    random excitations of the same energy; ``restarts`` starts: the best random one and
    uniform draws within the bounds."""
    rng = np.random.default_rng(seed)
    if budget is None:
        budget = default_budget(model, items, rng)
    ex = Excitation(model, b, items, budget)
    rand = [random_settings(model, items, budget, rng) for _ in range(max(random, 1))]
    _, (rg, rf, re) = ex.evaluate(jnp.asarray(np.stack([ex.free(s) for s in rand])))
    starts = [ex.free(rand[int(np.nanargmax(np.asarray(rg)))])]
    starts += [ex.free({v.field: v.draw(rng) for v in items}) for _ in range(max(restarts - 1, 0))]
    w, g = _adam(ex, np.stack(starts), steps, lr)
    k = int(np.argmax(g))
    _, (g_best, f_best, e_best) = ex.evaluate(jnp.asarray(w[k:k + 1]))
    p0 = np.asarray(b.precision)
    rand_after = [intervals(model, b, p0 + np.asarray(f)) for f in rf]
    control = budget is not None
    return InfoDesign(
        fields=tuple(v.field for v in items),
        settings={f: np.asarray(v) for f, v in ex.settings(jnp.asarray(w[k])).items()},
        gain=float(g_best[0]), energy=float(e_best[0]) if control else None, budget=budget,
        before=intervals(model, b, p0), after=intervals(model, b, p0 + np.asarray(f_best[0])),
        random_after={n: np.mean([r[n]["width"] for r in rand_after], axis=0).tolist()
                      for n in b.names},
        random_gain=float(np.mean(np.asarray(rg))),
        random_energy=float(np.mean(np.asarray(re))) if control else None,
        starts=[float(x) for x in g], units={u.name: u.unit for u in model.unknowns})
