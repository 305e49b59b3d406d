"""Turn draws into arviz InferenceData, a summary table, warnings in words, and a run folder."""
from __future__ import annotations

import csv
import hashlib
import io as _io
import json
import platform
import time
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path

import blackjax
import jax
import jax.numpy as jnp
import numpy as np
import numpyro

from .. import io, xla_flags
from ..ahead import Program
from ..compile import OBS_PREFIX, PRED_PREFIX
from ..errors import UsageError
from ..pooled import component_labels, experiment_dims
from ..version import __version__
from .base import cached
from .block_check import BLOCKS
from .blocks import Pacer
from .intervals import add_robust, shown_posterior
from . import left_out, posterior_data
from .left_out import CLEARANCE_SITE
from .local_pass import local_pass
from .problem import drawn
from .threads import thread_map


PLAIN = "plain"  # Settings.intervals of a fit that shows the model's intervals and makes no
# robust ones (their residual models cost seconds per fit, the block check its refits)
PASS_CHUNK = 64  # draws per call of the vmapped posterior pass (one compile for any number
# of draws, memory bounded: a rollout's states per draw), and per progress step of the pass


def build_inference_data(model, problem, flat: np.ndarray, stats: dict, settings,
                         on_chunk=None, stages=None, gaussian=None):
    """InferenceData with posterior (unknowns), predictive, observed data and pointwise log-lik.

    One rollout per draw (``posterior_pass``), the log-likelihood read off its predictions;
    ``on_chunk(m)`` after each ``m`` draws (a progress bar). ``gaussian``: (means, square
    roots) per chain where the draws are Gaussian (a Laplace fit's): their predictions from
    an expansion about each mode where it holds (``local_pass``). Then the robust intervals
    (``intervals.add_robust``). ``stages`` (``progress.Stages``): each part under a stage of
    its own, "predictions" (a bar over the draws) and "intervals" (a bar over the block
    check's refits), instead of ``on_chunk``.
    """
    chains, samples, _ = flat.shape
    reached: list = []
    with _stage(stages, "predictions", chains * samples) as st:
        advance = st.advance if st is not None else on_chunk
        local = None if gaussian is None else local_pass(model, problem, flat, *gaussian)
        if local is not None:
            constrained, loglik = local
            if advance is not None:
                advance(chains * samples)
        else:
            constrained, loglik = posterior_pass(model, problem, flat.reshape(chains * samples, -1),
                                                 advance, reached)
    left_out.check(model, reached)
    unknowns = set(model.unknown_names)
    shaped = lambda v: np.asarray(v).reshape(chains, samples, *v.shape[1:])  # noqa: E731
    posterior = {k: shaped(v) for k, v in constrained.items() if k in unknowns}
    preds = {k: shaped(v) for k, v in constrained.items() if k.startswith(PRED_PREFIX)}
    loglik = {OBS_PREFIX + k: shaped(v) for k, v in loglik.items()}
    observed = {OBS_PREFIX + o.obs.name: np.where(o.obs.mask, o.obs.values, np.nan)
                for o in model.observed}
    sample_stats = {k: np.asarray(v) for k, v in stats.items()}
    dims, coords = _dims(model, posterior)
    idata = posterior_data.from_dict(
        {"posterior": posterior, "posterior_predictive": preds, "observed_data": observed,
         "log_likelihood": loglik, "sample_stats": sample_stats}, dims=dims, coords=coords)
    shown = getattr(settings, "intervals", "robust")
    if shown == PLAIN:  # a fit only compared with others (``fit.quick_fit``): no sandwich
        idata.attrs["intervals"] = "model"
        return idata
    # a bar over the block check's refits where it runs (robust intervals of draws, not of
    # a kept mode alone; least squares)
    check = shown == "robust" and problem.gauss_newton is not None and chains * samples > 1
    total = BLOCKS if check else None
    with _stage(stages, "intervals", total) as st:
        return add_robust(idata, model, problem, flat, constrained, shown,  # + posterior_robust
                          on_block=None if st is None else st.advance)


