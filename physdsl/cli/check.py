"""``physdsl check SCENE.phys --posterior RUN/ -o REPORT/``: where the model misses the data."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("check")
    def check(
        scene: Path = typer.Argument(..., help="Scene file (.phys) that was fitted."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        posterior: Path = typer.Option(..., "--posterior", "-p", help="Run folder of `physdsl infer`."),
        out: Path = typer.Option(..., "-o", "--out", help="Report folder."),
        windows: int = typer.Option(4, "--windows", min=1, help="Equal time windows per observable."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty report folder."),
    ) -> None:
        """Residuals per observable and time window in noise units, misfit shapes, plots, HTML."""
        from .. import api, io
        from ..infer.progress import stage

        idata, _ = api.read_run(posterior)  # bad inputs fail before anything compiles
        io.prepare_outdir(out, force=force)
        model = api.compile(scene)
        with stage("check"):  # rollouts, tests and plots: elapsed time on stderr
            report = api.check(model, idata, outdir=out, windows=windows)
        typer.echo(report.text())
        typer.echo(f"wrote {out}/report.json, report.md, index.html")
