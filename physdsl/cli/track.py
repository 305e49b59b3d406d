"""``physdsl track``: colour-blob tracking of frames or a video into a trajectory CSV."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import UsageError


def _parse_color(text: str, index: int):
    """``R,G,B`` or ``NAME=R,G,B``; values in [0, 1] or 0..255."""
    name, _, rgb = text.rpartition("=")
    try:
        vals = [float(v) for v in rgb.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3:
        raise UsageError(f"cannot read the colour {text!r}", hint="write R,G,B or NAME=R,G,B")
    if max(vals) > 1.0:
        vals = [v / 255.0 for v in vals]
    return (name or (f"object{index}" if index else "object"), tuple(vals))


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
    from ..observe.image import load_frames
    from ..render.camera_json import load_camera_json
    from ..track import Target, parse_plane, to_world, track_image
    import numpy as np

    if out.exists() and not force:
        raise UsageError(f"{out} exists", hint="pass --force to overwrite it")
    targets = [Target(*_parse_color(c, i)) for i, c in enumerate(color)]
    spec = load_camera_json(camera) if camera is not None else None
    if (depth_plane or radius) and spec is None:
        raise UsageError("--depth-plane and --radius need --camera")
    if spec is not None and rate is None and not Path(source).suffix.lower() in (".mp4", ".avi"):
        rate = spec.frame_rate
    size = (spec.camera.width, spec.camera.height) if spec is not None else None
    times, frames = load_frames(source, rate=rate, size=size)
    rows = track_image(times, frames, targets, tolerance)
    world = None
    if spec is not None and (depth_plane or radius):
        uv = np.array([[r[2], r[3]] for r in rows]).reshape(-1, 2)
        area = np.array([r[4] for r in rows])
        world = to_world(spec.camera, uv, area,
                         plane=parse_plane(depth_plane) if depth_plane else None, radius=radius)
    from ..track import write_csv

    write_csv(out, rows, world)
    found = {r[1] for r in rows}
    for t in targets:
        n = sum(1 for r in rows if r[1] == t.name)
        typer.echo(f"{t.name}: found in {n} of {len(frames)} frames")
    if not found:
        typer.echo("warning: no target found in any frame; check --color and --tolerance",
                   err=True)


def register(app: typer.Typer) -> None:
    app.command("track")(track_command)
