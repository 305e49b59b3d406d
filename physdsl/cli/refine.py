"""``physdsl refine SCENE.phys -o OUT/``: fit, check, diagnose, add the effect, refit; watch the error fall."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .diagnose import REFIT_ADDRESS, REFIT_EXECUTOR, REFIT_WORKERS
from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("refine")
    def refine(
        scene: Path = typer.Argument(..., help="Scene file (.phys); it is never edited."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        out: Path = typer.Option(..., "-o", "--out", help="Output folder (round-0/, round-1/, ...)."),
        max_rounds: int = typer.Option(3, "--max-rounds", min=0, help="Effects to add at most."),
        backend: str = typer.Option("map", "--backend", "-b",
                                    help="Backend for each round's fit: map (fast, Laplace) or nuts, hmc, rmh."),
        chains: int = typer.Option(2, "--chains", min=1),
        warmup: int = typer.Option(300, "--warmup", min=0),
        samples: int = typer.Option(300, "--samples", min=1),
        seed: int = typer.Option(0, "--seed"),
        confirm: int = typer.Option(2, "--confirm", min=1,
                                    help="Refit the best N candidates per round to confirm one."),
        revise: list[str] = typer.Option([], "--revise", help="An effect of the scene (EFFECT@TARGET) the "
                                          "loop may swap for another law or drop, like those it adds."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
        allow_learned: bool = typer.Option(False, "--allow-learned", help="Where no library effect "
                                           "explains the misfit (or the best only half explains it), "
                                           "add the law distilled from a learned force to the next "
                                           "round when its evidence beats the library's (outside the "
                                           "library; without this flag it is only reported)."),
        learned: bool = typer.Option(True, "--learned/--no-learned", help="Learn a force where the "
                                     "library explains nothing or only half, and report it "
                                     "(round-k/beyond/)."),
        executor: str = REFIT_EXECUTOR, workers: Optional[int] = REFIT_WORKERS,
        address: Optional[str] = REFIT_ADDRESS,
    ) -> None:
        """The diagnosis loop: adds, swaps and drops effects until none improves the evidence."""
        from .. import api
        from ..batch.executors import check_executor, refits_on
        from ..infer import get_backend

        get_backend(backend)  # an unknown backend before anything runs
        check_executor(executor, address)
        with refits_on(executor, address, workers):
            rounds = api.refine(scene, out, max_rounds=max_rounds, backend=backend, chains=chains,
                                warmup=warmup, samples=samples, seed=seed, force=force,
                                confirm_top=confirm, revise=tuple(revise), echo=typer.echo,
                                progress=True,  # each round's fit: its stages on stderr
                                allow_learned=allow_learned, learned=learned)
        typer.echo("\nround  action   effect                             RMS (noise units)   ELPD")
        for r in rounds:
            add = f"{r.added['effect']} on {r.added['target']}" if r.added else "-"
            if r.added and r.added.get("outside_library"):
                add += " (learned: outside the library)"
            if r.replaced:
                add = (f"{r.replaced['effect']} -> {add}" if r.added
                       else f"{r.replaced['effect']} on {r.replaced['target']}")
            typer.echo(f"{r.index:>5}  {r.action or '-':<8} {add:<34} {r.rms_sigma:>17.2f}  {r.elpd:>8.1f}")
        typer.echo(f"wrote {out}/refine.json, refine.md, refine.png")
