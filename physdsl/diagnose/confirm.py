"""Confirmation by refitting: the best physical candidates are refitted with the effect added and
compared with the scene as it is by PSIS-LOO (ΔELPD), leave-future-out log predictive density
(ΔLFO), residual RMS in noise units and Laplace evidence."""
from __future__ import annotations

import difflib
import time

import numpy as np

from ..ahead import enabled as compiling_ahead
from ..compile import Model
from ..infer.fit import quick_fit
from ..infer.fit_ahead import compile_ahead
from ..infer.problem import model_problem
from .candidates import Candidate
from .diagnosis import Ranked, Refit
from . import refit_task
from .edits import Draft, scene_dir, unknown_key, unknown_keys
from .evidence import laplace_log_evidence
from .lfo import LFO_FRACTION, cutoff as lfo_cutoff, lfo_points
from .loo import combined_loo
from .ordering import doubtful_twin
from .sensor_terms import start_value
from .workflow import point_estimate

REFIT_FAILURES = refit_task.REFIT_FAILURES  # what a refit may raise without ending the diagnosis
EXTRA_REFITS = 2  # further candidates refitted while no refit has explained the misfit


class Baseline:
    """What every refit of one diagnosis is compared with: the scene as it is (its draft, fit,
    PSIS-LOO, residual RMS) and its leave-future-out scores (None: unavailable)."""

    def __init__(self, model, idata, draft: Draft, base_rms: float, echo):
        self.model, self.idata, self.draft, self.rms = model, idata, draft, base_rms
        self.loo = combined_loo(idata)
        self.cutoff = lfo_cutoff(model)
        echo(f"  fitting the first {LFO_FRACTION:.0%} of the recording (leave-future-out baseline)")
        try:
            # started at the whole record's fit (a point: searched from there alone)
            cut = quick_fit(Model(model.scene, until=self.cutoff), start=point_estimate(model, idata))
            self.lfo = lfo_points(model, cut, self.cutoff)
        except REFIT_FAILURES:
            self.lfo = None  # leave-future-out unavailable: judged on ΔELPD and RMS alone
        self._text = None
        self._log_z = ()

    def log_z(self) -> float | None:
        """The scene's Laplace log evidence (computed once, when a refit's PSIS-LOO is
        unreliable and the evidence must decide instead)."""
        if self._log_z == ():
            self._log_z = laplace_log_evidence(self.model, self.idata)
        return self._log_z

    def text(self) -> str:
        """The scene's text (printed once, for the snippets)."""
        if self._text is None:
            self._text = self.draft.text()
        return self._text


def confirm(model, idata, ranked: list[Ranked], k: int, base_rms: float, echo=None,
            draft: Draft | None = None) -> None:
    """Refit the best ``k`` physical candidates with the effect added; fill the comparison fields.

    Far from the truth (a misfit of tens of sigma) the score test's local ranking can put the
    true effect below the first ``k``: while no refit has brought the residual RMS down to
    the noise (its check flags no systematic residual), up to ``EXTRA_REFITS`` further
    candidates are refitted.

    A candidate that acts exactly like a better ranked one (``same_as``, see
    ``ordering.mark_twins``) would give the same refit, so it is skipped and the next distinct
    candidate is refitted instead. A refit that fails (a model error, or a fit the inference
    cannot complete) leaves that candidate unconfirmed with a note; it never ends the whole
    diagnosis. ``echo`` (a line -> None) hears of each refit as it starts and ends: on contact
    scenes each takes minutes. ``draft``: the scene with its AST (parsed when not given).
    """
    echo = echo or (lambda line: None)
    draft = draft or Draft.of(model.scene)
    # a sensor fault is refitted where it leads the score tests (on top of the effects' refits)
    first = next((r for r in ranked if not r.same_as), None)
    compiling = refits_ahead(draft, sure_refits(ranked, k, first))  # alive until fitted
    base = Baseline(model, idata, draft, base_rms, echo)
    done = 0
    ahead = submit_first(base, ranked, k, first)  # on an executor: the first refits at once
    for r in ranked:
        if r.same_as and doubtful_twin(r, ranked):
            r.same_as = None  # refitted on its own: the twins may part at a finite strength
        if r.same_as or (r.kind != "effect" and r is not first):
            continue
        explained = any(t.consistent_after for t in ranked)
        if r.kind == "effect" and (done >= k + EXTRA_REFITS or (done >= k and explained)):
            break
        done += r.kind == "effect"
        if r.kind == "effect" and not explained and max(k, 2) <= done < k + EXTRA_REFITS:
            compiling += refits_ahead(draft, _next_effect(ranked, r))  # needed if r fails too
        _refit_row(base, r, ahead, f"refit {done}", echo)
    for r in shared_siblings(ranked):  # the simpler hypothesis inside a confirmed group
        _refit_row(base, r, ahead, "refit (one shared strength)", echo)


