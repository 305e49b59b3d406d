"""Second thoughts of the refine loop: an effect the loop added is re-examined once others have
joined it, given those now present. Swapped for another law at the same target when the
evidence says so, dropped when its evidence has vanished.

Alternatives come from the library, not from a list: laws that act on the same target with a
one-sided scalar strength of the same sign and the same off value (on a body: linear and
quadratic drag, buoyancy, Magnus; on a joint: viscous damping, Coulomb friction, torsion
spring; on a contact pair: sliding friction and rolling resistance), and the same for a group
or material-level target (``shoulder+elbow``, ``table,*``). A steady push on a body (a vector
strength: ``constant_force``, ``wind``) has no source in the scene; on a body that touches
something it also gets the resisting contact laws on the contacts the fit shows it touching
(``contact_sources``: a steady force against the motion of a touching body comes from there).

Each refit's scene is the current one edited as a value (``edits.Draft``): nothing is parsed,
and the winner's text is printed only when ``refine`` writes it.

Decisions (``swap_wins``, ``drop_wins``) read two numbers of the scenes' fits: ΔELPD
(PSIS-LOO, with the tie margin of ``loo.tie_margin``: twice the standard error of the summed
pointwise differences, at least 4) and the Laplace log evidence Δlog Z (``evidence.py``),
which counts complexity. A swap needs ΔELPD beyond the margin with the evidence not against it,
or, within the margin, strong evidence (Bayes factor > 10). A drop needs ΔELPD within the margin
(the effect no longer predicts anything) with the evidence for the smaller scene. Where the
evidence is n/a (a kink at the mode) ΔELPD alone decides; where a fit's PSIS-LOO is unreliable
too, nothing does, and the scene stays as it is. A swap never rests on the priors alone: where
the two laws reach the same best fit (maximum log likelihood within ``FIT_TIE``), their Δlog Z
is the ratio of the priors' Occam factors, which a generic prior width (a steady push's 1 N per
axis) sets as much as the physics, so it is a tie: the current law stays and the experiment
that would decide is proposed.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..compile import Model
from ..design.experiment import design
from ..errors import UsageError
from ..infer.fit import quick_fit
from .candidates import REQUIRES, Candidate, physics_candidates
from .confirm import REFIT_FAILURES, strength_start
from .contact_sources import contact_alternatives, steady_push, touching
from .edits import Draft
from .evidence import STRONG, laplace_log_evidence
from .loo import combined_loo, tie_margin, unreliable
from .workflow import check_model, point_estimate


@dataclass
class Judged:
    """A scene's fit and what it earns: residual check, PSIS-LOO, Laplace log evidence."""

    model: object
    idata: object
    report: object
    loo: object
    log_z: float | None

    @property
    def elpd(self) -> float:
        return float(self.loo.elpd_loo)


def judge(model, idata, report=None) -> Judged:
    """Score a fitted scene (its check, its PSIS-LOO and its Laplace evidence)."""
    report = report or check_model(model, idata)
    return Judged(model, idata, report, combined_loo(idata), laplace_log_evidence(model, idata))


@dataclass
class Comparison:
    """A new scene against the current one: ΔELPD, its tie margin and Δlog Z (None: n/a);
    ``loo_ok``: both fits' PSIS-LOO can be read as evidence (``loo.unreliable``)."""

    d_elpd: float
    margin: float
    d_log_z: float | None
    loo_ok: bool = True
    d_fit: float | None = None  # Δ maximum log likelihood, −½Δχ² at the two modes (None: unknown)

    @property
    def fits_alike(self) -> bool:
        """Both scenes reach the same best fit: the data prefer neither (``FIT_TIE``)."""
        return self.d_fit is not None and abs(self.d_fit) < FIT_TIE

    @property
    def priors_only(self) -> bool:
        """What Δlog Z would decide here is the priors' Occam factors alone: the same best fit,
        and ΔELPD within its margin or unreadable."""
        return self.fits_alike and (not self.loo_ok or abs(self.d_elpd) <= self.margin)

    @property
    def by_evidence(self) -> bool:
        """Decided on Δlog Z alone: a fit's LOO is unreliable and the evidence is known."""
        return not self.loo_ok and self.d_log_z is not None

    @property
    def unreadable(self) -> bool:
        """Nothing can be read: a fit's PSIS-LOO is unreliable and the evidence is n/a."""
        return not self.loo_ok and self.d_log_z is None

    def text(self) -> str:
        z = "n/a" if self.d_log_z is None else f"{self.d_log_z:+.1f}"
        why = (" (PSIS-LOO unreliable: decided on Δlog Z)" if self.by_evidence else
               " (PSIS-LOO unreliable, Δlog Z n/a: no evidence either way)" if self.unreadable else "")
        return f"ΔELPD {self.d_elpd:+.1f} (tie margin {self.margin:.1f}), Δlog Z {z}{why}"


