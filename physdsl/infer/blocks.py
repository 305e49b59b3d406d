"""Many transitions per call: one jitted function advances every chain by up to ``length``
transitions (a ``fori_loop`` with the count as an argument, chains vmapped).

Python dispatches once per block of draws, not once per transition and chain, and no value
leaves the device in between. The count ``n`` is an argument and the buffers have the fixed
size ``length``, so warmup, every sampling block and the last, shorter block share one
compile; the data are an argument too, so Models of one structure share it as well.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .base import Problem, cached


def block_runner(problem: Problem, key, transition, length: int):
    """The compiled block of ``transition``, made once per Problem structure and ``key``.

    ``transition(data, key, carry, shared, i) -> (carry, out)`` advances one chain (``carry``:
    its state, adaptation state, tuning...) by one step; ``shared`` holds arguments common to
    the chains (e.g. an adaptation schedule indexed by ``i``). The returned function maps
    ``(data, keys (chains, 2), carries, shared, n)`` to ``(carries, outs)`` where every leaf of
    ``outs`` is (chains, length, ...) and only the first ``n`` rows are filled; step ``i`` of a
    chain uses ``fold_in(its key, i)``.
    """
    def build():
        def chain(data, k, carry, shared, n):
            _, out_shape = jax.eval_shape(transition, data, k, carry, shared, 0)
            bufs = jax.tree_util.tree_map(lambda s: jnp.zeros((length, *s.shape), s.dtype),
                                          out_shape)

            def body(i, c):
                carry, bufs = c
                carry, out = transition(data, jax.random.fold_in(k, i), carry, shared, i)
                return carry, jax.tree_util.tree_map(lambda b, o: b.at[i].set(o), bufs, out)

            return jax.lax.fori_loop(0, n, body, (carry, bufs))

        return jax.jit(jax.vmap(chain, in_axes=(None, 0, 0, None, None)))

    return cached(problem, ("block", key, length), build)


def run_blocks(run, problem: Problem, key, carries, n: int, length: int, shared_of=None,
               on_block=None):
    """Advance by ``n`` transitions in calls of at most ``length``; block ``b`` uses
    ``fold_in(key, b)`` split over chains and ``shared_of(start, m)`` (its first transition's
    index and count); ``on_block(m)`` is called once each block's results are on the host (a
    progress bar). Returns (carries, outs of every transition, leaves (chains, n, ...))."""
    chains = jax.tree_util.tree_leaves(carries)[0].shape[0]
    outs = []
    for b, start in enumerate(range(0, n, length)):
        m = min(length, n - start)
        keys = jax.random.split(jax.random.fold_in(key, b), chains)
        shared = shared_of(start, m) if shared_of is not None else ()
        carries, out = run(problem.data, keys, strong(carries), shared, m)
        outs.append(jax.tree_util.tree_map(lambda a: np.asarray(a[:, :m]), out))
        if on_block is not None:
            on_block(m)
    if not outs:
        return carries, None
    return carries, jax.tree_util.tree_map(lambda *a: np.concatenate(a, axis=1), *outs)


def strong(tree):
    """``tree`` with weak-typed leaves (made from Python numbers, e.g. an initial step size)
    made strong: the compiled block returns them strong, and a weak and a strong leaf are two
    signatures, so the block compiled again for the second call, and for the third."""
    return jax.tree_util.tree_map(
        lambda a: a.astype(a.dtype) if getattr(a, "weak_type", False) else a, tree)
