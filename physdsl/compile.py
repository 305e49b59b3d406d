"""Compile a checked Scene into a Model: a numpyro program plus pure JAX functions.

The numpyro program has one ``sample`` site per unknown (its prior, numpyro's own
distributions with their supports and transforms), the deterministic rollout of the physics
engine, a deterministic ``pred:<observation>`` site per observable (the noise-free
prediction at the data's times), and one observed site ``obs:<observation>`` per observation whose value is the
residual (measured - predicted, in the quantity's geometry) under the noise model.

The measurements are an argument of the program (``Model.data``: measured values, masks and
interpolation weights), not constants in it, so Models of one scene structure with other
data or another ``until`` share one simulator and one set of compiled functions
(``Model.compiled``, keyed by ``structure_key``).
"""
from __future__ import annotations

import dataclasses
import hashlib
import weakref
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from .ahead import ProgramCache, build_once
from .errors import ModelError, PhysTypeError
from .expr import evaluate, references
from .observe import sensor, trajectory
from .physics import build_simulator
from .physics.idle import clearance
from .physics.ruled_out import ruled_out_pairs, without_pairs
from .render.likelihood import scene_image_log_likelihood
from .scene import Observation, Prior, Scene, Unknown
from .syntax import load, loads
from .syntax.dists import find

PRED_PREFIX = "pred:"
OBS_PREFIX = "obs:"


def build_distribution(prior: Prior, values, shape: tuple[int, ...]):
    """The numpyro distribution of ``prior`` with event shape ``shape`` (arguments evaluated).

    Without numpyro's sample validation: a value in the potential comes through the prior's own
    transform, so it is in the support by construction, and a non-finite log density is caught
    by ``safe_logdensity``; the check would only add a select to every log-probability.
    """
    cls = find(prior.dist)
    if cls is None:  # the checker resolved the same name with the same table
        raise PhysTypeError(f"unknown distribution '{prior.dist}'")
    args = [evaluate(a, values) for a in prior.args]
    kwargs = {k: evaluate(v, values) for k, v in prior.kwargs}
    d = cls(*args, **kwargs, validate_args=False)
    event_dims = len(d.event_shape)
    batch_needed = shape[: len(shape) - event_dims] if event_dims else shape
    if tuple(d.batch_shape) != tuple(batch_needed):
        d = d.expand(tuple(batch_needed))
    if batch_needed:
        d = d.to_event(len(batch_needed))
    return d


def dependency_order(unknowns: tuple[Unknown, ...]) -> list[Unknown]:
    """Unknowns ordered so that each prior's arguments refer only to earlier ones."""
    by_name = {u.name: u for u in unknowns}
    done: list[Unknown] = []
    seen: set[str] = set()

    def visit(u: Unknown, stack: tuple[str, ...]):
        if u.name in seen:
            return
        if u.name in stack:
            raise ModelError(f"unknowns depend on each other in a cycle: {' -> '.join(stack + (u.name,))}",
                             u.span)
        deps = set()
        for a in list(u.prior.args) + [v for _, v in u.prior.kwargs]:
            deps |= references(a)
        for d in sorted(deps):
            if d in by_name:
                visit(by_name[d], stack + (u.name,))
        seen.add(u.name)
        done.append(u)

    for u in unknowns:
        visit(u, ())
    return done


@dataclass(frozen=True)
class ObservedTrajectory:
    """An observation prepared for the likelihood: static interpolation and filled data."""

    obs: Observation
    interp: trajectory.Interpolation
    measured: np.ndarray  # (N, D), missing cells filled with harmless values
    mask: np.ndarray  # (N, K) residual mask

    def data(self) -> dict:
        """The arrays the compiled program takes for this observation (see ``Model.data``)."""
        return {"measured": self.measured, "mask": self.mask, "rows": self.interp.rows,
                "w": self.interp.w}


