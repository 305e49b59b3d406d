"""``physdsl add-effect SCENE.phys EFFECT on TARGET -o NEW.phys``: add a library effect yourself."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("add-effect")
    def add_effect(
        scene: Path = typer.Argument(..., help="Scene file (.phys)."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        effect: str = typer.Argument(..., help="Library effect name, e.g. quadratic_drag."),
        on: str = typer.Argument(..., metavar="on", help="The word 'on'."),
        target: str = typer.Argument(..., help="Body, joint, 'a,b' pair or world."),
        out: Path = typer.Option(..., "-o", "--out", help="New scene file (never the input)."),
        force: bool = typer.Option(False, "--force", help="Overwrite an existing output file."),
    ) -> None:
        """Write a new scene with EFFECT on TARGET, its strength an unknown with the library prior."""
        from .. import io
        from ..diagnose.candidates import Candidate
        from ..diagnose.rank import with_effect
        from ..errors import PhysNameError, UsageError
        from ..syntax import load, loads

        if on != "on":
            raise UsageError(f"expected the word 'on' before the target, got '{on}'",
                             hint="physdsl add-effect scene.phys quadratic_drag on ball -o new.phys")
        if out.resolve() == scene.resolve():
            raise UsageError("the output must be a new file", hint="choose another -o path")
        io.refuse_overwrite(out, force)
        base = load(scene)
        if effect not in base.effect_library:
            import difflib

            close = difflib.get_close_matches(effect, list(base.effect_library), n=3)
            raise PhysNameError(f"unknown effect '{effect}'",
                                hint=f"did you mean {', '.join(close)}?" if close else
                                "known effects: " + ", ".join(sorted(base.effect_library)))
        cand = Candidate("effect", effect, tuple(t.strip() for t in target.strip("()").split(",")))
        text = with_effect(base, cand)
        loads(text, filename=str(out), base_dir=scene.parent)  # the result must check
        io.write_text(out, text)
        typer.echo(f"wrote {out}")
