"""Run a backend on a compiled Model: initialise, warm up, sample in blocks with checkpoints.

Every random number comes from ``seed`` through fixed splits (draw j of a chain from
``fold_in(its key, j)``, however the draws were cut into calls), so a run interrupted anywhere
and resumed from its checkpoint yields exactly the draws of an uninterrupted run. SIGINT and
SIGTERM stop a run within about a second of compiled work (``interrupt``, ``blocks.Pacer``);
the checkpoint is written after every call while sampling. Output: arviz InferenceData with
posterior, sample_stats, posterior_predictive, observed_data and log_likelihood groups.
"""
from __future__ import annotations

import hashlib
import json
import pickle
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import jax
import numpy as np

from .. import io
from ..compile import structure_key
from ..errors import InferenceError, UsageError
from .backends.map import LaplaceError
from .base import Settings, get_backend
from .blocks import Pacer
from .init import with_init
from .interrupt import Interrupted, critical, termination
from .left_out import ContactReached
from .fit_ahead import compile_ahead
from .multistart import describe, search, start_points
from .output import build_inference_data, save_run
from .problem import make_problem, model_problem
from .progress import Stages

CHECKPOINT = "checkpoint.pkl"
SAMPLE_CALL_S = 1.0  # seconds of sampling per call, and so between checkpoints
CENTRE_KEY = 1 << 20  # fold_in(k_init, .) of the prior's centre (prior draws use 0, 1, ...)


def infer(model, backend: str = "nuts", settings: Settings | None = None, outdir=None,
          resume: bool = False, force: bool = False, progress: bool = True, positions=None,
          init: dict | str | None = None, quality=None, **overrides):
    """Posterior over every unknown of ``model`` as arviz InferenceData (saved if ``outdir``;
    ``quality``: a function (model, idata) -> dict judging the fit against the data, e.g.
    ``diagnose.quality.fit_quality``, whose result run.json keeps as ``fit_quality``).

    ``positions`` (chains, dim): flat unconstrained starts that replace the initialisation
    (prior draws and their optimisation), e.g. modes found once and shared by two backends.
    ``init``: start values by name (numbers in SI, or value text with units: ``{"ball.velocity":
    "(3, 0, 2.5) m/s"}``, or the CLI's ``"name=value, ..."`` text), the first start (see
    ``init.with_init``). SIGINT/SIGTERM raise ``interrupt.Interrupted`` within seconds,
    leaving a checkpoint that ``resume=True`` continues exactly."""
    settings = replace(settings or Settings(), **overrides)
    if settings.samples is None:
        settings = replace(settings, samples=get_backend(backend).default_samples)
    if init:
        if positions is not None:
            raise UsageError("start values (init) and start positions (positions) both given",
                             hint="positions replace the whole initialisation: give one of them")
        settings = with_init(model, settings, init)
    with termination():
        try:
            try:
                return _run(model, backend, settings, outdir, resume, force, progress,
                            positions, quality)
            except ContactReached as reached:
                if progress:
                    print(reached, file=sys.stderr, flush=True)
                return _run(model.with_every_contact(), backend, settings, outdir, False, force,
                            progress, positions, quality)
        except Interrupted as ex:
            if outdir is not None and (Path(outdir) / CHECKPOINT).exists():
                ex.note = (f"the checkpoint in {outdir} keeps the draws so far: continue with "
                           "--resume (resume=True) and the same options")
            raise