def structure_key(scene: Scene) -> str:
    """Hash of everything in ``scene`` that its compiled functions depend on.

    Trajectory measurements enter as arguments, so only their shapes count (values, masks,
    times, file names and source positions do not); everything else (bodies, effects and
    their tables, priors, noise models, image frames, the simulated duration) is hashed.
    """
    h = hashlib.sha256()
    ex = scene.experiments
    if ex is not None:  # recordings: their names and settings, their data's shapes
        ex = dataclasses.replace(ex, source=Path(), span=None, recordings=tuple(
            dataclasses.replace(r, folder=Path(), row=None, observations=tuple(
                _structure_of(o) for o in r.observations)) for r in ex.recordings))
    _hash_walk(h, dataclasses.replace(
        scene, path=None, source="", experiments=ex,
        observations=tuple(_structure_of(o) for o in scene.observations)))
    h.update(repr(scene.duration).encode())
    return h.hexdigest()


def _structure_of(obs: Observation):
    if obs.quantity not in trajectory.QUANTITIES:
        return dataclasses.replace(obs, file=Path(), span=None)
    return dataclasses.replace(obs, file=Path(), span=None, times=np.shape(obs.times),
                               values=np.shape(obs.values), mask=np.shape(obs.mask))


def _hash_walk(h, x) -> None:
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        h.update(f"<{type(x).__qualname__}".encode())
        for f in dataclasses.fields(x):
            if f.name != "span":
                h.update(f.name.encode())
                _hash_walk(h, getattr(x, f.name))
        h.update(b">")
    elif isinstance(x, dict) or hasattr(x, "items") and hasattr(x, "keys"):
        h.update(b"{")
        for k in sorted(x.keys(), key=repr):
            _hash_walk(h, k)
            _hash_walk(h, x[k])
        h.update(b"}")
    elif isinstance(x, (tuple, list)):
        h.update(b"(")
        for v in x:
            _hash_walk(h, v)
        h.update(b")")
    elif isinstance(x, np.ndarray):
        h.update(f"a{x.shape}{x.dtype}".encode())
        h.update(np.ascontiguousarray(x).tobytes())
    else:
        h.update(f"{type(x).__name__}:{x!r};".encode())


class Compiled:
    """What Models of one scene structure share: the simulator, the simulator the likelihood
    reads (without the contact pairs the recording rules out, ``ruled_out``) and a cache of
    compiled functions.

    ``cache`` maps a name (e.g. a backend's transition) to a jitted function whose arguments
    include the data, so it serves every Model of the structure and of the same ``ruled_out``;
    its programs, and the simulators' rollouts, are named by ``key`` and ``ruled_out`` so that
    later processes load their traces (``physdsl.traces``).
    """

    def __init__(self, scene: Scene, key: str, ruled_out: tuple[int, ...] = (), simulator=None):
        self.simulator = build_simulator(scene) if simulator is None else simulator
        self.simulator.identify(key)
        self.ruled_out = ruled_out
        identity = key if not ruled_out else f"{key}:without{ruled_out}"
        self.likelihood_simulator = self.simulator if not ruled_out else build_simulator(
            without_pairs(scene, self.simulator.model, ruled_out))
        self.likelihood_simulator.identify(identity)
        self.cache = ProgramCache(identity)


# structure key -> Compiled, alive while some Model holds it
_COMPILED: "weakref.WeakValueDictionary[str, Compiled]" = weakref.WeakValueDictionary()


# other kinds of Model by name: "pooled", a scene with experiments (physdsl/pooled.py)
MODEL_KINDS: dict = {}


