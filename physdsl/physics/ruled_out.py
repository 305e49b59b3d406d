"""Contact pairs that a recording rules out: the fit's programs need not simulate them.

A pair is ruled out when the measurements keep its two bodies apart over the whole simulated
horizon by more than the contact margin plus ``CLEARANCE_SIGMAS`` noise scales (and what the
body may dip between two samples). Each side must be a static body whose pose and shape are
constants, a free body whose position is measured (no sensor model, constant noise) from the
first step to the last, or a body of a tree of hinges and sliders hung from the world whose
every joint from the world down is measured so (its positions then follow from the measured
angles by the model's own kinematics; a link of a chain of three or more has pairs with the
links it is not jointed to). This is a forecast: a fit run without the pairs is checked
afterwards against the exact rule of ``idle.clear`` on every draw (``Model.contact_reached``),
and run again with every contact where a draw comes within reach.
"""
from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..expr import evaluate, references
from ..scene import Scene
from .contact import contact_margin
from .idle import PRIMITIVES, bounding_radius
from .inertia import contact_size
from .kinematics import forward_kinematics
from .params import reference_poses, shape_size
from .structure import PhysicsModel

CLEARANCE_SIGMAS = 4.0  # noise scales of clearance beyond the contact margin
ACCEL_BOUND = 30.0  # m/s^2: how fast a body may curve away from the line between two samples


def ruled_out_pairs(scene: Scene, model: PhysicsModel) -> tuple[int, ...]:
    """Indices into ``model.pairs`` of the pairs the recording keeps apart (see the module).
    A fit that sees the data up to a cut-off alone (leave-future-out) is forecast from the
    whole recording too: the forecast picks the programs, and the check of its draws over the
    whole horizon keeps the fit exact (so it shares the whole fit's programs)."""
    if not model.ncon:
        return ()
    end = model.nsteps * model.dt
    jointed = _jointed_sides(scene, model, end)
    out = []
    for k, p in enumerate(model.pairs):
        if p.kind_a not in PRIMITIVES or p.kind_b not in PRIMITIVES:
            continue
        a, b = (jointed.get(i) or _side(scene, model, i, end) for i in (p.a, p.b))
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


def _jointed_sides(scene: Scene, model: PhysicsModel, end: float) -> dict:
    """Body index -> its ``_Side``, for each body of a hinge and slider tree hung from the world
    whose joints are all measured over the horizon at the same times, whose shape and every
    pose, anchor and axis on its way from the world are free of unknowns: positions by the
    model's kinematics at the measured coordinates; slack from each joint's noise scale times
    its lever arm, and from the dip between samples (the larger of ``ACCEL_BOUND`` and the
    measured positions' own second differences)."""
    measured = {}  # body index -> (times, coordinate (N,), noise scale)
    for o in scene.observations:
        if o.quantity == "angle" and o.target in model.joint_names:
            i = model.joint_names.index(o.target)
            if model.joints[i].kind in ("hinge", "slider"):
                track = _measured_track(scene, o.target, model.dt, end, quantity="angle")
                if track is not None:
                    measured[i] = (track[0], track[1][:, 0], track[2])
    paths = {}  # body -> its measured joints from the world down (static bodies: none)
    for i in model.order:
        tj, parent = model.joints[i], model.joints[i].parent
        if not _fixed_geometry(scene, model, i):
            continue
        if parent < 0 and tj.kind == "fixed":
            paths[i] = ()
        elif (parent < 0 or parent in paths) and (i in measured or tj.kind == "fixed"):
            paths[i] = (paths[parent] if parent >= 0 else ()) + ((i,) if i in measured else ())
    paths = {i: p for i, p in paths.items() if p}
    times = [measured[j][0] for p in paths.values() for j in p]
    if not paths or any(t.shape != times[0].shape or not np.allclose(t, times[0]) for t in times):
        return {}
    times = times[0]
    q = np.zeros((len(times), model.nq))
    for j in {j for p in paths.values() for j in p}:
        q[:, model.joints[j].qadr] = measured[j][1]
    for tj in model.joints:  # identity quaternions where a body off the paths has one
        if tj.kind in ("ball", "free"):
            q[:, tj.qadr + (3 if tj.kind == "free" else 0)] = 1.0
    # the geometry alone: no pose on the paths reads an unknown (bodies off them may)
    poses = reference_poses(scene, model, {u.name: np.ones(u.shape) for u in scene.unknowns})
    B = model.nbody
    prm = dict(zip(("ref_pos", "ref_quat", "anchor", "axis"), map(jnp.stack, poses)),
               mass=jnp.zeros(B), com=jnp.zeros((B, 3)), inertia=jnp.zeros((B, 3, 3)))
    pos = np.asarray(_positions(model, prm, jnp.asarray(q)))
    ref_pos, anchor = np.asarray(prm["ref_pos"]), np.asarray(prm["anchor"])
    gaps = np.diff(times)
    out = {}
    for i, path in paths.items():
        shape = scene.bodies[i].shape
        if shape is None or shape.kind == "plane":
            continue
        track = pos[:, i]
        error = 0.0  # position error per noise scale of the joints on the way
        for j in path:
            lever = 1.0
            if model.joints[j].kind == "hinge":  # the anchor is fixed in body j's frame
                lever = (np.linalg.norm(track - pos[:, j], axis=1).max()
                         + np.linalg.norm(ref_pos[j] - anchor[j]))
            error += measured[j][2] * lever
        accel = ACCEL_BOUND
        if len(times) > 2:
            second = track[2:] - 2 * track[1:-1] + track[:-2]
            accel = max(accel, float((np.linalg.norm(second, axis=1)
                                      / (gaps[1:] * gaps[:-1])).max()))
        csize = np.asarray(contact_size(shape.kind, shape_size(shape, {})), float)
        out[i] = _Side(track=track, times=times, radius=float(bounding_radius(shape.kind, csize)),
                       slack=CLEARANCE_SIGMAS * error + accel * float(gaps.max()) ** 2 / 8)
    return out


