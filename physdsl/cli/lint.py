"""``physdsl lint FILE...`` (alias ``check-syntax``): parse and resolve, report every error, list unknowns."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import PhysError
from .paths import ALLOW_PATH


def lint_files(files: list[Path], quiet: bool = False) -> int:
    """Lint each file; print errors to stderr and the unknowns table to stdout; 0 ok, 2 errors."""
    from rich.console import Console
    from rich.table import Table

    from ..syntax import load, unknowns_rows  # the language floor alone: no inference imported

    out = Console(file=sys.stdout, width=200, highlight=False, soft_wrap=True)
    code = 0
    for f in files:
        try:
            scene = load(f)  # = physdsl.load of a path
        except PhysError as err:
            print(err.render(), file=sys.stderr)
            code = max(code, 2)
            continue
        out.print(f"{f}: ok: scene '{scene.name}', {len(scene.bodies)} bodies, {len(scene.joints)} "
                  f"joints, {len(scene.effects)} effects, {len(scene.observations)} observations, "
                  f"{len(scene.unknowns)} unknowns", markup=False)
        note = integrator_note(scene)
        if note:
            out.print(f"{f}: note: {note}", markup=False)
        if quiet or not scene.unknowns:
            continue
        table = Table(title=f"unknowns of {scene.name}", title_justify="left")
        for col in ("name", "prior", "support", "shape", "unit", "used in"):
            table.add_column(col, overflow="fold")
        for row in unknowns_rows(scene):
            table.add_row(*row)
        out.print(table)
    return code


def integrator_note(scene) -> str | None:
    """Where the stepping differs from the chosen integrator (``physics.integrate.step``), in words."""
    if not scene.contact_pairs or scene.world.integrator == "semi_implicit_euler":
        return None
    how = ("the LCP contact step (velocity level, first order)" if scene.world.contact_model == "lcp"
           else "semi-implicit Euler with the penalty forces")
    return (f"integrator {scene.world.integrator} between contacts; a step with a contact within "
            f"reach ({len(scene.contact_pairs)} contact pair{'s' * (len(scene.contact_pairs) > 1)}) "
            f"is {how}")


def register(app: typer.Typer) -> None:
    def lint(files: list[Path] = typer.Argument(..., help="Scene files (.phys)."),
             allow_path: Optional[List[Path]] = ALLOW_PATH,
             quiet: bool = typer.Option(False, "--quiet", "-q", help="Only report errors.")) -> None:
        """Check scene files: syntax, names, units, structure, data; list the unknowns."""
        raise typer.Exit(lint_files(files, quiet))

    app.command("lint")(lint)
    app.command("check-syntax", help="Alias of 'lint'.")(lint)
