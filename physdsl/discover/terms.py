"""The dictionary a learned force is distilled on: candidate terms of a body's or a joint's
state, each with its unit, so every law written from them is checked like any effect.

A body term is a vector field phi(v, d) (d = x - center) times a scalar coefficient; a joint
term is a scalar function of (q, qdot). The coefficient's unit is the force's over the term's
(``coefficient_unit``). Fractional powers of speed are taken of |v| / (1 m/s), so every unit
has whole exponents. Terms the library already holds (v: linear drag, |v| v: quadratic drag,
q: joint spring, qdot: joint damping, tanh(qdot/eps): joint friction) are in the dictionary
too, so a distilled law that needs only them says so.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import jax.numpy as jnp

FRICTION_SMOOTHING = 0.01  # rad/s or m/s: tanh(qdot / this) stands for sign(qdot)
EPS = 1e-12


def _norm(x):
    return jnp.sqrt(jnp.sum(x * x, axis=-1, keepdims=True) + EPS * EPS)


@dataclass(frozen=True)
class Term:
    """One candidate term: ``name`` (a .phys parameter name), what it is in words, its unit
    (body: of the vector field; joint: hinge and slider), and its value ``fn``."""

    name: str
    words: str
    unit: tuple[str, ...]  # body: (term unit,); joint: (hinge term unit, slider term unit)
    fn: Callable  # body: (v (..., 3), d (..., 3)) -> (..., 3); joint: (q, qd) -> same shape


BODY_TERMS = (
    Term("v", "v", ("m/s",), lambda v, d: v),
    Term("v_sqrt_speed", "sqrt(|v| / (1 m/s)) v", ("m/s",), lambda v, d: jnp.sqrt(_norm(v)) * v),
    Term("v_speed", "|v| v", ("m^2/s^2",), lambda v, d: _norm(v) * v),
    Term("v_speed2", "|v|^2 v", ("m^3/s^3",), lambda v, d: _norm(v) ** 2 * v),
    Term("d", "d", ("m",), lambda v, d: d),
    Term("d_norm", "|d| d", ("m^2",), lambda v, d: _norm(d) * d),
    Term("d_inv", "d / |d|^2", ("1/m",), lambda v, d: d / _norm(d) ** 2),
    Term("d_inv2", "d / |d|^3", ("1/m^2",), lambda v, d: d / _norm(d) ** 3),
)

JOINT_TERMS = (
    Term("q", "q", ("rad", "m"), lambda q, qd: q),
    Term("q3", "q^3", ("rad^3", "m^3"), lambda q, qd: q ** 3),
    Term("qdot", "qdot", ("rad/s", "m/s"), lambda q, qd: qd),
    Term("qdot_abs", "qdot |qdot|", ("rad^2/s^2", "m^2/s^2"), lambda q, qd: qd * jnp.abs(qd)),
    Term("qdot3", "qdot^3", ("rad^3/s^3", "m^3/s^3"), lambda q, qd: qd ** 3),
    Term("sign_qdot", f"tanh(qdot / {FRICTION_SMOOTHING})", ("1", "1"),
         lambda q, qd: jnp.tanh(qd / FRICTION_SMOOTHING)),
)

TERMS = {t.name: t for t in BODY_TERMS + JOINT_TERMS}
FORCE_UNIT = {"body": "N", "hinge": "N*m", "slider": "N"}


def terms_for(kind: str) -> tuple[Term, ...]:
    """The dictionary of a body ("body") or a joint ("hinge", "slider")."""
    return BODY_TERMS if kind == "body" else JOINT_TERMS


def coefficient_unit(term: Term, kind: str) -> str:
    """The unit of ``term``'s coefficient on a target of ``kind``: force unit / term unit
    (read left to right: N/m^2*s^2 is N s^2 / m^2)."""
    unit = term.unit[1] if kind == "slider" else term.unit[0]
    force = FORCE_UNIT[kind]
    if unit == "1":
        return force
    num, *den = unit.split("/")
    out = force if num == "1" else f"{force}/{num.replace('*', '/')}"
    return "*".join([out, *den])


def law(terms: tuple[Term, ...], coefficients: dict, a, b):
    """Sum of the ``terms`` named in ``coefficients`` (name -> scalar) at the state (a, b):
    (v, d) for a body, (q, qdot) for a joint."""
    out = jnp.zeros_like(a)
    for t in terms:
        if t.name in coefficients:
            out = out + coefficients[t.name] * t.fn(a, b)
    return out


def body_law(coefficients: dict, v, d):
    """The body law at (v, d)."""
    return law(BODY_TERMS, coefficients, v, d)


def joint_law(coefficients: dict, q, qd):
    """The joint law at (q, qdot)."""
    return law(JOINT_TERMS, coefficients, q, qd)
