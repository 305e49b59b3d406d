"""A scene as a controller's model: one control period ``x' = f(params, x, u)`` from any state,
pure JAX and differentiable in the state, the control and the physical unknowns.

The state ``x`` is (joint coordinates, joint velocities) in the scene's joint order (hinges
and sliders); the controls are the scene's control sequences, held over one period (the
spacing of their ``times``). The physical unknowns are every unknown but the control
sequences, chosen in the prior's unconstrained space (``problem.constrain``) so a refit stays
in the prior's support. ``f`` reuses the scene's compiled physics (``integrate.step`` over
the world's substeps), so the controller and the fit share one model.
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
from numpyro.distributions import biject_to
from numpyro.infer.util import potential_energy

from ..compile import Model
from ..errors import ModelError
from ..infer.multistart import prior_centre
from ..infer.problem import model_problem, unconstrained_layout, unraveler
from ..physics.integrate import start_state, step
from .cost import CONTROL, control_effects
from .problem import constrain, flat_slices

ROTATIONAL = ("hinge", "slider")


@dataclass(frozen=True)
class Transition:
    """The scene's one-period dynamics and the places of what the controller reads and sets."""

    model: Model
    joints: tuple[str, ...]  # scene joint names, the state's order
    qadr: np.ndarray  # (J,) their coordinates in the physics' q
    vadr: np.ndarray  # (J,) and in v
    controls: tuple[str, ...]  # control unknowns (``control_force@TARGET.values``)
    targets: tuple[str, ...]  # what each control acts on (a joint or body name)
    sites: tuple[int, ...]  # their places in the params' effect list
    period: float  # s: one control value is held this long
    horizon: int  # control values in the scene's sequence
    substeps: int  # physics steps per period
    physical: tuple[str, ...]  # unknowns refitted from transitions
    index: np.ndarray  # their places in the flat unconstrained vector
    centre: np.ndarray  # the flat unconstrained vector at the prior's centre
    hinges: tuple[bool, ...] = ()  # per joint: an angle (periodic) rather than a length

    @property
    def nx(self) -> int:
        return 2 * len(self.joints)

    @property
    def nu(self) -> int:
        return len(self.controls)

    def values(self, z) -> dict:
        """Every unknown's value (SI) with the physical ones at unconstrained ``z``."""
        return constrain(self.model, jnp.asarray(self.centre).at[self.index].set(z))

    def params(self, z) -> dict:
        """The physics' params pytree at unconstrained physical unknowns ``z``."""
        return self.model.simulator.params(self.values(z))

    def step(self, prm: dict, x, u):
        """The state one control period after ``x`` under forces ``u`` (nu,), SI."""
        pm = self.model.simulator.model
        effects = list(prm["effects"])
        for site, value in zip(self.sites, u):
            effects[site] = dict(effects[site], values=jnp.full((self.horizon,), value))
        prm = dict(prm, effects=effects)
        q = prm["q0"].astype(x.dtype).at[self.qadr].set(x[:len(self.joints)])
        v = prm["v0"].astype(x.dtype).at[self.vadr].set(x[len(self.joints):])
        s = start_state(pm, q, v)
        h = self.period / self.substeps
        s = jax.lax.fori_loop(0, self.substeps, lambda k, s: step(pm, prm, s, k * h, h), s)
        return jnp.concatenate([s.q[self.qadr], s.v[self.vadr]])

    def neg_log_prior(self, z):
        """-log prior density of the physical unknowns at unconstrained ``z`` (with the
        Jacobian of the prior's transform; the held control sequences add a constant)."""
        unravel, _ = unraveler(unconstrained_layout(self.model))
        x = jnp.asarray(self.centre).at[self.index].set(z)
        return potential_energy(self.model.prior_values, (), {}, unravel(x))

    def physical_values(self, z) -> dict[str, np.ndarray]:
        """The physical unknowns' values (SI) at unconstrained ``z``."""
        values = self.values(jnp.asarray(z))
        return {n: np.asarray(values[n]) for n in self.physical}


