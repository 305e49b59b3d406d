"""Score tests of every candidate at the fit, in one augmented model: each candidate's effect is
added to the scene at its off value (exactly equivalent to absent), the scene is compiled once,
and one Jacobian gives every candidate's column (``score.py``)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import ahead
from ..compile import Model
from ..errors import PhysError
from ..expr import constant_value
from ..syntax.dists import find
from .candidates import Candidate, material_pairs, physics_candidates, sensor_candidates
from .edits import Draft, unknown_key
from .score import ScoreResult, jacobian, jacobian_ahead, project_out, score_test, sensor_columns
from .workflow import noise_unknowns, point_estimate

NUDGE = 1e-4  # one-sided strengths are tested this many prior sds inside the physical side
IMPLAUSIBLE = 1000.0  # prior sds: a one-step estimate this far out is not a physical effect
SCORE_TIE = 1e-6  # relative: scores closer than this are equal (what differs is rounding noise)


def score_all(model, idata, draft: Draft | None = None) -> list[tuple[Candidate, ScoreResult]]:
    """Score test of every candidate at the fit (``point_estimate``), in one augmented model
    (``draft``: ``model``'s scene with its AST; parsed from its source when not given).

    Per-target candidates are added to the augmented scene at their off values; a
    material-level candidate's column is the sum of its pairs' columns (the derivative with
    respect to the one shared coefficient, all pairs at the same off value).
    """
    draft = draft or Draft.of(model.scene)
    scene = draft.scene
    cands, usable, aug = _augmented(draft)
    values = point_estimate(model, idata)
    nuisance = _nuisance(model)
    tested = [unknown_key(scene, c) for c in usable]
    for c, key in zip(usable, tested):
        values[key] = np.full(aug.scene.unknown(key).shape, tested_value(scene.effect_library[c.name]))
    r, J_theta, J_psi, pred = jacobian(aug, values, nuisance, tested)
    by_key = dict(zip((c.key for c in usable), _split_columns(aug, tested, J_psi)))
    results = [(c, _tested(scene, c, r, J_theta, col)) for c, col in
               [(c, by_key[c.key]) for c in usable] + _group_columns(draft, cands, by_key)]
    for c in sensor_candidates(scene):
        cols = project_out(J_theta, sensor_columns(aug, values, c.name, c.target[0], pred))
        results.append((c, score_test(c.key, r, cols, 0)))
    return score_order(results)


def score_ahead(model, draft: Draft | None = None) -> Model | None:
    """Start compiling ``score_all``'s program for ``model`` in the background
    (``physdsl.ahead``): the augmented scene and the program's argument types depend on the
    scene alone, not on the fit. Returns the augmented Model, which holds the program: keep it
    until ``score_all`` has run (None where compiling ahead is off or failed)."""
    if not ahead.enabled():
        return None
    draft = draft or Draft.of(model.scene)
    try:
        _, usable, aug = _augmented(draft)
        jacobian_ahead(aug, _nuisance(model), [unknown_key(draft.scene, c) for c in usable])
    except Exception:  # noqa: BLE001 - an optimisation: score_all meets and reports it
        return None
    return aug


def _augmented(draft: Draft) -> tuple[list[Candidate], list[Candidate], Model]:
    """(every physics candidate, those added to the augmented scene one by one, the augmented
    Model): material-level and joint-group candidates take their columns from their parts'."""
    cands = physics_candidates(draft.scene)
    module, usable = draft.module, []
    for c in cands:
        if c.material or c.joints:  # columns from their parts' (below)
            continue
        try:
            module = draft.add(c, module)
            usable.append(c)
        except Exception:  # noqa: BLE001 - a candidate the language cannot express is skipped
            continue
    return cands, usable, Model(draft.resolved(module).scene)


def _nuisance(model) -> list[str]:
    """The unknowns a score test projects out: all but the noise scales."""
    noise = noise_unknowns(model)
    return [u.name for u in model.unknowns if u.name not in noise]


def score_order(results: list[tuple[Candidate, ScoreResult]]) -> list[tuple[Candidate, ScoreResult]]:
    """``results`` by score, most significant first (log p, then the statistic). Scores equal to
    ``SCORE_TIE`` relative keep the candidates' key order, so which of two equal candidates is
    refitted first does not depend on rounding that differs between runs."""
    ordered = sorted(results, key=lambda cr: (cr[1].log_p, -cr[1].statistic))
    out, run = [], []
    for cr in ordered:
        if run and not _same_score(run[0][1], cr[1]):
            out += sorted(run, key=lambda g: g[0].key)
            run = []
        run.append(cr)
    return out + sorted(run, key=lambda g: g[0].key)


def _same_score(a: ScoreResult, b: ScoreResult) -> bool:
    """Two scores that differ by no more than rounding (``SCORE_TIE`` relative)."""
    return (math.isclose(a.log_p, b.log_p, rel_tol=SCORE_TIE, abs_tol=1e-12)
            and math.isclose(a.statistic, b.statistic, rel_tol=SCORE_TIE, abs_tol=1e-12))


def _split_columns(aug, tested: list[str], J_psi) -> list[np.ndarray]:
    """``J_psi``'s columns per tested unknown, in ``tested``'s order (ravel_pytree orders
    dict keys)."""
    sizes = {k: int(np.prod(aug.scene.unknown(k).shape)) for k in tested}
    offset, columns = 0, {}
    for k in sorted(tested):
        columns[k] = J_psi[:, offset: offset + sizes[k]]
        offset += sizes[k]
    return [columns[k] for k in tested]


def _group_columns(draft: Draft, cands, by_key: dict) -> list[tuple[Candidate, np.ndarray]]:
    """Material-level and group candidates with their columns from their parts': a shared
    strength's column is the sum of its parts' columns, a strength per joint their concatenation."""
    scene, out = draft.scene, []
    for c in cands:
        if c.material:
            parts = [Candidate("effect", c.name, p).key for p in material_pairs(scene, c.name, c.target[0])]
            if all(p in by_key for p in parts) and expressible(draft, c):
                out.append((c, sum(by_key[p] for p in parts)))
        elif c.joints and all(p.key in by_key for p in c.parts()) and expressible(draft, c):
            cols = [by_key[p.key] for p in c.parts()]  # one shared strength: the sum
            out.append((c, sum(cols) if c.shared else np.concatenate(cols, axis=1)))
    return out


def _tested(scene, c: Candidate, r, J_theta, col) -> ScoreResult:
    """The score test of one physical candidate's column, the fitted directions projected out;
    p = 1 where the strength it would need is implausible (``prior_sds_needed``)."""
    cols = project_out(J_theta, col)
    sign = scene.effect_library[c.name].strength.sign if col.shape[1] == 1 else 0
    res = score_test(c.key, r, cols, sign)
    if prior_sds_needed(scene, c, res) is not None:
        res = dataclasses.replace(res, p_value=1.0, log_p=0.0)
    return res


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
    args = [np.asarray(constant_value(a)) for a in prior.args]
    kwargs = {k: np.asarray(constant_value(v)) for k, v in prior.kwargs}
    return float(np.sqrt(np.max(np.asarray(find(prior.dist)(*args, **kwargs).variance))))


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


def expressible(draft: Draft, cand: Candidate) -> bool:
    """Whether ``Draft.add`` can write the candidate (its shared param's name is free)."""
    try:
        draft.add(cand)
        return True
    except PhysError:
        return False
