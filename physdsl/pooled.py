"""A Model over many recordings of one scene (``experiments`` in the language).

Unknowns written ``~ per_experiment dist(..)`` are one numpyro sample site inside
``numpyro.plate("experiment", R)`` (shape (R, *shape)); every other unknown is shared, and a
per-recording prior may name shared unknowns (a hierarchical prior: ``mass ~ per_experiment
normal(mass_mu, mass_sd)``). The rollout is vectorised over recordings: ``jax.lax.map`` with
``batch_size`` runs ``CHUNK`` recordings at a time under ``vmap``, so memory holds one chunk's
rollouts, not all of them. Each recording's observations are observables of their own,
named ``ball.position[07]``, with their own data (``Model.data``), so the posterior, the
checks and the diagnosis see every recording, and their sums pool them.
"""
from __future__ import annotations

import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np
import numpyro

from .compile import MODEL_KINDS, OBS_PREFIX, PRED_PREFIX, Model, _interp, build_distribution
from .expr import evaluate, references
from .observe import sensor
from .physics.simulator import canonical_values, is_traced
from .scene import Observation, Prior
from .syntax.dists import find

CHUNK = int(os.environ.get("PHYSDSL_POOL_CHUNK", "16"))  # recordings per vmapped call
EXPERIMENT_DIM = "experiment"


def observation_name(obs: str, recording: str) -> str:
    """The name of observation ``obs`` of ``recording``: ``ball.position[07]``."""
    return f"{obs}[{recording}]"


class RecordingValues(dict):
    """One recording's values (``PooledModel.recording_values``), told apart from the pooled
    values so that they are not sliced twice."""


