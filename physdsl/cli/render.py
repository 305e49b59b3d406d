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
        import numpy as np

        from .. import io, syntax
        from ..compile import Model
        from ..render import files
        from ..render.scene import render_frames

        model = Model(syntax.load(scene))
        cam = files.pick_camera(model.scene, camera)
        if posterior is None:
            values = {**files.prior_medians(model), **files.parse_params(param, model)}
            folder = io.prepare_outdir(out, force=force)
            times = files.frame_times(model, cam, fps)
            images = np.asarray(render_frames(model.scene, model.simulator,
                                              model.simulate(values), values, cam, times))
            written = files.write_frames(images, folder, fps or _rate(times))
            typer.echo(f"wrote {len(images)} frames ({images.shape[2]}x{images.shape[1]}) "
                       f"of camera '{cam}' to {folder}"
                       + (" and render.mp4" if written[-1].suffix == ".mp4" else ""))
            return
        _posterior_grid(model, cam, posterior, out, draws, time, force)


def _rate(times) -> float:
    import numpy as np

    return float(1.0 / np.median(np.diff(times))) if len(times) > 1 else 30.0


def _posterior_grid(model, cam, run_dir, out, n, time, force):
    import numpy as np

    from .. import io
    from ..errors import UsageError
    from ..infer.output import load_run
    from ..observe.image import load_frames
    from ..render import files
    from ..render.inverse import grid
    from ..render.scene import render_frames

    io.refuse_overwrite(out, force)
    idata, _ = load_run(run_dir)
    post = idata.posterior
    missing = [u for u in model.unknown_names if u not in post]
    if missing:
        raise UsageError(f"the run has no draws of {', '.join(missing)}",
                         hint="give the run of this scene")
    obs = next((o for o in model.images if o.target == cam), None)
    t = time if time is not None else (float(obs.times[-1]) if obs is not None else 0.0)
    images = []
    if obs is not None:
        i = int(np.argmin(np.abs(np.asarray(obs.times) - t)))
        t = float(obs.times[i])
        images.append(load_frames([obs.frames[i]], times=[t])[1][0])
    flat = {u: np.asarray(post[u]).reshape((-1,) + np.asarray(post[u]).shape[2:])
            for u in model.unknown_names}
    total = next(iter(flat.values())).shape[0] if flat else 1
    for k in np.linspace(0, total - 1, min(n, total)).round().astype(int):
        values = {u: v[k] for u, v in flat.items()}
        images.append(np.asarray(render_frames(model.scene, model.simulator,
                                               model.simulate(values), values, cam,
                                               np.array([t])))[0])
    files.write_png(Path(out), grid(images, pad=2, columns=min(len(images), 9)))
    typer.echo(f"wrote {len(images)} images at t = {t:g} s to {out}")
