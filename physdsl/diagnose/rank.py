"""Which effect is missing: score-test every candidate, confirm the best few by refitting.

1. Candidates (``candidates.py``): library effects that could act and are absent, on every
   target, plus sensor faults per observation.
2. Score tests (``score.py``) at the fit (the most likely posterior draw) with all
   candidates switched off, in one augmented model: one Jacobian for all of them.
3. The best ``confirm`` physical candidates are refitted with the effect added; they are
   compared by PSIS-LOO (arviz), leave-future-out log predictive density (fit on the first
   70% of the recording, predict the rest) and residual RMS in noise units.
"""
from __future__ import annotations

import dataclasses
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import io
from ..errors import PhysError, PhysNameError
from ..infer import posterior_data
from ..syntax import format_source
from .candidates import Candidate, material_pairs, physics_candidates, sensor_candidates
from .edits import load_text as _load_text
from .evidence import laplace_log_evidence, model_probabilities
from .edits import prior_text, strength_name, unknown_key, unknown_keys, with_effect  # noqa: F401
from .score import ScoreResult, jacobian, project_out, score_test, sensor_columns
from .workflow import noise_unknowns, point_estimate, posterior_draws

LFO_FRACTION = 0.7
# what a refit may raise without ending the diagnosis: user-facing errors (model, inference)
# and numerical failures of the fit (non-positive-definite Laplace Hessian)
REFIT_FAILURES = (PhysError, np.linalg.LinAlgError, FloatingPointError)


@dataclass
class Ranked:
    rank: int
    kind: str
    effect: str
    target: str
    statistic: float
    p_value: float
    dof: int
    log_p: float = 0.0
    z: float | None = None
    estimate: float | None = None
    confirmed: bool | None = None
    delta_elpd: float | None = None
    delta_elpd_se: float | None = None
    delta_lfo: float | None = None
    rms_before: float | None = None
    rms_after: float | None = None
    fitted: dict | None = None
    snippet: str | None = None
    same_as: str | None = None  # "effect@target" of a better ranked candidate that acts alike
    tied_with: str | None = None  # "effect@target" of the winner whose evidence this one ties
    log_evidence: float | None = None  # Laplace log marginal likelihood of the refit (None: n/a)
    model_prob: float | None = None  # posterior probability among the confirmed (equal odds)
    consistent_after: bool | None = None  # the refit's check finds no systematic residual
    note: str = ""
    # pointwise differences to the fit without the effect (LOO per measurement time; log
    # predictive density per time after the cut-off): the standard errors of ties
    elpd_points: np.ndarray | None = field(default=None, repr=False)
    lfo_points: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {k: v for k, v in asdict(self).items() if k not in ("elpd_points", "lfo_points")}


@dataclass
class Diagnosis:
    ranking: list[Ranked]
    verdict: str
    winner: Ranked | None
    rms_sigma: float
    seconds: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return _clean({"verdict": self.verdict, "rms_sigma": self.rms_sigma,
                       "winner": self.winner.to_dict() if self.winner else None,
                       "ranking": [r.to_dict() for r in self.ranking], "seconds": self.seconds})

    def table(self) -> str:
        head = (f"{'#':>2} {'candidate':<34} {'score':>9} {'p-value':>9} "
                f"{'ΔELPD ± se':>16} {'ΔLFO':>8} {'P(model)':>8} {'RMS before → after':>20}")
        lines = [head, "-" * len(head)]
        for r in self.ranking:
            de = (f"{r.delta_elpd:+.1f} ± {r.delta_elpd_se:.1f}" if r.delta_elpd is not None else "")
            rms = (f"{r.rms_before:.2f}σ → {r.rms_after:.2f}σ" if r.rms_after is not None else "")
            name = f"{r.effect} on {r.target}" if r.kind == "effect" else f"sensor {r.effect} on {r.target}"
            lfo = f"{r.delta_lfo:+.1f}" if r.delta_lfo is not None else ""
            prob = ("" if not r.confirmed else "n/a" if r.model_prob is None else f"{r.model_prob:.3g}")
            lines.append(f"{r.rank:>2} {name:<34} {r.statistic:>9.1f} {p_value_text(r):>9} {de:>16} "
                         f"{lfo:>8} {prob:>8} {rms:>20}")
        return "\n".join(lines)