class PooledModel(Model):
    """The Model of a scene with ``experiments``: per-recording and shared unknowns in one
    program, the rollout vectorised over recordings (see the module's docstring)."""

    def __init__(self, scene, until: float | None = None, every_contact: bool = False):
        super().__init__(scene, until, every_contact)
        ex = scene.experiments
        self.recordings = ex.recordings
        self.n = len(ex.recordings)
        self.per_experiment = frozenset(u.name for u in scene.unknowns if u.per_experiment)
        self.base_shapes = {u.name: tuple(u.shape) for u in scene.unknowns}
        self.unknowns = tuple(dataclasses.replace(u, shape=(self.n, *u.shape))
                              if u.name in self.per_experiment else u for u in self.unknowns)
        self.settings = {k: np.array([r.settings[k] for r in ex.recordings], dtype=float)
                         for k in ex.settings}
        observed, self.recording_of, self.written = [], {}, {}
        for i, rec in enumerate(ex.recordings):
            for o in rec.observations:
                name = observation_name(o.name, rec.name)
                observed.append(self._prepare(dataclasses.replace(o, name=name)))
                self.recording_of[name] = i
                self.written[name] = o.name
        self.observed = tuple(observed)

    def _ruled_out(self) -> tuple[int, ...]:
        """Every contact pair stays in the likelihood: recordings differ in what they rule out."""
        return ()

    @property
    def recording_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.recordings)

    # -- values of one recording -----------------------------------------------------------
    def stacked(self, values) -> dict:
        """The values that differ between recordings: per-recording unknowns and settings,
        each with a leading axis of length R."""
        out = {k: values[k] for k in self.per_experiment if k in values}
        out.update({k: jnp.asarray(v) for k, v in self.settings.items()})
        return out

    def recording_values(self, values, r: int) -> dict:
        """The values one rollout of recording ``r`` reads (shared ones and its own)."""
        if isinstance(values, RecordingValues):  # already one recording's
            return values
        out = RecordingValues({k: v for k, v in values.items() if k not in self.per_experiment})
        out.update({k: v[r] for k, v in self.stacked(values).items()})
        return out

    # -- the rollout over recordings --------------------------------------------------------
    def rollouts(self, values):
        """Every recording's rollout, stacked (leaves (R, T, ...)); ``CHUNK`` recordings per
        vmapped call (``jax.lax.map``), so memory is bounded by one chunk's rollouts. Where
        nothing differs between recordings, one rollout serves all (leaves (T, ...)).

        Called with concrete values (the posterior pass's draws, a check's rollout), one
        compiled program of this Model's: a vmap run op by op would dispatch, and compile,
        every operation of the rollout on its own."""
        if is_traced(values):
            return self._rollouts(values)
        if self._compiled_rollouts is None:
            self._compiled_rollouts = jax.jit(self._rollouts)
        return self._compiled_rollouts(canonical_values(values))

    _compiled_rollouts = None

    def _rollouts(self, values):
        shared = {k: v for k, v in values.items() if k not in self.per_experiment}
        stacked = self.stacked(values)
        if not stacked:
            return self.simulator.simulate(shared, self.rollout_fields)

        def one(own):
            return self.simulator.simulate({**shared, **own}, self.rollout_fields)

        return chunked_map(one, stacked, self.n, min(CHUNK, self.n))

    @property
    def varies(self) -> bool:
        """Whether recordings differ in anything the rollout reads (else one rollout)."""
        return bool(self.per_experiment or self.settings)

    def _one(self, rollout, r: int):
        return jax.tree_util.tree_map(lambda a: a[r], rollout) if self.varies else rollout

    def rollout_of(self, rollout, obs_name: str):
        return self._one(rollout, self.recording_of[obs_name])

    def recording_rollouts(self, rollout) -> list:
        return [self._one(rollout, r) for r in range(self.n)]

    def written_name(self, obs_name: str) -> str:
        return self.written.get(obs_name, obs_name)

    def simulate(self, values):
        """Every recording's rollout (see ``rollouts``) for the unknowns' ``values``."""
        return self.rollouts(values)

    def fit_simulate(self, values):
        """The rollouts the likelihood reads: ``simulate``'s (no pair is left out here)."""
        return self.rollouts(values)

    def fit_simulate_ahead(self, values) -> None:
        """Nothing: the recordings' rollouts compile where they are first called."""

    def predict(self, values, rollout=None, data=None):
        """Noise-free predictions of every recording's observations: name -> (N, D)."""
        rollout = self.rollouts(values) if rollout is None else rollout
        data = self.data if data is None else data
        out = {}
        for o in self.observed:
            r = self.recording_of[o.obs.name]
            out[o.obs.name] = sensor.predict(self._one(rollout, r),
                                             self.simulator, o.obs, _interp(data[o.obs.name]),
                                             self.recording_values(values, r))
        return out

    def noise_scale(self, obs: Observation, values):
        return super().noise_scale(obs, self.recording_values(values, self.recording_of[obs.name]))

    def noise_distribution(self, obs: Observation, values, loc):
        return super().noise_distribution(
            obs, self.recording_values(values, self.recording_of[obs.name]), loc)

    # -- the probabilistic program ----------------------------------------------------------
    def prior_values(self):
        """Every unknown from its prior; per-recording ones inside ``plate("experiment")``."""
        values = {}
        for u in self.unknowns:
            if u.name in self.per_experiment:
                with numpyro.plate(EXPERIMENT_DIM, self.n):
                    d = self.plate_distribution(u.prior, values, self.base_shapes[u.name])
                    values[u.name] = numpyro.sample(u.name, d)
            else:
                values[u.name] = numpyro.sample(u.name, build_distribution(u.prior, values, u.shape))
        return values

    def plate_distribution(self, prior: Prior, values, shape: tuple[int, ...]):
        """The prior of one recording's value, batched over the R recordings (batch shape
        (R,), event ``shape``): arguments that differ between recordings are evaluated per
        recording and aligned on the leading axis."""
        cls = find(prior.dist)
        varying = set(self.per_experiment) | set(self.settings)
        stacked = self.stacked(values)
        shared = {k: v for k, v in values.items() if k not in self.per_experiment}

        def arg(e):
            if not references(e) & varying:
                return evaluate(e, shared)
            return jax.vmap(lambda own: jnp.asarray(evaluate(e, {**shared, **own}),
                                                    dtype=float))(stacked)

        args = [arg(a) for a in prior.args]
        kwargs = {k: arg(v) for k, v in prior.kwargs}
        first = lambda a, e: a[0] if _varies(e, varying) else a  # noqa: E731 - one recording's
        probe = cls(*[first(a, e) for a, e in zip(args, prior.args)],
                    **{k: first(v, e) for (k, e), v in zip(prior.kwargs, kwargs.values())},
                    validate_args=False)
        ev = len(probe.event_shape)
        batch = tuple(shape[: len(shape) - ev]) if ev else tuple(shape)
        rank = len(batch) + ev

        def align(a, e):  # (R, *a) -> (R, 1.., *a): the recording axis first, then batch
            return a.reshape((self.n,) + (1,) * (rank - a.ndim + 1) + a.shape[1:]) \
                if _varies(e, varying) else a

        d = cls(*[align(a, e) for a, e in zip(args, prior.args)],
                **{k: align(v, e) for (k, e), v in zip(prior.kwargs, kwargs.values())},
                validate_args=False)
        d = d.expand((self.n, *batch))
        return d.to_event(len(batch)) if batch else d

    def numpyro_model(self, data=None):
        """Priors (per-recording ones in a plate), the rollouts of every recording, their
        predictions and noisy observations (one observed site per recording's observable)."""
        data = self.data if data is None else data
        values = self.prior_values()
        preds = self.predict(values, data=data)
        for o in self.observed:
            d = data[o.obs.name]
            pred = preds[o.obs.name]
            numpyro.deterministic(PRED_PREFIX + o.obs.name, pred)
            res = self._residual(o.obs, pred, d)
            noise = self.noise_distribution(o.obs, values, jnp.zeros_like(res))
            numpyro.sample(OBS_PREFIX + o.obs.name, noise.mask(jnp.asarray(d["mask"])), obs=res)


