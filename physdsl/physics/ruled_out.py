"""Contact pairs that a recording rules out: the fit's programs need not simulate them.

A pair is ruled out when the measurements keep its two bodies apart over the whole simulated
horizon by more than the contact margin plus ``CLEARANCE_SIGMAS`` noise scales (and what the
body may dip between two samples). Each side must be either a static body whose pose and shape
are constants, or a free body whose position is measured (no sensor model, constant noise)
from the first step to the last. This is a forecast: a fit run without the pairs is checked
afterwards against the exact rule of ``idle.clear`` on every draw (``Model.contact_reached``),
and run again with every contact where a draw comes within reach.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from ..expr import evaluate, references
from ..scene import Scene
from .contact import contact_margin
from .idle import PRIMITIVES, bounding_radius
from .inertia import contact_size
from .params import shape_size
from .structure import PhysicsModel

CLEARANCE_SIGMAS = 4.0  # noise scales of clearance beyond the contact margin
ACCEL_BOUND = 30.0  # m/s^2: how fast a body may curve away from the line between two samples


def ruled_out_pairs(scene: Scene, model: PhysicsModel, until: float | None = None
                    ) -> tuple[int, ...]:
    """Indices into ``model.pairs`` of the pairs the recording keeps apart (see the module);
    none where the fit sees only data up to ``until`` (the rest of the horizon is unmeasured)."""
    if not model.ncon or until is not None:
        return ()
    end = model.nsteps * model.dt
    out = []
    for k, p in enumerate(model.pairs):
        if p.kind_a not in PRIMITIVES or p.kind_b not in PRIMITIVES:
            continue
        a, b = _side(scene, model, p.a, end), _side(scene, model, p.b, end)
        if a is None or b is None or (a.track is None and b.track is None):
            continue
        if a.track is None or a.normal is not None:
            a, b = b, a  # the measured one first; a plane second
        gap = _gap(a, b)
        if gap is not None and gap > contact_margin:
            out.append(k)
    return tuple(out)


class _Side(NamedTuple):
    """One body of a pair as the recording sees it: a measured track (times, positions, the
    clearance it must keep) or a constant point; its bounding radius; a plane's normal."""

    track: np.ndarray | None = None
    times: np.ndarray | None = None
    point: np.ndarray | None = None
    radius: float = 0.0
    normal: np.ndarray | None = None
    slack: float = 0.0


def _side(scene: Scene, model: PhysicsModel, i: int, end: float):
    body, joint = scene.bodies[i], model.joints[i]
    shape = body.shape
    if shape is None or _refs(shape.size.values()):
        return None
    csize = np.asarray(contact_size(shape.kind, shape_size(shape, {})), float)
    if joint.kind == "fixed" and joint.parent < 0:
        if _refs([body.position, body.orientation]):
            return None
        point = (np.zeros(3) if body.position is None
                 else np.asarray(evaluate(body.position, {}), float))
        if shape.kind == "plane":
            return _Side(point=point, normal=csize / np.linalg.norm(csize))
        # (a bounding sphere: the body's orientation does not matter)
        return _Side(point=point, radius=float(bounding_radius(shape.kind, csize)))
    if joint.kind != "free" or joint.parent >= 0 or shape.kind == "plane":
        return None
    track = _measured_track(scene, body.name, model.dt, end)
    if track is None:
        return None
    times, pos, sigma = track
    gaps = np.diff(times)
    slack = CLEARANCE_SIGMAS * sigma + ACCEL_BOUND * float(gaps.max(initial=0.0)) ** 2 / 8
    return _Side(track=pos, times=times, radius=float(bounding_radius(shape.kind, csize)),
                 slack=slack)


def _measured_track(scene: Scene, body: str, dt: float, end: float):
    """(times, positions (N, 3), noise scale) of ``body``'s measured position where it covers
    the horizon from the first step to the last; else None."""
    for o in scene.observations:
        if o.quantity != "position" or o.target != body or o.sensor is not None:
            continue
        if _refs([o.noise.scale]):
            continue
        rows = o.mask.all(axis=1)
        times = np.asarray(o.times, float)[rows]
        if len(times) < 2 or times[0] > dt + 1e-12 or times[-1] < end - dt - 1e-12:
            continue
        sigma = float(np.max(np.asarray(evaluate(o.noise.scale, {}), float)))
        return times, np.asarray(o.values, float)[rows], sigma
    return None


def _gap(a: _Side, b: _Side):
    """Smallest measured clearance of the pair less what each side must keep (None where it
    cannot be told: two tracks sampled at other times)."""
    if b.normal is not None:
        dist = (a.track - b.point) @ b.normal - a.radius
        return float(dist.min()) - a.slack
    if b.track is None:
        dist = np.linalg.norm(a.track - b.point, axis=1) - a.radius - b.radius
        return float(dist.min()) - a.slack
    if a.times.shape != b.times.shape or not np.allclose(a.times, b.times):
        return None
    dist = np.linalg.norm(a.track - b.track, axis=1) - a.radius - b.radius
    return float(dist.min()) - a.slack - b.slack


def _refs(exprs) -> bool:
    """Whether any of ``exprs`` names an unknown (after resolve, only unknowns are names)."""
    return any(references(e) for e in exprs if e is not None)


def without_pairs(scene: Scene, model: PhysicsModel, pairs: tuple[int, ...]) -> Scene:
    """``scene`` without the contact pairs ``pairs`` (indices into ``model.pairs``): the scene
    the likelihood simulates."""
    names = model.body_names
    drop = {frozenset((names[model.pairs[k].a], names[model.pairs[k].b])) for k in pairs}
    return dataclasses.replace(scene, contact_pairs=tuple(
        p for p in scene.contact_pairs if frozenset(p) not in drop))
