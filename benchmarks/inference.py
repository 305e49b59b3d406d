"""Inference benchmark: physdsl's compiled model against the same model written by hand.

Scene (``benchmarks/inference_ball.phys``): a ball thrown through air with quadratic drag
(F = -c |v| v, c = drag ratio x mass), RK4 at the data's 10 ms sample spacing over 1 s; 101
position measurements simulated at known values with 5 mm noise; unknown launch velocity (3,),
drag ratio and noise scale (5 unconstrained dimensions). The hand-written peers integrate the
same equations (x' = v, v' = g - k |v| v, classic RK4, 10 ms) with the same priors and noise:
once as a plain-JAX log density over the same flat unconstrained vector (log-Jacobians
included), so both log densities agree to rounding (``logdensity_max_abs_diff``), and once as a
numpyro program. All run in this one process on the same data and initial positions, 4 chains,
500 warmup and 1000 draws (the issue's protocol). Prints ``name: value`` lines:

- ``compile_s``: from the ``.phys`` text to the first value and gradient of the log density
  (cold: no compiled function of the scene's structure exists yet); ``compile_s_hand``: the
  hand-written log density to its first value and gradient; each starts from cleared JAX caches
  (``jax.clear_caches``) and no persistent compilation cache; ``compile_ratio``; ``*_cpu_s``:
  CPU seconds (``compile_cpu_ratio``);
- ``grad_ms_physdsl``, ``grad_ms_hand``, ``grad_time_ratio`` (compiled over hand-written):
  one jitted value-and-gradient call, median of repeats;
- ``ess_per_s_physdsl`` (``physdsl.infer(model, backend="nuts")``, second run: compiled stages are
  cached, so this is initialisation + warmup + sampling + posterior pass + InferenceData),
  ``ess_per_s_blackjax_hand`` (blackjax NUTS with window adaptation on the hand-written
  density, one jitted vmapped run, after compile; diagonal mass matrix, blackjax's default),
  ``ess_per_s_blackjax_hand_dense`` (the same with a dense mass matrix, as physdsl uses by
  default), ``ess_per_s_numpyro`` (numpyro ``MCMC`` + ``NUTS`` on the hand-written numpyro
  model, second run; its driver recompiles on every run, which is part of its cost); ESS is
  arviz's bulk ESS, minimum over the parameters; ``rhat_max_*``: the largest r-hat;
  ``leapfrog_per_draw_*``: mean leapfrog steps (gradients) per draw while sampling;
- ``ess_per_s_ratio`` (physdsl over hand-written blackjax), ``ess_per_s_ratio_vs_numpyro``,
  ``ess_per_s_ratio_vs_blackjax_hand_dense``; ``ess_per_cpu_s_ratio*``: the same per CPU
  second (process time), steadier than wall time on a shared machine;
- ``posterior_mean_*``: each parameter's posterior mean per sampler, and
  ``posterior_mean_max_z_vs_*``: the largest |difference of means| over its Monte Carlo
  standard error (arviz's mcse of both, in quadrature): below about 3.5 the means agree within
  Monte Carlo error (``posterior_means_agree``).

Run: .venv/bin/python benchmarks/inference.py   (a few minutes on 2 loaded cores)
"""
from __future__ import annotations

import physdsl

import shutil
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import physdsl  # noqa: E402,F401 - float64
from tests.infer.conftest import simulated_scene  # noqa: E402

SCENE = HERE / "inference_ball.phys"
CHAINS, WARMUP, SAMPLES = 4, 500, 1000
DT, STEPS, G = 0.01, 100, np.array([0.0, 0.0, -9.81])
X0 = np.array([0.0, 0.0, 1.8])
V_PRIOR, V_SCALE, RATIO_SCALE, NOISE_SCALE = np.array([6.0, 0.0, 6.0]), 3.0, 0.05, 0.01
TIMES = np.round(np.arange(STEPS + 1) * DT, 10)  # one measurement per step, 0 to 1 s
TRUTH = {"ball.velocity": np.array([6.2, 0.3, 5.8]), "drag_ratio": np.array(0.02)}
NOISE = 0.005  # m, the truth of the unknown noise scale
# physdsl's flat vector is ravel({name: unconstrained value}) in sorted order
NAMES = ("ball.position.noise", "ball.velocity", "drag_ratio")
LABELS = ("noise", "vx", "vy", "vz", "drag_ratio")


