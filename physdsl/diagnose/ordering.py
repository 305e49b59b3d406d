"""The order of the diagnosis table: candidates that act alike (twins: one refit serves them,
they share a rank), confirmed candidates by evidence (ΔELPD, ties broken by ΔLFO and strong
Laplace evidence; the evidence's ties share the winner's rank) and, within a tie, physics
before an implausible strength."""
from __future__ import annotations

import numpy as np

from .candidates import Candidate
from .diagnosis import Ranked
from .evidence import STRONG
from .loo import tie_margin

SAME_DIRECTION = 0.9999  # |cos| between score columns above which two candidates act alike


def mark_twins(ranked: list[Ranked], directions: dict) -> None:
    """Set ``same_as`` on every candidate whose score column coincides with that of a better
    ranked one of the same kind (``directions``: key -> unit column): linear drag on a
    pendulum's bob *is* joint damping, and no data of this kind can tell them apart."""
    seen: list[tuple[str, str, np.ndarray]] = []
    for r in ranked:
        d = directions.get(r.key)
        if d is None:
            continue
        twin = next((k for kind, k, e in seen if kind == r.kind and abs(float(d @ e)) > SAME_DIRECTION),
                    None)
        if twin is not None:
            r.same_as = twin
        else:
            seen.append((r.kind, r.key, d))
    _material_first(ranked)


def doubtful_twin(r: Ranked, ranked: list[Ranked]) -> bool:
    """Whether a twin (``same_as``) of another law must be refitted after all: the columns
    coincide at the off value, but its representative's refit left systematic residuals, so
    the two may part at a finite strength (a ball sliding at constant speed is slowed alike by
    quadratic drag and by sliding friction, until friction has spun it up to rolling). Twins
    of the same law (a material and its pairs) and twins of a representative that explains
    the misfit (linear drag on a pendulum's bob and joint damping) stay skipped."""
    rep = next((t for t in ranked if t.key == r.same_as), None)
    return (rep is not None and rep.effect != r.effect and rep.rms_after is not None
            and rep.consistent_after is False and not rep.note.startswith("refit failed"))


def _material_first(ranked: list[Ranked]) -> None:
    """In a group of twins, a material-level candidate (one coefficient for every pair of a
    table) represents the group: it explains the data alike and is the physically plainer
    model (a cloth has one friction coefficient; a pair the data cannot see gets it too)."""
    for rep in [r for r in ranked if not r.same_as]:
        group = [r for r in ranked if r.same_as == rep.key]
        if is_material(rep):
            continue
        new = next((r for r in group if is_material(r) and r.effect == rep.effect), None)
        if new is None:
            continue
        new.same_as = None
        for r in [rep] + group:
            if r is not new:
                r.same_as = new.key


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
        for t in [r] + [t for t in ranked if t.same_as == r.key]:
            t.rank = rank
            out.append(t)
    return out


def order_by_evidence(confirmed: list[Ranked]) -> list[Ranked]:
    """Confirmed candidates, best first: by ΔELPD, near-ties (``loo.tie_margin``) broken by ΔLFO.

    Pointwise LOO barely separates effects that bend a trajectory alike over the fitted span
    (linear vs quadratic drag at nearly constant speed); predicting the future does. Among
    the tied, strong Laplace evidence (a Bayes factor above 10 over the ΔLFO leader, see
    ``evidence.STRONG``) puts a candidate first: it counts what a strength costs its prior.
    """
    if any(not r.elpd_reliable for r in confirmed):
        return by_log_evidence(confirmed)
    best = sorted(confirmed, key=lambda r: -r.delta_elpd)
    if not best:
        return best
    tied = [r for r in best
            if best[0].delta_elpd - r.delta_elpd < tie_margin(best[0].elpd_points, r.elpd_points)]
    rest = [r for r in best if r not in tied]
    tied = sorted(tied, key=lambda r: -(r.delta_lfo or 0.0))
    known = [r for r in tied if r.log_evidence is not None]
    top = max(known, key=lambda r: r.log_evidence, default=None)
    if top is not None and tied[0].log_evidence is not None and \
            top.log_evidence - tied[0].log_evidence > STRONG:
        tied = [top] + [r for r in tied if r is not top]
    return tied + rest


