"""The checked Scene: the one type between the language and everything after it.

Produced by ``physdsl.syntax.resolve``; consumed by physics, rendering, inference, diagnosis.
Every number is an ``Expr`` in SI units (see ``physdsl.expr``); unknowns are ``Ref`` nodes
naming entries of ``Scene.unknowns``. Measurement data is already read and checked.

Conventions (all world frame, z up unless the scene's gravity says otherwise):
- quaternions are (w, x, y, z), unit, body frame -> world frame;
- a body's ``position``/``orientation`` is its pose when every joint is at 0 (the reference
  configuration); joints' ``anchor`` and ``axis`` are given in the world frame of that pose;
- a body with no joint and ``fixed=False`` moves freely (implicit free joint);
- box ``size`` holds full side lengths; cylinder/capsule ``length`` is the cylindrical part's
  full length along the body's local z axis;
- plane shapes are fixed bodies; their surface passes through ``position`` with normal
  ``normal`` (world frame).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import Span
from .expr import Expr
from .goal import Goal


@dataclass(frozen=True)
class Prior:
    """A numpyro distribution by snake_case name with arguments (SI, may reference unknowns)."""

    dist: str
    args: tuple[Expr, ...] = ()
    kwargs: tuple[tuple[str, Expr], ...] = ()


@dataclass(frozen=True)
class Unknown:
    """A quantity to infer: a named param or a field written ``~ dist(...)``.

    ``name`` is the param's name or the dotted field path (``ball.velocity``,
    ``quadratic_drag@ball.coefficient``). ``unit`` is the SI unit text of its dimension
    (``kg``, ``m/s``, ``1`` for dimensionless); ``used_in`` lists fields that depend on it.
    """

    name: str
    prior: Prior
    shape: tuple[int, ...]
    unit: str
    span: Span | None = None
    used_in: tuple[str, ...] = ()
    discrete: bool = False
    per_experiment: bool = False  # one value per recording (``~ per_experiment dist(..)``)


@dataclass(frozen=True)
class Shape:
    """Geometry of a body. kind: sphere | box | cylinder | capsule | plane | mesh.

    size keys: sphere {radius}; box {size: (3,)}; cylinder/capsule {radius, length};
    plane {normal: (3,)}; mesh {} with ``mesh_path`` (trimesh gives volume and inertia).
    """

    kind: str
    size: Mapping[str, Expr] = field(default_factory=dict)
    mesh_path: Path | None = None


@dataclass(frozen=True)
class Material:
    ambient: Expr | None = None  # scalar in [0, 1]
    diffuse: Expr | None = None  # scalar in [0, 1]


@dataclass(frozen=True)
class Body:
    """A rigid body. Mass from ``mass`` or ``density`` x volume; inertia from shape unless given."""

    name: str
    shape: Shape | None
    mass: Expr | None = None
    density: Expr | None = None
    inertia: Expr | None = None  # (3,) principal moments about the body axes, kg m^2
    position: Expr | None = None  # (3,) m
    orientation: Expr | None = None  # (4,) quaternion w, x, y, z
    velocity: Expr | None = None  # (3,) m/s, initial, world frame (free bodies)
    angular_velocity: Expr | None = None  # (3,) rad/s, initial, world frame (free bodies)
    color: Expr | None = None  # (3,) RGB in [0, 1]
    material: Material = field(default_factory=Material)
    fixed: bool = False
    span: Span | None = None


@dataclass(frozen=True)
class Marker:
    """A massless point fixed in a body's frame (MJCF's site): ``position`` (3,) m in the body
    frame, relative to the body's origin. Observable as ``NAME.position`` / ``NAME.velocity``."""

    name: str
    body: str
    position: Expr  # (3,) m, body frame
    color: Expr | None = None  # (3,) RGB in [0, 1]; a marker with a colour is drawn as a dot
    radius: Expr | None = None  # m, the drawn dot's radius
    span: Span | None = None


@dataclass(frozen=True)
class DH:
    """Denavit-Hartenberg parameters (classic convention) of one joint of a serial arm."""

    a: Expr
    alpha: Expr
    d: Expr
    theta: Expr


@dataclass(frozen=True)
class Joint:
    """A joint from ``parent`` (a body name or "world") to ``child``.

    kind: hinge | slider | ball | free | fixed. ``axis`` and ``anchor`` are world-frame at the
    reference configuration. ``initial``/``initial_velocity``: angle (rad) or displacement (m)
    and its rate for hinge/slider; for ball a quaternion (4,) and angular velocity (3,).
    """

    name: str
    kind: str
    parent: str
    child: str
    axis: Expr | None = None
    anchor: Expr | None = None
    limits: tuple[Expr, Expr] | None = None
    initial: Expr | None = None
    initial_velocity: Expr | None = None
    dh: DH | None = None
    span: Span | None = None


@dataclass(frozen=True)
class EffectParam:
    """One parameter of a library effect: its unit, default, default prior, and 'off' value.

    ``strength`` marks the parameter whose ``off`` value switches the effect off exactly;
    ``sign`` is +1 if physical values lie above ``off``, -1 below, 0 either side (for
    one-sided score tests).
    """

    name: str
    unit: str
    shape: tuple[int, ...] = ()
    default: Expr | None = None
    prior: Prior | None = None
    off: float | None = None
    strength: bool = False
    sign: int = 0


@dataclass(frozen=True)
class EffectDecl:
    """A physical effect of the standard library (or a user's own .phys library file).

    acts_on: body | joint | pair | world. ``doc`` is one line for the user.
    """

    name: str
    acts_on: str
    params: tuple[EffectParam, ...]
    doc: str = ""
    span: Span | None = None

    def param(self, name: str) -> EffectParam:
        return next(p for p in self.params if p.name == name)

    @property
    def strength(self) -> EffectParam | None:
        return next((p for p in self.params if p.strength), None)


