"""``--allow-path DIR``, taken by every command that loads a scene: a scene reads imports and
data files in its own folder tree and the standard library, and below the folders named here
(syntax/bounds.py)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def _allow(ctx: typer.Context, value: Optional[list[Path]]) -> Optional[list[Path]]:
    from ..syntax.bounds import allowing

    if value:
        ctx.with_resource(allowing(value))  # for the rest of this command, then undone
    return value


ALLOW_PATH = typer.Option(
    None, "--allow-path", metavar="DIR", exists=True, file_okay=False, is_eager=True,
    callback=_allow, help="Let the scene also read imports and data files below DIR "
                          "(repeatable); by default only its own folder tree and the stdlib.")
