"""Renderer throughput on CPU: frames per second after jit (fastest of several calls), compile
time, and the cost of a likelihood gradient relative to a forward render.

Run: .venv/bin/python benchmarks/render.py  (prints ``name: value`` lines)
"""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp

import physdsl  # noqa: F401
from physdsl.observe.image import image_log_likelihood
from physdsl.render import make_camera, make_light, make_objects, render


def _objects(n):
    xs = jnp.linspace(-0.2, 0.2, n)
    kinds = [i % 4 for i in range(n)]
    return make_objects(kinds, [[x, 0.0, 0.0] for x in xs], [[0.04, 0.04, 0.03]] * n,
                        [[0.8, 0.3, 0.2]] * n)


def _rate(fn, *args, repeat=5):
    """Calls per second of the fastest of ``repeat`` calls (robust to a busy machine)."""
    jax.block_until_ready(fn(*args))
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return 1.0 / best


def main():
    light = make_light([0.3, 0.5, -1.0])
    bg = jnp.array([0.8, 0.85, 0.9])
    t0 = time.perf_counter()
    cam = make_camera([0, -1.2, 0.2], [0, 0, 0], fovy=0.7, width=96, height=96)
    objs = _objects(8)
    jax.block_until_ready(render(objs, light, cam, bg, 0.5, kinds=tuple(int(k) for k in objs.kind)))
    print(f"compile_s.96.8obj: {time.perf_counter() - t0:.2f}")
    for size in (64, 96, 256):
        cam = make_camera([0, -1.2, 0.2], [0, 0, 0], fovy=0.7, width=size, height=size)
        for n in (1, 8):
            objs = _objects(n)
            kinds = tuple(int(k) for k in objs.kind)
            fwd = jax.jit(lambda o, cam=cam, kinds=kinds: render(o, light, cam, bg, 0.5,
                                                                 kinds=kinds))
            fps = _rate(fwd, objs, repeat=5 if size == 256 else 20)
            print(f"fps.{size}.{n}obj: {fps:.1f}")
            traced = jax.jit(lambda o, cam=cam: render(o, light, cam, bg, 0.5))
            print(f"fps_traced_kind.{size}.{n}obj: "
                  f"{_rate(traced, objs, repeat=5 if size == 256 else 20):.1f}")
            if n == 8 and size <= 96:
                target = fwd(objs)
                loss = jax.jit(jax.value_and_grad(
                    lambda p, o=objs, cam=cam, target=target, kinds=kinds: image_log_likelihood(
                        render(o._replace(pos=p), light, cam, bg, 0.5, kinds=kinds), target,
                        0.05)))
                gps = _rate(loss, objs.pos + 0.01)
                print(f"grad_over_forward.{size}: {fps / gps:.2f}")

if __name__ == "__main__":
    main()