def hand_rollout(v0, k):
    """Classic RK4 of x' = v, v' = g - k |v| v from X0, 10 ms steps: positions (T+1, 3)."""
    def acc(v):
        return G - k * jnp.sqrt(jnp.sum(v * v)) * v

    def step(carry, _):
        x, v = carry
        a1 = acc(v)
        v2 = v + 0.5 * DT * a1
        a2 = acc(v2)
        v3 = v + 0.5 * DT * a2
        a3 = acc(v3)
        v4 = v + DT * a3
        a4 = acc(v4)
        x = x + DT / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v = v + DT / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        return (x, v), x
    _, xs = jax.lax.scan(step, (jnp.asarray(X0), v0), None, length=STEPS)
    return jnp.concatenate([jnp.asarray(X0)[None], xs])


def hand_logdensity(measured):
    """Log density over z = (log noise, v0 (3,), log k): the scene's priors (half-normals with
    their log-Jacobians), the RK4 rollout and Gaussian noise."""
    norm = jax.scipy.stats.norm

    def logdensity(z):
        log_s, v0, log_k = z[0], z[1:4], z[4]
        s, k = jnp.exp(log_s), jnp.exp(log_k)
        lp = norm.logpdf(v0, V_PRIOR, V_SCALE).sum()
        lp += jnp.log(2.0) + norm.logpdf(k, 0.0, RATIO_SCALE) + log_k
        lp += jnp.log(2.0) + norm.logpdf(s, 0.0, NOISE_SCALE) + log_s
        return lp + norm.logpdf(measured, hand_rollout(v0, k), s).sum()
    return logdensity


def median_call_ms(fn, x, repeats=200):
    jax.block_until_ready(fn(x))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(x))
        times.append(time.perf_counter() - t0)
    return 1000 * float(np.median(times))


def min_ess(draws: np.ndarray) -> float:
    """Minimum bulk ESS over the last axis of (chains, draws, dim)."""
    import arviz as az

    return float(min(az.ess(draws[:, :, i], method="bulk") for i in range(draws.shape[2])))


def max_rhat(draws: np.ndarray) -> float:
    import arviz as az

    return float(max(az.rhat(draws[:, :, i]) for i in range(draws.shape[2])))


def mean_and_mcse(draws: np.ndarray):
    """Posterior mean and its Monte Carlo standard error per parameter: two (dim,) arrays."""
    import arviz as az

    return (draws.mean(axis=(0, 1)),
            np.array([float(az.mcse(draws[:, :, i], method="mean")) for i in range(draws.shape[2])]))


def constrained(z: np.ndarray) -> np.ndarray:
    """(..., 5) unconstrained -> (noise, vx, vy, vz, drag ratio)."""
    return np.concatenate([np.exp(z[..., :1]), z[..., 1:4], np.exp(z[..., 4:])], axis=-1)


def blackjax_hand(logdensity, key, x0, dense: bool = False):
    """Window adaptation + NUTS, vmapped over chains, all in one jitted function:
    (draws, wall seconds, CPU seconds) of the second, compiled run."""
    import blackjax

    def chain(k, x):
        k1, k2 = jax.random.split(k)
        adapt = blackjax.window_adaptation(blackjax.nuts, logdensity, is_mass_matrix_diagonal=not dense)
        (state, params), _ = adapt.run(k1, x, WARMUP)
        kernel = blackjax.nuts(logdensity, **params)

        def one(s, kk):
            s, info = kernel.step(kk, s)
            return s, (s.position, info.num_integration_steps)
        return jax.lax.scan(one, state, jax.random.split(k2, SAMPLES))[1]

    run = jax.jit(jax.vmap(chain))
    keys = jax.random.split(key, CHAINS)
    jax.block_until_ready(run(keys, x0))  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    draws, steps = jax.block_until_ready(run(jax.random.split(jax.random.fold_in(key, 1), CHAINS),
                                             x0))
    print(f"leapfrog_per_draw_blackjax_hand{'_dense' if dense else ''}: {float(np.mean(steps)):.2f}")
    return constrained(np.asarray(draws)), time.perf_counter() - t0, time.process_time() - c0


