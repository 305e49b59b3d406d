"""``physdsl mpc SCENE --plant PLANT -o OUT``: drive a plant in closed loop (iLQR over the
scene's horizon) while refitting the scene's physical unknowns from what the plant did."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def parse_initial(text: str | None) -> dict[str, float]:
    """``"joint=value, ..."`` (SI: rad, m) -> {joint: value}; a mistake is a usage error."""
    from ..errors import UsageError

    out: dict[str, float] = {}
    for part in (text or "").split(","):
        if not part.strip():
            continue
        name, eq, value = part.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq or not name.strip():
            raise UsageError(f"--initial: cannot read '{part.strip()}'",
                             hint="write JOINT=VALUE in SI (rad, m), e.g. pole_hinge=3.19")
    return out


def register(app: typer.Typer) -> None:
    @app.command("mpc")
    def mpc_cmd(
        scene: Path = typer.Argument(..., help="Scene (.phys) with unknown control sequences "
                                               "(the plan's grid and bounds) and a goal of holds."),
        plant: str = typer.Option(..., "--plant", help="An MJCF file (.xml, needs mujoco) or a "
                                                       "Python entry point 'module:factory'."),
        out: Path = typer.Option(..., "-o", "--out", help="Output folder."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        duration: float = typer.Option(3.0, "--duration", min=0.0, help="Plant time to run (s)."),
        refit_every: int = typer.Option(10, "--refit-every", min=0,
                                        help="Control periods between refits (0: never refit)."),
        early_refits: int = typer.Option(0, "--early-refits", min=0,
                                         help="Also refit after each of the first N transitions "
                                              "(from all so far: a far-off model is corrected "
                                              "before a fast system is lost)."),
        initial: Optional[str] = typer.Option(None, "--initial",
                                              help="Plant's initial joint values, SI: "
                                                   "'pole_hinge=3.19,cart_slider=0'."),
        settle: float = typer.Option(0.0, "--settle", min=0.0,
                                     help="The goal is judged from this time on (s)."),
        seed: int = typer.Option(0, "--seed", help="Seed of the plant's noise."),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
    ) -> None:
        """Closed-loop control with online refits: trajectory.csv, estimates.csv, mpc.json."""
        from .. import api
        from ..control import mpc_files
        from ..control.plant_spec import check_plant_spec
        from ..io import prepare_outdir

        start = parse_initial(initial)
        check_plant_spec(plant)
        prepare_outdir(out, force=force)  # refuse before the long part
        model = api.compile(scene, allowed_paths=allow_path or ())

        def progress(k, t, x, u, z) -> None:
            if k % 25 == 0:
                print(f"t {t:.2f} s: u {', '.join(f'{v:.3g}' for v in u)}", file=sys.stderr)

        settings = {"scene": str(scene), "plant": plant, "duration_s": duration,
                    "refit_every": refit_every, "early_refits": early_refits, "initial": start,
                    "seed": seed}
        result = api.mpc(model, plant, duration, refit_every=refit_every, initial=start, seed=seed,
                         outdir=out, force=True, settle=settle, settings=settings,
                         on_step=progress, early_refits=early_refits)
        summary = mpc_files.summary(result, settle)
        for joint, e in summary["hold_errors"].items():
            typer.echo(f"{joint}: max error {e['max_error']:.4g} (within {e['within']:g})")
        for name, value in summary["final_estimates"].items():
            typer.echo(f"{name} = {value:.4g} ± {summary['final_sd'][name]:.2g}")
        typer.echo(f"{summary['step_ms']['median']:.1f} ms per MPC step (median); "
                   f"goal {'held' if summary['held'] else 'NOT held'}; wrote {out}")
        if not summary["held"]:
            raise typer.Exit(1)
