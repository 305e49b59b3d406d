"""A goal as a cost on a rollout: pure JAX functions of (rollout, values), differentiable through
the physics (contacts included), and the goal's errors in the user's units.

The cost is a sum of squares (``goal_residuals``): errors divided by their tolerance
(dimensionless, so terms add) and ``weight * sum_k u_k^2 dt_k`` for the effort over the chosen
control sequences (zero-order hold), so Gauss-Newton steps know its curvature.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..expr import evaluate
from ..goal import Effort, Goal, Hold, Reach
from ..scene import Scene

CONTROL = "control_force"


class Track(NamedTuple):
    """Where a Reach term reads its position: a body's or a marker's column of the rollout."""

    markers: bool
    index: int


def control_effects(scene: Scene) -> dict[str, object]:
    """The control uses of ``scene`` by the name of their unknown sequence: ``control_force@T.values``."""
    return {f"{use.key}.values": use for use in scene.effects if use.effect == CONTROL}


def track_of(scene: Scene, body_names, marker_names, term: Reach) -> Track:
    """The rollout column of a Reach term's target (a body or a marker), or a located error."""
    if term.target in body_names:
        return Track(False, list(body_names).index(term.target))
    if term.target in marker_names:
        return Track(True, list(marker_names).index(term.target))
    raise ModelError(f"goal: '{term.target}' is neither a body nor a marker of the scene",
                     span=term.span, hint=f"bodies: {', '.join(body_names)}")


def check_goal(scene: Scene, simulator, goal: Goal) -> None:
    """Raise a located ModelError for a term the scene cannot evaluate."""
    end = float(simulator.times[-1])
    for term in goal.terms:
        if isinstance(term, Reach):
            track_of(scene, simulator.body_names, simulator.marker_names, term)
            _check_time(term.at, end, term.span)
            _check_tolerance(term.within, term.span)
        elif isinstance(term, Hold):
            if term.joint not in simulator.joint_names:
                raise ModelError(f"goal: '{term.joint}' is not a joint of the scene", span=term.span,
                                 hint=f"joints: {', '.join(simulator.joint_names) or 'none'}")
            if not term.start < term.end:
                raise ModelError("goal: a hold window must end after it starts", span=term.span)
            _check_time(term.end, end, term.span)
            _check_tolerance(term.within, term.span)
        elif isinstance(term, Effort) and term.weight < 0:
            raise ModelError("goal: an effort weight cannot be negative", span=term.span)


def _check_time(t: float, end: float, span) -> None:
    if not 0.0 <= t <= end + 1e-12:
        raise ModelError(f"goal: time {t:g} s lies outside the simulated 0 .. {end:g} s", span=span,
                         hint="set `world { duration: ... }` to simulate longer")


def _check_tolerance(within: float, span) -> None:
    if not within > 0:
        raise ModelError("goal: a tolerance ('within') must be positive", span=span)


def position_at(rollout, times, track: Track, t: float):
    """Position (3,) of a body or marker at time ``t``, linear between recorded steps."""
    column = (rollout.marker_pos if track.markers else rollout.body_pos)[:, track.index]
    return jnp.stack([jnp.interp(t, times, column[:, k]) for k in range(3)])


def effort_residuals(scene: Scene, values, chosen: tuple[str, ...]):
    """sqrt(dt_k) * gain * u_k over the chosen control sequences (zero-order hold to the end):
    their squared sum is ∫ u² dt."""
    uses = control_effects(scene)
    parts = [jnp.zeros(0)]
    for name in chosen:
        use = uses.get(name)
        if use is None:
            continue
        times = np.asarray(use.tables["times"], dtype=float)
        held = np.diff(np.append(times, max(scene.duration, float(times[-1]))))
        gain = evaluate(use.params["gain"], values) if "gain" in use.params else 1.0
        u = jnp.reshape(gain * jnp.asarray(values[name]), (len(times), -1))
        parts.append(jnp.sqrt(held)[:, None] * u)
    return jnp.concatenate([jnp.ravel(p) for p in parts])


def _window(simulator, term: Hold) -> np.ndarray:
    """The recorded steps inside a Hold term's window."""
    return np.flatnonzero((simulator.times >= term.start - 1e-12)
                          & (simulator.times <= term.end + 1e-12))


def term_miss(scene: Scene, simulator, term: Reach | Hold, rollout):
    """Predicted minus wanted, in the term's unit: (3,) for a Reach, one per step of the window
    for a Hold."""
    if isinstance(term, Reach):
        track = track_of(scene, simulator.body_names, simulator.marker_names, term)
        return (position_at(rollout, jnp.asarray(simulator.times), track, term.at)
                - jnp.asarray(term.point))
    j = list(simulator.joint_names).index(term.joint)
    return rollout.joint_pos[_window(simulator, term), j] - term.value


def term_errors(scene: Scene, simulator, goal: Goal, rollout, values, chosen: tuple[str, ...]
                ) -> list:
    """Each term's error in its own unit: a Reach's distance (m), a Hold's largest miss (rad or
    m); an Effort term's integral of u² over the chosen control sequences."""
    out = []
    for term in goal.terms:
        if isinstance(term, Effort):
            out.append(jnp.sum(effort_residuals(scene, values, chosen) ** 2))
        else:
            miss = term_miss(scene, simulator, term, rollout)
            out.append(jnp.linalg.norm(miss) if isinstance(term, Reach) else jnp.max(jnp.abs(miss)))
    return out


def goal_residuals(scene: Scene, simulator, goal: Goal, rollout, values, chosen: tuple[str, ...]):
    """The goal as a residual vector whose squared sum is the cost: (error / within) per axis of
    each Reach term, the same over each Hold window divided by the square root of its length
    (its mean), and sqrt(weight * dt_k) * u_k for Effort."""
    parts = [jnp.zeros(0)]
    for term in goal.terms:
        if isinstance(term, Effort):
            parts.append(np.sqrt(term.weight) * effort_residuals(scene, values, chosen))
            continue
        miss = term_miss(scene, simulator, term, rollout)
        scale = term.within if isinstance(term, Reach) else term.within * np.sqrt(miss.shape[0])
        parts.append(miss / scale)
    return jnp.concatenate([jnp.ravel(p) for p in parts])


def met(goal: Goal, errors) -> bool:
    """Whether every Reach and Hold term is within its tolerance."""
    return all(float(e) <= t.within for t, e in zip(goal.terms, errors) if isinstance(t, (Reach, Hold)))
