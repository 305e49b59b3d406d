"""A distilled law refitted in the scene: its coefficients become ordinary unknowns (normal
priors around 0, wide enough for the learned estimate), fitted jointly with the scene's own
unknowns from the base fit plus the regression's estimate; 90% intervals from the posterior."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..compile import Model
from ..diagnose.edits import load_text
from ..infer.fit import quick_fit
from .distil import Support
from .law_effect import NAME
from .learn import Fit, fitted
from .phys_text import law_scene_text

PRIOR_WIDTH = 5.0  # prior sd of a coefficient, in units of its learned estimate


@dataclass
class Law:
    """A law refitted: its support, scene text, fit, and coefficients (median, 90% interval)."""

    support: Support
    text: str
    fit: Fit
    coefficients: dict  # term -> (median, lo, hi), SI

    @property
    def terms(self) -> tuple[str, ...]:
        return self.support.terms


def unknown_name(target: str, term: str) -> str:
    return f"{NAME}@{target}.{term}"


def law_text(scene, target: str, kind: str, support: Support, center=None) -> str:
    """The scene's text with the law's declaration and use (coefficients unknown)."""
    priors = {t: (0.0, PRIOR_WIDTH * max(abs(c), 1e-12)) for t, c in support.coefficients.items()}
    note = (f"distilled by physdsl.discover from a residual force on {target}: outside the "
            "library")
    return law_scene_text(scene.source, target, kind, support.terms, center, priors=priors,
                          note=note)


def refit_law(base: Fit, target: str, kind: str, support: Support, center=None,
              seed: int = 0) -> Law:
    """Fit the base scene plus the law, from the base fit and the learned coefficients."""
    scene = base.model.scene
    text = law_text(scene, target, kind, support, center)
    model = Model(load_text(scene, text))
    start = {**base.values, **{unknown_name(target, t): np.asarray(c)
                               for t, c in support.coefficients.items()}}
    fit = fitted(model, quick_fit(model, seed=seed, start=start))
    coefs = {}
    for t in support.terms:
        draws = np.asarray(fit.idata.posterior[unknown_name(target, t)].values).reshape(-1)
        lo, med, hi = np.quantile(draws, [0.05, 0.5, 0.95])
        coefs[t] = (float(med), float(lo), float(hi))
    return Law(support, text, fit, coefs)