def p_value_text(r: Ranked) -> str:
    """The p-value for a table; one that underflows shows its order of magnitude from log p."""
    if r.p_value > 0 or r.log_p == 0.0:
        return f"{r.p_value:.2g}"
    return f"<1e{int(np.floor(r.log_p / np.log(10))) + 1}"


def _clean(obj):
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    return obj


def score_all(model, idata) -> list[tuple[Candidate, ScoreResult]]:
    """Score test of every candidate at the fit (``point_estimate``), in one augmented model.

    Per-target candidates are added to the augmented scene at their off values; a
    material-level candidate's column is the sum of its pairs' columns (the derivative with
    respect to the one shared coefficient, all pairs at the same off value).
    """
    from ..compile import Model

    scene = model.scene
    cands = physics_candidates(scene)
    text = scene.source
    usable = []
    for c in cands:
        if c.material or c.joints:  # columns from their parts' (below)
            continue
        try:
            text = with_effect(scene, c, text)
            usable.append(c)
        except Exception:  # noqa: BLE001 - a candidate the language cannot express is skipped
            continue
    aug = Model(_load_text(scene, text))
    values = point_estimate(model, idata)
    nuisance = [u.name for u in model.unknowns if u.name not in noise_unknowns(model)]
    tested = [unknown_key(scene, c) for c in usable]
    for c, key in zip(usable, tested):
        values[key] = np.full(aug.scene.unknown(key).shape, tested_value(scene.effect_library[c.name]))
    r, J_theta, J_psi, pred = jacobian(aug, values, nuisance, tested)
    sizes = {k: int(np.prod(aug.scene.unknown(k).shape)) for k in tested}
    offset = 0
    columns = {}
    for k in sorted(tested):  # ravel_pytree orders dict keys
        columns[k] = J_psi[:, offset: offset + sizes[k]]
        offset += sizes[k]
    by_key = {c.key: col for c, col in ((c, columns[k]) for c, k in zip(usable, tested))}
    groups = [(c, by_key[c.key]) for c in usable]
    for c in cands:
        if c.material:
            parts = [Candidate("effect", c.name, p).key for p in material_pairs(scene, c.name, c.target[0])]
            if all(p in by_key for p in parts) and _expressible(scene, c):
                groups.append((c, sum(by_key[p] for p in parts)))
        elif c.joints and all(p.key in by_key for p in c.parts()) and _expressible(scene, c):
            cols = [by_key[p.key] for p in c.parts()]  # one shared strength: the sum
            groups.append((c, sum(cols) if c.shared else np.concatenate(cols, axis=1)))
    results = []
    for c, col in groups:
        cols = project_out(J_theta, col)
        sign = scene.effect_library[c.name].strength.sign if col.shape[1] == 1 else 0
        res = score_test(c.key, r, cols, sign)
        if prior_sds_needed(scene, c, res) is not None:
            res = dataclasses.replace(res, p_value=1.0, log_p=0.0)
        results.append((c, res))
    for c in sensor_candidates(scene):
        cols = project_out(J_theta, sensor_columns(aug, values, c.name, c.target[0], pred))
        results.append((c, score_test(c.key, r, cols, 0)))
    results.sort(key=lambda cr: (cr[1].log_p, -cr[1].statistic))
    return results


NUDGE = 1e-4  # one-sided strengths are tested this many prior sds inside the physical side


def tested_value(decl) -> float:
    """Where a candidate's strength is score-tested: its off value, or for a one-sided strength
    (a sign) just inside the physical side, off + sign * 1e-4 prior sds. At the boundary
    itself a constraint solver's derivative can vanish: with a friction cone of zero width
    the LCP's complementarity is degenerate and d(trajectory)/d(mu) is exactly 0 at mu = 0,
    while at mu = 1e-5 it equals the finite difference. So near the boundary, the columns are
    the one-sided derivatives the test needs, and the residuals differ from those at off by
    1e-4 sds of the prior's effect."""
    p = decl.strength
    off = p.off if p.off is not None else 0.0
    if not p.sign or p.prior is None:
        return off
    return off + p.sign * NUDGE * prior_sd(p.prior)


