"""One job of a batch as a worker runs it: fit, refine or sample one scene into its own folder.

A job's folder is finished when its done marker (``job.json``) exists: it is written last, after
every output (each written atomically by the command itself), so a job cut off anywhere (a
killed worker, a stopped batch) leaves no marker and runs again. A job that finds its marker
already there (a retry of an attempt that finished but whose worker died before answering)
returns it instead of running twice. Errors are caught here and returned as the job's record,
so one broken scene never stops the others.
"""
from __future__ import annotations

import json
import os
import shutil
import socket
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import jax

from .. import api, cache, io
from ..errors import PhysError

DONE = "job.json"  # the done marker, written last
FAILED = "failed.json"  # a failed attempt's record (the job runs again on restart)
ATTEMPTS = Path(".batch") / "attempts"  # under the batch folder: one file per attempt


@dataclass(frozen=True)
class Job:
    """What a worker needs to run one job (plain values: it travels by pickle to any machine)."""

    name: str  # the job's folder below the batch folder, e.g. 'throw-03'
    command: str  # infer | refine | sample
    scene: str  # the scene (or program) file, absolute
    folder: str  # the output folder, absolute
    attempts: str  # this job's folder of attempt markers, absolute
    cache_dir: str = "off"  # JAX's persistent compilation cache on the worker ('off': none)
    options: dict = field(default_factory=dict)  # the command's keyword arguments


def is_done(folder: str | os.PathLike) -> bool:
    """Whether a job's folder holds its done marker."""
    return (Path(folder) / DONE).is_file()


def run_job(job: Job) -> dict:
    """Run ``job`` in this process and return its record (also written to its folder)."""
    cache.configure(job.cache_dir)  # every job of a structure shares the compiled programs
    folder = Path(job.folder)
    if is_done(folder):
        return json.loads((folder / DONE).read_text(encoding="utf-8"))
    attempt = _mark_attempt(Path(job.attempts))
    if folder.exists():
        shutil.rmtree(folder)  # a cut-off attempt's leftovers
    started, start = time.time(), time.perf_counter()
    with compile_clock() as clock:
        try:
            RUNNERS[job.command](job, folder)
            status, error = "done", None
        except PhysError as err:
            status, error = "failed", err.render()
        except Exception as ex:  # noqa: BLE001 - reported in the batch's summary, others go on
            tail = "".join(traceback.format_exception(ex)[-3:]).rstrip()
            status, error = "failed", f"internal error: {type(ex).__name__}: {ex}\n{tail}"
    record = dict(name=job.name, command=job.command, scene=job.scene, status=status,
                  error=error, attempt=attempt, host=socket.gethostname(), pid=os.getpid(),
                  started=round(started, 3), wall_s=round(time.perf_counter() - start, 3),
                  **clock)
    io.write_json(folder / (DONE if status == "done" else FAILED), record)
    return record


def _mark_attempt(folder: Path) -> int:
    """Leave a marker for this attempt (named by host and pid); return the attempt's number."""
    folder.mkdir(parents=True, exist_ok=True)
    io.write_text(folder / f"{socket.gethostname()}-{os.getpid()}-{time.time_ns()}", "")
    return sum(1 for p in folder.iterdir() if not p.name.startswith("."))


def _infer(job: Job, folder: Path) -> None:
    api.infer(api.compile(job.scene), outdir=folder, force=True, progress=False, **job.options)


def _refine(job: Job, folder: Path) -> None:
    lines: list[str] = []
    try:
        api.refine(job.scene, folder, force=True, progress=False, echo=lines.append,
                   **job.options)
    finally:
        if folder.is_dir():
            io.write_text(folder / "refine.log", "\n".join(lines) + "\n")


def _sample(job: Job, folder: Path) -> None:
    options = dict(job.options)
    api.sample(job.scene, options.pop("n"), outdir=folder, force=True, **options)


RUNNERS = {"infer": _infer, "refine": _refine, "sample": _sample}

# JAX's compile events, summed per job: XLA compilation (or loading the program from the
# persistent cache: the cache is read inside this event) and tracing + lowering to MLIR.
_DURATIONS = {"/jax/core/compile/backend_compile_duration": "compile_s",
              "/jax/core/compile/jaxpr_trace_duration": "trace_s",
              "/jax/core/compile/jaxpr_to_mlir_module_duration": "trace_s"}
_COUNTS = {"/jax/compilation_cache/cache_hits": "cache_hits",
           "/jax/compilation_cache/cache_misses": "cache_misses"}
_TOTALS = {"compile_s": 0.0, "trace_s": 0.0, "cache_hits": 0, "cache_misses": 0}
_LISTENING: list[bool] = []


def _on_duration(event: str, duration: float, **_: object) -> None:
    if event in _DURATIONS:
        _TOTALS[_DURATIONS[event]] += duration


def _on_event(event: str, **_: object) -> None:
    if event in _COUNTS:
        _TOTALS[_COUNTS[event]] += 1


@contextmanager
def compile_clock() -> Iterator[dict]:
    """Yield a dict that holds, on exit, this block's compile seconds and cache hits/misses."""
    if not _LISTENING:  # once per process: JAX keeps its listeners for good
        jax.monitoring.register_event_duration_secs_listener(_on_duration)
        jax.monitoring.register_event_listener(_on_event)
        _LISTENING.append(True)
    before = dict(_TOTALS)
    figures: dict = {}
    try:
        yield figures
    finally:
        for key, value in _TOTALS.items():
            figures[key] = round(value - before[key], 3) if isinstance(value, float) \
                else value - before[key]
