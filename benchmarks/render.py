"""Renderer throughput on CPU: frames per second after jit, and gradient cost relative to forward.

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
    jax.block_until_ready(fn(*args))
    t = time.perf_counter()
    for _ in range(repeat):
        jax.block_until_ready(fn(*args))
    return repeat / (time.perf_counter() - t)


def main():
    light = make_light([0.3, 0.5, -1.0])
    bg = jnp.array([0.8, 0.85, 0.9])
    for size in (64, 96, 256):
        cam = make_camera([0, -1.2, 0.2], [0, 0, 0], fovy=0.7, width=size, height=size)
        for n in (1, 8):
            objs = _objects(n)
            fwd = jax.jit(lambda o, cam=cam: render(o, light, cam, bg, 0.5))
            fps = _rate(fwd, objs, repeat=3 if size == 256 else 5)
            print(f"fps_{size}x{size}_{n}obj: {fps:.2f}")
            if size == 64:
                target = fwd(objs)
                loss = jax.jit(jax.value_and_grad(
                    lambda p, o=objs, cam=cam, target=target: image_log_likelihood(
                        render(o._replace(pos=p), light, cam, bg, 0.5), target, 0.05)))
                gps = _rate(loss, objs.pos + 0.01)
                print(f"grad_cost_ratio_{size}x{size}_{n}obj: {fps / gps:.2f}")


if __name__ == "__main__":
    main()
