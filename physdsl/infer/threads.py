"""Independent compiled calls side by side on the CPU's cores, from Python threads.

XLA runs calls made from different threads at once (a compiled program runs without the
GIL), so a fit's chains, its starts and its posterior draws share the cores with the
programs compiled once: a process pool would trace and compile each again (or load it from
the cache) per worker. Measured on the 2-core machine: 400 posterior draws of the README's
thrown ball in 1.19 s from one thread, 0.64 s from two.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor


def workers() -> int:
    """Threads to use: ``PHYSDSL_THREADS`` where set, else the cores this process may use."""
    given = os.environ.get("PHYSDSL_THREADS")
    if given:
        return max(1, int(given))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (not on Linux)
        return max(1, os.cpu_count() or 1)


def thread_map(fn, items) -> list:
    """``[fn(item) for item in items]``, the calls spread over ``workers()`` threads (in
    order; an exception of any call is raised here). An interrupt (``interrupt``: raised in
    the main thread while it waits) cancels the calls not yet started and does not wait for
    the running ones, which the callers keep to about a second (``blocks.Pacer``)."""
    items = list(items)
    n = min(workers(), len(items))
    if n <= 1:
        return [fn(item) for item in items]
    pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="physdsl")
    try:
        out = list(pool.map(fn, items))
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return out


def split(items, parts: int) -> list[list]:
    """``items`` cut into at most ``parts`` runs of consecutive items of near-equal length."""
    items = list(items)
    parts = max(1, min(parts, len(items)))
    size, extra = divmod(len(items), parts)
    out, start = [], 0
    for k in range(parts):
        end = start + size + (k < extra)
        out.append(items[start:end])
        start = end
    return [p for p in out if p]
