"""A Scene's renderer inputs: its bodies as Objects at frame times, its cameras and its light.

Sizes, colours, materials, cameras and the light are the Scene's expressions evaluated with
``physdsl.expr.evaluate``, so any of them may be unknowns; poses come from a rollout,
interpolated at the frame times (linear for positions, normalised linear for quaternions).
Body kinds are static (``scene_kinds``), so ``render(..., kinds=scene_kinds(scene))`` takes the
fast path. Mesh bodies are not drawn (the renderer has no meshes). A marker with a colour is
drawn as a dot (a sphere of its ``radius``, default ``DOT_RADIUS``) after the bodies.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..expr import evaluate
from ..observe import trajectory
from ..scene import Body, Marker, Scene
from .render import render
from .types import KIND_CODES, RenderCamera, Light, Objects, make_light

DEFAULT_COLOR = (0.5, 0.5, 0.5)  # MuJoCo's default geom colour
DEFAULT_BACKGROUND = (0.0, 0.0, 0.0)
DOT_RADIUS = 0.005  # m, a drawn marker's default radius


def drawn_bodies(scene: Scene) -> tuple[Body, ...]:
    """Bodies the renderer draws: every body with a primitive shape (not a mesh)."""
    return tuple(b for b in scene.bodies if b.shape is not None and b.shape.kind in KIND_CODES)


def drawn_markers(scene: Scene) -> tuple[Marker, ...]:
    """Markers the renderer draws as dots: those given a colour."""
    return tuple(m for m in scene.markers if m.color is not None)


def scene_kinds(scene: Scene) -> tuple[int, ...]:
    """Static kind codes of ``drawn_bodies`` then ``drawn_markers`` (for ``render(..., kinds=...)``)."""
    return (tuple(KIND_CODES[b.shape.kind] for b in drawn_bodies(scene))
            + (KIND_CODES["sphere"],) * len(drawn_markers(scene)))


def _size(body: Body, values):
    """Renderer size (3,) of a body: sphere (r, 0, 0), box half-extents, cylinder/capsule
    (r, half_length, 0), plane its unit normal."""
    sh = body.shape
    ev = {k: jnp.asarray(evaluate(v, values), dtype=float) for k, v in sh.size.items()}
    zero = jnp.zeros(())
    if sh.kind == "sphere":
        return jnp.stack([ev["radius"], zero, zero])
    if sh.kind == "box":
        return 0.5 * jnp.broadcast_to(ev["size"], (3,))
    if sh.kind in ("cylinder", "capsule"):
        return jnp.stack([ev["radius"], 0.5 * ev["length"], zero])
    n = jnp.broadcast_to(ev.get("normal", jnp.array([0.0, 0.0, 1.0])), (3,))
    return n / jnp.linalg.norm(n)


def _scalar(expr, values, default):
    return jnp.asarray(default if expr is None else evaluate(expr, values), dtype=float)


def frame_poses(simulator, rollout, times):
    """Body positions (F, B_sim, 3) and quaternions (F, B_sim, 4) at ``times`` (static, within
    the simulated span) read off the rollout grid."""
    interp = trajectory.interpolation(np.asarray(simulator.times), np.asarray(times, dtype=float))
    w = jnp.asarray(interp.w)[:, None, None]
    pos = (1 - w) * rollout.body_pos[interp.lo] + w * rollout.body_pos[interp.hi]
    q0, q1 = rollout.body_quat[interp.lo], rollout.body_quat[interp.hi]
    q1 = jnp.where(jnp.sum(q0 * q1, axis=-1, keepdims=True) < 0, -q1, q1)  # same hemisphere
    quat = (1 - w) * q0 + w * q1
    return pos, quat / jnp.linalg.norm(quat, axis=-1, keepdims=True)


def scene_objects(scene: Scene, simulator, rollout, values, times) -> Objects:
    """The drawn bodies at each frame time: Objects whose fields have a leading frame axis F
    (vmap ``render`` over it). ``values``: the unknowns (name -> value)."""
    bodies = drawn_bodies(scene)
    if not bodies:
        raise ModelError("nothing to draw: no body of this scene has a primitive shape",
                         scene.cameras[0].span if scene.cameras else None)
    pos_all, quat_all = frame_poses(simulator, rollout, times)
    idx = np.array([simulator.body_names.index(b.name) for b in bodies])
    pos, quat = pos_all[:, idx], quat_all[:, idx]
    n_frames = pos.shape[0]

    def per_body(fn):
        return jnp.stack([jnp.asarray(fn(b), dtype=float) for b in bodies])

    def frames(a):
        return jnp.broadcast_to(a, (n_frames,) + a.shape)

    objects = Objects(
        kind=frames(jnp.asarray(scene_kinds(scene)[:len(bodies)], dtype=jnp.int32)),
        pos=pos, quat=quat,
        size=frames(per_body(lambda b: _size(b, values))),
        color=frames(per_body(lambda b: jnp.broadcast_to(
            _scalar(b.color, values, DEFAULT_COLOR), (3,)))),
        ambient=frames(per_body(lambda b: _scalar(b.material.ambient, values, 1.0))),
        diffuse=frames(per_body(lambda b: _scalar(b.material.diffuse, values, 1.0))),
        visible=frames(jnp.ones(len(bodies))),
    )
    dots = _marker_dots(scene, simulator, rollout, values, times)
    if dots is None:
        return objects
    return Objects(*(jnp.concatenate([a, b], axis=1) for a, b in zip(objects, dots)))


def _marker_dots(scene: Scene, simulator, rollout, values, times) -> Objects | None:
    """The drawn markers as small spheres at each frame time (None: no marker is drawn)."""
    markers = drawn_markers(scene)
    if not markers:
        return None
    interp = trajectory.interpolation(np.asarray(simulator.times), np.asarray(times, dtype=float))
    idx = np.array([simulator.marker_names.index(m.name) for m in markers])
    track = rollout.marker_pos[:, idx]
    w = jnp.asarray(interp.w)[:, None, None]
    pos = (1 - w) * track[interp.lo] + w * track[interp.hi]
    n_frames, n = pos.shape[0], len(markers)

    def per_marker(fn):
        return jnp.broadcast_to(jnp.stack([jnp.asarray(fn(m), dtype=float) for m in markers]),
                                (n_frames, n) + jnp.shape(fn(markers[0])))

    zero = jnp.zeros(())
    return Objects(
        kind=jnp.full((n_frames, n), KIND_CODES["sphere"], dtype=jnp.int32),
        pos=pos, quat=jnp.broadcast_to(jnp.array([1.0, 0.0, 0.0, 0.0]), (n_frames, n, 4)),
        size=per_marker(lambda m: jnp.stack([_scalar(m.radius, values, DOT_RADIUS), zero, zero])),
        color=per_marker(lambda m: jnp.broadcast_to(_scalar(m.color, values, DEFAULT_COLOR), (3,))),
        ambient=jnp.ones((n_frames, n)), diffuse=jnp.ones((n_frames, n)),
        visible=jnp.ones((n_frames, n)),
    )


def scene_camera(scene: Scene, name: str, values) -> tuple[RenderCamera, jnp.ndarray]:
    """The camera called ``name`` and its background colour (3,)."""
    cam = next((c for c in scene.cameras if c.name == name), None)
    if cam is None:
        raise ModelError(f"no camera called '{name}' in scene '{scene.name}'")
    camera = RenderCamera(jnp.asarray(evaluate(cam.position, values), dtype=float),
                    jnp.asarray(evaluate(cam.look_at, values), dtype=float),
                    jnp.asarray(evaluate(cam.up, values), dtype=float),
                    jnp.asarray(evaluate(cam.fov, values), dtype=float),
                    int(cam.size[0]), int(cam.size[1]))
    background = jnp.broadcast_to(_scalar(cam.background, values, DEFAULT_BACKGROUND), (3,))
    return camera, background


def scene_light(scene: Scene, values) -> Light:
    """The scene's light, or the default (straight down, ambient 0.35, diffuse 0.65)."""
    if scene.light is None:
        return make_light()
    return make_light(evaluate(scene.light.direction, values),
                      evaluate(scene.light.ambient, values), evaluate(scene.light.diffuse, values))


def render_frames(scene: Scene, simulator, rollout, values, camera: str, times,
                  softness: float = 0.5):
    """Images (F, H, W, 3) of the scene seen by ``camera`` at ``times`` (static)."""
    objects = scene_objects(scene, simulator, rollout, values, times)
    cam, background = scene_camera(scene, camera, values)
    light = scene_light(scene, values)
    kinds = scene_kinds(scene)
    return jax.vmap(lambda o: render(o, light, cam, background, softness, kinds=kinds))(objects)