class Model:
    """A compiled scene: simulate, predict, the likelihood and the numpyro program (inference,
    checks and diagnosis are functions over it: ``physdsl.api``). A scene with
    ``experiments`` makes a ``pooled.PooledModel`` (many recordings)."""

    def __new__(cls, scene: Scene, until: float | None = None, every_contact: bool = False):
        if cls is Model and getattr(scene, "experiments", None) is not None:
            cls = MODEL_KINDS["pooled"]
        return super().__new__(cls)

    def __init__(self, scene: Scene, until: float | None = None, every_contact: bool = False):
        self.scene = scene
        self.until = until  # fit only measurements up to this time (leave-future-out)
        key = structure_key(scene)
        compiled = _COMPILED.get(key)
        if compiled is None:
            compiled = _COMPILED[key] = Compiled(scene, key)
        self.simulator = compiled.simulator
        # the contact pairs the recording rules out: the likelihood simulates without them
        ruled_out = () if every_contact else self._ruled_out()
        if ruled_out:
            key_fit = f"{key}:without{ruled_out}"
            fit = _COMPILED.get(key_fit)
            if fit is None:
                fit = _COMPILED[key_fit] = Compiled(scene, key, ruled_out, compiled.simulator)
            compiled = fit
        self.compiled = compiled
        self.ruled_out = compiled.ruled_out
        self.likelihood_simulator = compiled.likelihood_simulator
        self.unknowns = tuple(dependency_order(scene.unknowns))
        self.observed = tuple(self._prepare(o) for o in scene.observations
                              if o.quantity in trajectory.QUANTITIES)
        self.images = tuple(o for o in scene.observations if o.quantity == "image")
        # the rollout fields the likelihood reads (all when images are rendered from it)
        self.rollout_fields = None if self.images else tuple(sorted(
            {"t"} | {trajectory.source(o.obs, self.simulator) for o in self.observed}))

    # -- pieces -------------------------------------------------------------------------
    def _ruled_out(self) -> tuple[int, ...]:
        """The contact pairs the recording rules out (``physics.ruled_out``)."""
        return ruled_out_pairs(self.scene, self.simulator.model)

    def with_every_contact(self) -> "Model":
        """This Model with every contact pair in its likelihood (where a fit without the pairs
        the recording ruled out came within their reach: ``contact_reached``)."""
        return type(self)(self.scene, self.until, every_contact=True)

    def left_out_clearance(self, values, rollout):
        """How far (m) ``rollout`` (the likelihood's, at ``values``; it has the bodies'
        positions and velocities) stays beyond the reach of the contact pairs the likelihood
        leaves out, at the closest: ``idle.clear``'s rule, under which the rollout with every
        pair is this one, holds where positive (traced)."""
        full = self.simulator
        return clearance(full.model, full.params(values), rollout.body_pos, rollout.body_vel,
                         self.ruled_out)

    def contact_reached(self, values) -> np.ndarray:
        """Per draw of ``values`` (name -> (n, *shape)), whether its rollout comes within reach
        of a pair the likelihood leaves out (``left_out_clearance`` not positive); all False
        where no pair is left out."""
        n = len(next(iter(values.values()))) if values else 1
        if not self.ruled_out:
            return np.zeros(n, bool)

        def build():
            def reached(v):
                roll = self.likelihood_simulator.simulate(v, ("body_pos", "body_vel", "t"))
                return self.left_out_clearance(v, roll) <= 0.0
            return jax.jit(lambda vs: jax.lax.map(reached, vs))

        return np.asarray(self.cached("contact-reached", build)(
            {k: jnp.asarray(v) for k, v in values.items()}))

    def _prepare(self, obs: Observation) -> ObservedTrajectory:
        interp = trajectory.interpolation(np.asarray(self.simulator.times), obs.times, str(obs.file))
        measured = np.where(obs.mask, obs.values, 0.0)
        if obs.quantity == "orientation":
            missing = ~obs.mask.all(axis=1)
            measured[missing] = (1.0, 0.0, 0.0, 0.0)
        mask = trajectory.residual_mask(obs)
        if self.until is not None:
            mask = mask & (obs.times <= self.until)[:, None]
        return ObservedTrajectory(obs, interp, measured, mask)

    @property
    def data(self) -> dict:
        """The measurements as the program's argument: name -> {measured, mask, rows, w}."""
        return {o.obs.name: o.data() for o in self.observed}

    @property
    def unknown_names(self) -> tuple[str, ...]:
        return tuple(u.name for u in self.unknowns)

    def simulate(self, values):
        """Rollout of the scene for the unknowns' ``values`` (name -> array)."""
        return self.simulator.simulate(values)

    def fit_simulate(self, values):
        """The rollout the likelihood reads (``likelihood_simulator``: without the contact
        pairs the recording rules out; equal to ``simulate``'s where ``contact_reached`` is
        False, but for their contact forces)."""
        return self.likelihood_simulator.simulate(values)

    def fit_simulate_ahead(self, values) -> None:
        """Start compiling ``fit_simulate(values)`` in the background (``physdsl.ahead``);
        ``values`` may be ``jax.ShapeDtypeStruct``s."""
        self.likelihood_simulator.simulate_ahead(values)

    def rollout_of(self, rollout, obs_name: str):
        """The part of ``simulate``'s rollout that observation ``obs_name`` is read from (a
        pooled Model's rollout holds every recording's)."""
        return rollout

    def written_name(self, obs_name: str) -> str:
        """Observation ``obs_name``'s name as the scene writes it (a pooled Model names each
        recording's copy ``ball.position[07]``)."""
        return obs_name

    def recording_rollouts(self, rollout) -> list:
        """``simulate``'s rollout as one rollout per recording (one here)."""
        return [rollout]

    def predict(self, values, rollout=None, data=None):
        """Noise-free predictions of every trajectory observation: name -> (N, D)."""
        if rollout is None:
            rollout = self.likelihood_simulator.simulate(values, self.rollout_fields)
        data = self.data if data is None else data
        return {o.obs.name: sensor.predict(rollout, self.simulator, o.obs, _interp(data[o.obs.name]),
                                           values)
                for o in self.observed}

    def noise_scale(self, obs: Observation, values):
        """Noise scale of ``obs`` per residual axis: (K,)."""
        k = len(trajectory.axes(obs.quantity))
        return jnp.broadcast_to(jnp.asarray(evaluate(obs.noise.scale, values), dtype=float), (k,))

    def noise_distribution(self, obs: Observation, values, loc):
        scale = self.noise_scale(obs, values)
        if obs.noise.kind == "student_t":  # (residuals are real: no validation, as priors)
            df = evaluate(obs.noise.df, values) if obs.noise.df is not None else 4.0
            return dist.StudentT(df, loc, scale, validate_args=False)
        return dist.Normal(loc, scale, validate_args=False)

    def pointwise_log_likelihood(self, values, preds, data=None) -> dict:
        """Log-likelihood per measurement time (axes summed) given predictions: name -> (N,)."""
        data = self.data if data is None else data
        out = {}
        for o in self.observed:
            d = data[o.obs.name]
            res = self._residual(o.obs, preds[o.obs.name], d)
            lp = self.noise_distribution(o.obs, values, jnp.zeros_like(res)).log_prob(res)
            out[o.obs.name] = jnp.sum(jnp.where(d["mask"], lp, 0.0), axis=-1)
        return out

    def standardized_residuals(self, values, preds, data=None):
        """Every measured residual component over its noise scale, as one vector (0 where
        masked): the likelihood is -1/2 of its square sum plus noise-scale terms, for normal
        noise (``least_squares``)."""
        data = self.data if data is None else data
        return jnp.concatenate([
            (self._residual(o.obs, preds[o.obs.name], data[o.obs.name])
             / self.noise_scale(o.obs, values)).reshape(-1) for o in self.observed])

    @property
    def least_squares(self) -> bool:
        """Whether the likelihood is a sum of squared standardised residuals (normal noise on
        trajectories, no images): Gauss-Newton curvature then describes it."""
        return (not self.images and bool(self.observed)
                and all(o.obs.noise.kind != "student_t" for o in self.observed))

    @staticmethod
    def _residual(obs: Observation, pred, d):
        res = trajectory.residual(obs.quantity, pred, jnp.asarray(d["measured"]))
        return jnp.where(d["mask"], res, 0.0)

    # -- the probabilistic program --------------------------------------------------------
    def prior_values(self):
        """Sample every unknown from its prior inside a numpyro trace; returns name -> value."""
        values = {}
        for u in self.unknowns:
            values[u.name] = numpyro.sample(u.name, build_distribution(u.prior, values, u.shape))
        return values

    def numpyro_model(self, data=None):
        """The generative program: priors, rollout, predictions, noisy observations.

        ``data`` (default ``self.data``) holds the measurements; any Model of the same
        structure may pass its own.
        """
        data = self.data if data is None else data
        values = self.prior_values()
        rollout = self.likelihood_simulator.simulate(values, self.rollout_fields)
        for o in self.observed:
            d = data[o.obs.name]
            pred = sensor.predict(rollout, self.simulator, o.obs, _interp(d), values)
            numpyro.deterministic(PRED_PREFIX + o.obs.name, pred)
            res = self._residual(o.obs, pred, d)
            noise = self.noise_distribution(o.obs, values, jnp.zeros_like(res))
            numpyro.sample(OBS_PREFIX + o.obs.name, noise.mask(jnp.asarray(d["mask"])), obs=res)
        for obs in self.images:
            numpyro.factor(OBS_PREFIX + obs.name, self.image_log_likelihood(obs, rollout, values))

    def image_log_likelihood(self, obs: Observation, rollout, values):
        """Log-likelihood of one camera's frames given the rollout (see physdsl.render.likelihood)."""
        return scene_image_log_likelihood(self, obs, rollout, values)

    def log_likelihood(self, values, data=None):
        """Total log-likelihood of all trajectory measurements at ``values`` (scalar)."""
        ll = self.pointwise_log_likelihood(values, self.predict(values, data=data), data)
        return sum((jnp.sum(v) for v in ll.values()), jnp.zeros(()))

    def sample_prior(self, key, n: int) -> dict[str, np.ndarray]:
        """``n`` joint draws of every unknown from the prior: name -> (n, *shape)."""
        def build():
            def one(k):
                with numpyro.handlers.seed(rng_seed=k):
                    return self.prior_values()
            return jax.jit(jax.vmap(one))

        fn = self.cached("sample-prior", build)
        return {k: np.asarray(v) for k, v in fn(jax.random.split(key, n)).items()}

    def cached(self, key, build):
        """``self.compiled.cache[key]``, built once per scene structure (see ``Compiled``).

        Whatever ``build`` returns is shared by every Model of this structure, so it must take
        the data as an argument rather than read this Model's.
        """
        return build_once(self.compiled.cache, key, build)


def _interp(d) -> trajectory.Interpolation:
    return trajectory.Interpolation(d["rows"], d["w"])


def compile_scene(scene: Scene) -> Model:
    """Compile a checked Scene into a Model."""
    return Model(scene)


def load_source(source: str | Path, allowed_paths=()) -> Scene:
    """The checked Scene of a .phys file (a ``Path``, or a one-line string ending in ``.phys``)
    or of .phys text; its imports and data files must lie in its folder tree (text: the
    working folder's), the stdlib or below ``allowed_paths``."""
    if isinstance(source, Path) or (isinstance(source, str) and "\n" not in source
                                     and source.endswith(".phys")):
        return load(source, allowed_paths)
    return loads(source, filename="<string>", base_dir=Path.cwd(), allowed_paths=allowed_paths)


def compile(source: Scene | str | Path, allowed_paths=()) -> Model:  # noqa: A001 - the design's name
    """The Model of a Scene, or of a .phys file or text (``load_source``)."""
    return Model(source if isinstance(source, Scene) else load_source(source, allowed_paths))