def build_transition(model: Model) -> Transition:
    """The Transition of ``model``: a scene of hinges and sliders, with unknown control
    sequences on an even time grid (their spacing is the control period)."""
    pm = model.simulator.model
    scene = model.scene
    joints, qadr, vadr, hinges = [], [], [], []
    for tj in pm.joints:
        if tj.scene_joint is None:
            continue
        if tj.kind not in ROTATIONAL:
            raise ModelError(f"mpc: joint '{scene.joints[tj.scene_joint].name}' is a {tj.kind}; "
                             "the controller's state holds hinges and sliders only")
        joints.append(pm.joint_names[tj.scene_joint])
        qadr.append(tj.qadr)
        hinges.append(tj.kind == "hinge")
        vadr.append(tj.vadr)
    if len(qadr) != pm.nq or len(vadr) != pm.nv:
        raise ModelError("mpc: every body must hang on a hinge or slider (no free bodies)",
                         hint="attach free bodies by joints, or control them open-loop "
                              "(`physdsl control`)")
    uses = control_effects(scene)
    unknown = set(model.unknown_names)
    controls = tuple(n for n in uses if n in unknown)
    if not controls:
        raise ModelError("mpc: the scene has no unknown control sequence to choose",
                         hint="write `control NAME on JOINT { times: (...) s  values ~ "
                              "uniform(-10 N, 10 N) }`; its times are the plan's grid")
    sites = tuple(next(s.index for s in pm.sites
                       if s.effect == CONTROL and scene.effects[s.index] is uses[n])
                  for n in controls)
    grids = [np.asarray(uses[n].tables["times"], dtype=float) for n in controls]
    period, horizon = _grid(grids, uses[controls[0]].span)
    substeps = int(round(period / (pm.dt / pm.substeps)))
    if not np.isclose(substeps * pm.dt / pm.substeps, period, rtol=1e-6, atol=1e-12):
        raise ModelError(f"mpc: the control period {period:g} s is not a whole number of the "
                         f"world's steps ({pm.dt / pm.substeps:g} s)",
                         span=uses[controls[0]].span)
    physical = tuple(n for n in model.unknown_names if n not in controls
                     and not n.endswith((".initial", ".initial_velocity")))
    slices = flat_slices(model)
    index = np.concatenate([np.arange(slices[n].start, slices[n].stop) for n in physical]
                           ) if physical else np.zeros(0, int)
    centre = np.asarray(prior_centre(model_problem(model), jax.random.PRNGKey(0)), dtype=float)
    targets = tuple(uses[n].key.split("@", 1)[1] for n in controls)
    return Transition(model, tuple(joints), np.asarray(qadr), np.asarray(vadr), controls, targets,
                      sites, period, horizon, substeps, physical, index.astype(int), centre,
                      tuple(hinges))


def _grid(grids: list[np.ndarray], span) -> tuple[float, int]:
    """(period, length) of the controls' shared, evenly spaced time grid."""
    first = grids[0]
    if len(first) < 2 or any(len(g) != len(first) or not np.allclose(g, first) for g in grids):
        raise ModelError("mpc: the control sequences need one shared grid of at least two times",
                         span=span)
    gaps = np.diff(first)
    if not np.allclose(gaps, gaps[0], rtol=1e-6) or gaps[0] <= 0:
        raise ModelError("mpc: control times must be evenly spaced (the spacing is the control "
                         "period)", span=span)
    return float(gaps[0]), len(first)


def control_bounds(model: Model, controls: tuple[str, ...]):
    """w -> u for each control: the prior's bijection from unconstrained values to its support
    (``uniform(-10 N, 10 N)`` keeps every force within 10 N), as one function of (nu,) -> (nu,)."""
    with numpyro.handlers.trace() as tr, numpyro.handlers.seed(rng_seed=0):
        model.prior_values()
    maps = [biject_to(tr[n]["fn"].support) for n in controls]
    shapes = [np.shape(tr[n]["value"]) for n in controls]

    def squash(w):
        return jnp.stack([m(jnp.full(s, w[i])).reshape(-1)[0]
                          for i, (m, s) in enumerate(zip(maps, shapes))])

    return squash
