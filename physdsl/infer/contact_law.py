"""An error term for the contact law: the rebound at each contact pair is uncertain by a few
percent, and the unknowns an impact informs are uncertain by what that moves them.

The scene's contacts are an idealisation (an instantaneous impulse with Newton's restitution,
from an LCP); a real or differently simulated contact (MuJoCo's stiff spring, a rubber ball)
has a finite duration, during which an articulated body's joints react and the impulse's
point and size shift. The difference is not noise: it is one number per impact that no
residual statistic sees (the fit absorbs it into the unknowns the impact informs, e.g. where
a ball hit a link, leaving white residuals). It is taken as a nuisance per contact pair whose
restitution the scene fixes (a declared constant or the elastic default; a pair whose
restitution is an unknown fits its own rebound): its restitution scaled by s = exp(eta),
eta ~ N(0, ``WIDTH``^2), fixed at 0 in the fit. The reported covariance is the Laplace
approximation's with eta free, at the fit's mode, marginalised over eta
(``marginal_covariance``): the posterior covariance plus s M^-1 s^T, s = H^-1 J^T G the mode's
shift per unit eta (implicit function theorem) and M eta's posterior precision given the
unknowns. Where the data cannot tell a change of the law from a change of the unknowns, eta
keeps its prior width and the term is the sensitivity form WIDTH^2 s s^T (GUM's type-B
uncertainty); where they can, their own precision on eta sets it. J and G (the standardised
residuals' derivatives in the unknowns and in eta) come from central differences of the scene
with the scale written into each pair's restitution: one compile, two rollouts per pair and
per unknown, no refit. A pair that never impacts (no contact, or only resting ones below the
restitution threshold) has G = 0 exactly and adds nothing; a scene without contact pairs is
not touched.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import constrain_fn

from ..ahead import Program
from ..compile import Model
from ..expr import Binary, Ref, references
from ..physics.ruled_out import pair_names
from ..scene import EffectUse
from ..syntax.contact_sugar import SUGAR_PARAM
from .base import cached, gauss_newton_fn
from .problem import unconstrained_layout, unraveler

WIDTH = 0.05  # sd of log restitution per pair: how far a rebound from a soft, finite-time
# contact (the joints of an articulated body reacting during it, a rubber ball's damping) is
# taken to be from the instantaneous Newton law with the scene's coefficient
STEP = 1e-4  # central-difference step in log restitution: the rollout is smooth in it
# (impacts are split at their time), and 1e-4 keeps float64 round-off near 1e-12
WHITE_STEP = 1e-3  # central-difference step along the posterior's principal axes, in sd's
PREFIX = "contact_law:"  # names of the scales in the augmented scene's values
METHOD = "contact law"  # named in the summary where this term widened
NEGLIGIBLE = 1e-3  # a widening by at most this (relative sd, along every direction) is none:
# the draws are left as they are and the term is not named (rolling_ball's ramp-to-floor
# transition moves its residuals by a rebound that widens nothing beyond 2e-9)


def nuisance_pairs(scene) -> list[tuple[str, str]]:
    """The contact pairs whose restitution the scene fixes (no unknown in its coefficient)."""
    fitted = {frozenset(u.target) for u in scene.effects if u.effect == "restitution"
              and references(u.params[SUGAR_PARAM])}
    return [tuple(p) for p in scene.contact_pairs if frozenset(p) not in fitted]


def fitted_pairs(model) -> list[tuple[str, str]]:
    """``nuisance_pairs`` of ``model``'s scene but those its likelihood leaves out: the
    recording rules them out and every draw is checked to stay clear of them
    (``physics.ruled_out``), so none impacts and each would add exactly nothing."""
    left = pair_names(model.simulator.model, model.ruled_out)
    return [p for p in nuisance_pairs(model.scene) if frozenset(p) not in left]


def scale_name(pair) -> str:
    return f"{PREFIX}{pair[0]},{pair[1]}"


def augmented_scene(scene, pairs):
    """``scene`` with each pair's restitution coefficient multiplied by its value
    ``scale_name(pair)`` (a restitution effect added with the elastic 1 where it has none)."""
    by_key = {frozenset(p): p for p in pairs}
    effects, done = [], set()
    for use in scene.effects:
        key = frozenset(use.target)
        if use.effect == "restitution" and key in by_key:
            params = dict(use.params)
            params[SUGAR_PARAM] = Binary("*", params[SUGAR_PARAM], Ref(scale_name(by_key[key])))
            use = dataclasses.replace(use, params=params)
            done.add(key)
        effects.append(use)
    for key, pair in by_key.items():
        if key not in done:  # elastic by default: the coefficient is the scale itself
            effects.append(EffectUse("restitution", tuple(pair), {SUGAR_PARAM: Ref(scale_name(pair))}))
    return dataclasses.replace(scene, effects=tuple(effects))


def _residual_fn(model, problem, pairs):
    """(x (d,), scales (P,)) -> ``_residual_program`` at the Problem's data, as numpy."""
    fn = _residual_program(model, problem, pairs)
    return lambda x, scales: np.asarray(fn(jnp.asarray(x), jnp.asarray(scales), problem.data))


