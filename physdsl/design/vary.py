"""What an experiment may change (``--vary``): an unknown control sequence within its prior's
bounds, or an initial-state field within a range, mapped from free coordinates so that every
setting an optimiser or a random draw proposes is inside its bounds.

Both kinds of experiment design use this: the two-law separation (``experiment.py``: which
field, its range, the noise scales) and the information design (``information.py``:
controls within bounds and an energy budget).
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..control.cost import CONTROL, control_effects, effort_residuals
from ..errors import UsageError
from ..expr import constant_value
from ..observe import trajectory


def require_unknown(models, field: str) -> None:
    """A UsageError unless ``field`` is an unknown of every model."""
    for m in models:
        if field not in m.unknown_names:
            raise UsageError(f"--vary {field}: not an unknown of scene '{m.scene.name}'",
                             hint="vary a field written with a prior ('~ normal(...)') in both "
                                  "scenes, e.g. ball.velocity")


def noise_scales(model, values) -> dict:
    """Each observation's noise scale per axis (name -> (K,)) and its axis names (name:axes)."""
    out = {}
    for o in model.observed:
        out[o.obs.name] = np.asarray(model.noise_scale(o.obs, values))
        out[f"{o.obs.name}:axes"] = trajectory.axes(o.obs.quantity)
    return out


def _prior_args(model, field: str):
    u = next(u for u in model.unknowns if u.name == field)
    try:
        return u, [np.asarray(constant_value(a), float) for a in u.prior.args]
    except Exception:  # an argument that refers to another unknown
        return u, None


def prior_range(model, field: str, vector: bool) -> tuple[float, float]:
    """Mean ± 3 sd of a normal prior (of the magnitude, for a vector along its mean)."""
    u, args = _prior_args(model, field)
    if u.prior.dist != "normal" or args is None or len(args) < 2:
        raise UsageError(f"--vary {field}: its prior is not normal; give --range LO:HI")
    mean, sd = args[:2]
    centre = float(np.linalg.norm(mean)) if vector else float(mean)
    spread = 3 * float(np.max(sd))
    return max(centre - spread, 0.0) if vector else centre - spread, centre + spread


@dataclass(frozen=True)
class Varied:
    """One field an experiment sets: its bounds per component (SI) and, for a control
    sequence, its control use (for the energy ∫u² dt)."""

    field: str
    lower: np.ndarray
    upper: np.ndarray
    use: object = None  # the control use, None for an initial-state field

    @property
    def size(self) -> int:
        return int(self.lower.size)

    @property
    def control(self) -> bool:
        return self.use is not None

    def value(self, w):
        """The setting at free coordinates ``w`` (size,): inside [lower, upper] by construction."""
        lo, hi = jnp.asarray(self.lower), jnp.asarray(self.upper)
        return jnp.reshape(lo + (hi - lo) * jax.nn.sigmoid(w), self.lower.shape)

    def free(self, value) -> np.ndarray:
        """The free coordinates of a setting (inverse of ``value``; clipped inside the bounds)."""
        p = (np.ravel(np.asarray(value, float)) - np.ravel(self.lower)) / np.ravel(self.upper - self.lower)
        p = np.clip(p, 1e-6, 1 - 1e-6)
        return np.log(p) - np.log1p(-p)

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """A setting drawn uniformly within the bounds."""
        return rng.uniform(self.lower, self.upper)


def resolve(model, field: str) -> str:
    """The unknown ``field`` names: itself, or the control sequence on a target (``rail`` for
    ``control_force@rail.values``); a UsageError if neither is an unknown."""
    alias = f"{CONTROL}@{field}.values"
    if field not in model.unknown_names and alias in model.unknown_names:
        return alias
    require_unknown((model,), field)
    return field


def varied(model, field: str, rng: tuple[float, float] | None = None) -> Varied:
    """The Varied of ``field`` in ``model``: a control sequence (``values ~ uniform(LO, HI)``,
    the motor's limits) or an initial-state field within ``rng`` (default: a uniform prior's
    bounds or a normal prior's mean ± 3 sd, per component)."""
    field = resolve(model, field)
    u, args = _prior_args(model, field)
    shape = tuple(u.shape)
    uses = control_effects(model.scene)
    if field in uses:
        if u.prior.dist != "uniform" or args is None:
            raise UsageError(f"--vary {field}: a control to design needs bounds",
                             hint="write its values as `values ~ uniform(LO, HI)` (the motor's limits)")
        lo, hi = (np.broadcast_to(a, shape).astype(float) for a in args[:2])
        if np.any(lo > 0) or np.any(hi < 0):
            raise UsageError(f"--vary {field}: its bounds must include 0 (the energy budget "
                             "scales a push down towards no push)")
        return Varied(field, lo, hi, uses[field])
    if rng is not None:
        lo, hi = (np.full(shape, v, float) for v in rng)
    elif u.prior.dist == "uniform" and args is not None:
        lo, hi = (np.broadcast_to(a, shape).astype(float) for a in args[:2])
    elif u.prior.dist == "normal" and args is not None and len(args) >= 2:
        lo, hi = (np.broadcast_to(args[0] + s * 3 * args[1], shape).astype(float) for s in (-1, 1))
    else:
        raise UsageError(f"--vary {field}: no range", hint="give --range LO:HI (SI units)")
    if not np.all(hi > lo):
        raise UsageError(f"--vary {field}: empty range", hint="give --range LO:HI with LO < HI")
    return Varied(field, lo, hi)


def energy(model, items: tuple[Varied, ...], values):
    """∫u² dt summed over the control sequences among ``items`` (zero-order hold, the gain
    applied: the goal's effort), at ``values`` (name -> setting)."""
    names = tuple(v.field for v in items if v.control)
    if not names:
        return jnp.zeros(())
    return jnp.sum(effort_residuals(model.scene, values, names) ** 2)
