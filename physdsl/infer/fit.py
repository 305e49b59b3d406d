"""The fit policy of the diagnosis and the refine loop: MAP from modes found once, random-walk
Metropolis from the same modes where MAP's Laplace step fails, and the quick fit used to compare
candidate scenes. ``start_setting`` (``init.py``) turns constrained start values into the
``start`` setting these fits take."""
from __future__ import annotations

import jax
import numpy as np

from .backends.map import LaplaceError, find_mode, remember_modes
from .base import Settings, value_and_grad_fn
from .init import start_setting
from .output import PLAIN
from .problem import model_problem, start_position
from .run import infer, starts

FIT_DRAWS = 64  # Laplace draws per chain: enough for PSIS-LOO and 90% intervals; each draw
# costs one rollout in the posterior pass, the dominant cost of a fit on contact scenes

__all__ = ["FIT_DRAWS", "fit_with_fallback", "quick_fit", "start_setting", "warm_modes",
           "wider_than_prior"]


def fit_with_fallback(model, backend: str, **settings):
    """``infer(model, backend=...)``; for ``map``, the modes are found once and where MAP's
    Laplace step fails there (a log density with a kink at the mode, e.g. a contact that
    switches on, or a flat direction: LaplaceError, or draws wider than the prior, see
    ``wider_than_prior``) the posterior is sampled by random-walk Metropolis started at those
    same modes, which needs no Hessian and no gradient; ``idata.attrs["fit_note"]`` says so.
    ``warm=True`` with a ``start``: the mode is searched from that start alone (``warm_modes``)."""
    warm = settings.pop("warm", False)
    if backend != "map":
        return infer(model, backend=backend, **settings)
    run = {k: v for k, v in settings.items() if k in Settings.__dataclass_fields__}
    steps = max(run.get("warmup", 50), 50)
    modes = warm_modes(model, Settings(**run), steps) if warm and run.get("start") else None
    if modes is None:
        modes = np.asarray(starts(model, Settings(**run), steps)[1])
    try:
        idata = infer(model, backend="map", positions=modes, **settings)
        wide = wider_than_prior(model, idata)
        if not wide:
            return idata
        why = f"Laplace draws of {', '.join(wide)} wider than the prior"
    except LaplaceError as err:
        why = f"Laplace approximation failed ({err.message})"
    # each transition costs a rollout (on contact scenes the bulk of a fit): a short run
    settings = {**settings, "warmup": min(settings.get("warmup", 200), 200)}
    if settings.get("outdir") is not None:  # the sample replaces what the MAP attempt wrote
        settings.update(force=True, resume=False)
    idata = infer(model, backend="rmh", positions=modes, **settings)
    idata.attrs["fit_note"] = f"{why}; posterior sampled by random-walk Metropolis from the modes"
    return idata


def quick_fit(model, seed: int = 0, start: dict | None = None, warm: bool | None = None):
    """A fast posterior for comparisons: MAP from two prior draws with a Laplace approximation
    (random-walk Metropolis where that fails, see ``fit_with_fallback``), the model's
    intervals shown (comparisons are statements within the model); with ``start``
    (constrained values by name) the first optimisation starts there instead. ``warm``: the
    mode is searched from ``start`` alone (``warm_modes``); by default where ``start`` gives
    every unknown (a point, e.g. a nested model's fit: not a hint for some unknowns)."""
    start = start or {}
    if warm is None:
        warm = bool(start) and all(u.name in start for u in model.unknowns)
    return fit_with_fallback(model, "map", chains=2, warmup=300, samples=FIT_DRAWS, seed=seed,
                             progress=False, start=start_setting(start),
                             intervals=PLAIN, warm=warm)  # comparisons use the model's
    # posterior: no robust intervals (``intervals.add_robust``: residual models, block check)


def warm_modes(model, settings: Settings, steps: int) -> np.ndarray | None:
    """Every chain at the mode found from ``settings.start`` alone (Levenberg-Marquardt or
    L-BFGS, ``steps``), remembered as the run's mode so MAP keeps it; None where the start
    has no finite log density (the full multistart then runs).

    For a refit whose start is already near its mode (a candidate scene started at the fit
    without the candidate plus the score test's step, which nests it; a fit of the same scene
    on the first part of the record started at the whole record's fit): the multistart's
    other starts (the data's, the prior's centre, draws at the data's frequency) each cost an
    optimisation and programs of their own to compile, and at best end in the same basin."""
    problem = model_problem(model)
    key = jax.random.split(jax.random.PRNGKey(settings.seed), 3)[0]
    value = value_and_grad_fn(problem)  # (shares the Gauss-Newton program where there is one)
    x0 = start_position(problem, key, dict(settings.start))
    if not np.isfinite(float(value(jax.numpy.asarray(x0))[0])):
        return None
    mode = find_mode(problem, x0, steps)
    lp = float(value(jax.numpy.asarray(mode))[0])
    if not np.isfinite(lp):
        return None
    remember_modes(problem, [mode], [lp])
    return np.repeat(np.asarray(mode, dtype=float)[None], settings.chains, axis=0)


def wider_than_prior(model, idata, factor: float = 10.0) -> list[str]:
    """Unknowns whose posterior draws spread (interquartile range) more than ``factor`` times
    wider than their prior's: no posterior does that (data narrow a prior, they do not widen
    it), so it marks a failed approximation, e.g. a Laplace covariance whose curvature was
    floored where the likelihood has a kink."""
    prior = model.sample_prior(jax.random.PRNGKey(0), 400)
    out = []
    for u in model.unknowns:
        post = np.asarray(idata.posterior[u.name].values)
        post = post.reshape(-1, *post.shape[2:])
        width = np.subtract(*np.quantile(post, [0.75, 0.25], axis=0))
        prior_width = np.subtract(*np.quantile(np.asarray(prior[u.name]), [0.75, 0.25], axis=0))
        if np.any(width > factor * prior_width + 1e-300):
            out.append(u.name)
    return out
