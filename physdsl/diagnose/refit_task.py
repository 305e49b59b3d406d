"""One candidate refit as a task that may run in another process (``physdsl/batch``'s executors).

A refit compares the scene with a candidate added against the scene as it is. Everything it
needs travels as plain values (``RefitTask``: the new scene's text, the start, the baseline's
pointwise scores), and everything it yields comes back as plain values (``measure``'s dict),
so the same code serves a refit in this process and one on a worker. Where refits run is set
by a higher floor with ``submitting(submit)`` (``submit(fn, task) -> Future``); without it they
run here, one after another.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np

from .. import cache
from ..compile import Model
from ..errors import ModelError, PhysError
from ..infer.fit import quick_fit
from ..syntax import loads
from .evidence import STRONG, laplace_log_evidence
from .lfo import lfo_points
from .loo import combined_loo, sum_se, unreliable
from .workflow import check_model, point_estimate

# what a refit may raise without ending the diagnosis: user-facing errors (model, inference)
# and numerical failures of the fit (non-positive-definite Laplace Hessian)
REFIT_FAILURES = (PhysError, np.linalg.LinAlgError, FloatingPointError)
_SUBMIT: list[Callable[[Callable, Any], Any]] = []


@contextmanager
def submitting(submit: Callable[[Callable, Any], Any]) -> Iterator[None]:
    """Within this block, a diagnosis hands its first refits to ``submit`` (run concurrently)."""
    _SUBMIT.append(submit)
    try:
        yield
    finally:
        _SUBMIT.remove(submit)


def submitter() -> Callable[[Callable, Any], Any] | None:
    """The ``submit`` set by ``submitting``, or None: refits run in this process."""
    return _SUBMIT[-1] if _SUBMIT else None


@dataclass(frozen=True)
class RefitTask:
    """A refit as plain values: the scene with the candidate added (text, and where its data
    paths resolve), the fit's start, the baseline's pointwise ELPD and LFO, the LFO cut-off,
    the baseline's RMS and the names of the added strength's unknowns."""

    text: str
    filename: str
    base_dir: str
    start: dict | None
    base_loo: np.ndarray
    base_lfo: np.ndarray | None
    cutoff: float
    base_rms: float
    key: str
    keys: tuple[str, ...]
    cache_dir: str | None = None


def run(task: RefitTask) -> dict:
    """A worker's refit: the scene built from ``task.text``, fitted and measured; a refit that
    fails returns ``{"failed": message}`` (exceptions do not all survive pickling)."""
    if task.cache_dir is not None:
        cache.configure(task.cache_dir)  # the driver's compiled programs, where shared
    try:
        model = Model(loads(task.text, filename=task.filename, base_dir=task.base_dir))
        return measure(model, task)
    except REFIT_FAILURES as err:
        return {"failed": getattr(err, "message", None) or str(err)}


def result(future) -> dict:
    """A submitted refit's measures; a failed one raised as a ModelError here."""
    out = future.result()
    if "failed" in out:
        raise ModelError(out["failed"])
    return out


def measure(new, task: RefitTask) -> dict:
    """Fit ``new`` (the scene with the candidate) from ``task.start`` and compare it with the
    baseline: pointwise ΔELPD, ΔLFO, RMS after, Laplace evidence, consistency, the fitted
    strength (``fitted``) and whether the candidate is confirmed."""
    fit = quick_fit(new, start=task.start)
    rep = check_model(new, fit)
    loo = combined_loo(fit)
    elpd = np.asarray(loo.loo_i) - task.base_loo
    out = {"note": fit.attrs.get("fit_note") or None, "elpd_points": elpd,
           "delta_elpd": float(elpd.sum()), "delta_elpd_se": sum_se(elpd),
           "lfo_points": None, "delta_lfo": None, "elpd_reliable": not unreliable(loo)}
    if task.base_lfo is not None:
        cut = quick_fit(Model(new.scene, until=task.cutoff), start=task.start)
        out["lfo_points"] = lfo_points(new, cut, task.cutoff) - task.base_lfo
        out["delta_lfo"] = float(out["lfo_points"].sum())
    out.update(rms_before=task.base_rms, rms_after=float(rep.rms_sigma),
               log_evidence=laplace_log_evidence(new, fit), consistent_after=rep.consistent,
               fitted=fitted_summary(new, fit, task.key, list(task.keys)))
    out["confirmed"] = confirmed(out)
    return out


def confirmed(out: dict, base_log_z: float | None = None) -> bool:
    """Whether a refit's measures (``measure``) confirm its candidate: it predicts the left-out
    points better (ΔELPD beyond twice its standard error; where the refit's PSIS-LOO is
    unreliable, ``loo.unreliable``, strong Laplace evidence over the baseline's
    ``base_log_z`` instead, and where either evidence is n/a, ΔLFO beyond twice its standard
    error), does not predict the future worse (ΔLFO) and lowers the residual
    RMS by a tenth of its excess over the noise (a systematic residual at 1σ RMS, flagged by
    the check's runs or windows, can only fall a little: the check, not an RMS threshold,
    says whether anything is left to explain)."""
    if out["elpd_reliable"]:
        better = out["delta_elpd"] > 2 * max(out["delta_elpd_se"], 1.0)
    elif base_log_z is not None and out["log_evidence"] is not None:
        better = out["log_evidence"] - base_log_z > STRONG
    else:  # no evidence on one side: the future decides (refits, not importance weights)
        better = _predicts_the_future(out)
    base = out["rms_before"]
    return bool(better and (out["delta_lfo"] is None or out["delta_lfo"] > 0)
                and out["rms_after"] < base - 0.1 * max(base - 1.0, 0.0))


def _predicts_the_future(out: dict) -> bool:
    """ΔLFO beyond twice its standard error (at least 1): leave-future-out refits the scene on
    the record's first part and scores the rest, so it stands where PSIS-LOO is unreliable and
    a Laplace evidence is n/a (billiards round 1: rolling resistance on the table, 1.51σ ->
    0.97σ, ΔLFO +1085, was left unconfirmed and the loop stopped)."""
    points = out.get("lfo_points")
    if points is None or out.get("delta_lfo") is None:
        return False
    return out["delta_lfo"] > 2 * max(sum_se(np.asarray(points)), 1.0)


def fitted_summary(model, fit, key: str, keys: list[str]) -> dict:
    """The added strength's median and 90% interval (``key``), the medians of all it adds
    (``keys``) and the most likely draw of every unknown (``point``)."""
    return {"name": key, "median": float(np.median(fit.posterior[key].values)),
            "values": {k: float(np.median(fit.posterior[k].values)) for k in keys},
            "q5": float(np.quantile(fit.posterior[key].values, 0.05)),
            "q95": float(np.quantile(fit.posterior[key].values, 0.95)),
            "point": {k: np.asarray(v).tolist() for k, v in point_estimate(model, fit).items()}}


def current_cache() -> str | None:
    """The persistent compile cache's folder as a task carries it (None: off)."""
    folder = cache.current()
    return str(folder) if folder is not None else None
