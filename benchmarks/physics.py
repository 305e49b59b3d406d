"""Physics engine benchmark: prints ``name: value`` lines, in under 5 minutes on 2 CPU cores.

Per scene (ball, pendulum, chain10 = 10 hinged capsules, balls16 = 16 balls in a box):
compile_cpu_s / grad_compile_cpu_s / batch_compile_cpu_s (CPU seconds to compile the rollout,
its gradient and the three vmapped rollouts), steps_per_s (one rollout, after compile),
grad_over_forward (gradient time / rollout time), batch{1,64,1024}_body_steps_per_s (vmap over
that many scenes: moving bodies x steps per second; ``batch1024_vmap_chunk`` says where the 1024
lanes run as lax.map over vmapped chunks), mujoco_steps_per_s and
mujoco_body_steps_per_s (mj_step on the same scene, one thread), float32_speedup (float64 /
float32 rollout time, PHYSDSL_FLOAT32=1 in a subprocess) and float32_max_pos_err_m (largest
body-position difference between the float32 and float64 rollouts over the horizon),
one_kernel_loop (1: XLA compiled the rollout's loop into one kernel, ``physdsl/xla_flags.py``;
0: a call per operation, as with PHYSDSL_XLA_FLAGS=off or a library call in the loop). Then
benchmarks/contact.py's lines (LCP solve, implicit / unrolled / finite-difference gradients).
Then ``chain_scaling.*.N`` (N hinged links, N = 2, 5, 10, 20; also the recursive tree algorithms
the vectorised ``physics/tree.py`` replaced, as ``recursive_*``) and ``contact_scaling.*.N``
(N balls in a box, N = 2 .. 32): steps_per_s, mujoco_steps_per_s, ours_over_mujoco,
compile_cpu_s, growth_exponent (time per step ~ N^k between the smallest and largest N).
Then ``welded.*.N`` (N hinged links, each with a ball welded to it: steps/s with the welds
merged into their links, ``physics/welds.py``, and with every body stepped, their ratio, and
whether physdsl merges there by default; ``--welded``: those lines alone). ``--scaling``: the
scaling lines alone; ``--profile``: per-stage microseconds per step
(``benchmarks/step_profile.py``). Compile figures are true compilations: the persistent cache is
off (``PHYSDSL_CACHE_DIR=off`` unless set). Ours, the gradient and MuJoCo are timed side by side
(``side_by_side``: each the best of 5 rounds that take them in turn), so a ratio does not mix
figures taken minutes apart on a machine whose clock drifts.

Steps/s do not depend on the horizon, so each scene and batch size has its own, chosen so the
whole script fits the budget; ``horizon_steps.*`` lines say which.
Run: .venv/bin/python benchmarks/physics.py
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "physics"))
# compile figures are compilations, not loads from the persistent cache (``physdsl.cache``)
os.environ.setdefault("PHYSDSL_CACHE_DIR", "off")
sys.path.insert(0, str(HERE))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import physdsl  # noqa: E402,F401
from physdsl.expr import Binary, Const, Ref, Vec  # noqa: E402
from physdsl.physics import build_simulator  # noqa: E402
from physdsl.scene import Body, Shape  # noqa: E402
from scenes import c, chain, effect, gravity, pendulum, scene  # noqa: E402

import contact  # noqa: E402  (benchmarks/contact.py: the LCP lines and ``timed``)
import step_profile  # noqa: E402  (benchmarks/step_profile.py: ``--profile``)
from physdsl.physics import tree  # noqa: E402

DT = 1e-3
BATCHES = (1, 64, 1024)


def ball(steps):
    b = Body("ball", Shape("sphere", {"radius": Const(0.11)}), mass=Const(0.43),
             position=Vec((Const(0.0), Const(0.0), Ref("z0"))), velocity=c((6.5, 0.4, 6.0)))
    s = scene([b], effects=[gravity(), effect("quadratic_drag", "ball", coefficient=0.0057)],
              dt=DT, duration=steps * DT, integrator="rk4")
    xml = ('<mujoco><option timestep="0.001" integrator="RK4" density="1.204"/><worldbody>'
           '<body pos="0 0 1.8"><freejoint/><geom type="sphere" size="0.11" mass="0.43" '
           'fluidshape="ellipsoid" fluidcoef="0.125 0.25 1.5 1 1"/></body></worldbody></mujoco>')
    return s, xml, {"z0": 1.8}, "z0"


def pend(steps):
    s = pendulum(length=0.6, mass=0.3, angle=0.7, duration=steps * DT)
    s = s.__class__(**{**s.__dict__, "joints": (s.joints[0].__class__(
        **{**s.joints[0].__dict__, "initial": Ref("th0")}),)})
    xml = ('<mujoco><option timestep="0.001" integrator="RK4"/><worldbody><body pos="0 0 1">'
           '<joint type="hinge" axis="0 -1 0"/><geom type="sphere" pos="0 0 -0.6" size="0.02" '
           'mass="0.3"/></body></worldbody></mujoco>')
    return s, xml, {"th0": 0.7}, "th0"


def chain10(steps):
    """10 hinged capsules, semi-implicit Euler on both sides (RK4's four tree-dynamics stages
    take four times as long to compile, which alone would exceed the benchmark's budget)."""
    return chain_n(10, steps)


def chain_n(n, steps):
    """n hinged capsules hanging from the world (``chain10``'s links), semi-implicit Euler."""
    s = chain(n, link=0.1, mass=0.1, r=0.01, duration=steps * DT, integrator="semi_implicit_euler")
    s = s.__class__(**{**s.__dict__, "joints": (s.joints[0].__class__(
        **{**s.joints[0].__dict__, "initial": Ref("th0")}),) + s.joints[1:]})
    inner = ""
    for k in range(n):
        inner += (f'<body pos="0 0 {-0.1 if k else 0}"><joint type="hinge" axis="0 1 0"/>'
                  '<geom type="capsule" fromto="0 0 -0.01 0 0 -0.09" size="0.01" mass="0.1"/>')
    inner += "</body>" * n
    xml = (f'<mujoco><option timestep="0.001" integrator="Euler"/><worldbody>{inner}</worldbody>'
           '</mujoco>')
    return s, xml, {"th0": 0.3}, "th0"


def balls16(steps):
    """16 balls dropped into a box (floor + 4 walls), every pair a contact candidate, compliant
    contact (MuJoCo: its default soft contact)."""
    return balls_n(16, steps)


def balls_n(n, steps):
    """n balls of 5 cm dropped into a box (floor + 4 walls at +-0.3 m), every pair a contact
    candidate, compliant contact; 16 to a layer (4 x 4), layers 12 cm apart."""
    walls = [("floor", (0, 0, 1), (0, 0, 0)), ("wx0", (1, 0, 0), (-0.3, 0, 0)),
             ("wx1", (-1, 0, 0), (0.3, 0, 0)), ("wy0", (0, 1, 0), (0, -0.3, 0)),
             ("wy1", (0, -1, 0), (0, 0.3, 0))]
    bodies = [Body(nm_, Shape("plane", {"normal": c(nm)}), position=c(p), fixed=True)
              for nm_, nm, p in walls]
    rng = np.random.default_rng(0)
    names = []
    mj = ""
    for i in range(n):
        k = i % 16
        x, y = (k % 4 - 1.5) * 0.13, (k // 4 - 1.5) * 0.13
        z = 0.06 + 0.05 * rng.random() + 0.12 * (i // 16)  # contacts start within the horizon
        names.append(f"b{i}")
        pos = Vec((Const(x), Const(y), Binary("+", Const(z), Ref("dz"))))
        bodies.append(Body(f"b{i}", Shape("sphere", {"radius": Const(0.05)}), mass=Const(0.1),
                           position=pos))
        mj += (f'<body pos="{x} {y} {z}"><freejoint/><geom type="sphere" size="0.05" mass="0.1"/>'
               '</body>')
    pairs = [(w[0], b) for w in walls for b in names]
    pairs += [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    s = scene(bodies, effects=[gravity()], contact_pairs=pairs, contact_model="compliant",
              dt=DT, duration=steps * DT)
    planes = "".join(f'<geom type="plane" size="1 1 0.1" pos="{p[0]} {p[1]} {p[2]}" '
                     f'zaxis="{nm[0]} {nm[1]} {nm[2]}"/>' for _, nm, p in walls)
    xml = (f'<mujoco><option timestep="0.001"/><worldbody>{planes}{mj}</worldbody></mujoco>')
    return s, xml, {"dz": 0.0}, "dz"


# scene -> (builder, single-rollout horizon, horizon per batch size), in steps of 1 ms
SCENES = {
    "ball": (ball, 2000, {1: 2000, 64: 1000, 1024: 200}),
    "pendulum": (pend, 2000, {1: 2000, 64: 1000, 1024: 200}),
    "chain10": (chain10, 500, {1: 500, 64: 100, 1024: 20}),
    "balls16": (balls16, 200, {1: 200, 64: 20, 1024: 5}),
}
# vmap lanes per chunk of the 1024 batch (lax.map over chunks); absent: one vmap over all 1024.
# chain10 under a single vmap over 1024 lanes did not finish 5 steps in 240 s on XLA CPU, against
# 4.3 s for 20 steps at 512 lanes (superlinear in lanes: 0.37 s at 128, 1.25 s at 256).
CHUNK = {"chain10": 256}


def compile_cpu_s(f, *args):
    """(compiled f, CPU seconds to lower and compile it): robust to other load on the machine."""
    t0 = time.process_time()
    compiled = f.lower(*args).compile()
    return compiled, time.process_time() - t0


def values_of(vals):
    return {k: jnp.asarray(v, float) for k, v in vals.items()}


def rollout(name, steps):
    """(simulator, values, key of the varied unknown, MJCF) of scene ``name`` over ``steps``."""
    s, xml, vals, key = SCENES[name][0](steps)
    return build_simulator(s), values_of(vals), key, xml


def single(name):
    """Compile one rollout of ``name``: (simulator, values, compiled rollout, compile CPU s)."""
    sim, vals, _, _ = rollout(name, SCENES[name][1])
    fwd, t_c = compile_cpu_s(jax.jit(lambda v: sim.simulate(v).body_pos), vals)
    return sim, vals, fwd, t_c


def bench(name):
    """Every line of scene ``name`` except the float32 ones; returns its float64 rollout."""
    sim, vals, fwd, t_c = single(name)
    nsteps = len(sim.times) - 1
    moving = sum(1 for j in sim.model.joints if j.nv)
    print(f"horizon_steps.{name}: {nsteps}")
    print(f"compile_cpu_s.{name}: {t_c:.1f}")
    # 1: XLA compiled the rollout loop into one kernel (physdsl/xla_flags.py), 0: a call per op
    print(f"one_kernel_loop.{name}: {int('xla_cpu_small_call' in fwd.as_text())}")
    loss = jax.grad(lambda v: jnp.sum(sim.simulate(v).body_pos[:, :, 2]))
    grad, t_gc = compile_cpu_s(jax.jit(loss), vals)
    model = mujoco.MjModel.from_xml_string(rollout(name, 1)[3])
    t_f, t_g, t_mj = side_by_side([lambda: contact.timed(fwd, vals, repeat=3),
                                   lambda: contact.timed(grad, vals, repeat=3),
                                   lambda: mujoco_seconds_per_step(model)])
    rate = 1.0 / t_mj
    print(f"steps_per_s.{name}: {nsteps / t_f:.0f}", flush=True)
    print(f"grad_compile_cpu_s.{name}: {t_gc:.1f}")
    print(f"grad_over_forward.{name}: {t_g / t_f:.2f}", flush=True)
    t_bc = 0.0
    for n, steps in SCENES[name][2].items():
        bsim, bvals, key, _ = rollout(name, steps)
        xs = bvals[key] + jnp.linspace(0.0, 0.01, n)
        one = lambda x, bsim=bsim, bvals=bvals, key=key: bsim.simulate({**bvals, key: x}).body_pos  # noqa: E731
        chunk = CHUNK.get(name) if n == 1024 else None
        batched = (jax.vmap(one) if chunk is None else
                   lambda xs, one=one, chunk=chunk: jax.lax.map(one, xs, batch_size=chunk))
        f, t = compile_cpu_s(jax.jit(batched), xs)
        if chunk is not None:
            print(f"batch{n}_vmap_chunk.{name}: {chunk}")
        t_bc += t
        t_b = contact.timed(f, xs, repeat=2)
        print(f"horizon_steps.batch{n}.{name}: {steps}")
        print(f"batch{n}_body_steps_per_s.{name}: {n * moving * steps / t_b:.0f}", flush=True)
    print(f"batch_compile_cpu_s.{name}: {t_bc:.1f}")
    print(f"mujoco_steps_per_s.{name}: {rate:.0f}")
    print(f"mujoco_body_steps_per_s.{name}: {rate * moving:.0f}")
    print(f"ours_over_mujoco_steps.{name}: {nsteps / t_f / rate:.3f}", flush=True)
    return t_f, np.asarray(fwd(vals))


# chain_scaling / contact_scaling: sizes, and the horizon of each rollout timed (steps)
CHAIN_SIZES, CHAIN_STEPS = (2, 5, 10, 20), 500
BALL_SIZES, BALL_STEPS = (2, 4, 8, 16, 32), 200


def scaling(kind, builder, sizes, steps, recursive=False):
    """``KIND_scaling.*.N`` lines: our steps/s and MuJoCo's at each size N, their ratio, our
    compile CPU s; ``recursive``: also the per-body recursive tree algorithms (``tree.py`` off:
    the path before it) as ``recursive_steps_per_s``; and the growth exponent of the time per
    step between the smallest and largest N (1: linear)."""
    per_step = {}
    for n in sizes:
        s, xml, vals, _ = builder(n, steps)
        vals = values_of(vals)
        paths = [("", tree.TREE_MAX)] + ([("recursive_", -1)] if recursive else [])
        # the tree path at every size (a few dofs would otherwise take the recursive one)
        tree.RECURSIVE_MAX, keep_recursive = 0, tree.RECURSIVE_MAX
        fns = []
        for label, tmax in paths:
            tree.TREE_MAX, keep = tmax, tree.TREE_MAX
            sim = build_simulator(s)
            f, t_c = compile_cpu_s(jax.jit(lambda v, sim=sim: sim.simulate(v).body_pos), vals)
            tree.TREE_MAX = keep
            print(f"{kind}_scaling.{label}compile_cpu_s.{n}: {t_c:.1f}")
            fns.append(lambda f=f: contact.timed(f, vals, repeat=3))
        tree.RECURSIVE_MAX = keep_recursive
        model = mujoco.MjModel.from_xml_string(xml)
        *times, t_mj = side_by_side(fns + [lambda: mujoco_seconds_per_step(model)])
        for (label, _), t in zip(paths, times):
            per_step[label, n] = t / steps
            print(f"{kind}_scaling.{label}steps_per_s.{n}: {steps / t:.0f}")
        rate = 1.0 / t_mj
        per_step["mujoco_", n] = t_mj
        print(f"{kind}_scaling.mujoco_steps_per_s.{n}: {rate:.0f}")
        print(f"{kind}_scaling.ours_over_mujoco.{n}: {1 / (rate * per_step['', n]):.3f}",
              flush=True)
    a, b = sizes[0], sizes[-1]
    for label in ("", "recursive_", "mujoco_"):
        if (label, a) in per_step:
            k = np.log(per_step[label, b] / per_step[label, a]) / np.log(b / a)
            print(f"{kind}_scaling.{label}growth_exponent: {k:.2f}")


WELDED_SIZES = (1, 5, 10)


def welded_chain(n: int, steps: int) -> str:
    """.phys text: n hinged capsule links, a ball welded to each, no contacts, RK4."""
    lines = [f"scene welded_chain_{n} {{",
             f"  world {{ timestep: 1 ms  duration: {steps} ms  integrator: rk4 }}",
             "  param th0 ~ normal(0.3 rad, 0.1 rad)"]
    for k in range(n):
        z, parent = -0.1 * k, "world" if k == 0 else f"l{k - 1}"
        lines += [
            f"  body l{k} {{ shape: capsule(radius: 1 cm, length: 8 cm)  mass: 100 g  "
            f"position: (0, 0, {z - 0.05:.3f} m)  collide: false }}",
            f"  joint j{k}: hinge({parent} -> l{k}) {{ axis: (0, 1, 0)  anchor: (0, 0, {z:.3f}) m"
            f"  initial: {'th0' if k == 0 else '0.1 rad'} }}",
            f"  body w{k} {{ shape: sphere(radius: 1 cm)  mass: 50 g  "
            f"position: (0.02 m, 0, {z - 0.09:.3f} m)  collide: false }}",
            f"  joint f{k}: fixed(l{k} -> w{k})"]
    return "\n".join(lines + ["}"])


def welded(steps: int = 2000):
    """``welded.*.N`` lines: steps/s of ``welded_chain(N)`` with the welds merged (wherever
    there are any) and with every body stepped, side by side, and ``welded.pays.N``: whether
    physdsl merges them there (``welds.pays``, the rule these figures set)."""
    from physdsl import api
    from physdsl.physics import welds
    fuse, pays = welds.fuse, welds.pays
    for n in WELDED_SIZES:
        fns = []
        for label, fz in (("merged", fuse), ("every_body", lambda model: None)):
            welds.fuse, welds.pays = fz, (lambda core: True)
            sim = build_simulator(api.load(welded_chain(n, steps)))
            vals = {"th0": jnp.asarray(0.3)}
            f, t_c = compile_cpu_s(jax.jit(lambda v, sim=sim: sim.simulate(v).body_pos), vals)
            print(f"welded.{label}.compile_cpu_s.{n}: {t_c:.1f}")
            fns.append(lambda f=f, vals=vals: contact.timed(f, vals, repeat=3))
            welds.fuse, welds.pays = fuse, pays
        t_merged, t_every = side_by_side(fns)
        model = build_simulator(api.load(welded_chain(n, steps))).model
        print(f"welded.pays.{n}: {int(welds.fuse(model) is not None)}")
        print(f"welded.merged.steps_per_s.{n}: {steps / t_merged:.0f}")
        print(f"welded.every_body.steps_per_s.{n}: {steps / t_every:.0f}")
        print(f"welded.merged_over_every_body.{n}: {t_every / t_merged:.2f}", flush=True)


def profile():
    """``--profile``: where one step's time goes (``step_profile``), chains and balls."""
    cases = [("chain", chain_n, n, 200) for n in CHAIN_SIZES] + \
            [("balls", balls_n, n, 100) for n in (4, 16, 32)]
    for kind, builder, n, steps in cases:
        s, _, vals, _ = builder(n, steps)
        sim = build_simulator(s)
        for stage, us in step_profile.profile(sim, values_of(vals)).items():
            unit = "" if stage == "compile_cpu_s" else "_us_per_step"
            print(f"profile.{kind}{n}.{stage}{unit}: {us:.2f}", flush=True)


# rounds of ``side_by_side``: each figure is its best over this many rounds, taken in turn
ROUNDS = 5


def side_by_side(timers, rounds=ROUNDS):
    """Each timer's best over ``rounds`` rounds that call every timer in turn: on this shared
    machine the clock rate drifts over seconds, and figures taken minutes apart (ours, then
    MuJoCo's) moved a ratio by 1.6x between two runs of the same code."""
    best = [np.inf] * len(timers)
    for _ in range(rounds):
        for k, timer in enumerate(timers):
            best[k] = min(best[k], timer())
    return best


def mujoco_seconds_per_step(model, steps=2000):
    """Seconds per mj_step call (best of 3 runs of ``steps`` from the initial state)."""
    best = np.inf
    for _ in range(3):
        d = mujoco.MjData(model)
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, d)
        best = min(best, time.perf_counter() - t0)
    return best / steps


def float32_main(out_dir: str):
    """(Run under PHYSDSL_FLOAT32=1.) Time each scene's rollout; save its body positions."""
    assert jnp.result_type(float) == jnp.float32, "set PHYSDSL_FLOAT32=1"
    for name in SCENES:
        _, vals, fwd, _ = single(name)
        t_f = contact.timed(fwd, vals, repeat=3)
        np.save(Path(out_dir) / f"{name}.npy", np.asarray(fwd(vals)))
        print(f"{name} {t_f!r}", flush=True)


def float32_lines(results):
    """float32_speedup and float32_max_pos_err_m per scene (x64 is a process-wide switch, so
    float32 runs in a subprocess)."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PHYSDSL_FLOAT32": "1"}
        out = subprocess.run([sys.executable, __file__, "--float32", tmp], env=env,
                             capture_output=True, text=True, timeout=240)
        if out.returncode:
            print(f"float32_error: {out.stderr.strip().splitlines()[-1:]}")
            return
        for line in out.stdout.splitlines():
            name, t32 = line.split()
            t64, pos64 = results[name]
            pos32 = np.load(Path(tmp) / f"{name}.npy")
            print(f"float32_speedup.{name}: {t64 / float(t32):.2f}")
            print(f"float32_max_pos_err_m.{name}: {np.abs(pos32 - pos64).max():.1e}")


def main():
    if "--float32" in sys.argv:
        float32_main(sys.argv[sys.argv.index("--float32") + 1])
        return
    t0 = time.time()
    print(f"load_avg_1min_start: {os.getloadavg()[0]:.1f}")
    if "--profile" in sys.argv:
        profile()
        print(f"load_avg_1min_end: {os.getloadavg()[0]:.1f}")
        return
    if "--welded" in sys.argv:  # the welded lines alone
        welded()
        print(f"load_avg_1min_end: {os.getloadavg()[0]:.1f}")
        return
    if "--scaling" in sys.argv:  # the scaling lines alone
        scaling("chain", chain_n, CHAIN_SIZES, CHAIN_STEPS, recursive=True)
        scaling("contact", balls_n, BALL_SIZES, BALL_STEPS)
        print(f"load_avg_1min_end: {os.getloadavg()[0]:.1f}")
        return
    results = {name: bench(name) for name in SCENES}
    scaling("chain", chain_n, CHAIN_SIZES, CHAIN_STEPS, recursive=True)
    scaling("contact", balls_n, BALL_SIZES, BALL_STEPS)
    welded()
    float32_lines(results)
    contact.main()
    print(f"load_avg_1min_end: {os.getloadavg()[0]:.1f}")
    print(f"benchmark_wall_s: {time.time() - t0:.0f}")
    print(f"benchmark_cpu_s: {time.process_time():.0f}")


if __name__ == "__main__":
    main()
