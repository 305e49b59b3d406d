"""``physdsl import``: an MJCF or URDF model (read by MuJoCo) as a .phys scene."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command("import")
    def import_cmd(
        model: Path = typer.Argument(..., help="MJCF (.xml) or URDF (.urdf) model file."),
        out: Path = typer.Option(..., "-o", "--output", help="The .phys scene to write."),
        controls: Optional[str] = typer.Option(None, "--controls", help="CSV file (path as the scene should read it) whose columns, named after the actuators, drive them."),
        key: Optional[str] = typer.Option(None, "--key", help="Keyframe (name or index) giving the initial state; default MuJoCo's qpos0."),
        force: bool = typer.Option(False, "--force", help="Overwrite an existing output file."),
    ) -> None:
        """Import a MuJoCo model; what physdsl cannot express is listed on stderr and atop the scene."""
        from .. import api
        from ..io import refuse_overwrite, write_text

        refuse_overwrite(out, force)
        text, notes, files = api.import_model(model, controls=controls, key=key)
        for name in files:
            refuse_overwrite(out.parent / name, force)
        for name, content in files.items():
            write_text(out.parent / name, content)
        write_text(out, text)
        if notes:
            print(f"{model}: not expressed in physdsl (listed atop {out}):", file=sys.stderr)
            for n in notes:
                print(f"  - {n}", file=sys.stderr)
        typer.echo(f"wrote {out}")