def numpyro_hand(measured, key):
    """numpyro ``MCMC`` + ``NUTS`` on the hand-written model (vectorised chains): (draws, wall and
    CPU seconds of the second run)."""
    import numpyro
    import numpyro.distributions as dist
    from numpyro.infer import MCMC, NUTS

    def model():
        v0 = numpyro.sample("v0", dist.Normal(jnp.asarray(V_PRIOR), V_SCALE).to_event(1))
        k = numpyro.sample("k", dist.HalfNormal(RATIO_SCALE))
        s = numpyro.sample("s", dist.HalfNormal(NOISE_SCALE))
        numpyro.sample("obs", dist.Normal(hand_rollout(v0, k), s).to_event(2), obs=measured)

    mcmc = MCMC(NUTS(model), num_warmup=WARMUP, num_samples=SAMPLES, num_chains=CHAINS,
                chain_method="vectorized", progress_bar=False)
    mcmc.run(key, extra_fields=("num_steps",))  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    mcmc.run(jax.random.fold_in(key, 1), extra_fields=("num_steps",))
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"leapfrog_per_draw_numpyro: {float(np.mean(mcmc.get_extra_fields()['num_steps'])):.2f}")
    s = mcmc.get_samples(group_by_chain=True)
    draws = np.concatenate([np.asarray(s["s"])[..., None], np.asarray(s["v0"]),
                            np.asarray(s["k"])[..., None]], axis=2)
    return draws, seconds, cpu


