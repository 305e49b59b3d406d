"""Distil a learned force into a law: sample the network along the fitted motion, regress it on
the dictionary (``terms.py``) by sequentially thresholded least squares (PySINDy's STLSQ) over
a range of thresholds, and keep the distinct sparse supports, sparsest first; each is then
refitted in the scene as ordinary unknowns (``law.py``)."""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..physics.effects.residual_force import body_features, joint_features, network
from ..errors import UsageError
from .terms import terms_for

THRESHOLDS = np.geomspace(1e-3, 0.5, 30)  # on columns and force scaled to unit RMS
MAX_TERMS = 3
SAMPLES = 400


@dataclass
class Samples:
    """The learned force along the fitted motion: states and forces at ``SAMPLES`` times."""

    kind: str  # body | hinge | slider
    a: np.ndarray  # body: v (N, 3); joint: q (N,)
    b: np.ndarray  # body: d = x - center (N, 3); joint: qdot (N,)
    force: np.ndarray  # (N, 3) | (N,)


def learned_samples(fit, target: str, kind: str) -> Samples:
    """The residual force of ``fit`` (its most likely values) at states of its own rollout."""
    sim = fit.model.simulator
    roll = sim.simulate(fit.values)
    prm = sim.params(fit.values)
    k = next(i for i, e in enumerate(fit.model.scene.effects)
             if e.effect.startswith("residual_") and e.target == (target,))
    p = prm["effects"][k]
    idx = np.unique(np.linspace(0, len(roll.t) - 1, SAMPLES).astype(int))
    if kind == "body":
        b = sim.body_names.index(target)
        v = jnp.asarray(roll.body_vel)[idx, b]
        x = jnp.asarray(roll.body_pos)[idx, b]
        f = jax.vmap(lambda v, x: p["scale"] * network(p["weights"], body_features(v, x, p), 3))(v, x)
        return Samples(kind, np.asarray(v), np.asarray(x - p["center"]), np.asarray(f))
    j = sim.joint_names.index(target)
    q = jnp.asarray(roll.joint_pos)[idx, j]
    qd = jnp.asarray(roll.joint_vel)[idx, j]
    f = jax.vmap(lambda q, qd: p["scale"] * network(
        p["weights"], joint_features(q[None], qd[None], p), 1)[0])(q, qd)
    return Samples(kind, np.asarray(q), np.asarray(qd), np.asarray(f))


def design(s: Samples) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(Theta (M, K), y (M,), term names): every term's value at the samples, a body's three
    components stacked."""
    terms = terms_for(s.kind)
    cols = [np.asarray(t.fn(jnp.asarray(s.a), jnp.asarray(s.b)), dtype=float).reshape(-1)
            for t in terms]
    return np.stack(cols, axis=1), np.asarray(s.force, dtype=float).reshape(-1), [t.name for t in terms]


@dataclass
class Support:
    """A sparse law: its terms, least-squares coefficients on the learned force (SI) and the
    share of the learned force's variance it leaves unexplained."""

    terms: tuple[str, ...]
    coefficients: dict
    unexplained: float


def lstsq(theta, y, cols) -> tuple[np.ndarray, float]:
    """Least-squares coefficients on ``cols`` and the unexplained share of |y|^2."""
    c, *_ = np.linalg.lstsq(theta[:, cols], y, rcond=None)
    r = y - theta[:, cols] @ c
    return c, float(r @ r / max(y @ y, 1e-300))


def supports(s: Samples, max_terms: int = MAX_TERMS) -> list[Support]:
    """Distinct supports STLSQ finds over ``THRESHOLDS``, at most ``max_terms`` terms each,
    fewest terms first (then best fit); coefficients refitted by least squares."""
    try:  # an optional extra (physdsl[discover]); slow to import, so only where used
        from pysindy.optimizers import STLSQ
    except ImportError as err:
        raise UsageError("distilling a learned force needs PySINDy",
                         hint="pip install 'physdsl[discover]' (pysindy>=2.1)") from err
    theta, y, names = design(s)
    scale = np.sqrt(np.mean(theta ** 2, axis=0)) + 1e-300
    ys = y / (np.sqrt(np.mean(y ** 2)) + 1e-300)
    seen, out = set(), []
    for th in THRESHOLDS:
        opt = STLSQ(threshold=float(th), alpha=1e-6, max_iter=50).fit(theta / scale, ys)
        cols = tuple(int(i) for i in np.flatnonzero(np.abs(np.ravel(opt.coef_)) > 0))
        if not cols or len(cols) > max_terms or cols in seen:
            continue
        seen.add(cols)
        c, u = lstsq(theta, y, list(cols))
        out.append(Support(tuple(names[i] for i in cols), dict(zip((names[i] for i in cols),
                                                                   map(float, c))), u))
    for i in range(len(names)):  # every single term, so the sparsest laws are all tried
        if (i,) not in seen:
            c, u = lstsq(theta, y, [i])
            out.append(Support((names[i],), {names[i]: float(c[0])}, u))
    return sorted(out, key=lambda s: (len(s.terms), s.unexplained))
