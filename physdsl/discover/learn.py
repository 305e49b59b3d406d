"""A learned residual force added to a fitted scene and trained jointly with its unknowns.

The residual (``residual_force`` on a body, ``residual_joint_force`` on a hinge or slider) is
written into the scene's text like any effect, its network weights one vector unknown with a
normal prior: MAP (Levenberg-Marquardt, ``infer.fit.quick_fit``) is training with weight
decay, and its Laplace approximation the uncertainty. Its feature and force scales are read
off the scene's own fit (speeds, distances and joint ranges it reaches; the weight or gravity
torque of the target), so the prior N(0, 1) on the weights means "a force of a fraction of
the target's weight".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jax
import jax.numpy as jnp

from ..compile import Model
from ..diagnose.edits import load_text
from ..diagnose.evidence import MODE_SLACK, quadratic_log_evidence
from ..diagnose.workflow import check_model, point_estimate
from ..infer import levenberg_marquardt
from ..infer.levenberg_marquardt import newton_gain
from ..infer.base import Settings, cached, gauss_newton, value_fn
from ..infer.fit import FIT_DRAWS
from ..infer.problem import (least_squares_parts, model_problem, start_position,
                             unconstrained_layout, unraveler)
from ..infer.output import build_inference_data
from ..syntax.edit import add_effect

FORCE_FRACTION = 0.3  # the residual's force scale, as a fraction of the target's weight (torque)
G = 9.81
LEARN_STEPS = 300  # Levenberg-Marquardt steps (most fits converge in far fewer)
HIDDEN = 8  # hidden units: 99 weights on a body, 33 in a joint (16 gave 195 and 65)


@dataclass
class Fit:
    """A scene fitted: its Model, posterior, check report and most likely values."""

    model: object
    idata: object
    report: object
    values: dict
    log_z: float | None = None  # Laplace log evidence where the fit computed it already

    @property
    def rms(self) -> float:
        return float(self.report.rms_sigma)


def fitted(model, idata) -> Fit:
    """The Fit of ``model`` with posterior ``idata`` (checked at its most likely draw)."""
    return Fit(model, idata, check_model(model, idata), point_estimate(model, idata))


def target_kind(scene, target: str) -> str:
    """'body', 'hinge' or 'slider': what a residual force on ``target`` acts on."""
    joint = next((j for j in scene.joints if j.name == target), None)
    if joint is None:
        return "body"
    return joint.kind


def residual_effect(kind: str) -> str:
    return "residual_force" if kind == "body" else "residual_joint_force"


def _fmt(x: float) -> str:
    return f"{float(x):.4g}"


def residual_fields(base: Fit, target: str, kind: str, hidden: int, center=(0.0, 0.0, 0.0)):
    """The residual's fields (.phys text): scales from the base fit's rollout and masses."""
    sim = base.model.simulator
    roll = sim.simulate(base.values)
    prm = sim.params(base.values)
    if kind == "body":
        b = sim.body_names.index(target)
        v = np.asarray(roll.body_vel)[:, b]
        d = np.asarray(roll.body_pos)[:, b] - np.asarray(center)
        mass = float(np.asarray(prm["mass"])[b])
        return {"scale": f"{_fmt(FORCE_FRACTION * mass * G)} N",
                "speed": f"{_fmt(max(np.max(np.linalg.norm(v, axis=1)), 0.1))} m/s",
                "length": f"{_fmt(max(np.max(np.linalg.norm(d, axis=1)), 0.01))} m",
                "center": "(" + ", ".join(_fmt(c) for c in center) + ") m",
                "hidden": str(hidden)}
    j = sim.joint_names.index(target)
    q, qd = np.asarray(roll.joint_pos)[:, j], np.asarray(roll.joint_vel)[:, j]
    joint = base.model.scene.joints[j]
    child = sim.body_names.index(joint.child)
    mass = float(np.asarray(prm["mass"])[child])
    lever = float(np.linalg.norm(np.asarray(prm["ref_pos"])[child] - np.asarray(prm["anchor"])[child]))
    hinge = kind == "hinge"
    torque = FORCE_FRACTION * mass * G * (max(lever, 0.01) if hinge else 1.0)
    return {"scale": f"{_fmt(torque)} {'N*m' if hinge else 'N'}",
            "span": f"{_fmt(max(np.max(np.abs(q)), 1e-2))} {'rad' if hinge else 'm'}",
            "rate": f"{_fmt(max(np.max(np.abs(qd)), 1e-2))} {'rad/s' if hinge else 'm/s'}",
            "hidden": str(hidden)}


def with_residual(base: Fit, target: str, hidden: int = HIDDEN, center=(0.0, 0.0, 0.0)):
    """The base fit's scene with a residual force on ``target`` (a new Scene)."""
    scene = base.model.scene
    kind = target_kind(scene, target)
    fields = residual_fields(base, target, kind, hidden, center)
    text = add_effect(scene.source, residual_effect(kind), target, fields)
    return load_text(scene, text)