@contextmanager
def _stage(stages, name: str, total):
    """``stages.stage(name, total)``, or None without ``stages``."""
    if stages is None:
        yield None
        return
    with stages.stage(name, total=total) as st:
        yield st


def posterior_pass(model, problem, flat: np.ndarray, on_chunk=None, reached=None
                   ) -> tuple[dict, dict]:
    """(constrained sites: the unknowns and the ``pred:`` predictions; pointwise
    log-likelihood by observable) of each row of ``flat`` (draws, dim); ``on_chunk(m)`` after
    each call of ``m`` draws (a progress bar); ``reached`` (a list): each part's per-draw flags
    of a likelihood that left out contact pairs (``left_out``) are appended to it.

    Where the Problem has ``draw`` (least squares), draws go one by one through it, from
    ``threads.workers()`` threads at once: the fit's own value function
    (``problem.draw_function``), whose rollout is the likelihood's one compiled rollout
    (``model.fit_simulate``, which the fit's quality calls too), so the pass traces and
    compiles nothing new and costs one rollout a draw, in calls of about ``PASS_CALL_S``
    (``blocks.Pacer``). Where the draws left would take over ``vmap_after`` CPU seconds
    that way (many long rollouts: a vmapped rollout costs 2-3x less a draw), they go
    ``PASS_CHUNK`` a call through a vmapped program instead, which pays one compile of its
    own (the last call padded). Problems with no ``draw`` always take that one."""
    n = flat.shape[0]
    parts, done = [], 0
    pacer = Pacer(PASS_CALL_S)
    while problem.draw is not None and done < n:
        if pacer.per is not None and pacer.per * (n - done) > vmap_after(model):
            break
        m = pacer.next(n - done, PASS_CHUNK)
        t0 = time.process_time()  # (CPU: a shared machine's load does not decide)
        outs = drawn(problem, flat[done:done + m])
        pacer.record(m, time.process_time() - t0)
        sites, loglik = jax.tree_util.tree_map(lambda *a: np.stack(a), *outs)
        if reached is not None and CLEARANCE_SITE in sites:
            reached.append(np.asarray(sites[CLEARANCE_SITE]) <= 0.0)
        parts.append(_sites(model, (sites, loglik)))
        done += m
        if on_chunk is not None:
            on_chunk(m)
    if done < n:
        parts.append(_vmapped_pass(model, problem, flat[done:], on_chunk))
        if reached is not None and model.ruled_out:
            reached.append(model.contact_reached({k: parts[-1][0][k] for k in model.unknown_names}))
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *parts)


PASS_CALL_S = 1.0  # CPU seconds per call of the one-by-one pass (a progress step)
VMAP_AFTER_S = 80.0  # CPU seconds of one-by-one draws left beyond which the rest are
# vmapped: a vmapped draw costs 1/2-1/3 of one by one (chain_hit 14 vs 30 ms, the double
# pendulum 45 vs 155 ms, the pendulum 30 vs 62 ms), so its compile (39 s on chain_hit)
# pays off beyond about twice that
VMAP_AFTER_FREE_S = 10.0  # the same where the likelihood simulates no contact: the
# pendulum's vmapped program compiles and runs its first 64 draws in 5.6 s (10 000 steps)


def vmap_after(model) -> float:
    """CPU seconds of one-by-one draws left beyond which the posterior pass vmaps the rest.
    Never for a contact-free scene whose rollout loop runs as one kernel (``xla_flags``): there
    a draw costs no more one by one than vmapped, and the vmapped program's compile is saved
    (the pendulum's refine: 42 s of its compile)."""
    if model.likelihood_simulator.model.ncon:
        return VMAP_AFTER_S
    return np.inf if xla_flags.in_effect() else VMAP_AFTER_FREE_S


