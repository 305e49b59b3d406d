"""Physics engine benchmark: prints ``name: value`` lines.

steps_per_s.<scene> (single rollout, after compile), compile_cpu_s.<scene> and
grad_compile_cpu_s.<scene> (CPU seconds to compile the rollout and its gradient),
batch1024_body_steps_per_s.<scene> (vmap over 1024 scenes, moving bodies x steps per second), grad_over_forward.<scene> (reverse-mode
gradient time / forward time), mujoco_steps_per_s.<scene> (mj_step on the same scene),
float32 vs float64 steps_per_s for the pendulum, and benchmarks/contact.py's lines if present.
Run: .venv/bin/python benchmarks/physics.py
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "physics"))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import physdsl  # noqa: E402,F401
from physdsl.expr import Binary, Const, Ref, Vec  # noqa: E402
from physdsl.physics import build_simulator  # noqa: E402
from physdsl.scene import Body, Shape  # noqa: E402
from scenes import c, chain, effect, gravity, pendulum, scene, sphere  # noqa: E402

STEPS = 200


def ball():
    b = Body("ball", Shape("sphere", {"radius": Const(0.11)}), mass=Const(0.43),
             position=Vec((Const(0.0), Const(0.0), Ref("z0"))), velocity=c((6.5, 0.4, 6.0)))
    s = scene([b], effects=[gravity(), effect("quadratic_drag", "ball", coefficient=0.0057)],
              dt=1e-3, duration=STEPS * 1e-3, integrator="rk4")
    xml = ('<mujoco><option timestep="0.001" integrator="RK4" density="1.204"/><worldbody>'
           '<body pos="0 0 1.8"><freejoint/><geom type="sphere" size="0.11" mass="0.43" '
           'fluidshape="ellipsoid" fluidcoef="0.125 0.25 1.5 1 1"/></body></worldbody></mujoco>')
    return s, xml, {"z0": 1.8}, "z0"


def pend():
    s = pendulum(length=0.6, mass=0.3, angle=0.7, duration=STEPS * 1e-3)
    s = s.__class__(**{**s.__dict__, "joints": (s.joints[0].__class__(
        **{**s.joints[0].__dict__, "initial": Ref("th0")}),)})
    xml = ('<mujoco><option timestep="0.001" integrator="RK4"/><worldbody><body pos="0 0 1">'
           '<joint type="hinge" axis="0 -1 0"/><geom type="sphere" pos="0 0 -0.6" size="0.02" '
           'mass="0.3"/></body></worldbody></mujoco>')
    return s, xml, {"th0": 0.7}, "th0"


def chain10():
    s = chain(10, link=0.1, mass=0.1, r=0.01, duration=STEPS * 1e-3)
    s = s.__class__(**{**s.__dict__, "joints": (s.joints[0].__class__(
        **{**s.joints[0].__dict__, "initial": Ref("th0")}),) + s.joints[1:]})
    inner = ""
    for k in range(10):
        inner += (f'<body pos="0 0 {-0.1 if k else 0}"><joint type="hinge" axis="0 1 0"/>'
                  '<geom type="capsule" fromto="0 0 -0.01 0 0 -0.09" size="0.01" mass="0.1"/>')
    inner += "</body>" * 10
    xml = f'<mujoco><option timestep="0.001" integrator="RK4"/><worldbody>{inner}</worldbody></mujoco>'
    return s, xml, {"th0": 0.3}, "th0"


def balls16():
    """16 balls dropped into a box (floor + 4 walls), every pair colliding, compliant contact."""
    walls = [("floor", (0, 0, 1), (0, 0, 0)), ("wx0", (1, 0, 0), (-0.3, 0, 0)),
             ("wx1", (-1, 0, 0), (0.3, 0, 0)), ("wy0", (0, 1, 0), (0, -0.3, 0)),
             ("wy1", (0, -1, 0), (0, 0.3, 0))]
    bodies = [Body(n, Shape("plane", {"normal": c(nm)}), position=c(p), fixed=True)
              for n, nm, p in walls]
    rng = np.random.default_rng(0)
    names = []
    mj = ""
    for i in range(16):
        x, y = (i % 4 - 1.5) * 0.13, (i // 4 - 1.5) * 0.13
        z = 0.3 + 0.05 * rng.random()
        names.append(f"b{i}")
        pos = Vec((Const(x), Const(y), Binary("+", Const(z), Ref("dz"))))
        bodies.append(Body(f"b{i}", Shape("sphere", {"radius": Const(0.05)}), mass=Const(0.1),
                           position=pos))
        mj += (f'<body pos="{x} {y} {z}"><freejoint/><geom type="sphere" size="0.05" mass="0.1"/>'
               '</body>')
    pairs = [(w[0], n) for w in walls for n in names]
    pairs += [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    s = scene(bodies, effects=[gravity()], contact_pairs=pairs, contact_model="compliant",
              dt=1e-3, duration=STEPS * 1e-3)
    planes = "".join(f'<geom type="plane" size="1 1 0.1" pos="{p[0]} {p[1]} {p[2]}" '
                     f'zaxis="{nm[0]} {nm[1]} {nm[2]}"/>' for _, nm, p in walls)
    xml = (f'<mujoco><option timestep="0.001"/><worldbody>{planes}{mj}</worldbody></mujoco>')
    return s, xml, {"dz": 0.0}, "dz"


def timed(f, *args, reps=3):
    jax.block_until_ready(f(*args))  # compile
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        best = min(best, time.perf_counter() - t0)
    return best


def mujoco_rate(xml, steps=5000):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return steps / (time.perf_counter() - t0)


def compile_s(f, *args):
    """CPU seconds to lower and compile f for args (robust to other load on the machine)."""
    t0 = time.process_time()
    f.lower(*args).compile()
    return time.process_time() - t0


def bench(name, builder, batches):
    s, xml, vals, key = builder()
    sim = build_simulator(s)
    vals = {k: jnp.asarray(v, float) for k, v in vals.items()}
    nsteps = len(sim.times) - 1
    moving = sum(1 for j in sim.model.joints if j.nv)
    fwd = jax.jit(lambda v: sim.simulate(v).body_pos)
    print(f"compile_cpu_s.{name}: {compile_s(fwd, vals):.1f}", flush=True)
    t_f = timed(fwd, vals)
    print(f"steps_per_s.{name}: {nsteps / t_f:.0f}", flush=True)
    grad = jax.jit(jax.grad(lambda v: jnp.sum(sim.simulate(v).body_pos[:, :, 2])))
    print(f"grad_compile_cpu_s.{name}: {compile_s(grad, vals):.1f}", flush=True)
    t_g = timed(grad, vals)
    print(f"grad_over_forward.{name}: {t_g / t_f:.2f}", flush=True)
    for n in batches:
        xs = vals[key] + jnp.linspace(0.0, 0.01, n)
        f = jax.jit(jax.vmap(lambda x: sim.simulate({**vals, key: x}).body_pos))
        t_b = timed(f, xs, reps=1)
        print(f"batch{n}_body_steps_per_s.{name}: {n * moving * nsteps / t_b:.0f}", flush=True)
    print(f"mujoco_steps_per_s.{name}: {mujoco_rate(xml):.0f}", flush=True)


def float32_line():
    """Pendulum steps/s in float32 (separate process: x64 is a process-wide switch)."""
    env = {**os.environ, "PHYSDSL_FLOAT32": "1"}
    out = subprocess.run([sys.executable, __file__, "--single-pendulum"], env=env,
                         capture_output=True, text=True, timeout=300)
    return out.stdout.strip()


def single_pendulum():
    s, _, vals, _ = pend()
    sim = build_simulator(s)
    dt = str(jnp.result_type(float))
    t = timed(jax.jit(lambda v: sim.simulate(v).body_pos), {k: jnp.asarray(v, float) for k, v in vals.items()})
    print(f"steps_per_s.{dt}.pendulum: {(len(sim.times) - 1) / t:.0f}")


def main():
    if "--single-pendulum" in sys.argv:
        single_pendulum()
        return
    t0 = time.time()
    # one batch size per scene (each batch size is a compile of its own): the 1024 lanes
    bench("ball", ball, (1024,))
    bench("pendulum", pend, (1024,))
    bench("chain10", chain10, (1024,))
    bench("balls16", balls16, (1024,))
    single_pendulum()
    print(float32_line())
    contact = HERE / "contact.py"
    if contact.exists():
        out = subprocess.run([sys.executable, str(contact)], capture_output=True, text=True, timeout=300)
        for line in out.stdout.splitlines():
            if ":" in line:
                print(line)
    print(f"benchmark_wall_s: {time.time() - t0:.0f}")


if __name__ == "__main__":
    main()