@functools.partial(jax.jit, static_argnums=0)
def _positions(model: PhysicsModel, prm: dict, q):
    """Every body's origin (N, B, 3) at the joint coordinates ``q`` (N, nq): one compile per
    structure, where a Model of it is made many times (a refine's refits)."""
    return jax.vmap(lambda qt: forward_kinematics(model, prm, qt, jnp.zeros(model.nv)).pos)(q)


def _fixed_geometry(scene: Scene, model: PhysicsModel, i: int) -> bool:
    """Whether body ``i``'s shape, pose and joint (anchor, axis, DH parameters) name no
    unknown."""
    body, tj = scene.bodies[i], model.joints[i]
    exprs = [body.position, body.orientation]
    if body.shape is not None:
        exprs += list(body.shape.size.values())
    if tj.scene_joint is not None:
        joint = scene.joints[tj.scene_joint]
        exprs += [joint.anchor, joint.axis]
        if joint.dh is not None:
            exprs += [joint.dh.a, joint.dh.alpha, joint.dh.d, joint.dh.theta]
    return not _refs(exprs)


def _measured_track(scene: Scene, target: str, dt: float, end: float, quantity="position"):
    """(times, values (N, D), noise scale) of ``target``'s measured ``quantity`` where it
    covers the horizon from the first step to the last; else None."""
    for o in scene.observations:
        if o.quantity != quantity or o.target != target or o.sensor is not None:
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


def pair_names(model: PhysicsModel, pairs: tuple[int, ...]) -> set[frozenset]:
    """The pairs ``pairs`` (indices into ``model.pairs``) as sets of their two body names, as
    a scene's ``contact_pairs`` name them."""
    names = model.body_names
    return {frozenset((names[model.pairs[k].a], names[model.pairs[k].b])) for k in pairs}


def without_pairs(scene: Scene, model: PhysicsModel, pairs: tuple[int, ...]) -> Scene:
    """``scene`` without the contact pairs ``pairs`` (indices into ``model.pairs``): the scene
    the likelihood simulates."""
    drop = pair_names(model, pairs)
    return dataclasses.replace(scene, contact_pairs=tuple(
        p for p in scene.contact_pairs if frozenset(p) not in drop))