@dataclass(frozen=True)
class EffectUse:
    """An effect acting on a target: ("ball",), ("hinge",), ("floor", "ball") or ("world",).

    ``params`` maps every parameter of the declaration to an Expr (defaults filled in).
    ``tables`` holds static arrays an effect needs (e.g. control ``times`` and ``values``).
    """

    effect: str
    target: tuple[str, ...]
    params: Mapping[str, Expr]
    tables: Mapping[str, np.ndarray] = field(default_factory=dict)
    span: Span | None = None

    @property
    def key(self) -> str:
        """Stable name used for unknowns and reports: ``effect@target`` (pair as ``a,b``)."""
        return f"{self.effect}@{','.join(self.target)}"


@dataclass(frozen=True)
class Noise:
    """Measurement noise: kind normal | student_t; ``scale`` scalar or per axis (SI)."""

    kind: str
    scale: Expr
    df: Expr | None = None


@dataclass(frozen=True)
class Sensor:
    """Terms of a measuring device by sensor-fault name (SI expressions), in the faults'
    registration order: the built-ins make the observation read ``gain * pred(t - delay) +
    offset``; what each name does is its entry in ``observe.sensor.SENSOR_FAULTS``.
    ``sensor.gain`` reads a term (None where absent)."""

    terms: tuple[tuple[str, Expr], ...] = ()

    def get(self, name: str) -> Expr | None:
        """The term ``name``, None where the sensor has none."""
        return dict(self.terms).get(name)

    def __getattr__(self, name: str):
        if name.startswith("_") or name == "terms":
            raise AttributeError(name)
        return self.get(name)


@dataclass(frozen=True)
class Observation:
    """Measured data of one observable, read and checked.

    quantity: position | orientation | velocity | angular_velocity (bodies, D = 3/4/3/3),
    position | velocity (markers, D = 3), angle | angular_rate (hinge/slider joints, D = 1),
    image (cameras). ``times`` (N,) sorted,
    ``values`` (N, D) SI, ``mask`` (N, D) True where a value was measured. For images
    ``frames`` lists the image files, one per time.
    """

    name: str
    target: str
    quantity: str
    file: Path
    times: np.ndarray
    values: np.ndarray
    mask: np.ndarray
    columns: tuple[str, ...]
    noise: Noise
    frames: tuple[Path, ...] = ()
    span: Span | None = None
    sensor: "Sensor | None" = None  # offset, gain, delay of the measuring device


    @property
    def dim(self) -> int:
        return int(self.values.shape[1]) if self.values.ndim == 2 else 0


@dataclass(frozen=True)
class Light:
    direction: Expr  # (3,) direction the light travels
    ambient: Expr  # scalar or (3,)
    diffuse: Expr  # scalar or (3,)


@dataclass(frozen=True)
class Camera:
    """Pinhole camera, MuJoCo's convention: looks from ``position`` at ``look_at``; ``fov`` vertical (rad)."""

    name: str
    position: Expr
    look_at: Expr
    up: Expr
    fov: Expr
    size: tuple[int, int]  # (width, height) pixels
    background: Expr | None = None  # (3,) RGB
    span: Span | None = None


@dataclass(frozen=True)
class World:
    """Global settings. integrator: semi_implicit_euler | rk4; contact_model: lcp | compliant."""

    timestep: float = 1e-3
    duration: float | None = None
    substeps: int = 1
    integrator: str = "semi_implicit_euler"
    contact_model: str = "lcp"
    medium: str = "air"  # the fluid (physdsl/media.py): sets the physical scale of drag


@dataclass(frozen=True)
class Recording:
    """One recording of an ``experiments`` scene: its name, folder, known settings (SI, by
    the setting's dotted name ``throws.speed``) and its observations (read from its folder)."""

    name: str
    folder: Path
    settings: Mapping[str, float]
    observations: tuple[Observation, ...]
    row: int | None = None  # its manifest row (1-based, header = 1), None for a glob


@dataclass(frozen=True)
class Experiments:
    """``experiments NAME from "..."``: the recordings the scene's observations are read from
    (``Scene.observations`` holds the first one's); ``settings``: the per-recording known
    values' names, which stand as ``Ref`` nodes in the scene's expressions."""

    name: str
    source: Path
    recordings: tuple[Recording, ...]
    settings: tuple[str, ...] = ()
    span: Span | None = None


@dataclass(frozen=True)
class Scene:
    """A checked scene: everything physics, rendering and inference need, in SI."""

    name: str
    world: World
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    effects: tuple[EffectUse, ...]
    observations: tuple[Observation, ...]
    cameras: tuple[Camera, ...]
    unknowns: tuple[Unknown, ...]
    contact_pairs: tuple[tuple[str, str], ...] = ()
    light: Light | None = None
    effect_library: Mapping[str, EffectDecl] = field(default_factory=dict)
    path: Path | None = None
    source: str = ""
    markers: tuple[Marker, ...] = ()
    goal: Goal | None = None  # the scene's ``goal { ... }`` (physdsl.control meets it)
    experiments: Experiments | None = None  # many recordings (physdsl/pooled.py fits them)

    def body(self, name: str) -> Body:
        return next(b for b in self.bodies if b.name == name)

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    def marker(self, name: str) -> Marker:
        return next(m for m in self.markers if m.name == name)

    def unknown(self, name: str) -> Unknown:
        return next(u for u in self.unknowns if u.name == name)

    @property
    def duration(self) -> float:
        """Simulated time: the world's, or the last observation time."""
        if self.world.duration is not None:
            return float(self.world.duration)
        ends = [float(o.times[-1]) for o in self.observations if len(o.times)]
        return max(ends) if ends else 1.0
