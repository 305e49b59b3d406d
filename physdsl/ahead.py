"""Compiling ahead: XLA compiles a program in a background thread while this one goes on.

Most of a first ``refine`` is compiling, one program after another on one core, although
many programs are known before they run: a fit's posterior pass while its Gauss-Newton
program compiles, the score tests' program while the round is fitted, the second candidate
refit's programs while the first runs. ``Program.ahead(*args)`` traces and lowers a program
for those arguments here and hands XLA's compile (which releases the GIL) to a background
thread; calling the Program with arguments of the same types then runs that executable.
Tracing stays on the calling thread: numpyro's effect handlers are one stack per process.

A compile not yet started when its program is called is taken back and done by the caller
(it would otherwise wait behind the queue); a caller that must wait for a running one
compiles the next queued programs meanwhile, so both cores stay busy (except those queued
as needed ``later``, which could hold it up past its wait). A compile running when
the process exits is waited for (XLA aborts if the interpreter ends under a running compile;
those still queued are dropped), so only programs that will likely run should be prepared.
``PHYSDSL_COMPILE_AHEAD=off`` compiles everything where it is called, as JAX does.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import jax

from . import traces

ENV = "PHYSDSL_COMPILE_AHEAD"
OFF = ("off", "0", "false", "no")
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()
THREAD_NAME = "physdsl-compile"  # the background thread's name (a profiler tells it apart)
# programs prepared ahead, and of them: run (called), compiled by a caller that took them back
COUNTS = {"prepared": 0, "run": 0, "taken_back": 0}


def enabled() -> bool:
    """Whether ``ahead`` compiles in the background (``PHYSDSL_COMPILE_AHEAD`` not off)."""
    return os.environ.get(ENV, "").strip().lower() not in OFF


def _pool() -> ThreadPoolExecutor:
    """One background thread: the caller works on the other core (measured on two)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix=THREAD_NAME)
        return _POOL


def signature(args, static: tuple = ()) -> tuple:
    """What a compiled executable is specific to: the pytree structure, each leaf's shape,
    dtype and weak type, and the static arguments."""
    leaves, tree = jax.tree_util.tree_flatten(args)
    return tree, tuple(jax.typeof(x) for x in leaves), static


def _compile_unless_exiting(lowered):
    """The background thread's work: nothing once the main thread has ended (the process is
    exiting and waits for this thread: what is still queued will never be called)."""
    return lowered.compile() if threading.main_thread().is_alive() else None


def _traced(args) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(args))


class _Pending:
    """A lowered program and its compile: a Future from the background thread, or done here."""

    def __init__(self, lowered, later: bool = False):
        self.lowered = lowered
        self.later = later  # not taken back by a caller waiting for another (``ahead``)
        self.compiled = None
        self.lock = threading.Lock()  # a posterior pass calls its program from threads
        self.called = False
        COUNTS["prepared"] += 1
        self.future: Future = _pool().submit(_compile_unless_exiting, lowered)
        with _QUEUE_LOCK:
            _QUEUED.append(self)

    def _take_back(self) -> bool:
        """Compile here if the background thread has not started it (True: done here)."""
        if self.compiled is None and self.future.cancel():
            self.compiled = self.lowered.compile()
            self.lowered = None
            COUNTS["taken_back"] += 1
            return True
        return False

    def result(self):
        with self.lock:
            if not self.called:
                self.called = True
                COUNTS["run"] += 1
            if self.compiled is None and not self._take_back():
                # running in the background: meanwhile compile what is queued behind it
                while not self.future.done() and _take_back_next(self):
                    pass
                self.compiled = self.future.result()
                self.lowered = None
            _unqueue(self)
            return self.compiled


_QUEUED: list[_Pending] = []  # in submission order; a caller waiting for one compiles others
_QUEUE_LOCK = threading.Lock()


def _unqueue(p: _Pending) -> None:
    with _QUEUE_LOCK:
        if p in _QUEUED:
            _QUEUED.remove(p)


def _take_back_next(waiting: _Pending) -> bool:
    """Compile here the first queued program the background thread has not started."""
    with _QUEUE_LOCK:  # (those started or done can no longer be taken back)
        _QUEUED[:] = [p for p in _QUEUED if not (p.future.running() or p.future.done())]
        queued = list(_QUEUED)
    for p in queued:
        if p is not waiting and not p.later and p.lock.acquire(blocking=False):
            try:
                if p._take_back():
                    _unqueue(p)
                    return True
            finally:
                p.lock.release()
    return False