def prior_sd(prior) -> float:
    """Standard deviation of a library prior (constant arguments, SI)."""
    from ..expr import constant_value
    from ..syntax.dists import find

    args = [np.asarray(constant_value(a)) for a in prior.args]
    kwargs = {k: np.asarray(constant_value(v)) for k, v in prior.kwargs}
    return float(np.sqrt(np.max(np.asarray(find(prior.dist)(*args, **kwargs).variance))))


IMPLAUSIBLE = 1000.0  # prior sds: a one-step estimate this far out is not a physical effect


def prior_sds_needed(scene, cand: Candidate, res: ScoreResult) -> float | None:
    """How many prior sds the strength would need to explain the misfit (the one-step
    estimate), when that is beyond ``IMPLAUSIBLE``, else None. Such a candidate barely moves
    the predictions here (its column is tiny, e.g. rolling resistance on a nearly frictionless
    table) and only its direction happens to match the residuals: the score statistic, which
    is blind to scale, would call it significant; it is not proposed (p = 1, with a note)."""
    p = scene.effect_library[cand.name].strength
    if res.estimate is None or p.prior is None:
        return None
    sds = abs(res.estimate) / prior_sd(p.prior)
    return sds if sds > IMPLAUSIBLE else None


def _expressible(scene, cand: Candidate) -> bool:
    """Whether ``with_effect`` can write the candidate (its shared param's name is free)."""
    try:
        with_effect(scene, cand)
        return True
    except PhysError:
        return False


def combined_loo(idata):
    """PSIS-LOO over every measurement time of every observation (pointwise values kept)."""
    ll = posterior_data.group(idata, "log_likelihood")
    arrays = [np.asarray(ll[v].values) for v in ll.data_vars]
    stacked = np.concatenate([a.reshape(a.shape[0], a.shape[1], -1) for a in arrays], axis=2)
    with warnings.catch_warnings():  # said in words by loo_reliability, not as a raw warning
        warnings.simplefilter("ignore", UserWarning)
        warnings.simplefilter("ignore", RuntimeWarning)  # constant points, handled below
        loo = posterior_data.loo(stacked)
    return _constant_points_exact(loo, stacked.reshape(-1, stacked.shape[2]))


CONSTANT_LL = 1e-9  # spread of a point's log-likelihood over the draws below which it is constant


def _constant_points_exact(loo, ll):
    """PSIS-LOO with the points whose log-likelihood does not vary over the draws set exactly.

    Leaving such a point out changes no importance weight, so its LOO density is its
    log-likelihood itself; PSIS cannot fit a Pareto tail to equal weights and returns NaN
    there (a block that does not rotate: its measured orientation depends on no unknown),
    which would make the whole ELPD NaN."""
    flat = (ll.max(axis=0) - ll.min(axis=0)) < CONSTANT_LL
    if not flat.any():
        return loo
    loo_i = np.asarray(loo.loo_i).copy()
    loo_i[flat] = ll[:, flat].mean(axis=0)
    loo.loo_i = loo_i
    loo.pareto_k = np.where(flat, 0.0, loo.pareto_k)
    loo.elpd_loo = float(loo_i.sum())
    m = ll.max(axis=0)
    lppd = float(np.sum(m + np.log(np.mean(np.exp(ll - m), axis=0))))
    loo.p_loo = lppd - float(loo_i.sum())
    loo.se = float(np.sqrt(loo_i.size * np.var(loo_i)))
    return loo


def loo_reliability(loo) -> str | None:
    """A sentence when PSIS-LOO is unreliable (Pareto k > 0.7 at some points), else None."""
    k = np.asarray(loo.pareto_k)
    bad = int(np.sum(k > 0.7))
    if not bad:
        return None
    return (f"PSIS-LOO is unreliable at {bad} of {k.size} measurements (Pareto k > 0.7): read "
            "ΔELPD as indicative; the leave-future-out comparison does not rely on it")


def lfo_points(model, idata_cut, cutoff: float) -> np.ndarray:
    """Log predictive density of each measurement time after ``cutoff`` given a fit before it
    (all observations in turn); their sum is the leave-future-out score."""
    from ..infer.output import pointwise_log_likelihood

    draws = posterior_draws(model, idata_cut, max_draws=100)
    import jax.numpy as jnp

    ll = pointwise_log_likelihood(model, {k: jnp.asarray(v) for k, v in draws.items()})
    points = []
    for o in model.observed:
        late = o.obs.times > cutoff
        x = np.asarray(ll[o.obs.name][:, late])
        m = x.max(axis=0)
        points.append(m + np.log(np.mean(np.exp(x - m), axis=0)))
    return np.concatenate(points)