def _refit_row(base: Baseline, r: Ranked, ahead: dict, label: str, echo) -> None:
    """Refit ``r`` (or collect its refit submitted ahead) and fill its fields; a failure is a note."""
    echo(f"  {label}: with {r.effect} on {r.target}")
    t0 = time.perf_counter()
    try:
        if id(r) in ahead:
            drafted, future = ahead.pop(id(r))
            apply(base, r, refit_task.result(future), drafted)
        else:
            refit(base, r, refit_start(base.model, base.idata, r.candidate, r.estimate))
        echo(f"    {evidence_text(r)} ({time.perf_counter() - t0:.0f} s)")
    except REFIT_FAILURES as err:
        r.note = f"refit failed: {getattr(err, 'message', None) or err}"
        r.confirmed = False
        echo(f"    {r.note}")


def shared_siblings(ranked: list[Ranked]) -> list[Ranked]:
    """The one-shared-strength group (``hinge1+hinge2``) of each confirmed group with a strength
    per joint (``hinge1&hinge2``) that was not refitted: it nests in it with one parameter for
    several, and where the joints' strengths are equal (a chain damped alike in every hinge) the
    evidence, which counts parameters, prefers it; only a refit can say so."""
    out = []
    for r in ranked:
        c = r.candidate
        if not (r.confirmed and c is not None and c.joints and not c.shared):
            continue
        sib = next((t for t in ranked if t.candidate is not None and t.refit is None
                    and t.confirmed is None and t.candidate.shared and t.effect == r.effect
                    and t.candidate.joints == c.joints), None)
        if sib is not None:
            out.append(sib)
    return out


def evidence_text(r: Ranked) -> str:
    """ΔELPD ± se, ΔLFO and RMS before → after of a refitted candidate, as far as known."""
    parts = []
    if r.delta_elpd is not None:
        parts.append(f"ΔELPD {r.delta_elpd:+.1f} ± {r.delta_elpd_se or 0.0:.1f}")
    if r.delta_lfo is not None:
        parts.append(f"ΔLFO {r.delta_lfo:+.1f}")
    if r.rms_after is not None and r.rms_before is not None:
        parts.append(f"RMS {r.rms_before:.2f}σ → {r.rms_after:.2f}σ")
    return ", ".join(parts)


def refit(base: Baseline, r: Ranked, start: dict | None = None) -> None:
    """Fit the scene with ``r.candidate`` added (first chain from ``start``) and fill ``r``'s
    comparison fields; ``r.refit`` keeps the scene and its compiled Model."""
    draft = base.draft.with_candidate(r.candidate)
    new = Model(draft.scene)
    apply(base, r, refit_task.measure(new, task(base, r, draft, start)), draft, new)


def task(base: Baseline, r: Ranked, draft: Draft, start: dict | None) -> refit_task.RefitTask:
    """``r``'s refit as plain values (``refit_task.RefitTask``), to run here or on a worker."""
    scene, cand = base.model.scene, r.candidate
    return refit_task.RefitTask(
        draft.text(), str(scene.path or "<string>"), str(scene_dir(scene)), start,
        np.asarray(base.loo.loo_i), base.lfo, base.cutoff, base.rms,
        unknown_key(scene, cand), tuple(unknown_keys(scene, cand)), refit_task.current_cache())


def apply(base: Baseline, r: Ranked, out: dict, draft: Draft, new=None) -> None:
    """Fill ``r``'s comparison fields from a refit's measures (``refit_task.measure``)."""
    r.refit = Refit(draft, new if new is not None else Model(draft.scene))
    if out["note"]:
        r.note = out["note"]
    for name in ("elpd_points", "delta_elpd", "delta_elpd_se", "lfo_points", "delta_lfo",
                 "rms_before", "rms_after", "log_evidence", "consistent_after", "fitted",
                 "confirmed"):
        setattr(r, name, out[name])
    r.elpd_reliable = bool(out.get("elpd_reliable", True))
    if not out.get("elpd_reliable", True):  # its draws cannot say: the evidence decides
        r.confirmed = refit_task.confirmed(out, base.log_z())
        r.note = "; ".join(filter(None, [r.note, "PSIS-LOO unreliable for this refit (Pareto k > 0.7 "
                                         "at many points): judged on the Laplace evidence (n/a: on leave-future-out)"]))
    r.snippet = snippet(base.text(), draft.text())


