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
        from .. import api, io
        from ..errors import UsageError

        if on != "on":
            raise UsageError(f"expected the word 'on' before the target, got '{on}'",
                             hint="physdsl add-effect scene.phys quadratic_drag on ball -o new.phys")
        if out.resolve() == scene.resolve():
            raise UsageError("the output must be a new file", hint="choose another -o path")
        io.refuse_overwrite(out, force)
        new = api.add_effect(api.load(scene), effect, target)  # the result is checked
        io.write_text(out, new.source)
        typer.echo(f"wrote {out}")
