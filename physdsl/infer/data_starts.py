"""Starts from the data: initial-state unknowns set to what the first measured samples say.

A low-order polynomial (weighted least squares, in the quantity's geometry: angles unwrapped)
fitted to the first samples of every observed track gives the track's value and slope at
t = 0 with their standard errors. The unknowns the initial state depends on (those named in
bodies' poses and velocities and joints' anchors, axes and initial values) are then solved
for, by a small optimisation through the scene's own expressions and kinematics at t = 0 (no
rollout): the t = 0 predictions of every observed track matched to those estimates, plus the
prior. So a launch given as speed and angle is found as surely as a velocity vector, and the
result lies in the prior's support by construction (it is optimised in unconstrained space).
Every other unknown keeps the value of the start it is given (a prior draw).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import constrain_fn, potential_energy
from scipy.optimize import minimize

from ..ahead import Program
from ..expr import evaluate, references
from ..observe import trajectory
from ..physics.simulator import observe
from .base import cached
from .problem import unconstrained_layout, unraveler

WINDOW_S = 0.2  # at most the first 0.2 s of a track ...
WINDOW_SAMPLES = 20  # ... and at most 20 samples
MIN_SAMPLES = 4  # fewer measured samples in the window: no estimate from that track
DEGREE = 2  # constant acceleration over the window (a throw under gravity is exact)
MISFIT = 2.0  # a window whose polynomial misses its samples by more (RMS, noise units) holds
# an event (an impact, a release): it is halved until it fits, or the track is not used

# quantity -> index into physics.simulator.observe's outputs (pos, quat, lin, ang, jp, jv) of
# its value, and of its slope's (None: the slope is not a state quantity)
SOURCES = {"position": (0, 2), "orientation": (1, None), "velocity": (2, None),
           "angular_velocity": (3, None), "angle": (4, 5), "angular_rate": (5, None)}


@dataclass(frozen=True)
class Estimate:
    """A track's value (and slope) at t = 0 from its first samples, with standard errors."""

    obs: str  # observation name
    quantity: str
    target: str
    value: np.ndarray  # (D,) (a unit quaternion for orientations)
    value_sd: np.ndarray  # (K,) per residual axis
    slope: np.ndarray | None  # (D,) per second
    slope_sd: np.ndarray | None
    samples: int
    recording: int | None = None  # its recording's index in a pooled Model (physdsl/pooled.py)


def track_estimates(scene, observations=None) -> list[Estimate]:
    """Value and slope at t = 0 of every observed trajectory that starts near t = 0 (of
    ``observations``, default the scene's)."""
    out = []
    markers = {m.name for m in scene.markers}  # points on bodies, not body states
    for o in scene.observations if observations is None else observations:
        if o.quantity not in SOURCES or not len(o.times) or o.times[0] > WINDOW_S / 2 \
                or o.target in markers:
            continue
        est = _estimate(o)
        if est is not None:
            out.append(est)
    return out


