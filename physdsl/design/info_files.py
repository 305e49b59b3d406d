"""What an information design writes: ``design.json`` and ``design.txt`` (the report), each
chosen control sequence as ``control_TARGET.csv`` (readable by ``control NAME on TARGET from
"control_TARGET.csv" column u``) and ``experiment.phys``, the scene with the excitation
written in (controls read from their CSV, initial states set): the experiment to run.
"""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from .. import io
from ..compile import Model
from ..control.cost import control_effects
from ..control.output import control_file, control_table, planned_scene
from .excite import InfoDesign


def write(model: Model, design: InfoDesign, out_dir: Path, extra: dict | None = None) -> list[Path]:
    """Every output of ``design`` in ``out_dir`` (prepared by the caller); their paths."""
    out_dir = Path(out_dir)
    scene = model.scene
    joints = {j.name for j in scene.joints}
    uses = control_effects(scene)
    written = []
    for name, value in design.settings.items():
        if name in uses:
            target = uses[name].target[0]
            written.append(io.write_text(out_dir / control_file(target),
                                         control_table(uses[name], value, target in joints)))
    plan = SimpleNamespace(chosen=design.fields, values=design.settings)
    written.append(io.write_text(out_dir / "experiment.phys",
                                 planned_scene(SimpleNamespace(model=model), plan, out_dir)))
    written.append(io.write_text(out_dir / "design.txt", design.text() + "\n"))
    written.append(io.write_json(out_dir / "design.json", {**design.to_dict(), **(extra or {})}))
    return written
