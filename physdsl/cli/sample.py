"""``physdsl sample``: draw concrete scenes (and their simulated trajectories) from a program."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("sample")
    def sample_cmd(
        program: Path = typer.Argument(..., help="A .phys program, e.g. one written by `physdsl export`."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        n: int = typer.Option(..., "-n", help="How many scenes to draw."),
        seed: int = typer.Option(0, "--seed", help="Random seed."),
        out: Path = typer.Option(..., "-o", "--output", help="Folder for scene-0001/, ... and parameters.csv."),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty folder."),
        no_simulate: bool = typer.Option(False, "--no-simulate", help="Write scenes and parameters only."),
    ) -> None:
        """Draw N scenes: concrete .phys files, simulated trajectories, a parameter table."""
        from .. import api

        result = api.sample(program, n, seed, out, force=force, simulate=not no_simulate)
        typer.echo(result.summary())
        typer.echo(f"wrote {len(result.scenes)} scenes and parameters.csv to {result.outdir}")
