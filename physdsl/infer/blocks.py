"""Many transitions per call: one jitted function advances every chain by up to ``length``
transitions (a ``fori_loop`` with the count as an argument; chains vmapped on an accelerator,
on the CPU one chain's program called from a thread per chain: ``chains_side_by_side``).

Python dispatches once per block of draws, not once per transition and chain, and no value
leaves the device in between. The count ``n`` is an argument and the buffers have the fixed
size ``length``, so warmup, every sampling block and the last, shorter block share one
compile; the data are an argument too, so Models of one structure share it as well.

Transition ``j`` of a chain (counted from the start of its stage) draws its random numbers
from ``fold_in(chain key, j)``, whatever the calls it was split into: calls are sized by the
measured time per transition (``Pacer``: about a second each, so a signal is acted on within
seconds, even on contact scenes whose transitions take long), and a run cut anywhere and
resumed gives the draws of an uninterrupted one.
"""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from .base import Problem, cached
from .threads import thread_map


def block_runner(problem: Problem, key, transition, length: int):
    """The compiled block of ``transition``, made once per Problem structure and ``key``.

    ``transition(data, key, carry, shared, i) -> (carry, out)`` advances one chain (``carry``:
    its state, adaptation state, tuning...) by one step; ``shared`` holds arguments common to
    the chains (e.g. an adaptation schedule indexed by ``i``). The returned function maps
    ``(data, keys (chains, 2), carries, shared, n, offset)`` to ``(carries, outs)`` where every
    leaf of ``outs`` is (chains, length, ...) and only the first ``n`` rows are filled; step
    ``i`` of a chain uses ``fold_in(its key, offset + i)``.
    """
    def build():
        def chain(data, k, carry, shared, n, offset):
            _, out_shape = jax.eval_shape(transition, data, k, carry, shared, 0)
            bufs = jax.tree_util.tree_map(lambda s: jnp.zeros((length, *s.shape), s.dtype),
                                          out_shape)

            def body(i, c):
                carry, bufs = c
                carry, out = transition(data, jax.random.fold_in(k, offset + i), carry, shared, i)
                return carry, jax.tree_util.tree_map(lambda b, o: b.at[i].set(o), bufs, out)

            return jax.lax.fori_loop(0, n, body, (carry, bufs))

        if not chains_side_by_side():
            one = jax.jit(chain)

            def chains(data, keys, carries, shared, n, offset):  # a thread a chain
                outs = thread_map(lambda c: one(data, keys[c], jax.tree_util.tree_map(
                    lambda a: a[c], carries), shared, n, offset), range(keys.shape[0]))
                return jax.tree_util.tree_map(lambda *a: jnp.stack(a), *outs)
            chains._cache_size = one._cache_size  # its compiles, as a jitted block's
            return chains
        return jax.jit(jax.vmap(chain, in_axes=(None, 0, 0, None, None, None)))

    return cached(problem, ("block", key, length), build)


def chains_side_by_side() -> bool:
    """Whether the chains of a block run vmapped (on an accelerator, in parallel) or each in
    its own call of a one-chain program, from threads (``threads``, on the CPU: the cores run
    chains at once). On the CPU vmapping buys no parallelism, runs every chain to the longest
    NUTS tree of the lot, and batching the tree's while loops around a rollout cost most of
    the block's tracing (the README's thrown ball, under a profiler: 40 of 50 s)."""
    return jax.default_backend() != "cpu"


class Pacer:
    """How many transitions the next call may run to last about ``target`` seconds, from the
    time per transition measured on the calls so far (the first call, which compiles, and
    calls of unknown cost run ``first`` transitions)."""

    def __init__(self, target: float = 1.0, first: int = 1):
        self.target, self.first = target, first
        self.per: float | None = None  # seconds per transition, from the latest timed call
        self.calls = 0

    def next(self, remaining: int, cap: int) -> int:
        m = self.first if self.per is None else int(self.target / max(self.per, 1e-9))
        return max(1, min(m, remaining, cap))

    def record(self, m: int, seconds: float) -> None:
        self.calls += 1
        if self.calls > 1:  # the first call's time is mostly compilation
            self.per = seconds / max(m, 1)


_PACERS: dict = {}  # one Pacer per compiled block (id of the jitted function; both are kept)


def pacer_of(run) -> Pacer:
    """The Pacer of compiled block ``run`` (its time per transition outlives a stage)."""
    return _PACERS.setdefault(id(run), Pacer())


def run_blocks(run, problem: Problem, key, carries, n: int, length: int, shared_of=None,
               on_block=None, offset: int = 0):
    """Advance by ``n`` transitions in calls of at most ``length`` (fewer where ``Pacer``
    says a call would last over a second); the transitions are those numbered ``offset`` to
    ``offset + n - 1`` of the stage: their random numbers come from ``split(key, chains)`` and
    that number alone, so the draws do not depend on how the calls were cut. ``shared_of(
    start, m)`` (a call's first transition's index in the stage and count) gives the call's
    shared arguments; ``on_block(m)`` is called once each call's results are on the host (a
    progress bar). Returns (carries, outs of every transition, leaves (chains, n, ...))."""
    chains = jax.tree_util.tree_leaves(carries)[0].shape[0]
    keys = jax.random.split(key, chains)
    pacer = pacer_of(run)
    outs = []
    done = 0
    while done < n:
        m = pacer.next(n - done, length)
        start = offset + done
        shared = shared_of(start, m) if shared_of is not None else ()
        t0 = time.perf_counter()
        carries, out = run(problem.data, keys, strong(carries), shared, m, start)
        outs.append(jax.tree_util.tree_map(lambda a: np.asarray(a[:, :m]), out))
        pacer.record(m, time.perf_counter() - t0)
        done += m
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
