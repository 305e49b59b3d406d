"""``physdsl design-experiment SCENE_A SCENE_B --vary ball.velocity -o OUT``: the setting that
best tells two fitted models apart (see physdsl.design.experiment)."""
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


def _values(model, run: Optional[Path]) -> dict:
    """The fitted values: the most likely draw of ``run``, or of a MAP fit made here."""
    from ..diagnose.rank import fit_with_fallback
    from ..diagnose.workflow import point_estimate
    from ..infer.output import load_run

    idata = load_run(run)[0] if run is not None else fit_with_fallback(
        model, "map", chains=2, warmup=200, samples=200, seed=0, progress=False)
    return point_estimate(model, idata)


def register(app: typer.Typer) -> None:
    @app.command("design-experiment")
    def design_experiment(
        scene_a: Path = typer.Argument(..., help="First fitted scene (.phys)."),
        scene_b: Path = typer.Argument(..., help="Second fitted scene (.phys), same measurements."),
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
        force: bool = typer.Option(False, "--force", help="Overwrite a non-empty output folder."),
    ) -> None:
        """Propose the setting whose predictions of the two models differ most in noise units."""
        from .. import io
        from ..compile import Model
        from ..design.experiment import OBJECTIVES, design, require_unknown
        from ..syntax import load

        rng = _range(range_)
        ma, mb = Model(load(scene_a)), Model(load(scene_b))
        for field in vary:  # usage errors before any fit
            require_unknown((ma, mb), field)
        if objective not in OBJECTIVES:
            from ..errors import UsageError
            raise UsageError(f"unknown objective '{objective}'", hint=" or ".join(OBJECTIVES))
        va, vb = _values(ma, posterior_a), _values(mb, posterior_b)
        io.prepare_outdir(out, force=force)
        proposals = [design(ma, va, mb, vb, field, rng, objective, (scene_a.stem, scene_b.stem))
                     for field in vary]
        for p in proposals:
            typer.echo(p.text())
        io.write_json(out / "design.json", {"proposals": [p.to_dict() for p in proposals]})
        typer.echo(f"wrote {out}/design.json")