FIT_TIE = 1.0  # log-likelihood units: two best fits closer than this are alike (Δχ² < 2)


def compare(new: Judged, old: Judged) -> Comparison:
    new_points, old_points = np.asarray(new.loo.loo_i), np.asarray(old.loo.loo_i)
    dz = None if new.log_z is None or old.log_z is None else new.log_z - old.log_z
    return Comparison(float((new_points - old_points).sum()), tie_margin(new_points, old_points), dz,
                      not (unreliable(new.loo) or unreliable(old.loo)),
                      -0.5 * (_chi2(new.report) - _chi2(old.report)))


def _chi2(report) -> float:
    """The fit's χ²: its standardised residuals' sum of squares (RMS² times their count)."""
    return float(report.rms_sigma) ** 2 * int(report.n)


def swap_wins(c: Comparison) -> bool:
    """Another law beats the current one: it predicts better beyond the tie margin and the
    evidence does not disagree, or, predicting alike, the evidence is strong (> log 10); where
    a fit's PSIS-LOO is unreliable, strong evidence alone, and with the evidence n/a too, no
    swap (the current scene needs no evidence to stay, a change does); never on the priors
    alone (``Comparison.priors_only``)."""
    if c.unreadable or c.priors_only:
        return False
    if c.by_evidence:
        return c.d_log_z > STRONG
    if c.d_elpd > c.margin:
        return c.d_log_z is None or c.d_log_z > 0
    return c.d_elpd > -c.margin and c.d_log_z is not None and c.d_log_z > STRONG


def drop_wins(c: Comparison) -> bool:
    """The scene without an effect (``c``: without against with) predicts as well (within the
    tie margin) and the evidence, which counts the effect's parameter, prefers it; where a
    fit's PSIS-LOO is unreliable, the evidence alone, and with the evidence n/a too, no drop."""
    if c.unreadable:
        return False
    if c.by_evidence:
        return c.d_log_z > 0
    return c.d_elpd > -c.margin and (c.d_log_z is None or c.d_log_z > 0)


def alternatives(draft: Draft, cand: Candidate, bare: Draft | None = None,
                 touched: set | None = None) -> list[Candidate]:
    """Other library laws at ``cand``'s target, as candidates of the scene without ``cand``
    (``bare``, made here when not given): a one-sided scalar strength of the same sign and off
    value (see the module's docstring). A steady push on a body (``contact_sources``) also
    gets the resisting contact laws on the body's contacts, those in ``touched`` (the pairs in
    contact in the fitted rollout; None: every pair of the body)."""
    lib = draft.scene.effect_library
    mine = lib[cand.name].strength
    bare = bare or draft.without_candidate(cand)
    pool = physics_candidates(bare.scene)
    same = [c for c in pool
            if c.kind == "effect" and c.target == cand.target and c.name != cand.name
            and _alike(lib[c.name].strength, mine)]
    if _pushes(draft, cand):
        same += contact_alternatives(bare.scene, cand.target[0], pool, touched)
    return same


def sources_unexamined(draft: Draft, cand: Candidate, model, values) -> bool:
    """``cand``, just added (``draft``: the scene with it; ``model`` fitted at ``values``), is
    a steady push on a body the fit shows touching a pair where a resisting contact law could
    act (``contact_sources``). The diagnosis that chose it ranked those laws at other targets
    and refitted only its best few, so the next round re-examines the push against them."""
    if not _pushes(draft, cand):
        return False
    touched = [p for p in touching(model, values) if cand.target[0] in p]
    if not touched:  # free flight (two_effects_throw): nothing to examine
        return False
    bare = draft.without_candidate(cand)
    return bool(contact_alternatives(bare.scene, cand.target[0], physics_candidates(bare.scene),
                                     set(touched)))


def _pushes(draft: Draft, cand: Candidate) -> bool:
    """``cand`` is a steady push on one body (``contact_sources.steady_push``)."""
    return (cand.kind == "effect" and len(cand.target) == 1
            and steady_push(draft.scene.effect_library[cand.name]))


def _alike(s, mine) -> bool:
    """Two laws' strengths that can stand for each other: the same off value and shape, and,
    for scalars, the same physical sign (a vector strength, a steady push ``constant_force``
    or a ``wind``, has no sign: either can stand for the other once drag is in)."""
    if tuple(s.shape) != tuple(mine.shape) or not np.all(np.asarray(s.off) == np.asarray(mine.off)):
        return False
    return bool(s.shape) or bool(s.sign and s.sign == mine.sign)


@dataclass
class Action:
    """A swap (``removed`` → ``added``) or a drop (``added`` None) and the refit it rests on."""

    kind: str  # "swapped" | "dropped"
    removed: Candidate
    added: Candidate | None
    draft: Draft  # the new scene (its text printed when refine writes it)
    judged: Judged
    comparison: Comparison
    tried: list = field(default_factory=list)  # (description, Comparison or error) of each refit


