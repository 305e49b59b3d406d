"""physdsl's top floor: the whole workflow as plain functions over values.

``load`` (text or path -> Scene) -> ``compile`` (-> Model) -> ``infer`` (-> posterior, arviz)
-> ``check`` (-> Report) / ``diagnose`` (-> Diagnosis) -> ``add_effect`` (-> Scene) or the
whole loop ``refine``; ``design_experiment``, ``export``, ``sample``, ``render``, ``track``.
Each function calls the lower floors and holds no logic of its own beyond choosing what to
call; the command line (``physdsl.cli``) calls only these.
"""
from __future__ import annotations

import difflib
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from . import io, mjcf, syntax
from .compile import Model, load_source
from .compile import compile as _compile
from .control import ControlProblem, Plan, build as _control_problem, optimise as _optimise
from .control import mpc as _mpc
from .control import mpc_files
from .control.output import write_plan
from .control.plant_spec import load_plant
from .design.excite import InfoDesign, search as _information_search
from .design.experiment import OBJECTIVES, Proposal, design
from .design.info_files import write as _write_information
from .design.information import belief as _belief
from .design.vary import require_unknown, varied as _varied
from .diagnose.candidates import Candidate
from .diagnose.edits import load_text, with_effect
from .diagnose.diagnosis import Diagnosis
from .diagnose.quality import fit_quality
from .diagnose.rank import diagnose as _diagnose
from .diagnose.refine import Round
from .diagnose.refine import refine as _refine
from .diagnose.workflow import check_model, point_estimate
from .discover.beyond import beyond_library as _beyond_library
from .errors import PhysNameError, UsageError
from .goal import Goal
from .export import export as _export
from .infer.fit import fit_with_fallback
from .infer.init import start_setting, start_values
from .infer.output import load_run
from .infer.run import infer as _infer
from .export.mjcf import export_mjcf as _export_mjcf
from .render import files as render_files
from .sample import SampleResult
from .sample import sample as _sample
from .scene import Scene
from .track import Tracked, track_source

__all__ = [
    "load", "compile", "infer", "check", "diagnose", "refine", "add_effect", "design_experiment",
    "render", "render_draws", "track", "export", "export_mjcf", "sample", "read_run",
    "import_model", "format_source", "control", "mpc", "beyond_library",
]

format_source = syntax.format_source


def load(source: str | Path, allowed_paths=()) -> Scene:
    """The checked Scene of a .phys file (a path) or of .phys text; its imports and data files
    must lie in its folder tree (text: the working folder's), the stdlib or below ``allowed_paths``."""
    return load_source(source, allowed_paths)


def compile(source: Scene | str | Path, allowed_paths=()) -> Model:  # noqa: A001 - the design's name
    """The Model (numpyro program + simulator) of a Scene, a .phys path or .phys text."""
    return _compile(source, allowed_paths)


def infer(model: Model, backend: str = "nuts", *, fallback: str | None = None, init=None,
          **settings):
    """Posterior over every unknown of ``model`` (arviz; see ``physdsl.infer.run.infer`` for the
    settings: chains, warmup, samples, seed, outdir, resume, intervals, ...). ``init``: start
    values (``"name=value, ..."`` text or a dict). ``fallback="rmh"`` with ``backend="map"``:
    where the Laplace step fails, sample from the modes by random-walk Metropolis."""
    if fallback is not None and (fallback != "rmh" or backend != "map"):
        raise UsageError(f"--fallback {fallback} with --backend {backend}",
                         hint="--fallback rmh goes with --backend map: random-walk "
                              "Metropolis from the mode where the Laplace step fails")
    start = start_values(init, model.unknowns) if init else None  # errors before compiling
    settings = {"quality": fit_quality, **settings}  # run.json's fit_quality (with outdir)
    if fallback:  # refine's fallback; its starts read the start values as a setting
        return fit_with_fallback(model, backend, start=start_setting(start or {}), **settings)
    return _infer(model, backend, **settings, **({"init": start} if start else {}))


def check(model: Model, idata, outdir: str | Path | None = None, windows: int = 4):
    """Where ``model`` misses its measurements under the posterior ``idata``: a Report
    (residuals per observable and time window in noise units; files in ``outdir`` if given)."""
    return check_model(model, idata, outdir=outdir, windows=windows)


def diagnose(model: Model, idata, *, confirm_top: int = 2, outdir=None, echo=None, **options
             ) -> Diagnosis:
    """Which missing effect explains the misfit: ranked candidates, the best confirmed by
    refitting (``echo``: a line -> None hearing of the refits)."""
    return _diagnose(model, idata, confirm_top=confirm_top, outdir=outdir, echo=echo, **options)


