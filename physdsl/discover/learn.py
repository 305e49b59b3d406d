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

from ..compile import Model
from ..diagnose.edits import load_text
from ..diagnose.workflow import check_model, point_estimate
from ..infer.fit import FIT_DRAWS, fit_with_fallback, start_setting
from ..syntax.edit import add_effect

FORCE_FRACTION = 0.3  # the residual's force scale, as a fraction of the target's weight (torque)
G = 9.81
LEARN_STEPS = 1000  # Levenberg-Marquardt steps: a network's weights need more than a refit's 300


@dataclass
class Fit:
    """A scene fitted: its Model, posterior, check report and most likely values."""

    model: object
    idata: object
    report: object
    values: dict

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


def with_residual(base: Fit, target: str, hidden: int = 16, center=(0.0, 0.0, 0.0)):
    """The base fit's scene with a residual force on ``target`` (a new Scene)."""
    scene = base.model.scene
    kind = target_kind(scene, target)
    fields = residual_fields(base, target, kind, hidden, center)
    text = add_effect(scene.source, residual_effect(kind), target, fields)
    return load_text(scene, text)


def fit_residual(base: Fit, target: str, hidden: int = 16, center=(0.0, 0.0, 0.0),
                 seed: int = 0) -> Fit:
    """Fit the scene plus a residual force on ``target``, from the base fit's values and
    small random weights (all-zero weights are a saddle of the network: no gradient reaches
    the first layer)."""
    model = Model(with_residual(base, target, hidden, center))
    key = next(u for u in model.unknowns if u.name.endswith(".weights"))
    rng = np.random.default_rng(seed)
    start = {**base.values, key.name: 0.1 * rng.standard_normal(key.shape)}
    idata = fit_with_fallback(model, "map", chains=2, warmup=LEARN_STEPS, samples=FIT_DRAWS,
                              seed=seed, progress=False, start=start_setting(start))
    return fitted(model, idata)