def main() -> None:
    from physdsl.compile import compile as compile_phys
    from physdsl.infer.base import value_and_grad_fn
    from physdsl.infer.problem import make_problem, model_problem

    folder = Path(tempfile.mkdtemp(prefix="physdsl-bench-infer-"))
    scene = simulated_scene(folder, SCENE.read_text(), TRUTH, TIMES, NOISE, seed=3)
    measured = np.loadtxt(folder / "data.csv", delimiter=",", skiprows=1, usecols=(2, 3, 4))

    # start cold, as a fresh process: no compiled function of the scene's structure in memory
    # (the data simulation above compiled its rollout) and no persistent compilation cache
    # (the tests' helper module turns one on)
    from physdsl.compile import _COMPILED

    jax.config.update("jax_enable_compilation_cache", False)
    _COMPILED.clear()
    jax.clear_caches()
    x_ref = jnp.array([np.log(0.006), 6.1, 0.2, 5.9, np.log(0.03)])  # a point near the truth
    t0, c0 = time.perf_counter(), time.process_time()
    model = compile_phys(scene)  # parse, resolve, build the simulator
    print(f"compile_parse_build_s: {time.perf_counter() - t0:.2f}")
    vg = value_and_grad_fn(model_problem(model))
    jax.block_until_ready(vg(x_ref))
    compile_s = time.perf_counter() - t0
    compile_cpu = time.process_time() - c0
    print(f"compile_s: {compile_s:.2f}")
    print(f"compile_cpu_s: {compile_cpu:.2f}")

    # the hand-written density from cleared caches too: jax.numpy's own traced helpers (where,
    # concatenate, ...) are cached on first use, and neither side should inherit the other's
    jax.clear_caches()
    t0, c0 = time.perf_counter(), time.process_time()
    hand = hand_logdensity(jnp.asarray(measured))
    hand_vg = jax.jit(jax.value_and_grad(hand))
    jax.block_until_ready(hand_vg(x_ref))
    compile_hand = time.perf_counter() - t0
    compile_cpu_hand = time.process_time() - c0
    print(f"compile_s_hand: {compile_hand:.2f}")
    print(f"compile_cpu_s_hand: {compile_cpu_hand:.2f}")
    print(f"compile_ratio: {compile_s / compile_hand:.2f}")
    print(f"compile_cpu_ratio: {compile_cpu / compile_cpu_hand:.2f}")
    _, positions = make_problem(model, jax.random.PRNGKey(0), CHAINS)  # initial draws (shared)
    names = tuple(sorted(model.unknown_names))
    assert names == NAMES, names
    xs = [np.asarray(p) for p in positions] + [np.asarray(x_ref)]
    diffs = [abs(float(vg(jnp.asarray(x))[0]) - float(hand(jnp.asarray(x)))) for x in xs]
    grads = [float(np.max(np.abs(np.asarray(vg(jnp.asarray(x))[1]) - np.asarray(hand_vg(jnp.asarray(x))[1]))))
             for x in xs]
    print(f"logdensity_max_abs_diff: {max(diffs):.3g}")
    print(f"gradient_max_abs_diff: {max(grads):.3g}")

    x = jnp.asarray(xs[-1])
    g_phys, g_hand = median_call_ms(vg, x), median_call_ms(hand_vg, x)
    print(f"grad_ms_physdsl: {g_phys:.4f}")
    print(f"grad_ms_hand: {g_hand:.4f}")
    print(f"grad_time_ratio: {g_phys / g_hand:.2f}")

    settings = dict(backend="nuts", chains=CHAINS, warmup=WARMUP, samples=SAMPLES, progress=False)
    t0, c0 = time.perf_counter(), time.process_time()
    physdsl.infer(model, seed=0, **settings)
    print(f"physdsl_first_run_s: {time.perf_counter() - t0:.2f}")
    print(f"physdsl_first_run_cpu_s: {time.process_time() - c0:.2f}")
    t0, c0 = time.perf_counter(), time.process_time()
    idata = physdsl.infer(model, seed=1, **settings)
    t_phys, cpu_phys = time.perf_counter() - t0, time.process_time() - c0
    post = idata.posterior
    draws = {"physdsl": np.concatenate([post["ball.position.noise"].values[..., None],
                                        post["ball.velocity"].values,
                                        post["drag_ratio"].values[..., None]], axis=2)}
    seconds = {"physdsl": (t_phys, cpu_phys)}
    print(f"leapfrog_per_draw_physdsl: {float(idata.sample_stats['n_steps'].mean()):.2f}")
    print(f"physdsl_run_s: {t_phys:.2f}")
    print(f"physdsl_run_cpu_s: {cpu_phys:.2f}")

    x0 = jnp.asarray(np.stack(xs[:CHAINS]))
    for name, dense in (("blackjax_hand", False), ("blackjax_hand_dense", True)):
        d, t, cpu = blackjax_hand(hand, jax.random.PRNGKey(2), x0, dense=dense)
        draws[name], seconds[name] = d, (t, cpu)
        print(f"{name}_run_s: {t:.2f}")
        print(f"{name}_run_cpu_s: {cpu:.2f}")
    d, t, cpu = numpyro_hand(jnp.asarray(measured), jax.random.PRNGKey(3))
    draws["numpyro"], seconds["numpyro"] = d, (t, cpu)
    print(f"numpyro_run_s: {t:.2f}")
    print(f"numpyro_run_cpu_s: {cpu:.2f}")

    ess = {k: min_ess(d) for k, d in draws.items()}
    for k in draws:
        print(f"min_ess_{k}: {ess[k]:.0f}")
        print(f"ess_per_s_{k}: {ess[k] / seconds[k][0]:.2f}")
        print(f"rhat_max_{k}: {max_rhat(draws[k]):.4f}")
    stats = {k: mean_and_mcse(d) for k, d in draws.items()}
    for i, label in enumerate(LABELS):
        for k in draws:
            print(f"posterior_mean_{label}_{k}: {stats[k][0][i]:.5g}")
    agree = True
    for k in ("blackjax_hand", "blackjax_hand_dense", "numpyro"):
        (m1, e1), (m2, e2) = stats["physdsl"], stats[k]
        z = float(np.max(np.abs(m1 - m2) / np.hypot(e1, e2)))
        agree &= z < 3.5
        print(f"posterior_mean_max_z_vs_{k}: {z:.2f}")
    print(f"posterior_means_agree: {agree}")

    def ratio(peer, cpu=False):
        i = 1 if cpu else 0
        return ess["physdsl"] / seconds["physdsl"][i] / (ess[peer] / seconds[peer][i])

    print(f"ess_per_s_ratio: {ratio('blackjax_hand'):.3f}")
    print(f"ess_per_s_ratio_vs_numpyro: {ratio('numpyro'):.3f}")
    print(f"ess_per_s_ratio_vs_blackjax_hand_dense: {ratio('blackjax_hand_dense'):.3f}")
    # the same ratios per CPU second (less sensitive to other jobs on a shared machine)
    print(f"ess_per_cpu_s_ratio: {ratio('blackjax_hand', True):.3f}")
    print(f"ess_per_cpu_s_ratio_vs_numpyro: {ratio('numpyro', True):.3f}")
    print(f"ess_per_cpu_s_ratio_vs_blackjax_hand_dense: {ratio('blackjax_hand_dense', True):.3f}")
    shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
