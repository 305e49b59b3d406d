"""Inference benchmark: physdsl's compiled model against the same model written by hand.

Scene: a ball thrown through air with linear drag (semi-implicit Euler, 10 ms steps, 0.5 s),
11 position measurements with 1 cm noise; unknown launch velocity (3,) and drag coefficient.
The hand-written model integrates the same equations (x' = v, v' = g - (b/m) v, semi-implicit
Euler) with the same priors and noise, so both log densities agree to rounding
(``logdensity_max_abs_diff``). Prints ``name: value`` lines:

- ``compile_s``: from the ``.phys`` text to the first gradient of the log density;
  ``compile_s_hand``: the hand-written log density to its first gradient; ``compile_ratio``;
- ``grad_ms_physdsl``, ``grad_ms_hand``, ``grad_time_ratio`` (compiled over hand-written):
  one jitted value-and-gradient call, median of repeats;
- ``ess_per_s_physdsl`` (``physdsl infer --backend nuts``, second run: compiled stages are
  cached, so this is initialisation + warmup + sampling + posterior pass + InferenceData),
  ``ess_per_s_blackjax_hand`` (blackjax NUTS with window adaptation on the hand-written
  density, one jitted vmapped run, after compile; diagonal mass matrix, blackjax's default),
  ``ess_per_s_blackjax_hand_dense`` (the same with a dense mass matrix, as physdsl uses by
  default), ``ess_per_s_numpyro`` (numpyro NUTS on the hand-written model, second run); ESS
  is arviz's bulk ESS, minimum over parameters;
- ``ess_per_s_ratio`` (physdsl over hand-written blackjax), ``ess_per_s_ratio_vs_numpyro``,
  ``ess_per_s_ratio_vs_blackjax_hand_dense``; ``ess_per_cpu_s_ratio*``: the same per CPU
  second (process time), steadier than wall time on a shared machine.

All run 4 chains, 500 warmup and 1000 draws (the issue's protocol).

Run: .venv/bin/python benchmarks/inference.py   (about 3-5 minutes on 2 loaded cores)
"""
from __future__ import annotations

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
from tests.infer.conftest import (PROJECTILE_TIMES, PROJECTILE_TRUTH, projectile_text,  # noqa: E402
                                  simulated_scene)

CHAINS, WARMUP, SAMPLES = 4, 500, 1000
DT, STEPS, MASS, G = 0.01, 50, 0.2, np.array([0.0, 0.0, -9.81])
X0, NOISE = np.array([0.0, 0.0, 1.0]), 0.01


def hand_rollout(v0, b):
    """Semi-implicit Euler of x' = v, v' = g - (b/m) v from X0: positions at every step (T+1, 3)."""
    def step(carry, _):
        x, v = carry
        v = v + DT * (G - (b / MASS) * v)
        x = x + DT * v
        return (x, v), x
    _, xs = jax.lax.scan(step, (jnp.asarray(X0), v0), None, length=STEPS)
    return jnp.concatenate([jnp.asarray(X0)[None], xs])


def hand_logdensity(measured):
    """Log density over (v0 (3,), log b) with the scene's priors, noise and log-Jacobian."""
    idx = np.rint(PROJECTILE_TIMES / DT).astype(int)

    def logdensity(z):
        v0, log_b = z[:3], z[3]
        b = jnp.exp(log_b)
        lp = jax.scipy.stats.norm.logpdf(v0, jnp.array([3.0, 0.0, 4.0]), 1.0).sum()
        lp += jnp.log(2.0) + jax.scipy.stats.norm.logpdf(b, 0.0, 0.5) + log_b  # half-normal + Jacobian
        pred = hand_rollout(v0, b)[idx]
        return lp + jax.scipy.stats.norm.logpdf(measured, pred, NOISE).sum()
    return logdensity


def median_call_ms(fn, x, repeats=50):
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