def learner(problem):
    """x -> (log p, gradient, Gauss-Newton matrix) of ``problem`` for any number of unknowns.

    The inference's own Gauss-Newton stops at ``FORWARD_MODE_MAX`` unknowns (beyond, MAP runs
    L-BFGS on reverse-mode gradients): a network's weights number tens to hundreds, and
    L-BFGS crawls on them (1000 steps left the learned force short of a mode). Here the
    residuals' Jacobian is taken in forward mode over every unknown at once
    (``base.gauss_newton``), so Levenberg-Marquardt trains the network in tens of steps."""
    model = problem.model
    wr, nlp = least_squares_parts(model, unraveler(unconstrained_layout(model))[0])
    fn, prior = cached(problem, "learner", lambda: (jax.jit(gauss_newton(wr)),
                                                     jax.jit(jax.hessian(nlp))))
    data = problem.data

    def gn(x):
        v, g, JJ = fn(x, data)
        return v, g, JJ + prior(x)

    return gn


def fit_residual(base: Fit, target: str, hidden: int = HIDDEN, center=(0.0, 0.0, 0.0),
                 seed: int = 0) -> Fit:
    """Fit the scene plus a residual force on ``target`` by Levenberg-Marquardt (``learner``)
    from the base fit's values and small random weights (all-zero weights are a saddle of the
    network: no gradient reaches the first layer); its posterior the Laplace approximation
    with the Gauss-Newton matrix at that mode (``gn_laplace``). ``Fit.log_z``: the Laplace
    evidence from the same matrix (as ``laplace_log_evidence`` takes it)."""
    model = Model(with_residual(base, target, hidden, center))
    key = next(u for u in model.unknowns if u.name.endswith(".weights"))
    rng = np.random.default_rng(seed)
    start = {**base.values, key.name: 0.1 * rng.standard_normal(key.shape)}
    problem = model_problem(model)
    gn = learner(problem)
    x = levenberg_marquardt.run(gn, start_position(problem, jax.random.PRNGKey(seed), start),
                            LEARN_STEPS, value_fn(problem))
    v, g, H = (np.asarray(a, dtype=float) for a in gn(jnp.asarray(x)))
    fit = fitted(model, gn_laplace(model, problem, x, H, seed))
    fit.log_z = (quadratic_log_evidence(float(v), g, H)
                 if newton_gain(H, g) <= MODE_SLACK else None)
    return fit


def gn_laplace(model, problem, mode, H, seed: int = 0, chains: int = 2):
    """InferenceData of the Laplace approximation N(mode, H^-1) with H the Gauss-Newton matrix
    (J^T J + the prior's Hessian): the generalized Gauss-Newton Laplace usual for networks,
    positive definite where the exact Hessian of a network's log density has directions of
    negative curvature (the MAP backend's central differences then fail: measured on the
    sqrt-drag ball, 12 of 105 directions). Draw 0 of each chain is the mode itself."""
    w, vecs = np.linalg.eigh(0.5 * (H + H.T))
    w = np.maximum(w, 1e-12 * max(float(np.max(w)), 1e-300))
    z = np.random.default_rng(seed).standard_normal((chains, FIT_DRAWS, mode.size))
    flat = mode + z @ (vecs / np.sqrt(w)).T
    flat[:, 0] = mode  # the check judges the force at its mode: draws of a network's weights
    # from a Gaussian move the force far more than the data allow (the nonlinear predictive of
    # a Gauss-Newton Laplace underfits; Immer, Korzepa & Bauer 2021), so none is near the mode
    settings = Settings(chains=chains, samples=FIT_DRAWS, seed=seed, intervals="model")
    idata = build_inference_data(model, problem, flat, {}, settings)
    idata.attrs["laplace"] = "gauss-newton"  # not the MAP backend's central differences
    return idata
