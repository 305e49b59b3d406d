"""Run a backend on a compiled Model: initialise, warm up, sample in blocks with checkpoints.

Every random number comes from ``seed`` through fixed splits (block b uses
``fold_in(key, b)``), so a run interrupted between blocks and resumed from its checkpoint
yields exactly the draws of an uninterrupted run. Output: arviz InferenceData with
posterior, sample_stats, posterior_predictive, observed_data and log_likelihood groups.
"""
from __future__ import annotations

import hashlib
import pickle
import signal
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path

import jax
import numpy as np

from .. import io
from ..errors import InferenceError, UsageError
from .base import Settings, get_backend
from .backends.map import find_modes, major_modes
from .problem import make_problem, model_problem
from .progress import Stages

CHECKPOINT = "checkpoint.pkl"


def infer(model, backend: str = "nuts", settings: Settings | None = None, outdir=None,
          resume: bool = False, force: bool = False, progress: bool = True, positions=None,
          **overrides):
    """Posterior over every unknown of ``model`` as arviz InferenceData (saved if ``outdir``).

    ``positions`` (chains, dim): flat unconstrained starts that replace the initialisation
    (prior draws and their optimisation), e.g. modes found once and shared by two backends."""
    settings = replace(settings or Settings(), **overrides)
    algo = get_backend(backend)
    out = io.prepare_outdir(outdir, force=force, resume=resume) if outdir else None
    stages = Stages(enabled=progress)
    ckpt_path = out / CHECKPOINT if out else None
    fingerprint = run_fingerprint(model, backend, settings, positions)
    ckpt = _load_checkpoint(ckpt_path, fingerprint) if (resume and ckpt_path) else None

    key = jax.random.PRNGKey(settings.seed)
    _, k_warm, k_sample = jax.random.split(key, 3)  # the first key initialises (``starts``)
    with stages.stage("compile") as st:
        if positions is not None:
            problem, positions = model_problem(model), jax.numpy.asarray(positions)
            if positions.shape != (settings.chains, problem.dim):
                raise UsageError(f"start positions of shape {positions.shape} for "
                                 f"{settings.chains} chains of {problem.dim} dimensions")
        else:
            steps = settings.init_steps if (ckpt is None and algo.name != "map") else 0
            problem, positions = starts(model, settings, steps)
        st.done(f"{problem.dim} unconstrained dimensions, {settings.chains} chains")

    with _graceful_termination():
        if ckpt is None:
            with stages.stage("warmup", total=settings.warmup) as st:
                states, params, warm_info = algo.warmup(problem, positions, k_warm, settings,
                                                        on_block=st.advance)
                jax.block_until_ready(states)
                if st.count < settings.warmup:  # a backend without blocks (map)
                    st.advance(settings.warmup - st.count)
            ckpt = {"fingerprint": fingerprint, "states": _np(states), "params": _np(params),
                    "warm_info": _np(warm_info), "draws": [], "stats": []}
            _save_checkpoint(ckpt_path, ckpt)
        states, params = ckpt["states"], ckpt["params"]
        done = sum(d.shape[1] for d in ckpt["draws"])
        with stages.stage("sampling", total=settings.samples, completed=done) as st:
            block = 0 if not done else len(ckpt["draws"])
            while done < settings.samples:
                n = min(settings.block, settings.samples - done)
                states, draws, stats = algo.sample(problem, states, params,
                                                   jax.random.fold_in(k_sample, block), n, settings)
                ckpt["states"] = _np(states)
                ckpt["draws"].append(np.asarray(draws))
                ckpt["stats"].append(_np(stats))
                _save_checkpoint(ckpt_path, ckpt)
                done += n
                block += 1
                st.advance(n)

    flat = np.concatenate(ckpt["draws"], axis=1)  # (chains, samples, dim)
    stats = {k: np.concatenate([s[k] for s in ckpt["stats"]], axis=1) for k in ckpt["stats"][0]}
    from .output import build_inference_data

    idata = build_inference_data(model, problem, flat, stats, settings)
    if not np.all(np.isfinite(flat)):
        raise InferenceError("sampler produced non-finite draws",
                             hint="try --backend rmh or tighter priors")
    if out is not None:
        from .output import save_run

        save_run(out, model, idata, backend, settings)
        if ckpt_path.exists():
            ckpt_path.unlink()
    return idata


def starts(model, settings: Settings, optimise_steps: int):
    """(Problem, flat unconstrained starts (chains, dim)): prior draws (the first at
    ``settings.start``), each optimised for ``optimise_steps`` when positive, chains that end
    in a minor basin moved to the best mode (``major_modes``). Random numbers as in ``infer``."""
    k_init = jax.random.split(jax.random.PRNGKey(settings.seed), 3)[0]
    problem, positions = make_problem(model, k_init, settings.chains, dict(settings.start))
    if optimise_steps > 0:
        positions = major_modes(problem, find_modes(problem, positions, optimise_steps))[0]
    return problem, positions


def run_fingerprint(model, backend: str, settings: Settings, positions=None) -> str:
    """Hash of everything that determines the draws (scene text, data, backend, settings,
    given start positions)."""
    h = hashlib.sha256()
    if positions is not None:
        h.update(np.ascontiguousarray(np.asarray(positions, dtype=float)).tobytes())
    h.update(model.scene.source.encode())
    for o in model.scene.observations:
        h.update(np.ascontiguousarray(o.values).tobytes())
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


@contextmanager
def _graceful_termination():
    """Turn SIGTERM into KeyboardInterrupt so a kill leaves the last checkpoint intact."""
    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not in the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


__all__ = ["infer", "run_fingerprint"]
