"""The many-throws example's data, cut to fewer and shorter throws for fast tests."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

import physdsl

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "many_throws"
TRUTH = json.loads((EXAMPLE / "throws" / "truth.json").read_text())


def throws(tmp: Path, picks, max_t: float | None = None) -> Path:
    """A folder holding the example's scene and the throws ``picks`` (their first ``max_t``
    seconds); returns the scene's path."""
    for name in picks:
        rows = (EXAMPLE / "throws" / name / "trajectory.csv").read_text().splitlines()
        keep = [rows[0]] + [r for r in rows[1:] if max_t is None or float(r.split(",")[0]) <= max_t]
        (tmp / "throws" / name).mkdir(parents=True, exist_ok=True)
        (tmp / "throws" / name / "trajectory.csv").write_text("\n".join(keep) + "\n")
    scene = tmp / "scene.phys"
    scene.write_text((EXAMPLE / "scene.phys").read_text())
    return scene


def single(tmp: Path, name: str) -> Path:
    """The example's scene fitted to throw ``name`` alone, as a plain scene (no experiments);
    the throw's data are copied in (whole) unless ``tmp`` holds them already."""
    if not (tmp / "throws" / name / "trajectory.csv").exists():
        throws(tmp, [name])
    text = (EXAMPLE / "scene.phys").read_text()
    text = re.sub(r"\n\s*experiments [^\n]*", "", text).replace("per_experiment ", "")
    text = text.replace('from "trajectory.csv"', f'from "throws/{name}/trajectory.csv"')
    path = tmp / f"single_{name}.phys"
    path.write_text(text)
    return path


def interval(idata, name: str, level: float = 0.9) -> tuple[float, float]:
    x = np.asarray(idata.posterior[name].values).ravel()
    return tuple(np.quantile(x, [(1 - level) / 2, (1 + level) / 2]))


def drag_fit(scene: Path, chains: int = 1, **options):
    """(90% interval of the drag coefficient, the InferenceData) of a MAP/Laplace fit."""
    idata = physdsl.infer(physdsl.compile(scene), backend="map", chains=chains, progress=False,
                          **options)
    return interval(idata, "quadratic_drag@ball.coefficient"), idata


def without_drag(scene: Path) -> Path:
    """``scene`` with its drag effect line removed (what a diagnosis should find)."""
    text = re.sub(r"\n\s*effect quadratic_drag[^\n]*", "", scene.read_text())
    out = scene.with_name("naive_" + scene.name)
    out.write_text(text)
    return out