def chunked_map(fn, xs, n: int, chunk: int):
    """``vmap(fn)(xs)`` over the leading axis (length ``n``), ``chunk`` rows per vmapped call
    under ``lax.map`` (the rows padded with the last one); jax's own ``lax.map(batch_size=)``
    cannot reshape the zero-size leaves a rollout may hold."""
    calls = -(-n // chunk)
    pad = calls * chunk - n
    xs = jax.tree_util.tree_map(
        lambda a: jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)]) if pad else a, xs)
    xs = jax.tree_util.tree_map(lambda a: a.reshape((calls, chunk) + a.shape[1:]), xs)
    out = jax.lax.map(jax.vmap(fn), xs) if calls > 1 else jax.tree_util.tree_map(
        lambda a: a[None], jax.vmap(fn)(jax.tree_util.tree_map(lambda a: a[0], xs)))
    return jax.tree_util.tree_map(lambda a: a.reshape((calls * chunk,) + a.shape[2:])[:n], out)


def _varies(e, varying) -> bool:
    return bool(references(e) & varying)


def experiment_dims(model) -> tuple[dict, dict]:
    """(dims, coords) naming the ``experiment`` axis of per-recording unknowns (for arviz);
    ({}, {}) for a Model of one recording."""
    if not isinstance(model, PooledModel):
        return {}, {}
    dims = {}
    for u in model.unknowns:
        if u.name in model.per_experiment:
            dims[u.name] = [EXPERIMENT_DIM] + [f"{u.name}:dim_{i}"
                                               for i in range(len(u.shape) - 1)]
    return dims, {EXPERIMENT_DIM: list(model.recording_names)}


def component_labels(model, u) -> list[str]:
    """Labels of the scalar components of unknown ``u`` (row-major): ``name``, ``name[i]``,
    or for a per-recording unknown ``name[RECORDING]`` / ``name[RECORDING][i]``."""
    size = int(np.prod(u.shape))
    if not (isinstance(model, PooledModel) and u.name in model.per_experiment):
        return [u.name] if size == 1 else [f"{u.name}[{i}]" for i in range(size)]
    inner = size // model.n
    return [f"{u.name}[{rec}]" + (f"[{i}]" if inner > 1 else "")
            for rec in model.recording_names for i in range(inner)]


def rollout_bytes_per_recording(model) -> int:
    """Bytes of one recording's rollout as the likelihood reads it (its fields, float64)."""
    values = {u.name: jnp.zeros(model.base_shapes[u.name]) for u in model.unknowns}
    values.update({k: jnp.zeros(np.shape(v)[1:]) for k, v in model.settings.items()})
    out = jax.eval_shape(lambda v: model.simulator.simulate(v, model.rollout_fields), values)
    return int(sum(np.prod(leaf.shape) * leaf.dtype.itemsize
                   for leaf in jax.tree_util.tree_leaves(out)))


MODEL_KINDS["pooled"] = PooledModel

__all__ = ["CHUNK", "EXPERIMENT_DIM", "PooledModel", "component_labels", "experiment_dims",
           "observation_name",
           "rollout_bytes_per_recording"]
