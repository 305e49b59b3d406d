"""``physdsl infer SCENE.phys -o RUN/``: posterior over every unknown, saved and summarised."""
from __future__ import annotations

import sys
from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command("infer")
    def infer(
        scene: Path = typer.Argument(..., help="Scene file (.phys) with observations."),
        out: Path = typer.Option(..., "-o", "--out", help="Output folder for the run."),
        backend: str = typer.Option("nuts", "--backend", "-b",
                                    help="nuts | hmc | rmh | numpyro-nuts | map"),
        chains: int = typer.Option(4, "--chains", min=1, help="Chains (run vectorised)."),
        warmup: int = typer.Option(500, "--warmup", min=0, help="Warmup iterations per chain."),
        samples: int = typer.Option(500, "--samples", min=1, help="Draws per chain."),
        seed: int = typer.Option(0, "--seed", help="Random seed (runs are reproducible)."),
        target_accept: float = typer.Option(0.8, "--target-accept", min=0.05, max=0.999,
                                            help="Target acceptance rate of HMC/NUTS adaptation."),
        dense_mass: bool = typer.Option(True, "--dense-mass/--diagonal-mass",
                                        help="HMC/NUTS metric: dense (default) or diagonal."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
        resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in OUT."),
    ) -> None:
        """Fit a scene to its measurements; write posterior.nc, summary.csv and run.json."""
        from ..compile import Model
        from ..infer import get_backend
        from ..infer.output import format_table, summary_rows, warnings_in_words
        from ..syntax import load

        get_backend(backend)  # fail fast on an unknown name, before compiling
        model = Model(load(scene))
        idata = model.infer(backend=backend, chains=chains, warmup=warmup, samples=samples,
                            seed=seed, target_accept=target_accept, dense_mass=dense_mass,
                            outdir=out, force=force, resume=resume)
        rows = summary_rows(model, idata)
        typer.echo(format_table(rows))
        for w in warnings_in_words(rows, idata, backend):
            typer.echo(f"warning: {w}", err=True)
        typer.echo(f"wrote {out}/posterior.nc, summary.csv, run.json")
        sys.stdout.flush()
