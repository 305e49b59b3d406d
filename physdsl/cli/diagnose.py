"""``physdsl diagnose SCENE.phys --posterior RUN/ -o DIAG/``: which effect is missing."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        scene: Path = typer.Argument(..., help="Scene file (.phys) that was fitted."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        posterior: Path = typer.Option(..., "--posterior", "-p", help="Run folder of `physdsl infer`."),
        out: Path = typer.Option(..., "-o", "--out", help="Output folder."),
        confirm: int = typer.Option(2, "--confirm", min=0, help="Refit the best N candidates."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
    ) -> None:
        """Rank candidate missing effects (score tests), confirm the best by refitting."""
        from .. import api, io
        from ..infer.progress import stage

        idata, _ = api.read_run(posterior)  # bad inputs fail before anything compiles
        io.prepare_outdir(out, force=force)
        model = api.compile(scene)
        with stage("diagnose"):  # score tests and refits (each said as it goes): elapsed time
            d = api.diagnose(model, idata, confirm_top=confirm, outdir=out,
                             echo=lambda line: typer.echo(line, err=True))
        typer.echo(d.table())
        typer.echo(d.verdict)
        if d.winner is not None and d.winner.snippet:
            typer.echo("\nadd to the scene:\n" + d.winner.snippet)
        typer.echo(f"wrote {out}/diagnosis.json")