def _vmapped_pass(model, problem, flat: np.ndarray, on_chunk=None) -> tuple[dict, dict]:
    """``posterior_pass`` by a vmapped program, ``PASS_CHUNK`` draws a call (the last padded),
    the calls after the first (which compiles) from threads."""
    def one(x, data):
        c = problem.to_constrained(x, data)
        values = {k: c[k] for k in model.unknown_names}
        preds = {o.obs.name: c[PRED_PREFIX + o.obs.name] for o in model.observed}
        return c, model.pointwise_log_likelihood(values, preds, data)

    fn = cached(problem, ("posterior-pass", PASS_CHUNK),
                lambda: Program(jax.vmap(one, in_axes=(0, None))))
    def call(i):
        x = flat[i:i + PASS_CHUNK]
        m = x.shape[0]
        if m < PASS_CHUNK:
            x = np.concatenate([x, np.repeat(x[-1:], PASS_CHUNK - m, axis=0)])
        out = fn(jnp.asarray(x), problem.data)
        out = _sites(model, jax.tree_util.tree_map(lambda a: np.asarray(a)[:m], out))
        if on_chunk is not None:
            on_chunk(m)
        return out

    starts = list(range(0, flat.shape[0], PASS_CHUNK))
    # the first call compiles; the rest side by side (``threads``)
    parts = [call(starts[0])] + thread_map(call, starts[1:])
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *parts)


def _sites(model, out):
    """(sites, log-likelihood) with the sites cut to the unknowns and the predictions."""
    sites, loglik = out
    keep = set(model.unknown_names) | {PRED_PREFIX + o.obs.name for o in model.observed}
    return {k: v for k, v in sites.items() if k in keep}, loglik


def _dims(model, posterior):
    dims, coords = experiment_dims(model)  # the ``experiment`` axis of per-recording unknowns
    for o in model.observed:
        tdim = f"{o.obs.name}:time"
        coords[tdim] = o.obs.times
        adim = f"{o.obs.name}:axis"
        coords[adim] = list(o.obs.columns) if len(o.obs.columns) == o.obs.values.shape[1] else \
            [f"c{i}" for i in range(o.obs.values.shape[1])]
        dims[OBS_PREFIX + o.obs.name] = [tdim, adim]
        dims[PRED_PREFIX + o.obs.name] = [tdim, adim]
    return dims, coords


def pointwise_log_likelihood(model, values: dict) -> dict[str, np.ndarray]:
    """Log-likelihood per draw and measurement time: name -> (draws, N).

    Compiled once per scene structure (the data are an argument), e.g. for the
    leave-future-out scores of several cut-off fits.
    """
    def build():
        def one(vals, data):
            return model.pointwise_log_likelihood(vals, model.predict(vals, data=data), data)
        return Program(jax.vmap(one, in_axes=(0, None)))

    fn = model.cached("pointwise-log-likelihood", build)
    return {k: np.asarray(v) for k, v in fn(values, model.data).items()}


def summary_rows(model, idata) -> list[dict]:
    """Per scalar component of every unknown: mean, sd, 5%, 95%, ESS bulk/tail, r-hat, unit."""
    rows = []
    post, shown = shown_posterior(idata)  # robust (default) or model: ``intervals.py``
    for u in model.unknowns:
        arr = np.asarray(post[u.name].values)  # (chain, draw, *shape)
        flat = arr.reshape(arr.shape[0], arr.shape[1], -1)
        labels = component_labels(model, u)  # (a recording's by its name: pooled.py)
        for i in range(flat.shape[2]):
            x = flat[:, :, i]
            label = labels[i]
            rows.append({
                "name": label, "unit": u.unit, "mean": float(np.mean(x)), "sd": float(np.std(x)),
                "q5": float(np.quantile(x, 0.05)), "q95": float(np.quantile(x, 0.95)),
                "ess_bulk": _safe(lambda: posterior_data.ess(x, method="bulk")),
                "ess_tail": _safe(lambda: posterior_data.ess(x, method="tail")),
                "r_hat": _safe(lambda: posterior_data.rhat(x)) if x.shape[0] > 1 else float("nan"),
                "intervals": shown,
            })
    return rows


def _safe(fn) -> float:
    try:
        return float(fn())
    except Exception:  # noqa: BLE001 - a diagnostic that cannot be computed is reported as NaN
        return float("nan")


