"""From a compiled Model and its posterior to the arrays ``check`` reads (ObservableFit)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from ..compile import PRED_PREFIX
from ..errors import UsageError
from ..expr import references
from ..infer import posterior_data
from ..observe import trajectory
from .check import Report, check
from .report import write_report
from .residuals import ObservableFit

MAX_DRAWS = 200


def _require_unknowns(model, posterior) -> None:
    """A UsageError unless ``posterior`` holds draws of every unknown of ``model``."""
    missing = [u.name for u in model.unknowns if u.name not in posterior]
    if missing:
        raise UsageError(f"the posterior has no draws of {', '.join(missing)}",
                         hint="give the run folder of `physdsl infer` on this same scene")


def posterior_draws(model, idata, max_draws: int = MAX_DRAWS) -> dict[str, np.ndarray]:
    """Up to ``max_draws`` joint draws of every unknown: name -> (S, *shape), evenly thinned."""
    _require_unknowns(model, idata.posterior)
    return posterior_data.posterior_draws(idata, [u.name for u in model.unknowns], max_draws)


def point_estimate(model, idata) -> dict[str, np.ndarray]:
    """The posterior draw with the highest log-likelihood: the values the model is judged at.

    The Rao score test is defined at the fit of the model without the candidate (the
    restricted maximum-likelihood estimate), and a check asks whether the *best* the model can
    do is consistent with the noise; the most likely of some hundred draws is close to that
    fit. Unlike a component-wise median it is always a draw the posterior holds, and a few wild
    draws of an approximate posterior (a Laplace covariance that is nearly singular where the
    data cannot see a direction) cannot move it.
    """
    ll = getattr(idata, "log_likelihood", None)
    if ll is None or not ll.data_vars:
        raise UsageError("the posterior has no pointwise log-likelihood",
                         hint="give the run folder of `physdsl infer` on this same scene")
    total = sum(np.asarray(ll[v].values).reshape(*ll[v].shape[:2], -1).sum(axis=2)
                for v in ll.data_vars)
    total = np.where(np.isfinite(total), total, -np.inf)
    chain, draw = np.unravel_index(int(np.argmax(total)), total.shape)
    _require_unknowns(model, idata.posterior)
    return {u.name: np.asarray(idata.posterior[u.name].values[chain, draw]) for u in model.unknowns}


def noise_unknowns(model) -> set[str]:
    """Names of unknowns that only set measurement noise (nuisance for physics diagnosis)."""
    names: set[str] = set()
    for o in model.scene.observations:
        names |= references(o.noise.scale)
        if o.noise.df is not None:
            names |= references(o.noise.df)
    return names


def events(model, rollout) -> tuple[float, ...]:
    """Times at which a contact starts in ``rollout`` (normal force switches on)."""
    cf = np.asarray(getattr(rollout, "contact_force", np.zeros((len(rollout.t), 0))))
    if cf.size == 0:
        return ()
    on = (cf > 1e-9).any(axis=1)
    starts = np.nonzero(on[1:] & ~on[:-1])[0] + 1
    return tuple(float(rollout.t[i]) for i in starts)


def observable_fits(model, idata, max_draws: int = MAX_DRAWS) -> list[ObservableFit]:
    """One ObservableFit per trajectory observation: posterior-predictive draws (the band) and
    the prediction at the most likely draw (``point_estimate``: the residuals)."""
    draws = posterior_draws(model, idata, max_draws)
    values = point_estimate(model, idata)
    rollout = model.fit_simulate(values)
    central = {k: np.asarray(v) for k, v in model.predict(values, rollout).items()}
    pp = idata.posterior_predictive
    fits = []
    n = len(next(iter(draws.values()))) if draws else 1
    for o in model.observed:
        obs = o.obs
        roll = model.rollout_of(rollout, obs.name)  # its recording's (pooled Models)
        pred = np.asarray(pp[PRED_PREFIX + obs.name].values)
        pred = pred.reshape(-1, *pred.shape[2:])
        step = max(1, pred.shape[0] // max_draws)
        pred = pred[::step][:max_draws]
        sig = np.stack([np.asarray(model.noise_scale(obs, {k: v[i] for k, v in draws.items()}))
                        for i in range(min(n, len(pred)))]) if draws else \
            np.asarray(model.noise_scale(obs, {}))[None]
        point = central[obs.name]
        measured = obs.values
        mask = o.mask
        if obs.quantity == "orientation":
            measured = np.asarray(trajectory.rotation_vector(jnp.asarray(o.measured)))
            pred = np.asarray(trajectory.rotation_vector(jnp.asarray(pred)))
            point = np.asarray(trajectory.rotation_vector(jnp.asarray(point)))
        speed = None
        if obs.quantity == "position":  # the speed of the observed body or marker
            vel = np.asarray(trajectory.model_track(roll, model.simulator,
                                                    dataclasses.replace(obs, quantity="velocity")))
            speed_track = np.linalg.norm(vel, axis=1)
            speed = np.interp(obs.times, np.asarray(roll.t), speed_track)
        elif obs.quantity == "angle":
            rate = np.asarray(roll.joint_vel[:, model.simulator.joint_names.index(obs.target)])
            speed = np.interp(obs.times, np.asarray(roll.t), np.abs(rate))
        fits.append(ObservableFit(
            name=obs.name, axes=trajectory.axes(obs.quantity), unit=_unit(obs.quantity),
            times=obs.times, measured=np.where(mask, measured, np.nan), mask=mask,
            predicted=pred[: len(sig)], noise_sigma=sig, speed=speed, events=events(model, roll),
            point=point))
    return fits


def _unit(quantity: str) -> str:
    """The unit of the quantity's residuals (an orientation's: rad, its rotation vector)."""
    kind = trajectory.OBSERVATION_KINDS[quantity]
    return kind.residual_unit or kind.unit


def check_model(model, idata, outdir: Path | None = None, windows: int = 4) -> Report:
    """Posterior-predictive check of ``model`` against its measurements (writes a report if asked)."""
    fits = observable_fits(model, idata)
    report = check(fits, windows=windows)
    if outdir is not None:
        write_report(report, fits, Path(outdir))
    return report