FIT_DRAWS = 64  # Laplace draws per chain: enough for PSIS-LOO and 90% intervals; each draw
# costs one rollout in the posterior pass, the dominant cost of a fit on contact scenes


def fit_with_fallback(model, backend: str, **settings):
    """``infer(model, backend=...)``; for ``map``, the modes are found once and where MAP's
    Laplace step fails there (a log density with a kink at the mode, e.g. a contact that
    switches on, or a flat direction: LaplaceError, or draws wider than the prior, see
    ``wider_than_prior``) the posterior is sampled by random-walk Metropolis started at those
    same modes, which needs no Hessian and no gradient; ``idata.attrs["fit_note"]`` says so."""
    from ..infer.backends.map import LaplaceError
    from ..infer.base import Settings
    from ..infer.run import infer, starts
    from .workflow import wider_than_prior

    if backend != "map":
        return infer(model, backend=backend, **settings)
    run = {k: v for k, v in settings.items() if k in Settings.__dataclass_fields__}
    modes = np.asarray(starts(model, Settings(**run), max(run.get("warmup", 50), 50))[1])
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


def quick_fit(model, seed: int = 0, start: dict | None = None):
    """A fast posterior for comparisons: MAP from two prior draws with a Laplace approximation
    (random-walk Metropolis where that fails, see ``fit_with_fallback``); with ``start``
    (constrained values by name) the first optimisation starts there instead."""
    return fit_with_fallback(model, "map", chains=2, warmup=300, samples=FIT_DRAWS, seed=seed,
                             progress=False, start=start_setting(start or {}))


def start_setting(values: dict) -> tuple:
    """Constrained values by name as the ``start`` setting of a fit (hashable plain numbers:
    it enters the run's fingerprint)."""
    return tuple((k, np.asarray(v, dtype=float).tolist()) for k, v in values.items())


def refit_start(model, idata, cand: Candidate, estimate: float | None) -> dict:
    """Where a refit with ``cand`` added starts: the fit without it, and the candidate's strength
    at its off value moved by the score test's one-step estimate (kept on the physical side).

    The model with the effect nests the one without, so this start is at least as good as the
    smaller model's fit; a start drawn from the prior can instead land in another basin (a
    block given a friction coefficient that makes it stick cannot feel a change of mu).
    """
    if cand.kind == "sensor":
        from .sensor_terms import start_value

        return {**point_estimate(model, idata), unknown_key(model.scene, cand): start_value(cand, estimate)}
    decl = model.scene.effect_library[cand.name].strength
    off = np.asarray(decl.off if decl.off is not None else 0.0, dtype=float)
    start = dict(point_estimate(model, idata))
    if off.ndim or decl.shape:  # a vector strength (wind): its prior draws the start
        return start
    step = float(estimate) if estimate is not None and np.isfinite(estimate) else 0.0
    if decl.sign:  # one-sided: at least a hair inside the physical side
        step = decl.sign * max(decl.sign * step, 1e-3 * max(abs(float(off)), 1.0))
    for key in unknown_keys(model.scene, cand):
        start[key] = float(off) + step
    return start


SAME_DIRECTION = 0.9999  # |cos| between score columns above which two candidates act alike


def mark_twins(ranked: list[Ranked], directions: dict) -> None:
    """Set ``same_as`` on every candidate whose score column coincides with that of a better
    ranked one of the same kind (``directions``: key -> unit column): linear drag on a
    pendulum's bob *is* joint damping, and no data of this kind can tell them apart."""
    seen: list[tuple[str, str, np.ndarray]] = []
    for r in ranked:
        key = f"{r.effect}@{r.target}"
        d = directions.get(key)
        if d is None:
            continue
        twin = next((k for kind, k, e in seen if kind == r.kind and abs(float(d @ e)) > SAME_DIRECTION),
                    None)
        if twin is not None:
            r.same_as = twin
        else:
            seen.append((r.kind, key, d))
    _material_first(ranked)