def reexamine(current: Judged, draft: Draft, revisable: list[Candidate], echo=None
              ) -> tuple[Action | None, list, list]:
    """Refit each of ``revisable`` (effects in ``current``'s scene, ``draft``) dropped and
    swapped for each alternative, given the rest of the scene; return the best winning action
    (by Δlog Z, then a drop before a swap, then ΔELPD) or None, the lines describing every
    refit, and those of the swaps the data cannot decide that have an experiment proposed."""
    echo = echo or (lambda line: None)
    start = point_estimate(current.model, current.idata)
    wins, lines, ties = [], [], []
    # the pairs in contact at the current fit: where a steady push's contact alternatives act
    touched = touching(current.model, start) if any(_pushes(draft, c) for c in revisable) else None
    for cand in revisable:
        if _required(draft, cand):  # wind stays on drag: neither goes while the other is there
            continue
        bare = draft.without_candidate(cand)
        options = [(None, bare.module)] + [(alt, bare.add(alt))
                                           for alt in alternatives(draft, cand, bare, touched)]
        for alt, module in options:
            what = (f"drop {_name(cand)}" if alt is None else f"swap {_name(cand)} → {_name(alt)}")
            echo(f"  refit: {what}")
            t0 = time.perf_counter()
            try:
                new_draft = bare if alt is None else bare.resolved(module)
                model = Model(new_draft.scene)
                begin = {k: v for k, v in start.items() if k in set(model.unknown_names)}
                if alt is not None:  # the swapped-in law starts off: the bare scene it nests
                    begin.update(strength_start(bare.scene, alt))
                new = judge(model, quick_fit(model, start=begin))
            except REFIT_FAILURES as err:
                lines.append(f"{what}: refit failed ({getattr(err, 'message', None) or err})")
                echo(f"    {lines[-1]}")
                continue
            c = compare(new, current)
            ok = drop_wins(c) if alt is None else swap_wins(c)
            tie, proposal = "", None
            if alt is not None and not ok and tied(c):  # the data cannot tell: say what would
                proposal = experiment(current, new, cand, alt)
                tie = f" — a tie{f'; {EXPERIMENT}: {proposal.text()}' if proposal else ''}"
            lines.append(f"{what}: {c.text()}, RMS {new.report.rms_sigma:.2f}σ"
                         f"{' — wins' if ok else tie} ({time.perf_counter() - t0:.0f} s)")
            echo(f"    {lines[-1]}")
            if proposal is not None:
                ties.append(lines[-1])
            if ok:
                wins.append(Action("dropped" if alt is None else "swapped", cand, alt, new_draft, new, c))
    if not wins:
        return None, lines, ties
    # most evidence first; where it is n/a, a drop before a swap (fewer parameters), then ΔELPD
    best = max(wins, key=lambda a: (a.comparison.d_log_z if a.comparison.d_log_z is not None
                                    else -math.inf, a.kind == "dropped", a.comparison.d_elpd))
    return best, lines, ties


EXPERIMENT = "the experiment that would decide"


def tied(c: Comparison) -> bool:
    """Neither scene is better: ΔELPD within the tie margin and no strong evidence either way
    (no claim where nothing can be read: ``Comparison.unreadable``), or the same best fit where
    only the priors would decide (``Comparison.priors_only``)."""
    if c.priors_only:
        return True
    if c.unreadable:
        return False
    if c.by_evidence:
        return abs(c.d_log_z) <= STRONG
    return abs(c.d_elpd) <= c.margin and (c.d_log_z is None or abs(c.d_log_z) <= STRONG)


def experiment(current: Judged, new: Judged, cand: Candidate, alt: Candidate):
    """The measurement that would separate the scene with ``cand`` from the one with ``alt``
    (``design.experiment``, each at its most likely draw): varying the target's initial
    velocity (a body) or angle (a joint) over its prior range; None where neither is an
    unknown of both scenes."""
    names = set(current.model.unknown_names) & set(new.model.unknown_names)
    target = cand.target[0]
    field_ = next((f for f in (f"{target}.velocity", f"{target}.initial") if f in names), None)
    if field_ is None:
        return None
    try:
        return design(current.model, point_estimate(current.model, current.idata), new.model,
                      point_estimate(new.model, new.idata), field_, labels=(_name(cand), _name(alt)))
    except UsageError:
        return None


def _required(draft: Draft, cand: Candidate) -> bool:
    """Whether another effect of the scene needs ``cand`` (``candidates.REQUIRES``: wind, the
    change of drag in moving air, needs quadratic drag on its body)."""
    return any(REQUIRES.get(e.effect) == cand.name and tuple(e.target) == cand.target
               for e in draft.scene.effects)


def _name(c: Candidate) -> str:
    return f"{c.name} on {','.join(c.target)}"


def parse(key: str) -> Candidate:
    """``effect@target`` (as in refine.json and diagnosis.json) as a Candidate."""
    name, _, target = key.partition("@")
    return Candidate("effect", name, tuple(target.split(",")))
