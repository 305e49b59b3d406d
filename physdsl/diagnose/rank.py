"""Which effect is missing: score-test every candidate, confirm the best few by refitting.

1. Candidates (``candidates.py``): library effects that could act and are absent, on every
   target, plus sensor faults per observation.
2. Score tests (``screening.py``, ``score.py``) at the fit (the most likely posterior draw)
   with all candidates switched off, in one augmented model: one Jacobian for all of them.
3. The best ``confirm`` physical candidates are refitted with the effect added
   (``confirm.py``); they are compared by PSIS-LOO (``loo.py``), leave-future-out log
   predictive density (``lfo.py``: fit on the first 70% of the recording, predict the rest)
   and residual RMS in noise units, and ordered by that evidence (``ordering.py``).
4. Physics judges fitted drag strengths (``physical_scale.py``), and where the evidence ties
   two candidates the experiment that would separate them is proposed (``design.experiment``).
"""
from __future__ import annotations

import time

from ..design.experiment import for_tie
from ..infer.fit import wider_than_prior
from . import physical_scale
from .confirm import confirm
from .diagnosis import Diagnosis, Ranked, p_value_text
from .edits import Draft
from .evidence import model_probabilities
from .loo import ELPD_TIE
from .ordering import evidence_ties, mark_twins, order_by_evidence, plausible_first, tie_twins
from .screening import prior_sds_needed, score_all
from .workflow import check_model


def diagnose(model, idata, *, confirm_top: int = 2, alpha: float = 0.05, outdir=None,
             check_report=None, echo=None, draft: Draft | None = None) -> Diagnosis:
    """Rank candidate missing effects by evidence; confirm the best by refitting (``echo``: a
    line -> None that hears of the refits' progress; ``draft``: ``model``'s scene with its AST,
    parsed from its source when not given)."""
    t0 = time.perf_counter()
    draft = draft or Draft.of(model.scene)
    report = check_report or check_model(model, idata)
    unusable = wider_than_prior(model, idata)
    ranked = rows(model, score_all(model, idata, draft))
    t1 = time.perf_counter()
    n_tests = max(len(ranked), 1)
    significant = [r for r in ranked if r.p_value < alpha / n_tests]
    winner = None
    if significant and confirm_top > 0:
        confirm(model, idata, ranked, confirm_top, float(report.rms_sigma), echo, draft)
        winner, ranked = _by_evidence(ranked)
    physics = []  # what physics says of fitted drag strengths (physical_scale)
    if winner is not None:
        physics = physical_scale.notes(model, idata, [r for r in ranked if r.confirmed])
        winner, ranked = plausible_first(winner, ranked, physics)
    ranked = tie_twins(ranked)
    t2 = time.perf_counter()
    verdict = _verdict(winner, ranked, report, alpha / n_tests, confirm_top)
    if physics:
        verdict += "; physically: " + "; ".join(physical_scale.text(j) for j in physics)
    tied = next((r for r in ranked if r.tied_with), None) if winner is not None else None
    if tied is not None:  # the measurement that would separate them (design.experiment)
        proposal = for_tie(model, winner, tied)
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
        diag.write(outdir)
    return diag


def rows(model, scored) -> list[Ranked]:
    """The table's rows in score order, each with its candidate, twins marked (``same_as``)
    and notes on what the measurements cannot see."""
    ranked = []
    for i, (c, s) in enumerate(scored, start=1):
        sds = prior_sds_needed(model.scene, c, s) if c.kind == "effect" else None
        note = ("the measurements cannot see this effect" if s.information <= 0 else
                f"the measurements barely see this effect: explaining the misfit would need a "
                f"strength {sds:.2g} prior sds from off, so it is not proposed" if sds else "")
        ranked.append(Ranked(i, c.kind, c.name, ",".join(c.target), s.statistic, s.p_value, s.dof,
                             s.log_p, s.z, s.estimate, note=note, candidate=c))
    mark_twins(ranked, {c.key: s.direction for c, s in scored if s.direction is not None})
    for r in ranked:
        if r.same_as:
            r.note = (f"switched on a little, it changes the predictions exactly like "
                      f"{r.same_as.replace('@', ' on ')} (same score direction): the score test "
                      "cannot tell them apart, and only the first is refitted"
                      + (f"; {r.note}" if r.note else ""))
    return ranked


def _by_evidence(ranked: list[Ranked]) -> tuple[Ranked | None, list[Ranked]]:
    """(winner, ranked) after the refits: confirmed effects by evidence (``order_by_evidence``),
    then the rest by score; the evidence's ties marked and model probabilities set."""
    confirmed = order_by_evidence([r for r in ranked if r.confirmed])
    if not confirmed:
        return None, ranked
    winner = confirmed[0]
    ranked = confirmed + [r for r in ranked if not r.confirmed]
    for r in evidence_ties(winner, confirmed):
        r.tied_with = winner.key
    probs = model_probabilities({id(r): r.log_evidence for r in confirmed})
    for r in confirmed:
        r.model_prob = probs[id(r)]
    return winner, ranked


def _verdict(winner, ranked, report, threshold: float, confirm_top: int) -> str:
    """The diagnosis in a sentence: the winner and what it ties with, a sensor fault, a
    candidate the score test alone names, or why nothing is named."""
    top = ranked[0] if ranked else None
    if winner is not None:
        return _winner_text(winner, ranked)
    if top is not None and top.kind == "sensor" and top.p_value < threshold:
        return (f"the misfit looks like a sensor fault: {top.effect} on {top.target} "
                f"(p = {p_value_text(top)}), not a missing physical effect")
    if top is not None and confirm_top == 0 and top.p_value < threshold:
        return (f"most likely missing (score test only, not confirmed by a refit): "
                f"{top.effect} on {top.target} (p = {p_value_text(top)})")
    if report.consistent:
        return "no missing effect: the residuals are consistent with the noise"
    where = "; ".join(f.message for f in report.flags[:3])
    return ("nothing in the library explains the misfit"
            + (f"; where and how the model fails: {where}" if where else ""))


def _winner_text(winner: Ranked, ranked: list[Ranked]) -> str:
    what = "missing effect" if winner.kind == "effect" else "sensor fault"
    verdict = (f"{what}: {winner.effect} on {winner.target} (score p = {p_value_text(winner)}; "
               f"ΔELPD {winner.delta_elpd:+.1f} ± {winner.delta_elpd_se:.1f}; residual RMS "
               f"{winner.rms_before:.2f}σ → {winner.rms_after:.2f}σ)")
    rivals = [r for r in ranked if r.tied_with]
    twins = [r for r in ranked if r.same_as == winner.key]
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
    return verdict