def _material_first(ranked: list[Ranked]) -> None:
    """In a group of twins, a material-level candidate (one coefficient for every pair of a
    table) represents the group: it explains the data alike and is the physically plainer
    model (a cloth has one friction coefficient; a pair the data cannot see gets it too)."""
    for rep in [r for r in ranked if not r.same_as]:
        rep_key = f"{rep.effect}@{rep.target}"
        group = [r for r in ranked if r.same_as == rep_key]
        if is_material(rep):
            continue
        new = next((r for r in group if is_material(r) and r.effect == rep.effect), None)
        if new is None:
            continue
        new_key = f"{new.effect}@{new.target}"
        new.same_as = None
        for r in [rep] + group:
            if r is not new:
                r.same_as = new_key


def is_material(r: Ranked) -> bool:
    return r.kind == "effect" and Candidate(r.kind, r.effect, tuple(r.target.split(","))).material


def tie_twins(ranked: list[Ranked]) -> list[Ranked]:
    """Number the table: each candidate that acts exactly like another (``same_as``) follows
    it and shares its rank, as the data cannot order them."""
    out: list[Ranked] = []
    rank = 0
    for r in ranked:
        if r.same_as:
            continue
        rank += 0 if r.tied_with else 1
        key = f"{r.effect}@{r.target}"
        for t in [r] + [t for t in ranked if t.same_as == key]:
            t.rank = rank
            out.append(t)
    return out


EXTRA_REFITS = 2  # further candidates refitted while no refit has explained the misfit


def confirm(model, idata, ranked: list[Ranked], cands: dict, k: int, base_rms: float,
            echo=None) -> None:
    """Refit the best ``k`` physical candidates with the effect added; fill the comparison fields.

    Far from the truth (a misfit of tens of sigma) the score test's local ranking can put the
    true effect below the first ``k``: while no refit has brought the residual RMS down to
    the noise (its check flags no systematic residual), up to ``EXTRA_REFITS`` further
    candidates are refitted.

    A candidate that acts exactly like a better ranked one (``same_as``, see ``mark_twins``)
    would give the same refit, so it is skipped and the next distinct candidate is refitted
    instead. A refit that fails
    (a model error, or a fit the inference cannot complete) leaves that candidate unconfirmed
    with a note; it never ends the whole diagnosis. ``echo`` (a line -> None) hears of each
    refit as it starts and ends: on contact scenes each takes minutes.
    """
    from ..compile import Model

    base_loo = combined_loo(idata)
    times = np.concatenate([o.obs.times for o in model.observed])
    cutoff = float(times.min() + LFO_FRACTION * (times.max() - times.min()))
    echo = echo or (lambda line: None)
    echo(f"  fitting the first {LFO_FRACTION:.0%} of the recording (leave-future-out baseline)")
    try:
        base_lfo = lfo_points(model, quick_fit(Model(model.scene, until=cutoff)), cutoff)
    except REFIT_FAILURES:
        base_lfo = None  # leave-future-out unavailable: judged on ΔELPD and RMS alone
    done = 0
    # a sensor fault is refitted where it leads the score tests (on top of the effects' refits)
    first = next((r for r in ranked if not r.same_as), None)
    for r in ranked:
        if r.same_as or (r.kind != "effect" and r is not first):
            continue
        explained = any(t.consistent_after for t in ranked)
        if r.kind == "effect" and (done >= k + EXTRA_REFITS or (done >= k and explained)):
            break
        done += r.kind == "effect"
        echo(f"  refit {done}: with {r.effect} on {r.target}")
        t0 = time.perf_counter()
        try:
            cand = cands[r.effect + "@" + r.target]
            _refit(model, r, cand, base_loo, base_lfo, cutoff, base_rms,
                   refit_start(model, idata, cand, r.estimate))
            echo(f"    {_evidence_text(r)} ({time.perf_counter() - t0:.0f} s)")
        except REFIT_FAILURES as err:
            r.note = f"refit failed: {getattr(err, 'message', None) or err}"
            r.confirmed = False
            echo(f"    {r.note}")


