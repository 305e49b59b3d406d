"""``physdsl export``: write a posterior as a proto-program (a .phys file with fitted priors)."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export_cmd(
        scene: Path = typer.Argument(..., help="The .phys scene the posterior was fitted to."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        posterior: Path = typer.Option(..., "--posterior", help="Run folder of `physdsl infer` (posterior.nc, run.json)."),
        out: Path = typer.Option(..., "-o", "--output", help="The proto-program to write (.phys)."),
        free: Optional[List[str]] = typer.Option(None, "--free", help="Unknown that keeps its original prior (repeatable)."),
        drop: Optional[List[str]] = typer.Option(None, "--drop", help="Body, effect@target or target.quantity to remove with what depends on it (repeatable)."),
        widen: float = typer.Option(1.0, "--widen", help="Multiply every fitted scale (unconstrained space) by this factor."),
        observe: bool = typer.Option(True, "--observe/--no-observe", help="Keep observe blocks, or write a pure generator."),
        force: bool = typer.Option(False, "--force", help="Overwrite an existing output file."),
        fmt: str = typer.Option("phys", "--format", help="phys (a proto-program, default) or mjcf (the scene at the posterior medians, for MuJoCo)."),
    ) -> None:
        """Export a posterior as a scene program whose priors are the fitted posterior."""
        from .. import api
        from ..errors import UsageError
        from ..io import refuse_overwrite, write_text

        refuse_overwrite(out, force)
        if fmt not in ("phys", "mjcf"):
            raise UsageError(f"unknown --format '{fmt}'", hint="use phys or mjcf")
        if fmt == "mjcf" and (free or drop or widen != 1.0 or not observe):
            raise UsageError("--free, --drop, --widen and --no-observe shape a proto-program; "
                             "--format mjcf writes the posterior medians", hint="leave them out")
        idata, run = api.read_run(posterior)
        if fmt == "mjcf":
            text, notes = api.export_mjcf(scene, idata)
            write_text(out, text)
            if notes:
                typer.echo(f"{out}: not expressed in MJCF (listed in its first comment):", err=True)
                for n in notes:
                    typer.echo(f"  - {n}", err=True)
            typer.echo(f"wrote {out}")
            return
        text = api.export(scene, idata, free=tuple(free or ()), drop=tuple(drop or ()), widen=widen,
                          observe=observe, out_path=out, run=run)
        write_text(out, text)
        typer.echo(f"wrote {out}")
