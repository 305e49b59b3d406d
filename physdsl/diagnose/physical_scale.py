"""Physical sense of a fitted effect: its scale from the scene (a body's size and the medium for
drag, a joint's load for joint damping and friction), the dimensionless number that decides
which law holds, and whether a fitted strength is plausible.

Stokes drag on a sphere is b = 6πμr (Re ≲ 1); quadratic drag is c = ½ρC_dA with C_d of a
blunt body between ``CD_RANGE`` (Re ≳ 10³). A linear drag fitted far above Stokes
(> ``IMPLAUSIBLE`` ×) stands in for some other loss, and in air at Re ~ 10⁴-10⁵ that loss is
quadratic drag.

A joint's load is m g L: the mass m beyond the joint (every body it carries) times g times the
lever arm L from the hinge axis to that mass's centre (m g on a slider). Coulomb friction in a
joint is T = μ_J m g L with μ_J over ``FRICTION_RANGE`` like a friction coefficient (beyond it
the joint would hold its load in any pose); viscous damping b is measured against critical
damping b_c = 2 m L √(g L) (the point-mass pendulum's), and a damping ratio b / b_c above
``DAMPING_IMPLAUSIBLE`` is flagged. A contact friction coefficient above ``FRICTION_RANGE`` is
flagged too. The diagnosis reports these numbers beside the evidence (``notes``) and, where
the evidence ties two laws, prefers the physically plausible one (``plausible_first``).
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ..expr import constant_value, evaluate, is_constant, references
from ..media import MEDIA
from .workflow import point_estimate

CD_RANGE = (0.05, 2.0)  # drag coefficients of real bodies (streamlined .. flat plate)
IMPLAUSIBLE = 100.0  # fitted linear drag above this many Stokes drags is not viscous drag
DRAG = ("linear_drag", "quadratic_drag")
G = 9.81  # m/s², the load's scale (the scene's own gravity may differ a little)
FRICTION_RANGE = (0.0, 1.5)  # friction coefficients of real surfaces (ice .. rubber on rubber)
DAMPING_IMPLAUSIBLE = 10.0  # a joint damped beyond ten times critical is not a hinge's loss
JOINT_LAWS = ("joint_damping", "joint_friction")
DAMPING_RATIO_PRIOR_SD = 0.3  # half-normal sd of b / b_c: light (0.01) to critical damping
FRICTION_PRIOR_SD = 0.3  # half-normal sd of T / (m g L)


def _const(expr):
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
    """The body's speeds over the recording (every recording's, for a pooled Model) at the
    fit (the most likely draw)."""
    rolls = model.recording_rollouts(model.simulate(point_estimate(model, idata)))
    i = model.simulator.body_names.index(body)
    return np.concatenate([np.linalg.norm(np.asarray(r.body_vel)[:, i], axis=-1) for r in rolls])


def judge_drag(scene, effect: str, body_name: str, fitted: float, speed: np.ndarray) -> dict:
    """What physics says of a fitted drag strength on a body: the Reynolds range, the strength
    over its physical scale, and ``plausible`` (False: an implausible value)."""
    body = next(b for b in scene.bodies if b.name == body_name)
    out = {"effect": effect, "body": body_name, "target": body_name, "medium": scene.world.medium,
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


def typical_values(scene) -> dict[str, np.ndarray]:
    """A typical value of every unknown with a located prior (a normal's or lognormal's centre,
    a uniform's middle): where a scale is needed before any fit (a candidate's prior)."""
    out = {}
    for u in scene.unknowns:
        p, args = u.prior, u.prior.args
        if not args or not all(is_constant(a) for a in args):
            continue
        vals = [constant_value(a) for a in args]
        if p.dist == "normal":
            out[u.name] = vals[0]
        elif p.dist == "lognormal":
            out[u.name] = np.exp(vals[0])
        elif p.dist == "uniform" and len(vals) == 2:
            out[u.name] = (vals[0] + vals[1]) / 2
    return out


def _value(expr, values: Mapping) -> np.ndarray | None:
    """``expr``'s value given ``values``, or None where it is absent or needs another unknown."""
    if expr is None or not references(expr) <= set(values):
        return None
    return np.asarray(evaluate(expr, values), dtype=float)


def carried(scene, joint) -> list:
    """The bodies a joint carries: its child and every body jointed below it."""
    names, todo = set(), [joint.child]
    while todo:
        name = todo.pop()
        if name in names:
            continue
        names.add(name)
        todo += [j.child for j in scene.joints if j.parent == name]
    return [b for b in scene.bodies if b.name in names]


def joint_load(scene, joint_name: str, values: Mapping = {}) -> dict | None:
    """The load of a hinge or slider in its reference pose: carried mass m (kg), lever arm L (m,
    from the hinge axis to the carried centre of mass; None on a slider) and ``load`` = m g L
    (N m) on a hinge, m g (N) on a slider. None where a mass or position is not known."""
    joint = next((j for j in scene.joints if j.name == joint_name), None)
    if joint is None or joint.kind not in ("hinge", "slider"):
        return None
    bodies = carried(scene, joint)
    masses = [_value(b.mass, values) for b in bodies]
    if not bodies or any(m is None for m in masses):
        return None
    m = float(sum(masses))
    if joint.kind == "slider":
        return {"joint": joint_name, "kind": "slider", "mass": m, "arm": None, "load": m * G}
    places = [_value(b.position, values) for b in bodies]
    anchor, axis = _value(joint.anchor, values), _value(joint.axis, values)
    if any(p is None for p in places) or anchor is None or axis is None or m <= 0:
        return None
    centre = sum(mi * p for mi, p in zip(masses, places)) / m - anchor
    axis = axis / np.linalg.norm(axis)
    arm = float(np.linalg.norm(centre - np.dot(centre, axis) * axis))
    return {"joint": joint_name, "kind": "hinge", "mass": m, "arm": arm, "load": m * G * arm}


