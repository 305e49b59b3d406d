"""What each field of the language accepts: dimension, shape, constness (``checks.check``
holds a value to it). Adding a field to an item kind is one row of a table here."""
from __future__ import annotations

from dataclasses import dataclass

from .units import ANGLE, ANGVEL, DENSITY, DIMLESS, INERTIA, LENGTH, MASS, VEL, Dim


@dataclass(frozen=True)
class Spec:
    """What a field accepts: dimension(s), shape (None: scalar or any vector), words for messages."""

    dims: tuple[Dim, ...]
    shape: tuple[int, ...] | None = ()
    constant: bool = False  # must not depend on unknowns


def spec(dim: Dim, shape=(), constant=False) -> Spec:
    return Spec((dim,), shape, constant)


BODY_FIELDS = {
    "mass": spec(MASS), "density": spec(DENSITY), "inertia": spec(INERTIA, (3,)),
    "position": spec(LENGTH, (3,)), "orientation": spec(DIMLESS, (4,)),
    "velocity": spec(VEL, (3,)), "angular_velocity": spec(ANGVEL, (3,)),
    "color": spec(DIMLESS, (3,)),
}
BODY_FLAGS = {"fixed", "collide"}
MARKER_FIELDS = {"position": spec(LENGTH, (3,)), "color": spec(DIMLESS, (3,)),
                 "radius": spec(LENGTH)}
GROUND_FIELDS = {"normal": spec(DIMLESS, (3,)), "point": spec(LENGTH, (3,)),
                 "color": spec(DIMLESS, (3,))}
MATERIAL_FIELDS = {"ambient": spec(DIMLESS), "diffuse": spec(DIMLESS)}
SHAPE_ARGS = {
    "sphere": {"radius": spec(LENGTH)},
    "box": {"size": spec(LENGTH, (3,))},
    "cylinder": {"radius": spec(LENGTH), "length": spec(LENGTH)},
    "capsule": {"radius": spec(LENGTH), "length": spec(LENGTH)},
    "plane": {"normal": spec(DIMLESS, (3,))},
    "mesh": {},
}
JOINT_KINDS = ("hinge", "slider", "ball", "free", "fixed")
DH_FIELDS = {"a": spec(LENGTH), "alpha": spec(ANGLE), "d": spec(LENGTH), "theta": spec(ANGLE)}
CAMERA_FIELDS = {"position": spec(LENGTH, (3,)), "look_at": spec(LENGTH, (3,)),
                 "up": spec(DIMLESS, (3,)), "fov": spec(ANGLE), "background": spec(DIMLESS, (3,))}
LIGHT_FIELDS = {"direction": spec(DIMLESS, (3,)), "ambient": spec(DIMLESS, None),
                "diffuse": spec(DIMLESS, None)}
WORLD_FIELDS = {"gravity", "timestep", "duration", "substeps", "integrator", "contact", "medium"}
INTEGRATORS = ("semi_implicit_euler", "rk4")
OBSERVE_FIELDS = {"noise", "model", "df"}  # and the sensor faults' names (syntax/sensor.py)
EFFECT_TARGETS = ("body", "joint", "pair", "world")


def joint_table(kind: str) -> dict[str, Spec]:
    """The fields of a joint of ``kind`` (its coordinate's dimension follows the kind)."""
    if kind == "slider":
        q, qd, lim = spec(LENGTH), spec(VEL), spec(LENGTH, (2,))
    elif kind == "ball":
        q, qd, lim = spec(DIMLESS, (4,)), spec(ANGVEL, (3,)), spec(ANGLE, (2,))
    else:
        q, qd, lim = spec(ANGLE), spec(ANGVEL), spec(ANGLE, (2,))
    table = {"axis": spec(DIMLESS, (3,)), "anchor": spec(LENGTH, (3,))}
    if kind in ("hinge", "slider", "ball"):
        table.update(initial=q, initial_velocity=qd, limits=lim)
    return table