def submit_first(base: Baseline, ranked: list[Ranked], k: int, first) -> dict:
    """Where ``refit_task.submitting`` set an executor: the refits ``confirm`` makes whatever
    they show (a leading sensor fault, the first ``k`` distinct effects) submitted at once, by
    the row's id -> (draft, future); {} when refits run here."""
    submit = refit_task.submitter()
    if submit is None:
        return {}
    out = {}
    for r in sure_refits(ranked, k, first):
        try:
            draft = base.draft.with_candidate(r.candidate)
            start = refit_start(base.model, base.idata, r.candidate, r.estimate)
        except REFIT_FAILURES:
            continue  # refitted here by the loop, which reports the failure
        out[id(r)] = (draft, submit(refit_task.run, task(base, r, draft, start)))
    return out


def sure_refits(ranked: list[Ranked], k: int, first) -> list[Ranked]:
    """The refits ``confirm`` makes whatever they show: a leading sensor fault (``first``) and
    the first ``k`` distinct effects."""
    picks = [r for r in ranked if not r.same_as and (r.kind == "effect" or r is first)]
    effects = [r for r in picks if r.kind == "effect"][:k]
    return [r for r in picks if r.kind != "effect" or r in effects]


def _next_effect(ranked: list[Ranked], r: Ranked) -> list[Ranked]:
    """The distinct effect ranked next after ``r`` (none where there is none)."""
    after = ranked[ranked.index(r) + 1:]
    return [t for t in after if t.kind == "effect" and not t.same_as][:1]


def refits_ahead(draft: Draft, rows: list[Ranked]) -> list[Model]:
    """Where refits run here: start compiling the fit programs of the refits of ``rows`` in
    the background (``infer.fit_ahead``), so each compiles while the baseline and
    the refits before it run; their Models, which hold the programs until the refits take
    them. ``confirm`` prepares the sure refits at its start, and an extra refit (one that runs
    only while no refit has explained the misfit) while the refit before it runs, once an
    earlier refit has left the misfit unexplained: it is then likely to be needed."""
    if refit_task.submitter() is not None or not compiling_ahead():
        return []
    models = []
    for r in rows:
        try:
            new = Model(draft.with_candidate(r.candidate).scene)
            compile_ahead(model_problem(new))
        except REFIT_FAILURES:
            continue  # the refit itself reports it
        models.append(new)
    return models


def refit_start(model, idata, cand: Candidate, estimate: float | None) -> dict:
    """Where a refit with ``cand`` added starts: the fit without it, and the candidate's strength
    at its off value moved by the score test's one-step estimate (kept on the physical side).

    The model with the effect nests the one without, so this start is at least as good as the
    smaller model's fit; a start drawn from the prior can instead land in another basin (a
    block given a friction coefficient that makes it stick cannot feel a change of mu).
    """
    if cand.kind == "sensor":
        return {**point_estimate(model, idata), unknown_key(model.scene, cand): start_value(cand, estimate)}
    return {**point_estimate(model, idata), **strength_start(model.scene, cand, estimate)}


def strength_start(scene, cand: Candidate, estimate: float | None = None) -> dict:
    """Start values of the strength ``cand`` adds to ``scene`` (which lacks it): its off value
    moved by the one-step ``estimate``, a one-sided strength at least a hair inside its physical
    side, so the scene with it starts where it nests ``scene``; {} for a vector strength (a
    wind: its prior draws the start)."""
    decl = scene.effect_library[cand.name].strength
    off = np.asarray(decl.off if decl.off is not None else 0.0, dtype=float)
    if off.ndim or decl.shape:
        return {}
    step = float(estimate) if estimate is not None and np.isfinite(estimate) else 0.0
    if decl.sign:  # one-sided: at least a hair inside the physical side
        step = decl.sign * max(decl.sign * step, 1e-3 * max(abs(float(off)), 1.0))
    return {key: float(off) + step for key in unknown_keys(scene, cand)}


def snippet(before: str, after: str) -> str:
    """The lines ``after`` adds to ``before`` (the .phys text to paste)."""
    added = [ln[1:] for ln in difflib.ndiff(before.splitlines(), after.splitlines())
             if ln.startswith("+ ")]
    return "\n".join(added).strip("\n")