def _run(model, backend, settings, outdir, resume, force, progress, positions, quality):
    algo = get_backend(backend)
    out = io.prepare_outdir(outdir, force=force, resume=resume) if outdir else None
    stages = Stages(enabled=progress)
    ckpt_path = out / CHECKPOINT if out else None
    fingerprint = run_fingerprint(model, backend, settings, positions)
    basins: list[dict] = []  # the multistart's basins (``multistart.search``)
    ckpt = _load_checkpoint(ckpt_path, fingerprint) if (resume and ckpt_path) else None

    key = jax.random.PRNGKey(settings.seed)
    _, k_warm, k_sample = jax.random.split(key, 3)  # the first key initialises (``starts``)
    with stages.stage("compile") as st:
        compile_ahead(model_problem(model), starts=positions is None,
                      robust=settings.intervals == "robust")
        if positions is not None:
            problem, positions = model_problem(model), jax.numpy.asarray(positions)
            if positions.shape != (settings.chains, problem.dim):
                raise UsageError(f"start positions of shape {positions.shape} for "
                                 f"{settings.chains} chains of {problem.dim} dimensions")
        else:  # multistart (MAP's own optimisation then starts at the modes found)
            steps = 0 if ckpt is not None else (
                max(settings.warmup, 50) if algo.name == "map" else settings.init_steps)
            problem, positions = starts(model, settings, steps, basins, on_start=lambda i, label:
                                        st.say(f"optimising from start {i + 1} ({label})"))
        st.done(f"{problem.dim} unconstrained dimensions, {settings.chains} chains")
    if basins and progress:
        print("\n".join(describe(basins)), file=sys.stderr, flush=True)

    if ckpt is None:
        try:
            states, params, warm_info = _warmup(algo, problem, positions, k_warm, settings,
                                                stages)
        except LaplaceError as err:
            if out is not None and err.mode is not None:
                _keep_mode(out, model, problem, err, backend, settings, stages, quality)
            raise
        with critical():
            ckpt = {"fingerprint": fingerprint, "states": _np(states), "params": _np(params),
                    "warm_info": _np(warm_info), "draws": [], "stats": []}
            _save_checkpoint(ckpt_path, ckpt)
    states, params = ckpt["states"], ckpt["params"]
    done = sum(d.shape[1] for d in ckpt["draws"])
    pacer = Pacer(SAMPLE_CALL_S)
    with stages.stage("sampling", total=settings.samples, completed=done) as st:
        while done < settings.samples:
            n = pacer.next(settings.samples - done, settings.block) if getattr(
                algo, "paced", True) else min(settings.block, settings.samples - done)
            t0 = time.perf_counter()
            new_states, draws, stats = algo.sample(problem, states, params, k_sample, n,
                                                   settings, start=done)
            new_states, draws, stats = _np(new_states), np.asarray(draws), _np(stats)
            pacer.record(n, time.perf_counter() - t0)
            with critical():  # draws, states and the file change together
                states = ckpt["states"] = new_states
                ckpt["draws"].append(draws)
                ckpt["stats"].append(stats)
                _save_checkpoint(ckpt_path, ckpt)
                done += n
            st.advance(n)

    flat = np.concatenate(ckpt["draws"], axis=1)  # (chains, samples, dim)
    stats = {k: np.concatenate([s[k] for s in ckpt["stats"]], axis=1) for k in ckpt["stats"][0]}
    try:
        idata = build_inference_data(model, problem, flat, stats, settings, stages=stages,
                                     gaussian=algo.gaussian(states, params))
    except ContactReached:
        if ckpt_path is not None and ckpt_path.exists():
            ckpt_path.unlink()  # (the fit runs again with every contact)
        raise
    if basins:
        idata.attrs["basins"] = json.dumps(basins)
    if not np.all(np.isfinite(flat)):
        raise InferenceError("sampler produced non-finite draws",
                             hint="try --backend rmh or tighter priors")
    if out is not None:
        extra = {**_fit_quality(quality, model, idata, stages), **({"basins": basins} if basins else {})}
        save_run(out, model, idata, backend, settings, extra=extra)
        if ckpt_path.exists():
            ckpt_path.unlink()
    return idata


def _warmup(algo, problem, positions, key, settings, stages):
    """The backend's warmup under progress stages: for MAP each start's optimisation, then
    the Laplace step; for samplers the warmup's transitions."""
    if algo.name != "map":
        with stages.stage("warmup", total=settings.warmup) as st:
            out = algo.warmup(problem, positions, key, settings, on_block=st.advance)
            jax.block_until_ready(out[0])
        return out
    opt = stages.start("optimise", total=len(positions))
    laplace = []

    def on_laplace():
        opt.finish()
        laplace.append(stages.start("laplace"))

    try:
        out = algo.warmup(problem, positions, key, settings, on_block=opt.advance,
                          on_laplace=on_laplace)
    except BaseException:
        for st in [opt, *laplace]:
            st.stop()
        raise
    for st in [opt, *laplace]:
        st.finish()
    return out