def critical_damping(load: dict) -> float | None:
    """Critical damping 2 m L √(g L) (N m s/rad) of a hinge's load as a point-mass pendulum;
    None on a slider (no length, no natural frequency) or with no lever arm."""
    if load is None or load["kind"] != "hinge" or not load["arm"]:
        return None
    return 2 * load["mass"] * load["arm"] * math.sqrt(G * load["arm"])


def judge_joint(scene, effect: str, joint_name: str, fitted: float, values: Mapping = {}) -> dict:
    """What physics says of a fitted joint damping or friction: the joint's load m g L, the
    damping ratio b / b_c or the friction coefficient T / (m g L), and ``plausible``."""
    load = joint_load(scene, joint_name, values)
    out = {"effect": effect, "target": joint_name, "plausible": True,
           "load": None if load is None else load["load"]}
    if load is None:
        return out
    if effect == "joint_friction":
        out["friction_coefficient"] = fitted / load["load"]
        out["plausible"] = out["friction_coefficient"] <= FRICTION_RANGE[1]
    elif effect == "joint_damping":
        bc = critical_damping(load)
        if bc:
            out["damping_ratio"] = fitted / bc
            out["plausible"] = out["damping_ratio"] <= DAMPING_IMPLAUSIBLE
    return out


def judge_contact_friction(pair: str, fitted: float) -> dict:
    """A fitted contact friction coefficient against the range of real surfaces."""
    return {"effect": "contact_friction", "target": pair, "friction_coefficient": fitted,
            "plausible": FRICTION_RANGE[0] <= fitted <= FRICTION_RANGE[1]}


def text(j: dict) -> str:
    """One line of a ``judge_drag`` / ``judge_joint`` / ``judge_contact_friction`` result."""
    parts = [f"{j['effect']} on {j['target']}"]
    if "times_stokes" in j:
        parts.append(f"fitted {j['times_stokes']:.2g}× Stokes drag in {j['medium']}")
    if "cd" in j:
        parts.append(f"C_d = {j['cd']:.2g}")
    if j.get("reynolds"):
        parts.append(f"Re {j['reynolds'][0]:.2g}–{j['reynolds'][1]:.2g} at "
                     f"{j['speed'][0]:.3g}–{j['speed'][1]:.3g} m/s")
    if "damping_ratio" in j:
        parts.append(f"damping ratio {j['damping_ratio']:.2g} of critical (load m g L = {j['load']:.3g} N m)")
    if "friction_coefficient" in j:
        parts.append(f"friction coefficient {j['friction_coefficient']:.2g}" +
                     (f" of the load {j['load']:.3g}" if j.get("load") else "") +
                     f" (real surfaces {FRICTION_RANGE[0]:g}–{FRICTION_RANGE[1]:g})")
    return ": ".join(parts[:1]) + " " + ", ".join(parts[1:]) + \
        ("" if j["plausible"] else " (physically implausible)")


def notes(model, idata, ranked) -> list[dict]:
    """What physics says of every refitted drag on a body, damping or friction on a joint and
    contact friction on a pair (ranked rows with a fit), judged at the fit."""
    out, cache, values = [], {}, None
    scene = model.scene
    for r in ranked:
        if r.kind != "effect" or not r.fitted:
            continue
        fitted = float(r.fitted["median"])
        if r.effect in DRAG and any(b.name == r.target for b in scene.bodies):
            if r.target not in cache:
                cache[r.target] = speeds(model, idata, r.target)
            out.append(judge_drag(scene, r.effect, r.target, fitted, cache[r.target]))
        elif r.effect in JOINT_LAWS and any(j.name == r.target for j in scene.joints):
            values = point_estimate(model, idata) if values is None else values
            out.append(judge_joint(scene, r.effect, r.target, fitted, values))
        elif r.effect == "contact_friction" and "," in r.target and not r.target.endswith("*"):
            out.append(judge_contact_friction(r.target, fitted))
    return out


CD_PRIOR_SD = 1.0  # half-normal sd of C_d: covers 0.05-2 (its 4% and 95% points)


def prior_text(scene, cand) -> str | None:
    """The physical prior of a candidate's strength where physics gives a scale, else None
    (the library prior serves): quadratic drag on a body ~ half_normal(½ρ C_d A) with C_d's sd
    ``CD_PRIOR_SD``, in the world's medium; joint damping ~ half_normal(``DAMPING_RATIO_PRIOR_SD``
    b_c) and joint friction ~ half_normal(``FRICTION_PRIOR_SD`` m g L) from the joint's load at
    the unknowns' typical values (a group: the widest of its joints')."""
    if cand.kind != "effect" or len(cand.target) != 1:
        return None
    if cand.name == "quadratic_drag":
        body = next((b for b in scene.bodies if b.name == cand.target[0]), None)
        c = quadratic(scene, body, CD_PRIOR_SD) if body is not None else None
        return f"~ half_normal({c:.6g})" if c else None
    if cand.name not in JOINT_LAWS:
        return None
    values = typical_values(scene)
    scales = []
    for part in cand.parts():
        load = joint_load(scene, part.target[0], values)
        scale = (None if load is None else FRICTION_PRIOR_SD * load["load"] if cand.name == "joint_friction"
                 else None if critical_damping(load) is None else DAMPING_RATIO_PRIOR_SD * critical_damping(load))
        if not scale:
            return None  # one joint without a scale: the library's prior for the whole group
        scales.append(scale)
    return f"~ half_normal({max(scales):.6g})"
