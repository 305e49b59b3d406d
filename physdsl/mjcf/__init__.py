"""MJCF and URDF in, MJCF out: MuJoCo models as physdsl scenes and fitted scenes back as MJCF.

``import_model`` reads a model with ``mujoco.MjSpec`` (URDF through MuJoCo's own compiler)
and writes a .phys scene; ``scene_to_mjcf`` builds an MJCF document with ``MjSpec`` from a
Scene and values of its unknowns. MuJoCo is an optional dependency (``physdsl[mjcf]``).
"""
from __future__ import annotations

from pathlib import Path

from ..errors import UsageError

HINT = "pip install physdsl[mjcf]"


def require_mujoco():
    """The ``mujoco`` module, or a usage error (exit 2) saying how to install it."""
    try:
        import mujoco
    except ImportError:
        raise UsageError("MJCF/URDF import and export need MuJoCo, which is not installed",
                         hint=HINT) from None
    return mujoco


def load_spec(path: str | Path):
    """``MjSpec`` and compiled ``MjModel`` of an MJCF or URDF file; a usage error if MuJoCo refuses it."""
    mujoco = require_mujoco()
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"model file not found: {path}", hint="give an MJCF (.xml) or URDF (.urdf) file")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        model = spec.compile()
    except Exception as ex:  # MuJoCo reports XML and compile errors as ValueError
        raise UsageError(f"{path}: MuJoCo cannot load this model: {str(ex).strip()}",
                         hint="check the file with MuJoCo's own viewer or compile()") from None
    return spec, model


def import_model(path: str | Path, *, controls: str | None = None, key: str | None = None):
    """``Imported(text, notes, files)``: the .phys text of an MJCF/URDF model, what it cannot
    express, and mesh files (name -> OBJ text) to write beside the scene (see ``read``)."""
    from .read import read_model

    spec, model = load_spec(path)
    return read_model(spec, model, source=Path(path).name, controls=controls, key=key)


def scene_to_mjcf(scene, values=None) -> tuple[str, list[str]]:
    """MJCF text of ``scene`` at ``values`` (unknown -> array) and notes on what MJCF cannot hold."""
    require_mujoco()
    from .write import write_mjcf

    return write_mjcf(scene, values or {})