def by_log_evidence(confirmed: list[Ranked]) -> list[Ranked]:
    """Confirmed candidates best first by Laplace log evidence (n/a last, then by ΔLFO): where
    some refit's PSIS-LOO is unreliable (``loo.unreliable``: its draws are wider than its
    posterior) ΔELPD does not compare the candidates; on the double pendulum the two refits'
    -3864 and -3833 would have put friction on both hinges before friction on the elbow alone,
    whose evidence was 2.8 higher (P 0.94)."""
    ordered = sorted(confirmed, key=lambda r: (r.log_evidence is None, -(r.log_evidence or 0.0),
                                               -(r.delta_lfo or 0.0)))
    better = _outpredicts_leader(ordered)
    return ordered if better is None else [better] + [r for r in ordered if r is not better]


def _outpredicts_leader(ordered: list[Ranked]) -> Ranked | None:
    """The refit without evidence (its Laplace step failed) whose reliable PSIS-LOO beats the
    evidence leader's ΔELPD beyond the tie margin, best first; None if there is none. A missing
    evidence is no evidence against a law: an unreliable PSIS-LOO is optimistic (its heavy-tailed
    weights miss the points the fit leans on), so a reliable ΔELPD above even that one is a
    better prediction (billiards: sliding friction on the table 1.51σ, ΔELPD +39657, evidence
    n/a, had gone last behind quadratic drag on a ball at 5.38σ, +29594 unreliable, C_d 100)."""
    lead = ordered[0] if ordered else None
    if lead is None or lead.log_evidence is None or lead.delta_elpd is None:
        return None
    beat = [r for r in ordered if r.log_evidence is None and r.elpd_reliable
            and r.delta_elpd is not None
            and r.delta_elpd - lead.delta_elpd > tie_margin(lead.elpd_points, r.elpd_points)]
    return max(beat, key=lambda r: r.delta_elpd, default=None)


def _evidence_tied(a: Ranked, b: Ranked) -> bool:
    """Neither Laplace evidence is strong against the other (both known)."""
    return (a.log_evidence is not None and b.log_evidence is not None
            and abs(a.log_evidence - b.log_evidence) <= STRONG)


def _elpd_tied(a: Ranked, b: Ranked) -> bool:
    """Whether two confirmed refits predict alike by PSIS-LOO (ΔELPD within ``tie_margin``)."""
    if a.delta_elpd is None or b.delta_elpd is None:
        return False
    return abs(a.delta_elpd - b.delta_elpd) < tie_margin(a.elpd_points, b.elpd_points)


def evidence_ties(winner: Ranked, confirmed: list[Ranked]) -> list[Ranked]:
    """Confirmed candidates the evidence cannot separate from the winner: ΔELPD and ΔLFO both
    within ``tie_margin`` (e.g. linear and quadratic drag on a throw whose speed barely
    varies). They share the winner's rank: the winner is named (``refine`` adds one effect),
    but the table does not claim an order the data do not give. Where a refit's PSIS-LOO is
    unreliable, the Laplace evidence within a Bayes factor of 10."""
    if any(not r.elpd_reliable for r in confirmed):
        return [r for r in confirmed if r is not winner and _evidence_tied(winner, r)]
    return [r for r in confirmed if r is not winner
            and winner.delta_elpd - r.delta_elpd < tie_margin(winner.elpd_points, r.elpd_points)
            and abs((winner.delta_lfo or 0.0) - (r.delta_lfo or 0.0))
            < tie_margin(winner.lfo_points, r.lfo_points)]


def plausible_first(winner: Ranked, ranked: list[Ranked], physics: list[dict]):
    """(winner, ranked): where a confirmed rival predicts as well as the winner (ΔELPD within
    the tie margin; ΔLFO may differ: one split of the recording into past and future) and
    physics (``physical_scale.notes``) finds the winner's fitted strength implausible but the
    rival's plausible (linear drag at 10³ × Stokes against quadratic drag with C_d 0.24), the
    rival wins; the tie stays recorded. Judgements are keyed by their ``target`` (a body for
    drag, a joint for joint laws, a pair for contact friction)."""
    judged = {(j["effect"], j["target"]): j["plausible"] for j in physics}
    if judged.get((winner.effect, winner.target), True):
        return winner, ranked
    rival = next((r for r in ranked if r is not winner and r.confirmed
                  and judged.get((r.effect, r.target)) is True
                  and (r.tied_with == winner.key or _elpd_tied(winner, r))), None)
    if rival is None:
        return winner, ranked
    for r in ranked:
        if r.tied_with:
            r.tied_with = rival.key
    rival.tied_with, winner.tied_with = None, rival.key
    return rival, [rival] + [r for r in ranked if r is not rival]
