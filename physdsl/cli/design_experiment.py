"""``physdsl design-experiment SCENE_A SCENE_B --vary ball.velocity -o OUT``: the setting that
best tells two fitted models apart (see physdsl.design.experiment); ``physdsl design-experiment
SCENE --posterior RUN --vary rail -o OUT``: the excitation that teaches the most about the
scene's unknowns (see physdsl.design.excite)."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .paths import ALLOW_PATH


def _range(text: Optional[str]):
    from ..errors import UsageError

    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise UsageError(f"--range {text}: expected LO:HI in SI units", hint="e.g. --range 2:20") from None
    return lo, hi


def register(app: typer.Typer) -> None:
    @app.command("design-experiment")
    def design_experiment(
        scene_a: Path = typer.Argument(..., help="First fitted scene (.phys)."),
        scene_b: Optional[Path] = typer.Argument(None, help="Second fitted scene (.phys), same "
                                                 "measurements; without it: the most informative "
                                                 "excitation of SCENE_A."),
        allow_path: Optional[List[Path]] = ALLOW_PATH,
        vary: List[str] = typer.Option(..., "--vary", help="Unknown of both scenes to vary "
                                       "(e.g. ball.velocity: its speed, direction kept)."),
        out: Path = typer.Option(..., "-o", "--out", help="Output folder (design.json)."),
        posterior_a: Optional[Path] = typer.Option(None, "--posterior-a", help="Run of SCENE_A (else MAP here)."),
        posterior_b: Optional[Path] = typer.Option(None, "--posterior-b", help="Run of SCENE_B (else MAP here)."),
        range_: Optional[str] = typer.Option(None, "--range", help="LO:HI of the varied speed or "
                                             "value, SI (default: prior mean ± 3 sd)."),
        objective: str = typer.Option("max_sigma", "--objective", help="max_sigma (largest "
                                      "|Δ|/σ) or chi2 (summed (Δ/σ)²)."),
        posterior: Optional[Path] = typer.Option(None, "--posterior", help="Run of SCENE_A whose "
                                                 "posterior the experiment should narrow (one scene)."),
        energy: Optional[float] = typer.Option(None, "--energy", help="Budget of ∫u² dt over the "
                                               "varied controls, SI (default: a random push's)."),
        restarts: int = typer.Option(4, "--restarts", min=1, help="Gradient searches (one scene)."),
        random: int = typer.Option(8, "--random", min=1, help="Random excitations of the same "
                                   "energy to compare with (one scene)."),
        seed: int = typer.Option(0, "--seed"),
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
    ) -> None:
        """Propose the setting whose predictions of the two models differ most in noise units,
        or (one scene) the excitation that narrows its unknowns' posterior the most."""
        from .. import api, io

        rng = _range(range_)
        if scene_b is None:
            model = api.compile(scene_a)
            idata = api.read_run(posterior)[0] if posterior is not None else None
            found = api.design_experiment(model, None, vary, idata_a=idata, rng=rng, energy=energy,
                                          restarts=restarts, random=random, seed=seed,
                                          outdir=out, force=force)
            typer.echo(found.text())
            typer.echo(f"wrote {out}/design.json, design.txt, experiment.phys")
            return
        ma, mb = api.compile(scene_a), api.compile(scene_b)
        idata_a = api.read_run(posterior_a)[0] if posterior_a is not None else None
        idata_b = api.read_run(posterior_b)[0] if posterior_b is not None else None
        proposals = api.design_experiment(ma, mb, vary, idata_a=idata_a, idata_b=idata_b,
                                          rng=rng, objective=objective,
                                          labels=(scene_a.stem, scene_b.stem))
        io.prepare_outdir(out, force=force)
        for p in proposals:
            typer.echo(p.text())
        io.write_json(out / "design.json", {"proposals": [p.to_dict() for p in proposals]})
        typer.echo(f"wrote {out}/design.json")
