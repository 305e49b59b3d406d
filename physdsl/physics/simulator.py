"""Simulator: a Scene compiled to a pure, jitted ``simulate(values) -> Rollout``.

The static PhysicsModel is built once; each call evaluates the params from ``values`` inside the
traced function, scans ``step`` over the recorded times and reads body and joint observables
from the states. Free bodies under central effects alone (``central.decoupled``) scan their
translation and rotation separately, and a caller that names the fields it reads
(``simulate(values, fields)``) gets no rotation it does not read. Derivatives of the
trajectory use forward mode for few unknowns (``forward.forward_mode``), else reverse mode with
``jax.checkpoint`` on each step (O(T) memory).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..ahead import Program
from ..scene import Scene
from . import central, idle
from .forward import FORWARD_MODE_MAX, forward_mode
from .integrate import State, kinematics, start_state, step
from .markers import marker_tracks
from .model import build_model
from .params import evaluate_params
from .rows import place
from .structure import PhysicsModel


class Rollout(NamedTuple):
    t: jnp.ndarray  # (T,)
    q: jnp.ndarray  # (T, nq)
    v: jnp.ndarray  # (T, nv)
    body_pos: jnp.ndarray  # (T, B, 3) body frame origins (= COM for primitives)
    body_quat: jnp.ndarray  # (T, B, 4) (w, x, y, z) body -> world
    body_vel: jnp.ndarray  # (T, B, 3) world linear velocity of the origin
    body_angvel: jnp.ndarray  # (T, B, 3) world angular velocity
    joint_pos: jnp.ndarray  # (T, J) hinge angle / slider displacement, 0 for other kinds
    joint_vel: jnp.ndarray  # (T, J)
    contact_force: jnp.ndarray  # (T, C) normal force per candidate contact (0 when apart)
    marker_pos: jnp.ndarray | None = None  # (T, M, 3) markers' world positions
    marker_vel: jnp.ndarray | None = None  # (T, M, 3) markers' world velocities


def observe(model: PhysicsModel, prm: dict, q, v):
    """Body poses/velocities and scene-joint coordinates at one state."""
    kin = kinematics(model, prm, q, v)
    w = kin.ang
    lin = kin.vcom + jnp.cross(w, kin.pos - kin.com)
    jp, jv = [], []
    for name_idx in range(len(model.joint_names)):
        tj = next((j for j in model.joints if j.scene_joint == name_idx), None)
        if tj is not None and tj.kind in ("hinge", "slider"):
            jp.append(q[tj.qadr])
            jv.append(v[tj.vadr])
        else:
            jp.append(jnp.zeros((), q.dtype))
            jv.append(jnp.zeros((), q.dtype))
    stack = lambda xs: jnp.stack(xs) if xs else jnp.zeros(0, q.dtype)  # noqa: E731
    return kin.pos, kin.quat, lin, w, stack(jp), stack(jv)


def _recorded(state):
    """What a rollout records of a state: all but the contact solver's warm start."""
    return state._replace(lcp_warm=None) if isinstance(state, State) else state


