"""Contact LCP benchmark: prints ``name: value`` lines.

lcp_solve_ms.c8_n12 (one jitted solve_lcp_step, C=8 contacts, n=12, F=4), implicit and
unrolled gradient times, unrolled_over_implicit_grad.lcp, and fd_over_implicit_grad.lcp: the
time of a central finite-difference gradient (2 solves per parameter over every entry of M,
v_free, mu and e, timed by running them) over the time of one implicit gradient.
Run: .venv/bin/python benchmarks/contact.py; ``--idle``: the cost of a contact that never
comes near (``idle_contact``).
"""
from __future__ import annotations

import json
import time

import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401  (float64)
from physdsl.physics.contact import IPSettings, LCPSettings, solve_lcp_step

N, C, F, H = 12, 8, 4, 0.01


def problem(seed=0):
    """Random SPD M, compressive contacts with mixed stick/slide friction."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(N, N))
    M = B @ B.T + N * np.eye(N)
    Jn = rng.normal(size=(C, N))
    t1, t2 = rng.normal(size=(C, N)), rng.normal(size=(C, N))
    Jt = np.stack([t1, -t1, t2, -t2], axis=1)
    v = -0.5 * np.linalg.lstsq(Jn, np.ones(C), rcond=None)[0] + 0.05 * rng.normal(size=N)
    params = {"M": M, "v_free": v, "mu": rng.uniform(0.3, 1.0, C), "e": rng.uniform(0.2, 0.8, C)}
    fixed = {"Jn": Jn, "Jt": Jt, "vn_pre": -rng.uniform(0.5, 1.0, C), "dist": np.zeros(C),
             "active": np.ones(C, bool)}
    return ({k: jnp.asarray(x) for k, x in params.items()},
            {k: jnp.asarray(x) for k, x in fixed.items()})


def loss_fn(implicit: bool):
    settings = LCPSettings(solver=IPSettings(implicit=implicit))

    def loss(p, f):
        M = 0.5 * (p["M"] + p["M"].T)
        v, lam_n, *_ = solve_lcp_step(M, p["v_free"], f["Jn"], f["Jt"], p["mu"], p["e"],
                                      f["vn_pre"], f["dist"], f["active"], H, settings)
        return jnp.sum(v ** 2) + jnp.sum(lam_n)

    return loss


def timed(fn, *args, repeat=10):
    """Best-of-``repeat`` wall time (s) of fn(*args) after a warm-up (compile) call (the
    minimum is the least disturbed by other load on the machine)."""
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return float(np.min(times))


def main():
    p, f = problem()
    loss = jax.jit(loss_fn(True))
    t_solve = timed(loss, p, f)
    t_implicit = timed(jax.jit(jax.grad(loss_fn(True))), p, f)
    t_unrolled = timed(jax.jit(jax.grad(loss_fn(False))), p, f)

    flat, unravel = jax.flatten_util.ravel_pytree(p)
    loss_flat = jax.jit(lambda x: loss(unravel(x), f))
    x0 = np.asarray(flat)
    eps = 1e-6
    jax.block_until_ready(loss_flat(x0))

    def fd_gradient():
        out = np.empty(x0.size)
        for i in range(x0.size):
            d = np.zeros_like(x0)
            d[i] = eps
            out[i] = (float(loss_flat(x0 + d)) - float(loss_flat(x0 - d))) / (2 * eps)
        return out

    t0 = time.perf_counter()
    g_fd = fd_gradient()
    t_fd = time.perf_counter() - t0
    g_implicit = jax.flatten_util.ravel_pytree(jax.grad(loss_fn(True))(p, f))[0]
    rel = float(np.max(np.abs(g_fd - g_implicit)) / np.max(np.abs(g_implicit)))

    print(f"lcp_solve_ms.c{C}_n{N}: {1e3 * t_solve:.3f}")
    print(f"implicit_grad_ms.lcp: {1e3 * t_implicit:.3f}")
    print(f"unrolled_grad_ms.lcp: {1e3 * t_unrolled:.3f}")
    print(f"unrolled_over_implicit_grad.lcp: {t_unrolled / t_implicit:.2f}")
    print(f"fd_params.lcp: {x0.size}")
    print(f"fd_over_implicit_grad.lcp: {t_fd / t_implicit:.1f}")
    print(f"fd_vs_implicit_max_rel_err.lcp: {rel:.2e}")


def idle_contact(chains: int = 2, repeat: int = 30):
    """A contact that never comes near costs (next to nothing): the README's thrown ball
    (examples/thrown_ball, RK4, 1430 steps, 7 unknowns) with and without its ground plane, the
    log density's value and gradient (jit, float64), alone and vmapped over ``chains`` chains
    as the samplers run them. Prints ``idle_contact_ms.*`` and ``ground_over_none.*``."""
    import dataclasses
    from pathlib import Path

    from physdsl.compile import compile_scene
    from physdsl.infer.problem import model_problem, start_position

    path = Path(__file__).resolve().parents[1] / "examples" / "thrown_ball" / "thrown_ball.phys"
    scene = physdsl.load(path)
    truth = json.loads((path.parent / "truth.json").read_text())["unknowns"]
    ms = {}
    for name, sc in (("ground", scene), ("none", dataclasses.replace(scene, contact_pairs=()))):
        model = compile_scene(sc)
        problem = model_problem(model)
        # the truth and throws near it: the ball lands after the recording ends (ground idle)
        x = jnp.stack([start_position(problem, jax.random.PRNGKey(0), {
            **truth, "ball.velocity": np.add(truth["ball.velocity"], (-0.1 * i, 0, 0.1 * i))})
            for i in range(chains)])
        vg = jax.value_and_grad(problem.logdensity)
        ms[f"single.{name}"] = 1e3 * timed(jax.jit(vg), x[0], problem.data, repeat=repeat)
        ms[f"vmap{chains}.{name}"] = 1e3 * timed(jax.jit(jax.vmap(vg, in_axes=(0, None))), x,
                                                 problem.data, repeat=repeat)
    for k, v in ms.items():
        print(f"idle_contact_ms.{k}: {v:.1f}")
    for k in ("single", f"vmap{chains}"):
        print(f"ground_over_none.{k}: {ms[k + '.ground'] / ms[k + '.none']:.2f}")


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--idle"]:
        idle_contact()
    else:
        main()
