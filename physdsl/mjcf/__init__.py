"""MJCF and URDF in, MJCF out: MuJoCo models as physdsl scenes and fitted scenes back as MJCF.

``import_model`` reads a model with ``mujoco.MjSpec`` (URDF through MuJoCo's own compiler)
and writes a .phys scene; ``scene_to_mjcf`` builds an MJCF document with ``MjSpec`` from a
Scene and values of its unknowns. MuJoCo is an optional dependency (``physdsl[mjcf]``).
"""
from __future__ import annotations

from pathlib import Path

from .loading import HINT, load_spec, require_mujoco
from .read import read_model
from .write import write_mjcf

__all__ = ["HINT", "require_mujoco", "load_spec", "import_model", "scene_to_mjcf"]


def import_model(path: str | Path, *, controls: str | None = None, key: str | None = None):
    """``Imported(text, notes, files)``: the .phys text of an MJCF/URDF model, what it cannot
    express, and mesh files (name -> OBJ text) to write beside the scene (see ``read``)."""
    spec, model = load_spec(path)
    return read_model(spec, model, source=Path(path).name, controls=controls, key=key)


def scene_to_mjcf(scene, values=None) -> tuple[str, list[str]]:
    """MJCF text of ``scene`` at ``values`` (unknown -> array) and notes on what MJCF cannot hold."""
    require_mujoco()
    return write_mjcf(scene, values or {})
