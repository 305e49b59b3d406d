"""Where a batch's jobs run: one interface, two implementations.

An executor takes a function and its argument and returns a ``concurrent.futures.Future``, so
the batch waits on either kind with the standard library's ``wait``/``as_completed``:

- ``InlineExecutor``: this process, one job at a time (the future is done when submitted). No
  start-up cost: what a diagnosis's refits use by default (see ``refits``).
- ``LocalExecutor``: a process pool on this machine (``spawn``: JAX does not survive ``fork``).
  No set-up. A worker that dies breaks the pool: its jobs are reported failed, and a restarted
  batch runs them again.
- ``RayExecutor``: Ray tasks on a Ray cluster (``address`` HOST:PORT of its head; none: a Ray
  started for this batch on this machine). A worker that dies has its job retried by Ray
  (``max_retries``) on any node; the job's own errors are not retried (they are its result).
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Protocol

from ..diagnose import refit_task
from ..errors import UsageError

EXECUTORS = ("local", "ray", "inline")


class Executor(Protocol):
    """Runs ``fn(arg)`` somewhere; ``slots`` jobs at a time."""

    name: str
    slots: int

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> Future: ...

    def describe(self) -> dict: ...

    def shutdown(self, cancel: bool = False) -> None: ...


class InlineExecutor:
    """This process: ``fn(arg)`` runs when submitted (its error is the future's exception)."""

    name = "inline"
    slots = 1

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(arg))
        except Exception as ex:  # noqa: BLE001 - the caller reads it from the future
            future.set_exception(ex)
        return future

    def describe(self) -> dict:
        return {"executor": self.name, "workers": 1}

    def shutdown(self, cancel: bool = False) -> None:
        pass


class LocalExecutor:
    """A pool of ``workers`` processes on this machine (default: one per CPU)."""

    name = "local"

    def __init__(self, workers: int | None = None):
        self.slots = max(1, workers or os.cpu_count() or 1)
        self._pool = ProcessPoolExecutor(max_workers=self.slots,
                                         mp_context=multiprocessing.get_context("spawn"))

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> Future:
        return self._pool.submit(fn, arg)

    def describe(self) -> dict:
        return {"executor": self.name, "workers": self.slots}

    def shutdown(self, cancel: bool = False) -> None:
        self._pool.shutdown(wait=True, cancel_futures=cancel)


class RayExecutor:
    """Ray tasks (``num_cpus`` each, retried ``retries`` times if their worker dies)."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None,
                 retries: int = 3, num_cpus: float = 1.0):
        ray = _import_ray()
        self._ray, self.address, self.retries = ray, address, retries
        self._started = not ray.is_initialized()
        if self._started:
            _connect(ray, address, workers)
        self._options = dict(num_cpus=num_cpus, max_retries=retries, retry_exceptions=False)
        self._remote: dict[Callable, Any] = {}
        self._refs: list = []
        self.slots = max(1, int(ray.cluster_resources().get("CPU", 1) // num_cpus))

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> Future:
        if fn not in self._remote:
            self._remote[fn] = self._ray.remote(**self._options)(fn)
        ref = self._remote[fn].remote(arg)
        self._refs.append(ref)
        return ref.future()

    def describe(self) -> dict:
        return {"executor": self.name, "address": self.address or "local Ray",
                "cpus": self.slots, "max_retries": self.retries,
                "nodes": len([n for n in self._ray.nodes() if n.get("Alive")])}

    def shutdown(self, cancel: bool = False) -> None:
        if cancel:
            for ref in self._refs:
                self._ray.cancel(ref, force=True)
        if self._started:
            self._ray.shutdown()


def _import_ray():
    try:
        import ray
    except ImportError:
        raise UsageError("--executor ray needs Ray, which is not installed",
                         hint="pip install 'physdsl[ray]' (on every machine of the cluster)") from None
    return ray


def _connect(ray, address: str | None, workers: int | None) -> None:
    """Join the cluster at ``address``, or start a Ray on this machine (``workers`` CPUs)."""
    try:
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(address="local", num_cpus=workers, include_dashboard=False,
                     log_to_driver=False)  # "local": a new Ray, never one found running
    except (ConnectionError, RuntimeError, ValueError) as ex:
        raise UsageError(f"cannot reach a Ray cluster at {address or 'this machine'}: {ex}",
                         hint="start its head with `ray start --head --port PORT` and pass "
                              "--address HOST:PORT; a cluster with token authentication also "
                              "needs RAY_AUTH_MODE=token here (the token in ~/.ray/auth_token "
                              "or RAY_AUTH_TOKEN)") from None


def check_executor(name: str, address: str | None = None) -> None:
    """Refuse an unknown executor, or an address without Ray (before anything runs)."""
    if name not in EXECUTORS:
        raise UsageError(f"unknown executor '{name}'",
                         hint="local (a process pool), ray, or inline (this process)")
    if name != "ray" and address:
        raise UsageError("--address goes with --executor ray",
                         hint="add --executor ray, or leave --address out")


def make_executor(name: str, address: str | None = None, workers: int | None = None,
                  retries: int = 3) -> Executor:
    """The executor called ``name`` (``local`` or ``ray``)."""
    check_executor(name, address)
    if name == "inline":
        return InlineExecutor()
    return LocalExecutor(workers) if name == "local" else RayExecutor(address, workers, retries)


@contextmanager
def refits_on(name: str = "inline", address: str | None = None,
              workers: int | None = None) -> Iterator[None]:
    """Within this block, a diagnosis runs its first candidate refits on the executor
    ``name`` (``inline``: here, one after another, the default: on a machine of few cores
    the workers' start-up and tracing cost more than they save, see docs/scale.md)."""
    check_executor(name, address)
    if name == "inline":
        yield
        return
    pool = make_executor(name, address, workers)
    try:
        with refit_task.submitting(pool.submit):
            yield
    finally:
        pool.shutdown()