def _estimate(o) -> Estimate | None:
    rows = np.flatnonzero(o.mask.all(axis=1) & (o.times <= o.times[0] + WINDOW_S))[:WINDOW_SAMPLES]
    t, y = o.times[rows], np.array(o.values[rows], dtype=float)
    if o.quantity == "angle":
        y = np.unwrap(y, axis=0)
    elif o.quantity == "orientation":  # one hemisphere, then components fitted as numbers
        y = y * np.where(y @ y[0] < 0, -1.0, 1.0)[:, None]
    sigma = _noise(o, y.shape[1])
    while len(t) >= MIN_SAMPLES:
        deg = min(DEGREE, len(t) - 2)
        X = np.vander(t, deg + 1, increasing=True)  # columns 1, t, t^2: value and slope at 0
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        resid = y - X @ coef
        scale = sigma if sigma is not None else np.sqrt(
            np.sum(resid**2, axis=0) / max(len(t) - deg - 1, 1)) + 1e-12
        if np.sqrt(np.mean((resid / scale) ** 2)) <= MISFIT:
            cov = np.linalg.inv(X.T @ X)
            value, slope = coef[0], coef[1]
            sd0, sd1 = scale * np.sqrt(cov[0, 0]), scale * np.sqrt(cov[1, 1])
            if o.quantity == "orientation":
                value = value / np.linalg.norm(value)
                sd0 = np.full(3, 2.0 * float(np.max(sd0)))  # rotation-vector axes
            has_slope = SOURCES[o.quantity][1] is not None
            return Estimate(o.name, o.quantity, o.target, value, sd0,
                            slope if has_slope else None, sd1 if has_slope else None, len(t))
        t, y = t[: len(t) // 2], y[: len(y) // 2]
    return None


def _noise(o, d: int) -> np.ndarray | None:
    """The observation's noise scale per column when it is a known number, else None."""
    try:
        s = np.asarray(evaluate(o.noise.scale, {}), dtype=float)
    except Exception:  # noqa: BLE001 - a noise scale that is itself unknown: estimated instead
        return None
    return np.broadcast_to(s, (d,)) if s.size in (1, d) else np.full(d, float(np.max(s)))


def initial_state_unknowns(scene) -> set[str]:
    """Unknowns the state at t = 0 depends on (poses, velocities, joints' geometry and values)."""
    exprs = [e for b in scene.bodies
             for e in (b.position, b.orientation, b.velocity, b.angular_velocity)]
    exprs += [e for j in scene.joints
              for e in (j.anchor, j.axis, j.initial, j.initial_velocity)]
    names = set().union(*(references(e) for e in exprs if e is not None))
    return names & {u.name for u in scene.unknowns if not u.discrete}


def data_start(problem, x0, others=()) -> np.ndarray | None:
    """``x0`` (flat unconstrained) with its initial-state unknowns fitted to the first samples
    of the data (see the module's docstring); None where the data say nothing about them.
    ``others``: more flat points whose initial-state coordinates are tried as starts of that
    small fit (the best result wins)."""
    found = _objective(problem)
    if found is None:
        return None
    fn, mask = found
    x0 = np.asarray(x0, dtype=float)
    best = None
    for start in (x0, *(np.asarray(o, dtype=float) for o in others)):
        def f(z, start=start):
            v, g = fn(jnp.asarray(np.where(mask, _fill(mask, z), x0)))
            return float(v), np.asarray(g, dtype=float)[mask]

        z0 = start[mask]
        if not np.isfinite(f(z0)[0]):
            continue
        res = minimize(f, z0, jac=True, method="BFGS", options={"maxiter": 200, "gtol": 1e-8})
        if np.isfinite(res.fun) and (best is None or res.fun < best[0]):
            best = (float(res.fun), res.x)
    if best is None:
        return None
    return np.where(mask, _fill(mask, best[1]), x0)


def model_estimates(model) -> list[Estimate]:
    """The track estimates of ``model``'s data: of each recording, for a pooled Model."""
    if getattr(model, "recordings", None) is None:
        return track_estimates(model.scene)
    return [replace(e, recording=r) for r, rec in enumerate(model.recordings)
            for e in track_estimates(model.scene, rec.observations)]


def _fill(mask, z):
    out = np.zeros(mask.shape)
    out[mask] = z
    return out


def data_start_ahead(problem) -> None:
    """Start compiling ``data_start``'s program (``physdsl.ahead``); nothing where it has none."""
    found = _program(problem)
    if found is not None:
        program, numbers, _ = found
        program.ahead(jax.ShapeDtypeStruct((problem.dim,), jnp.result_type(float)), numbers)


def _objective(problem):
    """(x -> (misfit at t = 0 + negative log prior, gradient), mask of x's initial-state
    coordinates); None where the data say nothing about the initial state."""
    found = _program(problem)
    if found is None:
        return None
    program, numbers, mask = found
    return (lambda x: program(x, numbers)), mask


def _program(problem):
    """(compiled (x, numbers) -> (misfit, gradient), the data's numbers, mask of x's
    coordinates that belong to the initial-state unknowns), or None where there are none or
    no track says anything about them. The estimates' numbers are arguments of the compiled
    program, not constants in it, so another recording of the same scene reuses it
    (physdsl/cache.py)."""
    model = problem.model
    names = tuple(sorted(initial_state_unknowns(model.scene)))
    estimates = model_estimates(model)
    if not names or not estimates:
        return None
    sim = model.simulator

    layout = unconstrained_layout(model)
    unravel, _ = unraveler(layout)
    leaves = jax.tree_util.tree_leaves_with_path(layout)
    mask = np.concatenate([np.full(int(np.prod(leaf.shape)), _key(path) in names)
                           for path, leaf in leaves]) if leaves else np.zeros(0, bool)
    if not mask.any():
        return None

    numbers = [tuple(None if a is None else jnp.asarray(a, dtype=float)
                     for a in (e.value, e.value_sd, e.slope, e.slope_sd)) for e in estimates]
    # one compiled program per structure and set of tracks: the start from the data and the
    # prior draws thrown as the data say (``multistart``) share it (each compiled its own)
    key = ("data-start-misfit", names, tuple((e.quantity, e.target, e.recording,
                                              e.slope is None) for e in estimates))
    program = cached(problem, key, lambda: Program(jax.value_and_grad(
        _misfit(model, sim, estimates, unravel))))
    return program, numbers, mask


def _misfit(model, sim, estimates, unravel):
    """(x, numbers) -> misfit at t = 0 of the ``estimates`` (their numbers an argument) plus
    the negative log prior."""
    def misfit(x, numbers):
        u = unravel(x)
        values = constrain_fn(model.prior_values, (), {}, u)
        states = {}  # the state at t = 0 of each recording (one: None)
        total = potential_energy(model.prior_values, (), {}, u)
        for e, (value, value_sd, slope, slope_sd) in zip(estimates, numbers):
            if e.recording not in states:
                prm = sim.params(values if e.recording is None
                                 else model.recording_values(values, e.recording))
                states[e.recording] = observe(sim.model, prm, prm["q0"], prm["v0"])
            state = states[e.recording]
            i_val, i_slope = SOURCES[e.quantity]
            idx = (sim.body_names if i_val < 4 else sim.joint_names).index(e.target)
            pred = state[i_val][idx].reshape(-1)
            r = trajectory.residual(e.quantity, pred[None], value[None])[0]
            total = total + 0.5 * jnp.sum((r / value_sd) ** 2)
            if slope is not None:
                ps = state[i_slope][idx].reshape(-1)
                total = total + 0.5 * jnp.sum(((ps - slope) / slope_sd) ** 2)
        return total

    return misfit


def _key(path) -> str:
    return str(getattr(path[0], "key", path[0]))


__all__ = ["Estimate", "data_start", "initial_state_unknowns", "track_estimates"]
