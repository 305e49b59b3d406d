"""``physdsl fmt FILE``: print the canonical text; ``--check`` exits 1 if not formatted; ``--write`` rewrites."""
from __future__ import annotations

import sys
from pathlib import Path

import typer

from ..errors import PhysImportError


def register(app: typer.Typer) -> None:
    @app.command("fmt")
    def fmt(file: Path = typer.Argument(..., help="Scene or library file (.phys)."),
            check: bool = typer.Option(False, "--check", help="Exit 1 if the file is not formatted."),
            write: bool = typer.Option(False, "--write", "-w", help="Rewrite the file in place.")) -> None:
        """Format a .phys file canonically (comments kept)."""
        from ..syntax import format_source  # = physdsl.format_source; no inference imported
        from ..io import write_text

        try:
            text = file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as ex:
            raise PhysImportError(f"cannot read {file}: {getattr(ex, 'strerror', ex)}") from None
        pretty = format_source(text, str(file))
        if check:
            if pretty != text:
                print(f"{file}: not formatted (run 'physdsl fmt --write {file}')", file=sys.stderr)
                raise typer.Exit(1)
            raise typer.Exit(0)
        if write:
            if pretty != text:
                write_text(file, pretty)
            raise typer.Exit(0)
        sys.stdout.write(pretty)
