"""``physdsl render``: draw a scene's frames, or posterior draws of a run as a grid image."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def register(app: typer.Typer) -> None:
    @app.command("render")
    def render_cmd(
        scene: Path = typer.Argument(..., help="The .phys scene."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        out: Path = typer.Option(..., "-o", "--output",
                                 help="Folder for frames (or the grid .png with --posterior)."),
        param: Optional[List[str]] = typer.Option(None, "--param",
                                                  help="NAME=VALUE (or NAME=x,y,z) for an "
                                                       "unknown; others at their prior median."),
        camera: Optional[str] = typer.Option(None, "--camera", help="Camera name (default: first)."),
        fps: Optional[float] = typer.Option(None, "--fps", help="Frames per second (default: "
                                            "the camera's observed frame times, else 30)."),
        posterior: Optional[Path] = typer.Option(None, "--posterior",
                                                 help="A run folder (posterior.nc): render "
                                                      "draws as a grid image."),
        draws: int = typer.Option(8, "--draws", help="Posterior draws in the grid."),
        time: Optional[float] = typer.Option(None, "--time",
                                             help="Time of the grid frame (default: the "
                                                  "last observed frame, else 0)."),
        force: bool = typer.Option(False, "--force", help="Overwrite the output."),
    ) -> None:
        """Render a scene seen by one of its cameras (PNG frames and render.mp4), or with
        --posterior a grid: the observed frame (if any) then posterior draws."""
        from .. import api, io
        from ..render import files
        from ..render.inverse import grid

        model = api.compile(scene)
        files.pick_camera(model.scene, camera)  # a wrong camera name before anything else
        if posterior is None:
            values = files.parse_params(param, model)
            folder = io.prepare_outdir(out, force=force)
            frames = api.render(model, values, camera=camera, fps=fps)
            written = files.write_frames(frames.images, folder, fps or files.frame_rate(frames.times))
            typer.echo(f"wrote {len(frames.images)} frames ({frames.images.shape[2]}x"
                       f"{frames.images.shape[1]}) of camera '{frames.camera}' to {folder}"
                       + (" and render.mp4" if written[-1].suffix == ".mp4" else ""))
            return
        io.refuse_overwrite(out, force)
        idata, _ = api.read_run(posterior)
        images, t = api.render_draws(model, idata, camera=camera, draws=draws, time=time)
        files.write_png(Path(out), grid(images, pad=2, columns=min(len(images), 9)))
        typer.echo(f"wrote {len(images)} images at t = {t:g} s to {out}")