class Simulator:
    """Compiled simulation of one Scene; ``simulate`` is pure in ``values`` and jit/vmap/grad-able."""

    def __init__(self, scene: Scene, model: PhysicsModel):
        self.scene = scene
        self.model = model
        self.body_names = model.body_names
        self.joint_names = model.joint_names
        self.marker_names = tuple(m.name for m in scene.markers)
        n = model.nsteps
        self.times = np.arange(n + 1) * model.dt
        self.integrator = model.integrator  # between contacts (``integrate.step``)
        free = idle.free_scene(scene, model)  # contacts that may never come near (``idle``)
        self._free = None if free is None else Simulator(*free)
        self.trace_count = 0
        self._jit = Program(self._simulate, static_argnums=(1,))

    def identify(self, structure: str) -> None:
        """Name the compiled rollout by ``structure`` (a hash of this Simulator's scene and of
        its contact pairs) so that later processes load its trace (``physdsl.traces``)."""
        self._jit.identity = f"{structure}/simulate"

    def params(self, values) -> dict:
        """The numeric params pytree for ``values`` (masses, inertia, poses, effects, q0, v0)."""
        return evaluate_params(self.scene, self.model, values)

    def _trajectory(self, prm: dict, checkpoint: bool):
        """States (q (T+1, nq), v (T+1, nv), contact normal force (T+1, C)) for params ``prm``;
        ``checkpoint``: recompute each step in reverse mode (O(T) memory)."""
        model = self.model
        dtype = prm["ref_pos"].dtype
        s0 = start_state(model, prm["q0"].astype(dtype), prm["v0"].astype(dtype))
        # not checkpointed: differentiated in forward mode alone (``integrate.either``)
        traj = self._scan(lambda s, t, h: step(model, prm, s, t, h, not checkpoint), s0,
                          checkpoint)
        return traj.q, traj.v, traj.contact_force

    def _translation(self, prm: dict, checkpoint: bool) -> central.Translation:
        """Free bodies under central effects (``central.decoupled``): their translation alone."""
        model = self.model
        s0, _ = central.split(model, prm["q0"], prm["v0"])
        fr = central.frame(model, prm)
        return self._scan(lambda s, t, h: central.translation_step(model, prm, fr, s, t, h), s0,
                          checkpoint)

    def _rotation(self, prm: dict, checkpoint: bool) -> central.Rotation:
        """Free bodies under central effects: their torque-free rotation alone."""
        model = self.model
        _, s0 = central.split(model, prm["q0"], prm["v0"])
        return self._scan(lambda s, t, h: central.rotation_step(model, prm, s, h), s0, checkpoint)

    def _scan(self, advance, s0, checkpoint: bool):
        """``s0`` and the state after each recorded step (pytree of (T+1, ...) leaves), by
        ``advance(state, t, h)`` over the model's substeps; a contact solver's warm start
        (``State.lcp_warm``) is carried, not recorded."""
        model = self.model
        h = model.dt / model.substeps
        ns = model.substeps

        def substep(state, k):
            return advance(state, k * h, h), None

        def record(state, i):
            if ns == 1:
                state = advance(state, i * h, h)
            else:
                state, _ = jax.lax.scan(substep, state, i * ns + jnp.arange(ns))
            return state, _recorded(state)

        if checkpoint:
            record = jax.checkpoint(record)
        _, traj = jax.lax.scan(record, s0, jnp.arange(model.nsteps))
        return jax.tree_util.tree_map(lambda a, b: jnp.concatenate([a[None], b]),
                                      _recorded(s0), traj)

    def _simulate(self, values, fields=None) -> Rollout:
        self.trace_count += 1
        n_in = sum(int(np.size(x)) for x in jax.tree_util.tree_leaves(values)
                   if jnp.issubdtype(jnp.result_type(x), jnp.floating))
        if 0 < n_in <= FORWARD_MODE_MAX:
            return forward_mode(lambda v: self._rollout(v, fields, False))(values)
        return self._rollout(values, fields, True)

    def _rollout(self, values, fields, checkpoint: bool, fly_first: bool = True) -> Rollout:
        """The Rollout for ``values`` (only ``fields``, if given, are sure to be filled);
        ``fly_first``: contact scenes of free bodies fly first (``idle``)."""
        model = self.model
        prm = evaluate_params(self.scene, model, values)
        if fly_first and self._free is not None:
            return idle.free_unless_near(
                model, prm, self._free._rollout(values, fields, checkpoint),
                lambda vals: self._rollout(vals, fields, checkpoint, False), values,
                not checkpoint)
        t = jnp.arange(model.nsteps + 1, dtype=prm["ref_pos"].dtype) * model.dt
        if central.decoupled(model):
            # each part on its own, the rotation only for a caller that reads it
            tr = self._translation(prm, checkpoint)
            fb = model.free_bodies
            pos = jax.vmap(lambda x: place(prm["ref_pos"], fb, x))(tr.x)
            lin = jax.vmap(lambda v: place(jnp.zeros_like(prm["ref_pos"]), fb, v))(tr.v)
            cf = jnp.zeros((len(t), 0), t.dtype)
            if fields is not None and set(fields) <= TRANSLATION_FIELDS:
                return Rollout(t, None, None, pos, None, lin, None, None, None, cf)
            q, v = central.join(tr, self._rotation(prm, checkpoint))
        else:
            q, v, cf = self._trajectory(prm, checkpoint)
        obs = jax.vmap(lambda q, v: observe(model, prm, q, v))(q, v)
        if central.decoupled(model):  # the same values, read off the translation alone
            obs = (pos, obs[1], lin) + obs[3:]
        if not self.scene.markers:
            return Rollout(t, q, v, *obs, cf)
        return Rollout(t, q, v, *obs, cf, *marker_tracks(self.scene, self.body_names, values,
                                                        *obs[:4]))

    def simulate(self, values, fields: tuple[str, ...] | None = None) -> Rollout:
        """Roll the scene out from t = 0 to the last recorded time for the unknowns' ``values``.

        ``fields``: the Rollout fields the caller reads (default all); others may be None, and
        what they alone need is then neither traced nor compiled.
        """
        values = canonical_values(values)
        fields = None if fields is None else tuple(sorted(fields))
        if is_traced(values):
            # inside a traced function: inline (a nested jit would be linearized as a whole,
            # partial-evaluating the forward-mode scan again, for nothing: XLA inlines it anyway)
            return self._simulate(values, fields)
        return self._jit(values, fields)

    def simulate_ahead(self, values, fields: tuple[str, ...] | None = None) -> None:
        """Start compiling ``simulate(values, fields)`` in the background (``ahead``);
        ``values`` may be ``jax.ShapeDtypeStruct``s."""
        fields = None if fields is None else tuple(sorted(fields))
        self._jit.ahead(jax.eval_shape(canonical_values, values), fields)


# Rollout fields of a decoupled scene (``central.decoupled``) that need no rotation
TRANSLATION_FIELDS = {"t", "body_pos", "body_vel", "contact_force"}


def canonical_values(values) -> dict:
    """``values`` as a compiled rollout takes them (``_canonical``): one compile for equal types."""
    return {k: _canonical(v) for k, v in dict(values).items()}


def is_traced(values) -> bool:
    """Whether ``values`` hold tracers (a call from inside a traced function), not numbers."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(values))


def _canonical(x):
    """Floats as strong-typed default-float arrays, so 0.5 and jnp.float64(0.5) share one compile."""
    a = jnp.asarray(x)
    if jnp.issubdtype(a.dtype, jnp.floating) or jnp.issubdtype(a.dtype, jnp.integer) and a.ndim > 0:
        return jnp.asarray(a, dtype=jnp.result_type(float))
    return a


def build_simulator(scene: Scene) -> Simulator:
    """Compile ``scene`` into a Simulator; raises ModelError for unsupported structure."""
    return Simulator(scene, build_model(scene))