def warnings_in_words(rows: list[dict], idata, backend: str) -> list[str]:
    """Problems a user should act on, each with what to try."""
    out = []
    bad_rhat = [r for r in rows if np.isfinite(r["r_hat"]) and r["r_hat"] > 1.01]
    if bad_rhat and backend != "map":
        worst = max(bad_rhat, key=lambda r: r["r_hat"])
        out.append(f"r-hat of {worst['name']} is {worst['r_hat']:.3f} > 1.01: the chains disagree. "
                   "Try more --warmup and --samples, or check for several modes (tighter priors).")
    low = [r for r in rows if np.isfinite(r["ess_bulk"]) and r["ess_bulk"] < 100]
    if low and backend != "map":
        worst = min(low, key=lambda r: r["ess_bulk"])
        out.append(f"bulk ESS of {worst['name']} is only {worst['ess_bulk']:.0f}: estimates are noisy. "
                   "Run more --samples or more --chains.")
    ss = posterior_data.group(idata, "sample_stats") or {}
    if "diverging" in ss:
        n = int(np.asarray(ss["diverging"].values).sum())
        if n:
            out.append(f"{n} divergent transitions: the sampler met regions it cannot integrate. "
                       "Raise the target acceptance (e.g. 0.95) or give weakly identified unknowns "
                       "tighter priors.")
    return out


def format_table(rows: list[dict]) -> str:
    """The summary as aligned text (what the CLI prints)."""
    head = f"{'unknown':<40} {'mean':>12} {'sd':>10} {'5%':>12} {'95%':>12} {'ess_bulk':>8} {'ess_tail':>8} {'r_hat':>6}  unit"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['name']:<40} {r['mean']:>12.5g} {r['sd']:>10.3g} {r['q5']:>12.5g} "
                     f"{r['q95']:>12.5g} {r['ess_bulk']:>8.0f} {r['ess_tail']:>8.0f} "
                     f"{r['r_hat']:>6.3f}  {r['unit']}")
    return "\n".join(lines)


def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def save_run(out: Path, model, idata, backend: str, settings, extra: dict | None = None
             ) -> dict[str, Path]:
    """Write posterior.nc, summary.csv and run.json into ``out`` atomically (``extra``: more
    entries of run.json, e.g. ``fit_quality``)."""
    paths = {}
    paths["posterior"] = posterior_data.write(idata, out / "posterior.nc")
    rows = summary_rows(model, idata)
    buf = _io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]) if rows else ["name"])
    writer.writeheader()
    writer.writerows(rows)
    paths["summary"] = io.write_text(out / "summary.csv", buf.getvalue())
    scene = model.scene
    data = {}
    for o in scene.observations:
        if Path(o.file).exists():
            data[str(o.file)] = file_sha256(o.file)
    run = {
        "scene": str(scene.path) if scene.path else None,
        "scene_sha256": hashlib.sha256(scene.source.encode()).hexdigest(),
        "data_sha256": data,
        "backend": backend,
        "settings": asdict(settings),
        "seed": settings.seed,
        "versions": {"physdsl": __version__, "jax": jax.__version__, "numpyro": numpyro.__version__,
                     "blackjax": blackjax.__version__, "arviz": posterior_data.VERSION,
                     "python": platform.python_version()},
        "warnings": warnings_in_words(rows, idata, backend),
        **(extra or {}),
    }
    run["warnings"] += (run.get("fit_quality") or {}).get("warnings", [])
    paths["run"] = io.write_json(out / "run.json", run)
    return paths


def load_run(run_dir) -> tuple[object, dict]:
    """Read a run folder written by ``save_run``: (the posterior, an arviz InferenceData or
    DataTree by version: ``posterior_data``; run.json contents)."""
    run_dir = Path(run_dir)
    post = run_dir / "posterior.nc"
    if not post.exists():
        raise UsageError(f"'{run_dir}' holds no posterior.nc",
                         hint="give the -o folder of a finished `physdsl infer` run")
    idata = posterior_data.read(post)
    meta = json.loads((run_dir / "run.json").read_text()) if (run_dir / "run.json").exists() else {}
    return idata, meta
