"""``physdsl diagnose SCENE.phys --posterior RUN/ -o DIAG/``: which effect is missing."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH

# where a diagnosis's candidate refits run (physdsl/batch/executors.py: refits_on)
REFIT_EXECUTOR = typer.Option("inline", "--executor", help="Where the candidate refits run: "
                              "inline (this process, one after another; default), local (a "
                              "process pool: --workers) or ray (--address HOST:PORT).")
REFIT_WORKERS = typer.Option(None, "--workers", min=1, help="Processes of the local pool "
                             "(default: one per CPU), or CPUs of a Ray started here.")
REFIT_ADDRESS = typer.Option(None, "--address", help="The Ray cluster's head, with --executor ray.")


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        scene: Path = typer.Argument(..., help="Scene file (.phys) that was fitted."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        posterior: Path = typer.Option(..., "--posterior", "-p", help="Run folder of `physdsl infer`."),
        out: Path = typer.Option(..., "-o", "--out", help="Output folder."),
        confirm: int = typer.Option(2, "--confirm", min=0, help="Refit the best N candidates."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
        executor: str = REFIT_EXECUTOR, workers: Optional[int] = REFIT_WORKERS,
        address: Optional[str] = REFIT_ADDRESS,
    ) -> None:
        """Rank candidate missing effects (score tests), confirm the best by refitting."""
        from .. import api, io
        from ..batch.executors import check_executor, refits_on
        from ..infer.progress import stage

        check_executor(executor, address)

        idata, _ = api.read_run(posterior)  # bad inputs fail before anything compiles
        io.prepare_outdir(out, force=force)
        model = api.compile(scene)
        with stage("diagnose"), refits_on(executor, address, workers):  # refits said as they go
            d = api.diagnose(model, idata, confirm_top=confirm, outdir=out,
                             echo=lambda line: typer.echo(line, err=True))
        typer.echo(d.table())
        typer.echo(d.verdict)
        if d.winner is not None and d.winner.snippet:
            typer.echo("\nadd to the scene:\n" + d.winner.snippet)
        typer.echo(f"wrote {out}/diagnosis.json")
