"""``physdsl infer SCENE.phys -o RUN/``: posterior over every unknown, saved and summarised."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("infer")
    def infer(
        scene: Path = typer.Argument(..., help="Scene file (.phys) with observations."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        out: Path = typer.Option(..., "-o", "--out", help="Output folder for the run."),
        backend: str = typer.Option("nuts", "--backend", "-b",
                                    help="nuts | hmc | rmh | numpyro-nuts | map"),
        chains: int = typer.Option(4, "--chains", min=1, help="Chains (run vectorised)."),
        warmup: int = typer.Option(500, "--warmup", min=0, help="Warmup iterations per chain."),
        samples: Optional[int] = typer.Option(None, "--samples", min=1,
                                              help="Draws per chain (default 500; 250 with "
                                                   "--backend map, whose draws are independent)."),
        seed: int = typer.Option(0, "--seed", help="Random seed (runs are reproducible)."),
        target_accept: float = typer.Option(0.8, "--target-accept", min=0.05, max=0.999,
                                            help="Target acceptance rate of HMC/NUTS adaptation."),
        dense_mass: bool = typer.Option(True, "--dense-mass/--diagonal-mass",
                                        help="HMC/NUTS metric: dense (default) or diagonal."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
        resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in OUT."),
        init: str = typer.Option(None, "--init",
                                 help="Start values, e.g. 'h0=1.1 m, ball.velocity=(3, 0, 2.5) "
                                      "m/s' (the first start; units as in the scene)."),
        fallback: str = typer.Option(None, "--fallback",
                                     help="With --backend map: where the Laplace step fails, "
                                          "sample from the mode with this sampler (rmh)."),
        intervals: str = typer.Option("robust", "--intervals",
                                      help="Intervals in summary.csv: robust (widened where the "
                                           "residuals are above the noise or in runs) or model "
                                           "(the plain posterior); posterior.nc holds both."),
    ) -> None:
        """Fit a scene to its measurements; write posterior.nc, summary.csv and run.json.

        Ctrl-C or SIGTERM stops within seconds (a second Ctrl-C at once), leaving a checkpoint
        in OUT that --resume continues exactly; the exit code is then 130 (SIGINT) or 143
        (SIGTERM)."""
        from .. import api
        from ..errors import UsageError
        from ..infer import get_backend
        from ..infer.backends.map import LaplaceError
        from ..infer.intervals import SHOWN

        get_backend(backend)  # fail fast on an unknown name, before compiling
        if intervals not in SHOWN:
            raise UsageError(f"unknown --intervals '{intervals}'", hint="robust or model")
        model = api.compile(scene)
        try:
            idata = api.infer(model, backend, fallback=fallback, init=init, chains=chains,
                              warmup=warmup, samples=samples, seed=seed,
                              target_accept=target_accept, dense_mass=dense_mass, outdir=out,
                              force=force, resume=resume, intervals=intervals)
        except LaplaceError as err:
            if getattr(err, "idata", None) is not None:
                _report(model, err.idata, backend)
            raise
        except KeyboardInterrupt as ex:  # Interrupted, or a second Ctrl-C (click would say
            note = getattr(ex, "note", "")  # 'Aborted!' and exit 1)
            typer.echo("interrupted" + (f": {note}" if note else ""), err=True)
            raise typer.Exit(128 + getattr(ex, "signum", 2))  # the shell's code: 130, 143
        _report(model, idata, backend)
        typer.echo(f"wrote {out}/posterior.nc, summary.csv, run.json")
        sys.stdout.flush()


def _report(model, idata, backend: str) -> None:
    """The summary table and the fit's quality on stdout; warnings on stderr."""
    import json

    from ..infer.intervals import describe
    from ..diagnose.quality import fit_quality_lines
    from ..infer.output import format_table, summary_rows, warnings_in_words

    rows = summary_rows(model, idata)
    typer.echo(format_table(rows))
    typer.echo(describe(idata))
    if "fit_note" in idata.attrs:
        typer.echo(f"note: {idata.attrs['fit_note']}", err=True)
    quality = json.loads(idata.attrs["fit_quality"]) if "fit_quality" in idata.attrs else None
    if quality:
        typer.echo("\n".join(fit_quality_lines(quality)))
    for w in warnings_in_words(rows, idata, backend) + (quality or {}).get("warnings", []):
        typer.echo(f"warning: {w}", err=True)
