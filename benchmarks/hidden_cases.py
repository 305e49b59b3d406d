"""The scenes of the hidden-effect cases as ``refine``'s first round fits them: ``naive.phys``
with each hidden effect of ``truth.json`` added by ``diagnose.edits.with_effect``, its strength
an unknown with the library's (or the physical-scale) prior. Shared by ``fits.py`` and
``coverage.py``. (Added plainly, ``effect restitution on (floor, ball)`` keeps the library's
default e = 1: the naive model again, fitted at 11.9σ.)"""
from __future__ import annotations

import json
from pathlib import Path


def scene_text(folder: Path) -> str:
    """``folder``'s naive scene with its hidden effect(s) added as refine adds a candidate."""
    from physdsl.diagnose.candidates import Candidate
    from physdsl.diagnose.edits import with_effect
    from physdsl.syntax import loads

    truth = json.loads((folder / "truth.json").read_text())
    text = (folder / "naive.phys").read_text()
    for eff in [truth["hidden_effect"]] + truth.get("also_hidden", []):
        scene = loads(text, filename=str(folder / "naive.phys"), base_dir=folder)
        cand = Candidate("effect", eff["effect"], tuple(eff["target"].split(",")))
        text = with_effect(scene, cand)  # the scene (loaded from text) with cand added
    return text