def _scene_path(scene) -> Path:
    scene = scene.scene if isinstance(scene, Model) else scene
    if isinstance(scene, Scene):
        if scene.path is None:
            raise UsageError("this needs a scene read from a file (refine and export read its text "
                             "and data beside it)", hint="load it from its .phys path")
        return Path(scene.path)
    return Path(scene)


def refine(scene: Scene | str | Path, outdir: str | Path, *, allow_learned: bool = False,
           learned: bool = True, **options) -> list[Round]:
    """The loop fit, check, diagnose, add the effect, refit until nothing improves the evidence;
    each round's files in ``outdir`` (see ``physdsl.diagnose.refine.refine`` for the options).
    Where nothing in the library explains the misfit, or the round's library winner leaves
    systematic residuals and less than 90% of the misfit explained, it learns a force and
    distils a law (``learned=False``: it does not); the law enters the next round only with
    ``allow_learned=True``, always labelled as outside the library."""
    return _refine(_scene_path(scene), outdir, beyond=_beyond_library if learned else None,
                   allow_learned=allow_learned, **options)


def beyond_library(model: Model, idata, outdir: str | Path, **options):
    """Learn a residual force where the check points (or on ``target``), distil it into a law,
    refit the law; a ``physdsl.discover.Beyond`` (see ``physdsl.discover.beyond``)."""
    report = options.pop("report", None)
    return _beyond_library(model, idata, report, outdir, **options)


def add_effect(scene: Scene, effect: str, target: str | Sequence[str]) -> Scene:
    """``scene`` with the library effect ``effect`` on ``target`` (a body, joint, ``"a,b"`` pair
    or ``world``), its strength a new unknown with the library prior; the new Scene's
    ``source`` is its text."""
    if effect not in scene.effect_library:
        close = difflib.get_close_matches(effect, list(scene.effect_library), n=3)
        raise PhysNameError(f"unknown effect '{effect}'",
                            hint=f"did you mean {', '.join(close)}?" if close else
                            "known effects: " + ", ".join(sorted(scene.effect_library)))
    parts = target.strip("()").split(",") if isinstance(target, str) else target
    return load_text(scene, with_effect(scene, Candidate("effect", effect, tuple(t.strip() for t in parts))))


def control(model: Model, goal: Goal | None = None, idata=None, *, outdir: str | Path | None = None,
            force: bool = False, draws: int = 16, steps: int = 200, on_step=None
            ) -> tuple[ControlProblem, Plan]:
    """Choose the scene's unknown control sequences and the goal's decisions so ``goal`` (default:
    the scene's ``goal`` block) is met: L-BFGS through the rollout from screened prior draws;
    with a posterior ``idata``, the expected cost over up to ``draws`` of its draws. Files
    (controls CSV, planned.phys, predicted.csv, cost.png, plan.json) in ``outdir`` if given."""
    goal = goal if goal is not None else model.scene.goal
    if goal is None:
        raise UsageError("the scene has no goal", hint="add a `goal { ... }` block (docs/control.md)")
    started = time.perf_counter()
    problem = _control_problem(model, goal, idata=idata, draws=draws)
    plan = _optimise(problem, steps=steps, on_step=on_step)
    if outdir is not None:
        io.prepare_outdir(outdir, force=force)
        write_plan(problem, plan, Path(outdir), time.perf_counter() - started)
    return problem, plan


def mpc(model: Model, plant, duration: float, *, refit_every: int = 10, initial=None,
        seed: int = 0, outdir: str | Path | None = None, force: bool = False, settle: float = 0.0,
        settings: dict | None = None, on_step=None, early_refits: int = 0):
    """Drive ``plant`` (an object with ``period``, ``reset()``, ``step()``; or an MJCF path or
    ``"module:factory"``) for ``duration`` seconds by iLQR over the scene's horizon, refitting
    the scene's physical unknowns every ``refit_every`` periods (and after each of the first
    ``early_refits`` transitions, from all so far); an ``MpcResult`` (files in
    ``outdir``: trajectory.csv, estimates.csv, mpc.json, judged from ``settle`` s on)."""
    controller = _mpc.Controller(model)
    if isinstance(plant, (str, Path)):
        plant = load_plant(plant, period=controller.transition.period, initial=initial or {},
                           seed=seed)
    result = _mpc.run(model, plant, duration, refit_every=refit_every, controller=controller,
                      on_step=on_step, early=tuple(range(1, early_refits + 1)))
    if outdir is not None:
        mpc_files.write(result, outdir, settle=settle, force=force, settings=settings)
    return result


def _fitted_values(model: Model, idata=None) -> dict:
    """The values a fitted model is judged at: the most likely draw of ``idata``, or of a
    quick MAP fit made here when there is none."""
    if idata is None:
        idata = fit_with_fallback(model, "map", chains=2, warmup=200, samples=200, seed=0,
                                  progress=False)
    return point_estimate(model, idata)


