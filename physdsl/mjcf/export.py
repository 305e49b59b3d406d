"""``physdsl export --format mjcf``: a scene at its posterior medians, written as MJCF."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ..errors import UsageError


def posterior_medians(scene, idata) -> dict[str, np.ndarray]:
    """Median of every unknown of ``scene`` over all chains and draws of ``idata``."""
    from ..export import posterior_draws

    names = [u.name for u in scene.unknowns]
    missing = [n for n in names if n not in idata.posterior.data_vars]
    if missing:
        raise UsageError(f"the posterior has no draws of '{missing[0]}'",
                         hint="export with the scene the posterior was fitted to")
    return {n: np.median(d, axis=0) for n, d in posterior_draws(idata, names).items()}


def export_mjcf(scene_path: str | Path, idata) -> tuple[str, list[str]]:
    """(MJCF text, notes) of the scene at ``scene_path`` with its unknowns at the posterior medians."""
    from .. import syntax
    from . import require_mujoco, scene_to_mjcf

    require_mujoco()
    scene = syntax.load(scene_path)
    return scene_to_mjcf(scene, posterior_medians(scene, idata))


def export_mjcf_cli(scene_path: Path, posterior: Path, out: Path, proto_options: bool) -> None:
    """The CLI's mjcf branch: write ``out`` atomically and list what MJCF cannot hold on stderr."""
    from ..infer.output import load_run
    from ..io import write_text
    from . import require_mujoco

    if proto_options:
        raise UsageError("--free, --drop, --widen and --no-observe shape a proto-program; "
                         "--format mjcf writes the posterior medians", hint="leave them out")
    require_mujoco()
    idata, _ = load_run(posterior)
    text, notes = export_mjcf(scene_path, idata)
    write_text(out, text)
    if notes:
        print(f"{out}: not expressed in MJCF (listed in its first comment):", file=sys.stderr)
        for n in notes:
            print(f"  - {n}", file=sys.stderr)
    print(f"wrote {out}")