def residuals_ahead(model, problem) -> None:
    """Start compiling ``marginal_covariance``'s rollout program (``physdsl.ahead``) where it
    will run: a fit that makes robust intervals compiles it in the background while it
    searches for its modes (``later``: not while it waits for its Gauss-Newton program)."""
    pairs = _nuisance_pairs_to_fit(model, problem)
    if pairs:
        x = jax.ShapeDtypeStruct((problem.dim,), jnp.result_type(float))
        scales = jax.ShapeDtypeStruct((len(pairs),), jnp.result_type(float))
        _residual_program(model, problem, pairs).ahead(x, scales, problem.data, later=True)


def _residual_program(model, problem, pairs) -> Program:
    """(x (d,), scales (P,), data) -> every standardised residual of the augmented scene (one
    vector, ``Model.standardized_residuals``' order, 0 where not measured), compiled once per
    scene structure: x the unconstrained unknowns, scales the pairs' restitution factors."""
    names = [scale_name(p) for p in pairs]

    def build():
        aug = Model(augmented_scene(model.scene, pairs), model.until)
        unravel, _ = unraveler(unconstrained_layout(model))

        def residuals(x, scales, data):
            values = constrain_fn(model.prior_values, (), {}, unravel(x))
            full = {**values, **{n: scales[i] for i, n in enumerate(names)}}
            return aug.standardized_residuals(full, aug.predict(full, data=data), data)

        return Program(residuals)

    return cached(problem, ("contact-law-residuals", tuple(names)), build)


def _nuisance_pairs_to_fit(model, problem) -> list[tuple[str, str]]:
    """``fitted_pairs`` where ``marginal_covariance`` can run (a least-squares curvature, one
    recording), else none."""
    if gauss_newton_fn(problem) is None or getattr(model.scene, "experiments", None) is not None:
        return []
    return fitted_pairs(model)


def _central(f, x, directions, h: float) -> np.ndarray:
    """(N, k): central differences of the vector function ``f`` along each column of
    ``directions`` (d, k) at ``x``, step ``h``."""
    return np.stack([(f(x + h * u) - f(x - h * u)) / (2.0 * h) for u in directions.T], axis=1)


def marginal_covariance(model, problem, mode, width: float = WIDTH) -> dict | None:
    """The unknowns' covariance added by the contact law's nuisances (d, d), with what it
    came from; None where the scene has no pair with a fixed restitution (nothing computed:
    the intervals are those without this term, bit for bit), or no Gauss-Newton curvature.

    The Laplace approximation of the scene with every nuisance pair's log restitution eta
    free under its prior N(0, ``width``^2), at the mode (eta = 0), marginalised over eta:
    Cov(theta) = H^-1 + H^-1 J^T G M^-1 G^T J H^-1, M = G^T G + width^-2 - G^T J H^-1 J^T G
    (J, G: the standardised residuals' derivatives in theta and eta; H: the fit's curvature).
    The added term only widens. Where the data cannot tell a change of the law from a change
    of the unknowns (G in the span of J), the law's prior width passes into the unknowns whole
    (the sensitivity d theta / d eta times ``width``); where they can, the data's own precision
    on eta does. J and G by central differences of the augmented scene's rollout (no
    refit, no second Jacobian program); H is the fit's own Gauss-Newton curvature."""
    pairs = _nuisance_pairs_to_fit(model, problem)
    if not pairs:
        return None
    gn = gauss_newton_fn(problem)
    mode = np.asarray(mode, dtype=float)
    H = np.asarray(gn(mode)[2], dtype=float)
    L = np.linalg.cholesky(np.linalg.inv(0.5 * (H + H.T)))  # posterior sd's axes: L L^T = H^-1
    f = _residual_fn(model, problem, pairs)
    one = np.ones(len(pairs))
    G = _central(lambda e: f(mode, np.exp(e)), np.zeros(len(pairs)), np.eye(len(pairs)), STEP)
    moved = np.flatnonzero(np.any(G != 0.0, axis=0))  # the pairs that impact in the record
    if moved.size == 0:
        return {"cov": np.zeros_like(H), "pairs": [], "eta_sd": [], "width": width}
    G = G[:, moved]
    Jw = _central(lambda x: f(x, one), mode, L, WHITE_STEP)  # J L: the whitened Jacobian
    A = Jw.T @ G  # (d, P): H_theta,eta in whitened theta (H_theta,theta = I there)
    lam, U = np.linalg.eigh(G.T @ G - A.T @ A)  # the data's information on eta given theta
    M = (U * np.maximum(lam, 0.0)) @ U.T + np.eye(moved.size) / width ** 2
    Vw = A @ np.linalg.solve(M, A.T)
    return {"cov": L @ (0.5 * (Vw + Vw.T)) @ L.T,
            "pairs": [f"{pairs[i][0]},{pairs[i][1]}" for i in moved],
            "eta_sd": np.sqrt(np.diag(np.linalg.inv(M))).tolist(), "width": width}


__all__ = ["WIDTH", "METHOD", "nuisance_pairs", "fitted_pairs", "augmented_scene", "marginal_covariance",
           "residuals_ahead"]