def _evidence_text(r: Ranked) -> str:
    """ΔELPD ± se, ΔLFO and RMS before → after of a refitted candidate, as far as known."""
    parts = []
    if r.delta_elpd is not None:
        parts.append(f"ΔELPD {r.delta_elpd:+.1f} ± {r.delta_elpd_se or 0.0:.1f}")
    if r.delta_lfo is not None:
        parts.append(f"ΔLFO {r.delta_lfo:+.1f}")
    if r.rms_after is not None and r.rms_before is not None:
        parts.append(f"RMS {r.rms_before:.2f}σ → {r.rms_after:.2f}σ")
    return ", ".join(parts)


def _refit(model, r: Ranked, cand: Candidate, base_loo, base_lfo, cutoff: float,
           base_rms: float, start: dict | None = None) -> None:
    """Fit the scene with ``cand`` added (first chain from ``start``) and fill ``r``'s
    comparison fields."""
    from ..compile import Model
    from .workflow import check_model

    text = with_effect(model.scene, cand)
    new = Model(_load_text(model.scene, text))
    fit = quick_fit(new, start=start)
    if fit.attrs.get("fit_note"):
        r.note = fit.attrs["fit_note"]
    rep = check_model(new, fit)
    new_loo = combined_loo(fit)
    r.elpd_points = np.asarray(new_loo.loo_i) - np.asarray(base_loo.loo_i)
    r.delta_elpd, r.delta_elpd_se = float(r.elpd_points.sum()), _sum_se(r.elpd_points)
    if base_lfo is not None:
        new_cut = quick_fit(Model(new.scene, until=cutoff), start=start)
        r.lfo_points = lfo_points(new, new_cut, cutoff) - base_lfo
        r.delta_lfo = float(r.lfo_points.sum())
    r.rms_before, r.rms_after = base_rms, float(rep.rms_sigma)
    key = unknown_key(model.scene, cand)
    r.log_evidence = laplace_log_evidence(new, fit)
    r.consistent_after = rep.consistent
    r.fitted = {"name": key, "median": float(np.median(fit.posterior[key].values)),
                "values": {k: float(np.median(fit.posterior[k].values))
                           for k in unknown_keys(model.scene, cand)},
                "q5": float(np.quantile(fit.posterior[key].values, 0.05)),
                "q95": float(np.quantile(fit.posterior[key].values, 0.95)),
                "point": {k: np.asarray(v).tolist() for k, v in point_estimate(new, fit).items()}}
    r.snippet = _snippet(format_source(model.scene.source), text)
    r.confirmed = bool(r.delta_elpd > 2 * max(r.delta_elpd_se, 1.0)
                       and (r.delta_lfo is None or r.delta_lfo > 0)
                       and r.rms_after < 0.9 * base_rms)


def _sum_se(points: np.ndarray) -> float:
    """Standard error of the sum of pointwise values (as arviz's ``compare``)."""
    return float(np.sqrt(points.size) * points.std())


ELPD_TIE = 4.0  # differences below this are negligible however small their standard error


def tie_margin(a: Ranked, b: Ranked, which: str) -> float:
    """How far apart two candidates' ΔELPD (``which`` = "elpd") or ΔLFO ("lfo") may be and
    still tie: twice the standard error of the summed pointwise differences between them (both
    fits are scored on the same points), at least ``ELPD_TIE``."""
    pa, pb = getattr(a, f"{which}_points"), getattr(b, f"{which}_points")
    if pa is None or pb is None or np.shape(pa) != np.shape(pb):
        return ELPD_TIE
    return max(2.0 * _sum_se(np.asarray(pa) - np.asarray(pb)), ELPD_TIE)


def order_by_evidence(confirmed: list[Ranked]) -> list[Ranked]:
    """Confirmed candidates, best first: by ΔELPD, near-ties (``tie_margin``) broken by ΔLFO.

    Pointwise LOO barely separates effects that bend a trajectory alike over the fitted span
    (linear vs quadratic drag at nearly constant speed); predicting the future does. Among
    the tied, strong Laplace evidence (a Bayes factor above 10 over the ΔLFO leader, see
    ``stepwise.STRONG``) puts a candidate first: it counts what a strength costs its prior.
    """
    from .stepwise import STRONG

    best = sorted(confirmed, key=lambda r: -r.delta_elpd)
    if not best:
        return best
    tied = [r for r in best if best[0].delta_elpd - r.delta_elpd < tie_margin(best[0], r, "elpd")]
    rest = [r for r in best if r not in tied]
    tied = sorted(tied, key=lambda r: -(r.delta_lfo or 0.0))
    known = [r for r in tied if r.log_evidence is not None]
    top = max(known, key=lambda r: r.log_evidence, default=None)
    if top is not None and tied[0].log_evidence is not None and \
            top.log_evidence - tied[0].log_evidence > STRONG:
        tied = [top] + [r for r in tied if r is not top]
    return tied + rest