def design_experiment(model_a: Model, model_b: Model | None = None, vary: Sequence[str] = (), *,
                      idata_a=None, idata_b=None, rng: tuple[float, float] | None = None,
                      objective: str = "max_sigma", labels=("A", "B"), energy: float | None = None,
                      restarts: int = 4, random: int = 8, steps: int = 60, seed: int = 0,
                      outdir: str | Path | None = None, force: bool = False
                      ) -> list[Proposal] | InfoDesign:
    """Two models: for each field of ``vary`` (an unknown of both, e.g. ``ball.velocity``), the
    setting whose predictions of the two fitted models differ most in noise units (models
    without a posterior are fitted here by MAP); a list of Proposals.

    One model (``model_b`` None): the excitation of the ``vary`` fields (control sequences
    within their bounds and the energy budget ``energy`` (∫u² dt; default: a typical random
    push's), initial states within ``rng``) that maximises the expected information about the
    other unknowns (D-optimal, Laplace/Fisher through the rollout), ``idata_a`` their posterior
    (else the prior); an InfoDesign, compared with ``random`` random excitations of the same
    energy; files (design.json/.txt, control CSVs, experiment.phys) in ``outdir`` if given."""
    if model_b is None:
        items = tuple(_varied(model_a, f, rng) for f in vary)  # usage errors first
        if not items:
            raise UsageError("nothing to vary", hint="give --vary CONTROL_OR_INITIAL_FIELD")
        if outdir is not None:
            io.prepare_outdir(outdir, force=force)
        found = _information_search(model_a, _belief(model_a, tuple(v.field for v in items), idata_a,
                                                     seed), items, budget=energy,
                                    restarts=restarts, random=random, steps=steps, seed=seed)
        if outdir is not None:
            _write_information(model_a, found, Path(outdir))
        return found
    for field in vary:  # usage errors before any fit
        require_unknown((model_a, model_b), field)
    if objective not in OBJECTIVES:
        raise UsageError(f"unknown objective '{objective}'", hint=" or ".join(OBJECTIVES))
    va, vb = _fitted_values(model_a, idata_a), _fitted_values(model_b, idata_b)
    return [design(model_a, va, model_b, vb, field, rng, objective, labels) for field in vary]


def render(model: Model, values: dict | None = None, *, camera: str | None = None,
           fps: float | None = None) -> render_files.Frames:
    """Frames of the scene seen by ``camera`` (default: its first): the unknowns at ``values``
    (missing ones at their prior medians), at the camera's observed frame times or every 1/fps."""
    return render_files.render_scene(model, values or {}, camera, fps)


def render_draws(model: Model, idata, *, camera: str | None = None, draws: int = 8,
                 time: float | None = None) -> tuple[list[np.ndarray], float]:
    """(images, t): the observed frame at ``t`` (if the camera observes one) then ``draws``
    posterior draws rendered at ``t`` (default: the last observed frame, else 0)."""
    return render_files.posterior_images(model, idata.posterior, camera, draws, time)


def track(source: str | Path, colors: Sequence, *, tolerance: float = 0.08,
          camera: str | Path | None = None, depth_plane: str | None = None,
          radius: float | None = None, rate: float | None = None) -> Tracked:
    """Colour-blob tracks of frames or a video: image positions (t, body, u, v) or, with a
    ``camera.json`` and a depth plane or the object's radius, world positions."""
    return track_source(source, colors, tolerance=tolerance, camera=camera,
                        depth_plane=depth_plane, radius=radius, rate=rate)


def export(scene: Model | Scene | str | Path, idata, **options) -> str:
    """A proto-program: the scene's text with the posterior ``idata`` as its priors (options:
    free, drop, widen, observe, out_path, run; see ``physdsl.export.export``)."""
    return _export(_scene_path(scene), idata, **options)


def export_mjcf(scene: Model | Scene | str | Path, idata) -> tuple[str, list[str]]:
    """(MJCF text, what MJCF cannot hold) of the scene at the posterior medians (needs mujoco)."""
    return _export_mjcf(_scene_path(scene), idata)


def sample(program: str | Path, n: int, seed: int = 0, outdir: str | Path = "samples", *,
           force: bool = False, simulate: bool = True) -> SampleResult:
    """Draw ``n`` concrete scenes (and their simulated trajectories) from a program."""
    return _sample(program, n, seed, outdir, force=force, simulate=simulate)


def read_run(run_dir: str | Path):
    """(posterior, run.json contents) of a run folder written by ``infer(..., outdir=...)``."""
    return load_run(run_dir)


def import_model(path: str | Path, *, controls: str | None = None, key: str | None = None):
    """``(text, notes, files)``: an MJCF/URDF model as .phys text (needs mujoco)."""
    return mjcf.import_model(path, controls=controls, key=key)
