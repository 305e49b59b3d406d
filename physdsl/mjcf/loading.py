"""The optional MuJoCo dependency: the module itself (or a usage error saying how to install
it), and an MJCF or URDF file read into ``MjSpec`` and a compiled ``MjModel``."""
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