def evidence_ties(winner: Ranked, confirmed: list[Ranked]) -> list[Ranked]:
    """Confirmed candidates the evidence cannot separate from the winner: ΔELPD and ΔLFO both
    within ``tie_margin`` (e.g. linear and quadratic drag on a throw whose speed barely
    varies). They share the winner's rank: the winner is named (``refine`` adds one effect),
    but the table does not claim an order the data do not give."""
    return [r for r in confirmed if r is not winner
            and winner.delta_elpd - r.delta_elpd < tie_margin(winner, r, "elpd")
            and abs((winner.delta_lfo or 0.0) - (r.delta_lfo or 0.0)) < tie_margin(winner, r, "lfo")]


def _snippet(before: str, after: str) -> str:
    """The lines ``after`` adds to ``before`` (the .phys text to paste)."""
    import difflib

    added = [ln[1:] for ln in difflib.ndiff(before.splitlines(), after.splitlines())
             if ln.startswith("+ ")]
    return "\n".join(added).strip("\n")


def diagnose(model, idata, *, confirm_top: int = 2, alpha: float = 0.05, outdir=None,
             check_report=None, echo=None) -> Diagnosis:
    """Rank candidate missing effects by evidence; confirm the best by refitting (``echo``: a
    line -> None that hears of the refits' progress)."""
    from .workflow import check_model, wider_than_prior

    t0 = time.perf_counter()
    report = check_report or check_model(model, idata)
    unusable = wider_than_prior(model, idata)
    scored = score_all(model, idata)
    t1 = time.perf_counter()
    ranked, cands = [], {}
    for i, (c, s) in enumerate(scored, start=1):
        cands[c.key] = c
        sds = prior_sds_needed(model.scene, c, s) if c.kind == "effect" else None
        note = ("the measurements cannot see this effect" if s.information <= 0 else
                f"the measurements barely see this effect: explaining the misfit would need a "
                f"strength {sds:.2g} prior sds from off, so it is not proposed" if sds else "")
        ranked.append(Ranked(i, c.kind, c.name, ",".join(c.target), s.statistic, s.p_value, s.dof,
                             s.log_p, s.z, s.estimate, note=note))
    mark_twins(ranked, {c.key: s.direction for c, s in scored if s.direction is not None})
    for r in ranked:
        if r.same_as:
            r.note = (f"switched on a little, it changes the predictions exactly like "
                      f"{r.same_as.replace('@', ' on ')} (same score direction): the score test "
                      "cannot tell them apart, and only the first is refitted"
                      + (f"; {r.note}" if r.note else ""))
    n_tests = max(len(ranked), 1)
    significant = [r for r in ranked if r.p_value < alpha / n_tests]
    winner = None
    if significant and confirm_top > 0:
        confirm(model, idata, ranked, cands, confirm_top, float(report.rms_sigma), echo)
        confirmed = order_by_evidence([r for r in ranked if r.confirmed])
        if confirmed:
            winner = confirmed[0]
            # final order: confirmed effects by evidence (ΔELPD), then the rest by score
            ranked = confirmed + [r for r in ranked if not r.confirmed]
            for r in evidence_ties(winner, confirmed):
                r.tied_with = f"{winner.effect}@{winner.target}"
            probs = model_probabilities({id(r): r.log_evidence for r in confirmed})
            for r in confirmed:
                r.model_prob = probs[id(r)]
    physics = []  # what physics says of fitted drag strengths (physical_scale)
    if winner is not None:
        from . import physical_scale

        physics = physical_scale.notes(model, idata, [r for r in ranked if r.confirmed])
        winner, ranked = _plausible_first(winner, ranked, physics)
    ranked = tie_twins(ranked)
    t2 = time.perf_counter()
    top = ranked[0] if ranked else None
    if winner is not None:
        what = "missing effect" if winner.kind == "effect" else "sensor fault"
        verdict = (f"{what}: {winner.effect} on {winner.target} (score p = {p_value_text(winner)}; "
                   f"ΔELPD {winner.delta_elpd:+.1f} ± {winner.delta_elpd_se:.1f}; residual RMS "
                   f"{winner.rms_before:.2f}σ → {winner.rms_after:.2f}σ)")
        rivals = [r for r in ranked if r.tied_with]
        twins = [r for r in ranked if r.same_as == f"{winner.effect}@{winner.target}"]
        if twins:
            verdict += ("; switched on a little it acts on these data exactly like " +
                        ", ".join(f"{r.effect} on {r.target}" for r in twins) +
                        " (the score test cannot tell them apart; some may part at larger "
                        "strengths, as quadratic and linear drag on a swing do)")
        if rivals:
            verdict += ("; these data barely tell it from " +
                        ", ".join(f"{r.effect} on {r.target}" for r in rivals) +
                        " (ΔELPD and ΔLFO apart by less than twice their standard errors, or "
                        f"{ELPD_TIE:g}): a recording over a wider "
                        "range of speeds or longer would separate them")
    elif top is not None and top.kind == "sensor" and top.p_value < alpha / n_tests:
        verdict = (f"the misfit looks like a sensor fault: {top.effect} on {top.target} "
                   f"(p = {p_value_text(top)}), not a missing physical effect")
    elif top is not None and confirm_top == 0 and top.p_value < alpha / n_tests:
        verdict = (f"most likely missing (score test only, not confirmed by a refit): "
                   f"{top.effect} on {top.target} (p = {p_value_text(top)})")
    elif report.consistent:
        verdict = "no missing effect: the residuals are consistent with the noise"
    else:
        where = "; ".join(f.message for f in report.flags[:3])
        verdict = ("nothing in the library explains the misfit"
                   + (f"; where and how the model fails: {where}" if where else ""))
    if physics:
        verdict += "; physically: " + "; ".join(physical_scale.text(j) for j in physics)
    tied = next((r for r in ranked if r.tied_with), None) if winner is not None else None
    if tied is not None:  # the measurement that would separate them (design.experiment)
        from ..design.experiment import for_tie

        proposal = for_tie(model, cands, winner, tied)
        if proposal is not None:
            verdict += "; the experiment that would decide: " + proposal.text()
    if unusable:
        verdict = (f"the fit is not usable: the posterior draws of {', '.join(unusable)} spread "
                   "far wider than the prior (a failed approximation, e.g. Laplace across a kink "
                   "of the likelihood at a contact); refit with --backend rmh or nuts before "
                   "reading this diagnosis. " + verdict)
    diag = Diagnosis(ranked, verdict, winner, float(report.rms_sigma),
                     {"score_tests": t1 - t0, "confirmation": t2 - t1})
    if outdir is not None:
        out = io.prepare_outdir(outdir, force=True)
        io.write_json(out / "diagnosis.json", diag.to_dict())
        io.write_text(out / "diagnosis.md", _markdown(diag))
        if winner is not None and winner.snippet:
            io.write_text(out / "fix.phys", winner.snippet + "\n")
    return diag


def _plausible_first(winner, ranked, physics):
    """Where the evidence ties the winner with a rival and physics finds the winner's fitted
    strength implausible but the rival's plausible (linear drag at 10⁴ × Stokes against
    quadratic drag with C_d 0.3), the rival wins; the tie stays recorded."""
    judged = {(j["effect"], j["body"]): j["plausible"] for j in physics}
    if judged.get((winner.effect, winner.target), True):
        return winner, ranked
    rival = next((r for r in ranked if r.tied_with == f"{winner.effect}@{winner.target}"
                  and judged.get((r.effect, r.target)) is True), None)
    if rival is None:
        return winner, ranked
    key = f"{rival.effect}@{rival.target}"
    for r in ranked:
        if r.tied_with:
            r.tied_with = key
    rival.tied_with, winner.tied_with = None, key
    return rival, [rival] + [r for r in ranked if r is not rival]


def _markdown(d: Diagnosis) -> str:
    lines = ["# Diagnosis", "", d.verdict, "", "```", d.table(), "```"]
    if d.winner and d.winner.snippet:
        lines += ["", "Add to the scene:", "", "```", d.winner.snippet, "```"]
    return "\n".join(lines) + "\n"
