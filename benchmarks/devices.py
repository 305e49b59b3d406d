"""The same physics on every device JAX sees: agreement and throughput, side by side in one run.

Prints ``name: value`` lines. Per scene of ``benchmarks/physics.py`` (ball, pendulum, chain10,
balls16) and per device kind (``cpu``, and ``gpu`` where one is present):
``steps_per_s.DEV.SCENE`` (one rollout after compile), ``batchN_body_steps_per_s.DEV.SCENE``
(vmap over N scenes that differ in one initial value: what a posterior's draws or many
recordings cost), and, where a GPU is present, ``gpu_vs_cpu_max_pos_diff_m.SCENE`` (largest
body-position difference between the two devices' float64 rollouts, single and batched) and
``gpu_vs_cpu_grad_rel_diff.SCENE`` (relative difference of the gradient of a scalar of the
trajectory). A GPU that runs the physics differently from the CPU shows here before any fit.
Run: python benchmarks/devices.py [--batches 64,1024,8192] [--scenes ball,chain10]
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests" / "physics"))
os.environ.setdefault("PHYSDSL_CACHE_DIR", "off")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import physics  # noqa: E402  (benchmarks/physics.py: the scenes)
from contact import timed  # noqa: E402

# scene -> steps per rollout for the single and the batched timings (1 ms steps)
HORIZON = {"ball": (2000, 200), "pendulum": (2000, 200), "chain10": (500, 20), "balls16": (200, 5)}


def devices():
    """{kind: first device of that kind} for cpu and gpu (where present)."""
    found = {"cpu": jax.devices("cpu")[0]}
    try:
        found["gpu"] = jax.devices("gpu")[0]
    except RuntimeError:
        pass
    return found


def on(device, tree):
    return jax.device_put(tree, device)


def measure(name, kind, device, batches):
    """(single-rollout positions, gradient, {N: batched positions}) of scene ``name`` on
    ``device``, printing its timings."""
    steps, bsteps = HORIZON[name]
    sim, vals, key, _ = physics.rollout(name, steps)
    vals = on(device, vals)
    fwd = jax.jit(lambda v: sim.simulate(v).body_pos)
    t = timed(fwd, vals, repeat=3)
    print(f"steps_per_s.{kind}.{name}: {steps / t:.0f}", flush=True)
    grad = jax.jit(jax.grad(lambda v: jnp.sum(sim.simulate(v).body_pos[:, :, 2])))
    g = np.asarray(grad(vals)[key])
    bsim, bvals, _, _ = physics.rollout(name, bsteps)
    bvals = on(device, bvals)
    moving = sum(1 for j in bsim.model.joints if j.nv)
    batched = {}
    for n in batches:
        xs = on(device, bvals[key] + jnp.linspace(0.0, 0.01, n))
        f = jax.jit(jax.vmap(lambda x: bsim.simulate({**bvals, key: x}).body_pos))
        try:
            tb = timed(f, xs, repeat=2)
        except Exception as err:  # noqa: BLE001  (out of memory or time: say so, go on)
            print(f"batch{n}_error.{kind}.{name}: {type(err).__name__}", flush=True)
            continue
        print(f"batch{n}_body_steps_per_s.{kind}.{name}: {n * moving * bsteps / tb:.0f}",
              flush=True)
        batched[n] = np.asarray(f(xs))
    return np.asarray(fwd(vals)), g, batched


def main():
    batches = (64, 1024)
    if "--batches" in sys.argv:
        batches = tuple(int(b) for b in sys.argv[sys.argv.index("--batches") + 1].split(","))
    names = list(HORIZON)
    if "--scenes" in sys.argv:
        names = sys.argv[sys.argv.index("--scenes") + 1].split(",")
    found = devices()
    t0 = time.time()
    for kind, dev in found.items():
        print(f"device.{kind}: {dev.device_kind}")
    print(f"float64: {jnp.result_type(float) == jnp.float64}")
    for name in names:
        runs = {kind: measure(name, kind, dev, batches) for kind, dev in found.items()}
        if "gpu" in runs:
            (pc, gc, bc), (pg, gg, bg) = runs["cpu"], runs["gpu"]
            diffs = [np.abs(pc - pg).max()] + [np.abs(bc[n] - bg[n]).max()
                                               for n in bc if n in bg]
            print(f"gpu_vs_cpu_max_pos_diff_m.{name}: {max(diffs):.1e}")
            rel = np.abs(gc - gg).max() / max(np.abs(gc).max(), 1e-300)
            print(f"gpu_vs_cpu_grad_rel_diff.{name}: {rel:.1e}", flush=True)
    print(f"benchmark_wall_s: {time.time() - t0:.0f}")


if __name__ == "__main__":
    main()
