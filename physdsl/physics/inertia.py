"""Mass properties of shapes: volume, inertia about the centre of mass, contact size packing.

Primitives are centred on their body frame (COM at the origin); capsules include their two
hemispherical caps, with mass split by volume. Meshes use trimesh's exact polyhedral integrals.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError

PI = np.pi
SHAPE_KINDS = ("sphere", "box", "cylinder", "capsule", "plane")


def volume(kind: str, size: dict):
    """Volume (m^3) of a shape from its evaluated size dict."""
    if kind == "sphere":
        return 4.0 / 3.0 * PI * size["radius"] ** 3
    if kind == "box":
        s = size["size"]
        return s[0] * s[1] * s[2]
    if kind == "cylinder":
        return PI * size["radius"] ** 2 * size["length"]
    if kind == "capsule":
        r, L = size["radius"], size["length"]
        return PI * r**2 * L + 4.0 / 3.0 * PI * r**3
    if kind == "plane":
        return jnp.asarray(0.0)
    raise ValueError(kind)


def unit_inertia(kind: str, size: dict):
    """Principal moments (3,) per unit mass about the COM, body axes (z = symmetry axis)."""
    if kind == "sphere":
        i = 0.4 * size["radius"] ** 2
        return jnp.stack([i, i, i])
    if kind == "box":
        x, y, z = size["size"][0], size["size"][1], size["size"][2]
        return jnp.stack([y * y + z * z, x * x + z * z, x * x + y * y]) / 12.0
    if kind == "cylinder":
        r, L = size["radius"], size["length"]
        t = (3 * r * r + L * L) / 12.0
        return jnp.stack([t, t, 0.5 * r * r])
    if kind == "capsule":
        r, L = size["radius"], size["length"]
        vc, vh = PI * r * r * L, 4.0 / 3.0 * PI * r**3
        fc, fh = vc / (vc + vh), vh / (vc + vh)  # mass fractions: cylinder, both caps
        # each cap (mass fh/2): 2/5 m r^2 about its flat face centre, COM 3r/8 from the face
        cap_com = (0.4 - 9.0 / 64.0) * r * r
        d = 0.5 * L + 3.0 * r / 8.0
        t = fc * (L * L / 12.0 + r * r / 4.0) + fh * (cap_com + d * d)
        return jnp.stack([t, t, fc * 0.5 * r * r + fh * 0.4 * r * r])
    if kind == "plane":
        return jnp.zeros(3)
    raise ValueError(kind)


def contact_size(kind: str, size: dict):
    """Size packing (3,) of the contact module: sphere (r,0,0); box half extents; capsule/cylinder (r, L/2, 0); plane normal."""
    z = jnp.asarray(0.0)
    if kind == "sphere":
        return jnp.stack([size["radius"], z, z])
    if kind == "box":
        return 0.5 * size["size"]
    if kind in ("cylinder", "capsule"):
        return jnp.stack([size["radius"], 0.5 * size["length"], z])
    if kind == "plane":
        n = size["normal"]
        return n / jnp.sqrt(jnp.sum(n * n))
    return jnp.zeros(3)


@lru_cache(maxsize=64)
def mesh_properties(path: str):
    """(volume, com (3,), inertia per unit mass about the COM (3, 3)) of a closed mesh file."""
    import trimesh

    try:
        mesh = trimesh.load(Path(path), force="mesh")
    except Exception as exc:  # trimesh raises many kinds
        raise ModelError(f"cannot read mesh '{path}': {exc}",
                         hint="give a closed triangle mesh (.obj, .stl, .ply)") from exc
    if not mesh.is_volume:
        raise ModelError(f"mesh '{path}' is not a closed, consistently oriented volume",
                         hint="repair it (watertight, outward normals) or give mass and inertia explicitly")
    vol = float(mesh.volume)
    return vol, np.asarray(mesh.center_mass, float), np.asarray(mesh.moment_inertia, float) / vol
