"""``physdsl batch infer|refine|sample --scenes 'dir/*/scene.phys' -o OUT``: one job per scene,
on a local process pool (default) or a Ray cluster (``--executor ray --address HOST:PORT``).

Exit code 0 when every job finished, 1 when any failed (each reported with its error, the
others run on), 2 for a usage error. Run the same command again to finish a stopped batch:
finished jobs are skipped."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

SCENES = typer.Option(..., "--scenes", metavar="GLOB",
                      help="Scene files, a quoted glob such as 'throws/*/scene.phys' (** spans "
                           "folders; repeatable). One job per file.")
OUT = typer.Option(..., "-o", "--out", help="Batch folder: OUT/<job>/ per scene, OUT/batch.json.")
EXECUTOR = typer.Option("local", "--executor", help="local (a process pool here), ray, or inline (this process, one job at a time).")
ADDRESS = typer.Option(None, "--address", metavar="HOST:PORT",
                       help="The Ray cluster's head (with --executor ray; none: start Ray here).")
WORKERS = typer.Option(None, "--workers", min=1,
                       help="Jobs at a time on the local pool (default: one per CPU); with "
                            "--executor ray and no --address, CPUs of the Ray started here.")
RETRIES = typer.Option(3, "--retries", min=0, help="Ray: runs of a job whose worker died.")
FORCE = typer.Option(False, "--force", help="Run every job again (and accept other settings "
                                            "or a non-batch folder as OUT).")
QUIET = typer.Option(False, "--quiet", help="No progress on stderr.")


def register(app: typer.Typer) -> None:
    batch = typer.Typer(help="Run one job per scene (a fit, a refine loop, a sampling) on a "
                             "local process pool or a Ray cluster; restartable.",
                        no_args_is_help=True)
    app.add_typer(batch, name="batch")

    @batch.command("infer")
    def batch_infer(
        scenes: List[str] = SCENES, out: Path = OUT, executor: str = EXECUTOR,
        address: Optional[str] = ADDRESS, workers: Optional[int] = WORKERS,
        retries: int = RETRIES, force: bool = FORCE, quiet: bool = QUIET,
        backend: str = typer.Option("nuts", "--backend", "-b",
                                    help="nuts | hmc | rmh | numpyro-nuts | map"),
        chains: int = typer.Option(4, "--chains", min=1),
        warmup: int = typer.Option(500, "--warmup", min=0),
        samples: int = typer.Option(500, "--samples", min=1),
        seed: int = typer.Option(0, "--seed"),
        intervals: str = typer.Option("robust", "--intervals", help="robust or model"),
    ) -> None:
        """Fit every scene (as `physdsl infer`): OUT/<job>/posterior.nc, summary.csv, run.json."""
        from ..infer import get_backend
        from ..infer.intervals import SHOWN
        from ..errors import UsageError

        get_backend(backend)
        if intervals not in SHOWN:
            raise UsageError(f"unknown --intervals '{intervals}'", hint="robust or model")
        _run("infer", scenes, out, dict(backend=backend, chains=chains, warmup=warmup,
                                        samples=samples, seed=seed, intervals=intervals),
             executor, address, workers, retries, force, quiet)

    @batch.command("refine")
    def batch_refine(
        scenes: List[str] = SCENES, out: Path = OUT, executor: str = EXECUTOR,
        address: Optional[str] = ADDRESS, workers: Optional[int] = WORKERS,
        retries: int = RETRIES, force: bool = FORCE, quiet: bool = QUIET,
        max_rounds: int = typer.Option(3, "--max-rounds", min=0),
        backend: str = typer.Option("map", "--backend", "-b"),
        chains: int = typer.Option(2, "--chains", min=1),
        warmup: int = typer.Option(300, "--warmup", min=0),
        samples: int = typer.Option(300, "--samples", min=1),
        seed: int = typer.Option(0, "--seed"),
        confirm: int = typer.Option(2, "--confirm", min=1),
    ) -> None:
        """Run the diagnosis loop on every scene (as `physdsl refine`)."""
        from ..infer import get_backend

        get_backend(backend)
        _run("refine", scenes, out, dict(max_rounds=max_rounds, backend=backend, chains=chains,
                                         warmup=warmup, samples=samples, seed=seed,
                                         confirm_top=confirm),
             executor, address, workers, retries, force, quiet)

    @batch.command("sample")
    def batch_sample(
        scenes: List[str] = SCENES, out: Path = OUT, executor: str = EXECUTOR,
        address: Optional[str] = ADDRESS, workers: Optional[int] = WORKERS,
        retries: int = RETRIES, force: bool = FORCE, quiet: bool = QUIET,
        n: int = typer.Option(..., "-n", min=1, help="Scenes to draw per program."),
        seed: int = typer.Option(0, "--seed"),
        no_simulate: bool = typer.Option(False, "--no-simulate"),
    ) -> None:
        """Draw N scenes from every program (as `physdsl sample`)."""
        _run("sample", scenes, out, dict(n=n, seed=seed, simulate=not no_simulate),
             executor, address, workers, retries, force, quiet)


def _run(command: str, scenes: list[str], out: Path, options: dict, executor: str,
         address: Optional[str], workers: Optional[int], retries: int, force: bool,
         quiet: bool) -> None:
    """Run the batch; print its counts; exit 1 if any job failed."""
    from ..batch import run_batch

    try:
        summary = run_batch(command, scenes, out, options, executor, address=address,
                            workers=workers, retries=retries, force=force, progress=not quiet)
    except KeyboardInterrupt as ex:  # click would say 'Aborted!' and exit 1
        typer.echo(f"interrupted: the finished jobs are kept in {out} (batch.json); run the "
                   "same command again to run the others", err=True)
        raise typer.Exit(128 + getattr(ex, "signum", 2))
    counts = summary["counts"]
    rate = summary["fits_per_hour"]
    typer.echo(f"{counts['done']} done, {counts['failed']} failed, {counts['skipped']} skipped "
               f"(finished before) in {summary['wall_s']:.1f} s"
               + (f" ({rate:.0f} jobs/hour)" if rate else ""))
    for name in summary["failed"]:
        typer.echo(f"failed: {name} (see {out / name / 'failed.json'})")
    typer.echo(f"wrote {out / 'batch.json'}")
    if counts["failed"]:
        raise typer.Exit(1)