class Program:
    """``jax.jit(fn, static_argnums)`` whose compile for given arguments may be started ahead
    (``ahead``); called with arguments of those types it runs that executable, with any
    others (or tracers) it is the jitted function. With an ``identity`` (a name that says what
    it computes, the same in every process), its trace for given argument types is kept on
    disk and loaded by later processes instead of traced again (``physdsl.traces``)."""

    def __init__(self, fn, static_argnums: tuple[int, ...] = (), identity: str | None = None):
        self.fn = fn
        self.jitted = jax.jit(fn, static_argnums=static_argnums)
        self.static_argnums = tuple(static_argnums)
        self.identity = identity
        self._ahead: dict[tuple, _Pending] = {}
        self._stored: dict[tuple, traces.Stored | None] = {}
        self._storing = threading.Lock()  # one trace per types where threads call it first

    def _split(self, args):
        static = tuple(args[i] for i in self.static_argnums)
        dynamic = tuple(a for i, a in enumerate(args) if i not in self.static_argnums)
        return dynamic, static

    def _bound(self, static):
        """``fn`` of the dynamic arguments alone, ``static`` put back in their places."""
        def fn(*dynamic):
            args, rest = [], iter(dynamic)
            for i in range(len(dynamic) + len(static)):
                args.append(static[self.static_argnums.index(i)] if i in self.static_argnums
                            else next(rest))
            return self.fn(*args)
        return fn

    def _stored_program(self, dynamic, static, key) -> "traces.Stored | None":
        """The program kept on disk for arguments of ``key`` (loaded, or traced and written
        now), or None where there is none to keep (no identity, the cache off, no export)."""
        if self.identity is None or traces.folder() is None:
            return None
        if key not in self._stored:
            with self._storing:
                if key not in self._stored:
                    self._stored[key] = traces.load_or_export(self.identity,
                                                              self._bound(static), dynamic, key)
        return self._stored[key]

    def ahead(self, *args, later: bool = False) -> None:
        """Trace and lower for ``args`` (arrays or ``jax.ShapeDtypeStruct``s) now, compile in the
        background; nothing where that is off or already done for these types. ``later``: a
        program needed well after the ones queued before it, which a caller waiting for one
        of those does not compile meanwhile (it could outlast the wait and hold the caller up:
        the background thread compiles it, or its own first caller)."""
        if not enabled():
            return
        dynamic, static = self._split(args)
        key = signature(dynamic, static)
        if key not in self._ahead:
            stored = self._stored_program(dynamic, static, key)
            lowered = self.jitted.lower(*args) if stored is None else \
                stored.call.lower(*jax.tree_util.tree_leaves(dynamic))
            self._ahead[key] = _Pending(lowered, later)

    def _cache_size(self) -> int:
        """Executables made so far (jit's, as ``jax.jit``'s own count, those loaded from disk,
        and those ahead)."""
        loaded = sum(s.call._cache_size() for s in self._stored.values() if s is not None)
        return self.jitted._cache_size() + loaded + len(self._ahead)

    def __call__(self, *args):
        if self.identity is None and not self._ahead:
            return self.jitted(*args)  # (no signature to compute: jit's own fast path)
        dynamic, static = self._split(args)
        if _traced(dynamic):
            return self.jitted(*args)
        key = signature(dynamic, static)
        pending = self._ahead.get(key)
        stored = self._stored_program(dynamic, static, key)
        if stored is not None:
            return stored.run(stored.call if pending is None else pending.result(), dynamic)
        if pending is not None:
            return pending.result()(*dynamic)
        return self.jitted(*args)


class ProgramCache(dict):
    """Compiled stages by name, shared by everything of one scene structure (``compile.Compiled``),
    with the structure's ``identity``: ``build_once`` names the Programs built into it."""

    def __init__(self, identity: str | None = None):
        super().__init__()
        self.identity = identity


def build_once(cache: dict, key, build):
    """``cache[key]``, built once by ``build()``. A ``Program`` built into a ``ProgramCache``
    without an identity is named by the cache's identity and ``key``, so that its trace is kept
    across processes (``physdsl.traces``)."""
    if key not in cache:
        made = build()
        identity = getattr(cache, "identity", None)
        if isinstance(made, Program) and made.identity is None and identity is not None \
                and _plain(key):
            made.identity = f"{identity}/{key!r}"
        cache[key] = made
    return cache[key]


def _plain(key) -> bool:
    """Whether ``repr(key)`` is the same in every process (strings, numbers, tuples of them)."""
    if isinstance(key, tuple):
        return all(_plain(k) for k in key)
    return key is None or isinstance(key, (str, int, float, bool))
