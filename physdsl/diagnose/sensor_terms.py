"""A sensor-fault candidate as a scene edit: the term (``offset``, ``gain``, ``delay``, a plug-in
fault) written into its observation's block with a prior, so ``refine`` can add it and fit it
like any unknown (``hinge.angle.offset``). The prior is centred on the fault's off value and,
by the fault's unit, broad against what one noise sigma or one sample interval can show: in the
quantity's unit (an offset) sd 20 sigma, in seconds (a delay) 10 dt, dimensionless (a gain) 0.1.
"""
from __future__ import annotations

import numpy as np

from ..expr import constant_value, is_constant
from ..observe.sensor import SENSOR_FAULTS
from .candidates import Candidate

OFFSET_SIGMAS = 20.0  # offset prior sd in noise sigmas
GAIN_SD = 0.1  # prior sd of a dimensionless term
DELAY_SAMPLES = 10.0  # delay prior sd in sample intervals


def _observation(scene, cand: Candidate):
    return next(o for o in scene.observations if o.name == cand.target[0])


def prior_text(scene, cand: Candidate) -> str:
    """``~ normal(...)`` of the term, in SI numbers (no units needed)."""
    obs, fault = _observation(scene, cand), SENSOR_FAULTS[cand.name]
    off = f"{fault.off:g}"
    if fault.unit == "s":
        dt = float(np.median(np.diff(obs.times))) if len(obs.times) > 1 else 0.01
        return f"~ normal({off}, {DELAY_SAMPLES * dt:.6g})"
    if fault.unit is not None:
        return f"~ normal({off}, {GAIN_SD:g})"
    sigma = constant_value(obs.noise.scale) if is_constant(obs.noise.scale) else np.asarray(1.0)
    sd = OFFSET_SIGMAS * np.broadcast_to(np.asarray(sigma, float), (obs.dim,))
    if np.allclose(sd, sd[0]) or not fault.per_axis:
        return f"~ normal({off}, {float(sd[0]):.6g})"
    vec = ", ".join(f"{v:.6g}" for v in sd)
    return f"~ normal(({', '.join(off for _ in sd)}), ({vec}))"


def sensor_term(scene, cand: Candidate) -> tuple[str, str]:
    """(path, value text) of the term ``cand`` writes into its observation's block
    (``syntax.edit.value_set``): ``hinge.angle.offset``, ``~ normal(0, 0.02)``."""
    return f"{cand.target[0]}.{cand.name}", prior_text(scene, cand)


def unknown_key(cand: Candidate) -> str:
    return f"{cand.target[0]}.{cand.name}"


def start_value(cand: Candidate, estimate: float | None) -> float:
    """Where the term's refit starts: exact, moved by the score test's one-step estimate
    (a gain's estimate is g in measured = (1 + g) true)."""
    step = float(estimate) if estimate is not None and np.isfinite(estimate) else 0.0
    return SENSOR_FAULTS[cand.name].off + step