def _fit_quality(quality, model, idata, stages) -> dict:
    """``{"fit_quality": quality(model, idata)}`` under a progress stage, kept in
    ``idata.attrs`` too; {} without ``quality``."""
    if quality is None:
        return {}
    with stages.stage("fit quality"):
        try:
            q = quality(model, idata)
        except Exception as ex:  # noqa: BLE001 - a diagnostic must not lose a finished fit
            q = {"error": f"{type(ex).__name__}: {ex}", "warnings": []}
    idata.attrs["fit_quality"] = json.dumps(q)
    return {"fit_quality": q}


def _keep_mode(out, model, problem, err, backend, settings, stages, quality):
    """Where MAP's Laplace step failed: write the mode (posterior.nc with the mode as a single
    draw, summary.csv, run.json marking ``laplace: failed`` with the flat directions) and say
    so in ``err`` (``err.idata``: the mode's InferenceData)."""
    flat = np.asarray(err.mode, dtype=float)[None, None, :]
    idata = build_inference_data(model, problem, flat, {}, settings, stages=stages)
    idata.attrs["laplace"] = "failed"
    judged = _fit_quality(quality, model, idata, stages)
    directions = [{"curvature": c, "components": [{"name": n, "weight": w} for n, w in comps]}
                  for c, comps in err.directions]
    save_run(out, model, idata, backend, settings,
             extra={"laplace": "failed", "laplace_error": err.message,
                    "laplace_directions": directions, "log_density_at_mode": err.log_density,
                    **judged})
    err.idata = idata
    err.message += (f". The mode is kept in {out} (posterior.nc holds it as a single draw, "
                    "summary.csv, run.json with laplace: failed)")


def starts(model, settings: Settings, optimise_steps: int, basins: list | None = None,
           on_start=None):
    """(Problem, flat unconstrained starts (chains, dim)): ``settings.start`` where given, a
    start from the data's first samples, the prior's centre and prior draws
    (``multistart.start_points``); each optimised for ``optimise_steps`` when positive, the
    modes grouped into basins (appended to ``basins`` where given) and chains that end in a
    minor basin moved to the best mode (``multistart.search``). Random numbers as in ``infer``."""
    k_init = jax.random.split(jax.random.PRNGKey(settings.seed), 3)[0]
    problem, positions = make_problem(model, k_init, settings.chains, dict(settings.start))
    positions, labels = start_points(problem, positions, jax.random.fold_in(k_init, CENTRE_KEY),
                                     given=bool(settings.start))
    if optimise_steps > 0:
        found = search(problem, positions, labels, optimise_steps, on_start,  # (progress)
                       key=jax.random.fold_in(k_init, CENTRE_KEY + 1))
        positions = found.modes
        if basins is not None:
            basins.extend(found.basins)
    return problem, jax.numpy.asarray(positions)


def run_fingerprint(model, backend: str, settings: Settings, positions=None) -> str:
    """Hash of everything that determines the draws (the scene's structure and text, data,
    backend, settings, given start positions). The structure counts too: a scene edited as a
    value (a diagnosis candidate) has no text."""
    h = hashlib.sha256()
    if positions is not None:
        h.update(np.ascontiguousarray(np.asarray(positions, dtype=float)).tobytes())
    h.update(model.scene.source.encode())
    h.update(structure_key(model.scene).encode())
    h.update(repr(model.ruled_out).encode())  # the pairs its likelihood leaves out
    for o in model.scene.observations:
        h.update(np.ascontiguousarray(o.values).tobytes())
    h.update(b"draw j from fold_in(key, j)")  # checkpoints of the per-block keys differ
    h.update(backend.encode())
    h.update(repr(sorted(asdict(settings).items())).encode())
    return h.hexdigest()


def _np(tree):
    return jax.tree_util.tree_map(np.asarray, tree)


def _save_checkpoint(path, ckpt):
    if path is None:
        return
    with io.atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            pickle.dump(ckpt, f)


def _load_checkpoint(path: Path, fingerprint: str):
    if not path.exists():
        raise UsageError(f"nothing to resume in '{path.parent}' (no {CHECKPOINT})",
                         hint="run without --resume to start afresh")
    with open(path, "rb") as f:
        ckpt = pickle.load(f)
    if ckpt.get("fingerprint") != fingerprint:
        raise UsageError(f"the checkpoint in '{path.parent}' belongs to another scene, data or "
                         "settings", hint="resume with the same options, or use --force")
    return ckpt


__all__ = ["infer", "run_fingerprint"]