def blackjax_hand(logdensity, key, x0, dense: bool = False):
    """Window adaptation + NUTS, vmapped over chains, all in one jitted function:
    (draws, wall seconds, CPU seconds) of the second, compiled run."""
    import blackjax

    def chain(k, x):
        k1, k2 = jax.random.split(k)
        adapt = blackjax.window_adaptation(blackjax.nuts, logdensity, is_mass_matrix_diagonal=not dense)
        (state, params), _ = adapt.run(k1, x, WARMUP)
        kernel = blackjax.nuts(logdensity, **params)
        _, xs = jax.lax.scan(lambda s, kk: (lambda r: (r[0], r[0].position))(kernel.step(kk, s)),
                             state, jax.random.split(k2, SAMPLES))
        return xs

    run = jax.jit(jax.vmap(chain))
    keys = jax.random.split(key, CHAINS)
    jax.block_until_ready(run(keys, x0))  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    draws = jax.block_until_ready(run(jax.random.split(jax.random.fold_in(key, 1), CHAINS), x0))
    return np.asarray(draws), time.perf_counter() - t0, time.process_time() - c0


def numpyro_hand(measured, key):
    """numpyro NUTS on the hand-written model (vectorised chains): (draws, wall and CPU
    seconds of the second run)."""
    import numpyro
    import numpyro.distributions as dist
    from numpyro.infer import MCMC, NUTS

    idx = np.rint(PROJECTILE_TIMES / DT).astype(int)

    def model():
        v0 = numpyro.sample("v0", dist.Normal(jnp.array([3.0, 0.0, 4.0]), 1.0).to_event(1))
        b = numpyro.sample("b", dist.HalfNormal(0.5))
        numpyro.sample("obs", dist.Normal(hand_rollout(v0, b)[idx], NOISE).to_event(2), obs=measured)

    mcmc = MCMC(NUTS(model), num_warmup=WARMUP, num_samples=SAMPLES, num_chains=CHAINS,
                chain_method="vectorized", progress_bar=False)
    mcmc.run(key)  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    mcmc.run(jax.random.fold_in(key, 1))
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = mcmc.get_samples(group_by_chain=True)
    return np.concatenate([np.asarray(s["v0"]), np.asarray(s["b"])[..., None]], axis=2), seconds, cpu


