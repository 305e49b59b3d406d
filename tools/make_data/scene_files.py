"""Write a generated .phys file in the canonical form ``physdsl fmt`` prints (the examples are
checked to be canonical), so a regenerated scene never differs from a formatted one."""
from __future__ import annotations

from pathlib import Path


def write_scene(path: Path, text: str) -> None:
    from physdsl.syntax import format_source  # only when writing: simulating needs MuJoCo alone

    path.write_text(format_source(text, str(path)))
