"""``physdsl control SCENE -o OUT``: choose the scene's unknown control sequences and the goal's
decisions so its ``goal`` is met (``physdsl design`` is the same command for a scene whose
goal chooses only design values: its result is ``planned.phys``)."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def _command(app: typer.Typer, name: str, summary: str) -> None:
    @app.command(name, help=summary)
    def control(
        scene: Path = typer.Argument(..., help="Scene file (.phys) with a goal block."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        out: Path = typer.Option(..., "-o", "--out", help="Output folder."),
        posterior: Optional[Path] = typer.Option(
            None, "--posterior", help="Run folder of a fit of this scene: the plan minimises the "
                                      "expected cost over its draws (else the prior's centre)."),
        draws: int = typer.Option(16, "--draws", min=1, help="Posterior draws averaged over."),
        steps: int = typer.Option(200, "--steps", min=1, help="L-BFGS steps at most per start."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
    ) -> None:
        from .. import api

        model = api.compile(scene)
        idata = api.read_run(posterior)[0] if posterior is not None else None

        def progress(start: int, step: int, cost: float) -> None:
            if step % 10 == 0:
                print(f"start {start + 1} step {step}: cost {cost:.4g}", file=sys.stderr)

        problem, plan = api.control(model, idata=idata, outdir=out, force=force, draws=draws,
                                    steps=steps, on_step=progress)
        for term, err in zip(problem.goal.terms, plan.errors):
            within = getattr(term, "within", None)
            label = getattr(term, "target", None) or getattr(term, "joint", None) or "effort"
            typer.echo(f"{label}: error {err:.4g}" + (f" (within {within:g})" if within else ""))
        typer.echo(f"goal {'met' if plan.met else 'NOT met'}; wrote {out}/plan.json")
        if not plan.met:
            raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    _command(app, "control", "Choose control sequences (and decisions) that meet the scene's goal.")
    _command(app, "design", "Choose design values (the goal's decide:) that meet the scene's goal; "
                            "writes planned.phys.")