def main() -> None:
    from physdsl.compile import compile as compile_phys
    from physdsl.infer.base import value_and_grad_fn
    from physdsl.infer.problem import make_problem

    folder = Path(tempfile.mkdtemp(prefix="physdsl-bench-infer-"))
    scene = simulated_scene(folder, projectile_text(NOISE), PROJECTILE_TRUTH, PROJECTILE_TIMES,
                            NOISE, seed=3)
    measured = np.loadtxt(folder / "data.csv", delimiter=",", skiprows=1, usecols=(2, 3, 4))

    from physdsl.compile import _COMPILED

    _COMPILED.clear()  # the data simulation above compiled this structure's simulator: start cold
    t0, c0 = time.perf_counter(), time.process_time()
    model = compile_phys(scene)  # parse, resolve, build the simulator
    print(f"compile_parse_build_s: {time.perf_counter() - t0:.2f}")
    problem, positions = make_problem(model, jax.random.PRNGKey(0), CHAINS)
    vg = value_and_grad_fn(problem)
    jax.block_until_ready(vg(positions[0]))
    compile_s = time.perf_counter() - t0
    print(f"compile_s: {compile_s:.2f}")
    print(f"compile_cpu_s: {time.process_time() - c0:.2f}")

    t0, c0 = time.perf_counter(), time.process_time()
    hand = hand_logdensity(jnp.asarray(measured))
    hand_vg = jax.jit(jax.value_and_grad(hand))
    jax.block_until_ready(hand_vg(positions[0]))
    compile_hand = time.perf_counter() - t0
    print(f"compile_s_hand: {compile_hand:.2f}")
    print(f"compile_cpu_s_hand: {time.process_time() - c0:.2f}")
    print(f"compile_ratio: {compile_s / compile_hand:.1f}")
    # the flat vector of physdsl is ravel({name: value}) in sorted order: velocity, then drag
    names = sorted(model.unknown_names)
    assert names == ["ball.velocity", "linear_drag@ball.coefficient"], names
    xs = [np.asarray(p) for p in positions] + [np.array([3.1, 0.3, 4.2, np.log(0.25)])]
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
    model.infer(seed=0, **settings)
    print(f"physdsl_first_run_s: {time.perf_counter() - t0:.2f}")
    print(f"physdsl_first_run_cpu_s: {time.process_time() - c0:.2f}")
    t0, c0 = time.perf_counter(), time.process_time()
    idata = model.infer(seed=1, **settings)
    t_phys = time.perf_counter() - t0
    cpu_phys = time.process_time() - c0
    post = idata.posterior
    phys_draws = np.concatenate([post["ball.velocity"].values,
                                 post["linear_drag@ball.coefficient"].values[..., None]], axis=2)
    ess_phys = min_ess(phys_draws) / t_phys
    print(f"physdsl_run_s: {t_phys:.2f}")
    print(f"physdsl_run_cpu_s: {cpu_phys:.2f}")
    print(f"ess_per_s_physdsl: {ess_phys:.2f}")

    bj_draws, t_bj, cpu_bj = blackjax_hand(hand, jax.random.PRNGKey(2),
                                           jnp.asarray(np.stack(xs[:CHAINS])))
    ess_bj = min_ess(bj_draws) / t_bj
    print(f"blackjax_hand_run_s: {t_bj:.2f}")
    print(f"blackjax_hand_run_cpu_s: {cpu_bj:.2f}")
    print(f"ess_per_s_blackjax_hand: {ess_bj:.2f}")
    bjd_draws, t_bjd, cpu_bjd = blackjax_hand(hand, jax.random.PRNGKey(2),
                                              jnp.asarray(np.stack(xs[:CHAINS])), dense=True)
    ess_bjd = min_ess(bjd_draws) / t_bjd
    print(f"blackjax_hand_dense_run_s: {t_bjd:.2f}")
    print(f"blackjax_hand_dense_run_cpu_s: {cpu_bjd:.2f}")
    print(f"ess_per_s_blackjax_hand_dense: {ess_bjd:.2f}")

    np_draws, t_np, cpu_np = numpyro_hand(jnp.asarray(measured), jax.random.PRNGKey(3))
    ess_np = min_ess(np_draws) / t_np
    print(f"numpyro_run_s: {t_np:.2f}")
    print(f"numpyro_run_cpu_s: {cpu_np:.2f}")
    print(f"ess_per_s_numpyro: {ess_np:.2f}")

    print(f"posterior_mean_drag_physdsl: {float(phys_draws[..., 3].mean()):.4f}")
    print(f"posterior_mean_drag_blackjax_hand: {float(np.exp(bj_draws[..., 3]).mean()):.4f}")
    print(f"posterior_mean_drag_numpyro: {float(np_draws[..., 3].mean()):.4f}")
    print(f"ess_per_s_ratio: {ess_phys / ess_bj:.3f}")
    print(f"ess_per_s_ratio_vs_numpyro: {ess_phys / ess_np:.3f}")
    print(f"ess_per_s_ratio_vs_blackjax_hand_dense: {ess_phys / ess_bjd:.3f}")
    # the same ratios per CPU second (less sensitive to other jobs on a shared machine)
    ess = {k: min_ess(d) for k, d in (("phys", phys_draws), ("bj", bj_draws), ("np", np_draws),
                                        ("bjd", bjd_draws))}
    print(f"ess_per_cpu_s_ratio: {ess['phys'] / cpu_phys / (ess['bj'] / cpu_bj):.3f}")
    print(f"ess_per_cpu_s_ratio_vs_numpyro: {ess['phys'] / cpu_phys / (ess['np'] / cpu_np):.3f}")
    print(f"ess_per_cpu_s_ratio_vs_blackjax_hand_dense: "
          f"{ess['phys'] / cpu_phys / (ess['bjd'] / cpu_bjd):.3f}")


if __name__ == "__main__":
    main()
