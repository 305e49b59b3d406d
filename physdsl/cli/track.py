"""``physdsl track``: colour-blob tracking of frames or a video into a trajectory CSV."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import UsageError


def track_command(
    source: str = typer.Argument(..., help="Video file, folder of frames, or a glob of frames."),
    color: List[str] = typer.Option(..., "--color", help="R,G,B or NAME=R,G,B (repeatable)."),
    out: Path = typer.Option(..., "-o", "--output", help="Trajectory CSV to write."),
    tolerance: float = typer.Option(0.08, help="Chromaticity distance counted as the colour."),
    camera: Optional[Path] = typer.Option(None, help="camera.json for 3D positions."),
    depth_plane: Optional[str] = typer.Option(None, help="Plane the objects move in: y=0 or nx,ny,nz,d."),
    radius: Optional[float] = typer.Option(None, help="Object radius (m): depth from apparent size."),
    rate: Optional[float] = typer.Option(None, help="Frame rate (Hz); default camera.json or video."),
    force: bool = typer.Option(False, "--force", help="Overwrite the output file."),
) -> None:
    """Track coloured objects: image positions (t,body,u,v) or, with a camera, world (t,body,x,y,z)."""
    from .. import api

    if out.exists() and not force:
        raise UsageError(f"{out} exists", hint="pass --force to overwrite it")
    tracked = api.track(source, color, tolerance=tolerance, camera=camera,
                        depth_plane=depth_plane, radius=radius, rate=rate)
    tracked.write_csv(out)
    for t in tracked.targets:
        typer.echo(f"{t.name}: found in {tracked.found_in(t.name)} of {tracked.frames} frames")
    if not tracked.rows:
        typer.echo("warning: no target found in any frame; check --color and --tolerance",
                   err=True)


def register(app: typer.Typer) -> None:
    app.command("track")(track_command)
