"""Physical sense of a drag law: its scale from the body's size and the medium, the Reynolds
number that decides which law holds, and whether a fitted strength is plausible.

Stokes drag on a sphere is b = 6πμr (Re ≲ 1); quadratic drag is c = ½ρC_dA with C_d of a
blunt body between ``CD_RANGE`` (Re ≳ 10³). A linear drag fitted far above Stokes
(> ``IMPLAUSIBLE`` ×) stands in for some other loss, and in air at Re ~ 10⁴-10⁵ that loss is
quadratic drag. The diagnosis reports these numbers beside the evidence (``notes``) and, where
the evidence ties two drag laws, prefers the physically plausible one (``plausible_first``).
"""
from __future__ import annotations

import math

import numpy as np

from ..media import MEDIA

CD_RANGE = (0.05, 2.0)  # drag coefficients of real bodies (streamlined .. flat plate)
IMPLAUSIBLE = 100.0  # fitted linear drag above this many Stokes drags is not viscous drag
DRAG = ("linear_drag", "quadratic_drag")


def _const(expr):
    from ..expr import constant_value, is_constant

    return float(np.max(constant_value(expr))) if expr is not None and is_constant(expr) else None


def radius(body) -> float | None:
    """A body's drag radius: a sphere's, a cylinder's or capsule's, half a box's largest side."""
    if body.shape is None:
        return None
    size = body.shape.size
    if "radius" in size:
        return _const(size["radius"])
    if "size" in size:
        s = _const(size["size"])
        return None if s is None else s / 2
    return None


def medium(scene):
    return MEDIA[getattr(scene.world, "medium", "air")]


def stokes(scene, body) -> float | None:
    """Stokes drag coefficient 6πμr (kg/s) of ``body`` in the scene's medium."""
    r = radius(body)
    return None if r is None else 6 * math.pi * medium(scene).viscosity * r


def quadratic(scene, body, cd: float = 1.0) -> float | None:
    """Quadratic drag coefficient ½ρC_dA (kg/m) of ``body`` for drag coefficient ``cd``."""
    r = radius(body)
    return None if r is None else 0.5 * medium(scene).density * cd * math.pi * r * r


def reynolds(scene, body, speed: float) -> float | None:
    """ρ v d / μ of ``body`` moving at ``speed`` in the scene's medium."""
    r, m = radius(body), medium(scene)
    return None if r is None or m.viscosity <= 0 else m.density * speed * 2 * r / m.viscosity


def speeds(model, idata, body: str) -> np.ndarray:
    """The body's speeds over the recording at the fit (the most likely draw)."""
    from .workflow import point_estimate

    roll = model.simulate(point_estimate(model, idata))
    v = np.asarray(roll.body_vel)[:, model.simulator.body_names.index(body)]
    return np.linalg.norm(v, axis=-1)


def judge_drag(scene, effect: str, body_name: str, fitted: float, speed: np.ndarray) -> dict:
    """What physics says of a fitted drag strength on a body: the Reynolds range, the strength
    over its physical scale, and ``plausible`` (False: an implausible value)."""
    body = next(b for b in scene.bodies if b.name == body_name)
    out = {"effect": effect, "body": body_name, "medium": scene.world.medium,
           "speed": [float(np.min(speed)), float(np.max(speed))], "plausible": True}
    lo, hi = (reynolds(scene, body, float(v)) for v in out["speed"])
    out["reynolds"] = None if lo is None else [lo, hi]
    if effect == "linear_drag":
        b = stokes(scene, body)
        if b:
            out["times_stokes"] = fitted / b
            out["plausible"] = fitted / b <= IMPLAUSIBLE
    else:
        c1 = quadratic(scene, body)
        if c1:
            out["cd"] = fitted / c1
            out["plausible"] = fitted / c1 <= 5 * CD_RANGE[1]
    return out


def text(j: dict) -> str:
    """One line of a ``judge_drag`` result for the verdict."""
    parts = [f"{j['effect']} on {j['body']}"]
    if "times_stokes" in j:
        parts.append(f"fitted {j['times_stokes']:.2g}× Stokes drag in {j['medium']}")
    if "cd" in j:
        parts.append(f"C_d = {j['cd']:.2g}")
    if j.get("reynolds"):
        parts.append(f"Re {j['reynolds'][0]:.2g}–{j['reynolds'][1]:.2g} at "
                     f"{j['speed'][0]:.3g}–{j['speed'][1]:.3g} m/s")
    return ": ".join(parts[:1]) + " " + ", ".join(parts[1:]) + \
        ("" if j["plausible"] else " (physically implausible)")


def notes(model, idata, ranked) -> list[dict]:
    """``judge_drag`` of every refitted drag candidate on a body (ranked rows with a fit)."""
    out, cache = [], {}
    for r in ranked:
        if r.kind != "effect" or r.effect not in DRAG or not r.fitted or "," in r.target:
            continue
        if not any(b.name == r.target for b in model.scene.bodies):
            continue
        if r.target not in cache:
            cache[r.target] = speeds(model, idata, r.target)
        out.append(judge_drag(model.scene, r.effect, r.target, float(r.fitted["median"]),
                              cache[r.target]))
    return out


CD_PRIOR_SD = 1.0  # half-normal sd of C_d: covers 0.05-2 (its 4% and 95% points)


def prior_text(scene, cand) -> str | None:
    """The physical prior of a candidate's strength where physics gives a scale, else None
    (the library prior serves): quadratic drag on a body ~ half_normal(½ρ C_d A) with C_d's sd
    ``CD_PRIOR_SD``, in the world's medium."""
    if cand.kind != "effect" or cand.name != "quadratic_drag" or len(cand.target) != 1:
        return None
    body = next((b for b in scene.bodies if b.name == cand.target[0]), None)
    c = quadratic(scene, body, CD_PRIOR_SD) if body is not None else None
    return f"~ half_normal({c:.6g})" if c else None

