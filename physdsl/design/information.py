"""What an experiment would teach, in the Laplace/Fisher approximation: the learned unknowns
(every unknown but the varied fields) as a Gaussian in the prior's unconstrained space, its
precision taken from a posterior's draws (the prior's curvature for unknowns the posterior
lacks), plus the experiment's Fisher information JᵀJ, J the Jacobian through the rollout of
the predicted observations over their noise with respect to those unknowns.

The criterion is D-optimal, log det(P0 + JᵀJ) - log det P0: under this approximation it *is*
twice the expected entropy reduction (½ log det of the precision ratio, in nats), and unlike
A- or E-optimal criteria it does not depend on the units or the parameterisation of each
unknown (a kg or a g, a mass or its log give the same choice).
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import potential_energy, unconstrain_fn

from ..compile import Model
from ..errors import ModelError
from ..infer.multistart import prior_centre
from ..infer.posterior_data import group, posterior_draws
from ..infer.problem import model_problem, unconstrained_layout, unraveler
from ..control.problem import constrain, flat_slices

Z90 = 1.6448536269514722  # the 95% normal quantile: a central 90% interval is mean ± Z90 sd


@dataclass(frozen=True)
class Belief:
    """The learned unknowns' Gaussian in unconstrained space: their flat indices, the full
    vector's centre (the varied fields' coordinates unused) and the precision over the indices."""

    names: tuple[str, ...]
    index: np.ndarray  # (p,) positions in the flat unconstrained vector
    centre: np.ndarray  # (dim,) posterior mean where fitted, prior centre elsewhere
    precision: np.ndarray  # (p, p)
    from_posterior: tuple[str, ...]  # the names whose belief came from the posterior's draws


def belief(model: Model, varied: tuple[str, ...], idata=None, seed: int = 0) -> Belief:
    """The Belief of ``model``'s unknowns other than ``varied``: posterior draws' mean and
    inverse covariance (unconstrained) where ``idata`` holds them, else the prior's centre and
    the negative Hessian of its log density there (with the transform's Jacobian)."""
    slices = flat_slices(model)
    learned = tuple(sorted((n for n in model.unknown_names if n not in varied),
                           key=lambda n: slices[n].start))  # the flat vector's order
    if not learned:
        raise ModelError("nothing to learn: every unknown of the scene is varied",
                         hint="the experiment teaches the unknowns that are not --vary fields")
    index = np.concatenate([np.arange(slices[n].start, slices[n].stop) for n in learned])
    centre = np.array(prior_centre(model_problem(model), jax.random.PRNGKey(seed)), float)
    prior_h = np.asarray(_prior_hessian(model)(jnp.asarray(centre)))
    precision = prior_h[np.ix_(index, index)]
    fitted = _fitted(model, learned, idata)
    if fitted:
        rows = _unconstrained_draws(model, idata, fitted, centre, slices)
        cols = np.concatenate([np.arange(slices[n].start, slices[n].stop) for n in fitted])
        centre[cols] = rows[:, cols].mean(axis=0)
        cov = np.atleast_2d(np.cov(rows[:, cols], rowvar=False))
        where = np.searchsorted(index, cols)
        precision = _replace_block(precision, where, np.linalg.inv(cov + 1e-12 * np.eye(len(cols))))
    return Belief(learned, index, centre, precision, fitted)


def _fitted(model: Model, learned, idata) -> tuple[str, ...]:
    if idata is None:
        return ()
    held = set(group(idata, "posterior").data_vars)
    fitted = tuple(n for n in learned if n in held)
    if not fitted:
        raise ModelError("the posterior holds none of the scene's unknowns",
                         hint="give the run of a fit whose unknowns have this scene's names")
    return fitted


def _replace_block(precision, where, block):
    """``precision`` with the fitted rows/columns replaced by ``block`` (no prior coupling)."""
    out = np.array(precision, float)
    out[where, :] = 0.0
    out[:, where] = 0.0
    out[np.ix_(where, where)] = block
    return out


def _prior_hessian(model: Model):
    unravel, _ = unraveler(unconstrained_layout(model))
    return jax.jit(jax.hessian(lambda x: potential_energy(model.prior_values, (), {}, unravel(x))))


def _unconstrained_draws(model: Model, idata, fitted, centre, slices) -> np.ndarray:
    """The posterior's draws of ``fitted`` as flat unconstrained rows (others at ``centre``)."""
    values = posterior_draws(idata, fitted)
    base = constrain(model, jnp.asarray(centre))
    n = len(next(iter(values.values())))
    if n < 2 * len(fitted) + 2:
        raise ModelError(f"the posterior has {n} draws: too few for a covariance",
                         hint="give a run with more draws")

    def one(draw):
        return unconstrain_fn(model.prior_values, (), {}, {**base, **draw})

    free = jax.jit(jax.vmap(one))({k: jnp.asarray(v) for k, v in values.items()})
    rows = np.repeat(np.asarray(centre)[None, :], n, axis=0)
    for k in fitted:
        rows[:, slices[k]] = np.reshape(np.asarray(free[k]), (n, -1))
    return rows


def standardized_predictions(model: Model, b: Belief, settings: dict, data=None):
    """theta (the learned unknowns' unconstrained coordinates) -> every measured component of
    the predicted observations over its noise scale (0 where not measured), with the varied
    fields at ``settings``; noise scales held at the belief's centre. ``data``: the
    measurements' masks and times (default ``model.data``; an argument in compiled code)."""
    data = model.data if data is None else data
    centre = jnp.asarray(b.centre)
    point = {**constrain(model, centre), **settings}
    scales = {o.obs.name: jax.lax.stop_gradient(model.noise_scale(o.obs, point)) for o in model.observed}

    def fn(theta):  # the residuals' geometry (angles wrap, orientations as rotation vectors)
        values = {**constrain(model, centre.at[b.index].set(theta)), **settings}
        preds = model.predict(values, data=data)
        return jnp.concatenate([(Model._residual(o.obs, preds[o.obs.name], data[o.obs.name])
                                 / scales[o.obs.name]).reshape(-1) for o in model.observed])

    return fn


def fisher(model: Model, b: Belief, settings: dict, data=None):
    """JᵀJ of the standardised predictions at the belief's centre (forward mode: p columns)."""
    theta = jnp.asarray(b.centre)[b.index]
    jac = jax.jacfwd(standardized_predictions(model, b, settings, data))(theta)
    return jac.T @ jac


def gain(model: Model, b: Belief, settings: dict):
    """The D-optimal criterion: log det(P0 + F) - log det(P0) (twice the expected entropy
    reduction in nats)."""
    p0 = jnp.asarray(b.precision)
    return jnp.linalg.slogdet(p0 + fisher(model, b, settings))[1] - jnp.linalg.slogdet(p0)[1]


def intervals(model: Model, b: Belief, precision) -> dict[str, dict]:
    """Each learned unknown's 90% interval (per component, SI) under the Gaussian of
    ``precision``: the centre ± 1.645 sd in unconstrained space, mapped through the prior's
    transform (its quantiles: the transforms are monotone per component)."""
    cov = np.linalg.inv(np.asarray(precision, float))
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    slices = flat_slices(model)
    out = {}
    for name in b.names:
        ends = []
        for sign in (-1.0, 1.0):
            x = np.array(b.centre)
            x[b.index] += sign * Z90 * sd
            ends.append(np.ravel(np.asarray(constrain(model, jnp.asarray(x))[name], float)))
        lo, hi = np.minimum(*ends), np.maximum(*ends)
        k = np.searchsorted(b.index, np.arange(slices[name].start, slices[name].stop))
        out[name] = {"lower": lo.tolist(), "upper": hi.tolist(), "width": (hi - lo).tolist(),
                     "sd_unconstrained": sd[k].tolist()}
    return out
