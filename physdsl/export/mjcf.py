"""``export --format mjcf``: a scene at its posterior medians, written as MJCF."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import syntax
from ..errors import UsageError
from ..infer import posterior_data
from ..mjcf import require_mujoco, scene_to_mjcf


def posterior_medians(scene, idata) -> dict[str, np.ndarray]:
    """Median of every unknown of ``scene`` over all chains and draws of ``idata``."""
    names = [u.name for u in scene.unknowns]
    missing = [n for n in names if n not in idata.posterior.data_vars]
    if missing:
        raise UsageError(f"the posterior has no draws of '{missing[0]}'",
                         hint="export with the scene the posterior was fitted to")
    return {n: np.median(d, axis=0) for n, d in posterior_data.posterior_draws(idata, names).items()}


def export_mjcf(scene_path: str | Path, idata) -> tuple[str, list[str]]:
    """(MJCF text, notes) of the scene at ``scene_path`` with its unknowns at the posterior medians."""
    require_mujoco()
    scene = syntax.load(scene_path)
    return scene_to_mjcf(scene, posterior_medians(scene, idata))

