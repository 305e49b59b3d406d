"""A batch: one independent job per scene, run through an executor, each into its own folder.

``OUT/<name>/`` holds a job's outputs and, written last, its done marker; ``OUT/batch.json``
the batch's settings and every job's record (rewritten atomically as jobs finish, so a stopped
batch still says what it did). Running the same batch again into the same OUT skips finished
jobs and runs the rest (failed or never finished); other settings into the same OUT are
refused unless ``force``, which runs every job again.
"""
from __future__ import annotations

import glob
import json
import os
import shutil
import time
from concurrent.futures import FIRST_COMPLETED, Future, wait
from pathlib import Path
from typing import Iterable

from .. import cache, io
from ..errors import UsageError
from ..infer.interrupt import termination
from .executors import Executor, check_executor, make_executor
from .jobs import DONE, FAILED, ATTEMPTS, Job, is_done, run_job
from .progress import BatchProgress

SUMMARY = "batch.json"
COMMANDS = ("infer", "refine", "sample")


def find_scenes(patterns: Iterable[str]) -> list[Path]:
    """The scene files matched by glob ``patterns`` (``**`` spans folders), sorted, each once."""
    found: dict[Path, None] = {}
    patterns = list(patterns)
    for pattern in patterns:
        for hit in sorted(glob.glob(os.path.expanduser(pattern), recursive=True)):
            if Path(hit).is_file():
                found.setdefault(Path(hit).resolve(), None)
    if not found:
        raise UsageError(f"no scene file matches {' '.join(repr(p) for p in patterns)}",
                         hint="quote the pattern so the batch expands it, e.g. "
                              "--scenes 'throws/*/scene.phys'")
    return list(found)


def job_names(paths: list[Path]) -> list[str]:
    """A folder name per scene: its folder below the scenes' common folder when every scene
    has the same file name (``throws/03/scene.phys`` -> ``03``), else its path there without
    the suffix (``runs/a.phys`` -> ``a``)."""
    if len(paths) == 1:
        return [paths[0].parent.name if paths[0].stem == "scene" else paths[0].stem]
    root = Path(os.path.commonpath([p.parent for p in paths]))
    same_file = len({p.name for p in paths}) == 1 and all(p.parent != root for p in paths)
    if same_file:
        return [p.parent.relative_to(root).as_posix() for p in paths]
    return [p.relative_to(root).with_suffix("").as_posix() for p in paths]


def plan(command: str, patterns: Iterable[str], out: Path, options: dict,
         force: bool = False) -> list[Job]:
    """The batch's jobs (every scene matched), after checking OUT may take this batch."""
    if command not in COMMANDS:
        raise UsageError(f"unknown batch command '{command}'", hint=" | ".join(COMMANDS))
    scenes = find_scenes(patterns)
    _check_out(out, command, options, force)
    folder = cache.current()
    cache_dir = os.fspath(folder) if folder is not None else "off"
    return [Job(name=name, command=command, scene=os.fspath(scene),
                folder=os.fspath(out / name),
                attempts=os.fspath(out / ATTEMPTS / name.replace("/", "__")),
                cache_dir=cache_dir, options=options)
            for name, scene in zip(job_names(scenes), scenes)]


def _settings(command: str, options: dict) -> dict:
    return json.loads(json.dumps({"command": command, "options": options}, default=str))


def _check_out(out: Path, command: str, options: dict, force: bool) -> None:
    """Refuse an OUT that holds something else than this batch (unless ``force``)."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"output '{out}' exists and is not a folder", hint="choose another -o")
    if force or not out.exists() or not any(out.iterdir()):
        return
    summary = out / SUMMARY
    if not summary.is_file():
        raise UsageError(f"output folder '{out}' is not empty and holds no {SUMMARY}",
                         hint="choose another -o folder, or pass --force to write into it")
    before = json.loads(summary.read_text(encoding="utf-8"))
    if _settings(before.get("command"), before.get("options")) != _settings(command, options):
        raise UsageError(f"'{out}' holds a batch with other settings "
                         f"({before.get('command')} {before.get('options')})",
                         hint="run it with the same command and options to finish it, pass "
                              "--force to run every job again with these, or choose another -o")


def run_batch(command: str, patterns: Iterable[str], out: str | os.PathLike,
              options: dict | None = None, executor: str | Executor = "local", *,
              address: str | None = None, workers: int | None = None, retries: int = 3,
              force: bool = False, progress: bool = True) -> dict:
    """Run ``command`` (infer, refine, sample) on every scene matching ``patterns``, one job
    each, into ``out``; return the summary (also written to ``out/batch.json``).

    ``executor``: ``local`` (a process pool of ``workers``), ``ray`` (Ray at ``address``,
    a killed worker's job retried ``retries`` times) or an Executor. Finished jobs of an
    earlier run into ``out`` are skipped (``force``: all run again)."""
    out, options = Path(out), dict(options or {})
    patterns = list(patterns)
    if isinstance(executor, str):
        check_executor(executor, address)
    jobs = plan(command, patterns, out, options, force)
    if force:
        for job in jobs:
            Path(job.folder, DONE).unlink(missing_ok=True)
    finished = [job for job in jobs if is_done(job.folder)]
    todo = [job for job in jobs if not is_done(job.folder)]
    for job in todo:
        shutil.rmtree(job.attempts, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    head = dict(_settings(command, options), scenes=patterns, cache_dir=jobs[0].cache_dir,
                started=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    skipped = [dict(_read_record(job), skipped=True) for job in finished]
    records: list[dict] = []
    start = time.perf_counter()
    pool = None
    with termination():  # SIGTERM too stops the batch with its summary written
        try:
            if todo:
                if executor == "local":  # no idle processes: at most one per job
                    workers = min(workers or os.cpu_count() or 1, len(todo))
                pool = executor if not isinstance(executor, str) else \
                    make_executor(executor, address, workers, retries)
                head["executor"] = pool.describe()
            _write_summary(out, head, skipped, records, start, "running")
            if todo:
                _collect(pool, todo, out, head, skipped, records, start,
                         BatchProgress(len(todo), len(finished), enabled=progress))
        except KeyboardInterrupt:
            if pool is not None:
                pool.shutdown(cancel=True)
                pool = None
            _write_summary(out, head, skipped, records, start, "interrupted")
            raise
        finally:
            if pool is not None and pool is not executor:
                pool.shutdown()
    return _write_summary(out, head, skipped, records, start, "finished")


def _collect(pool: Executor, todo: list[Job], out: Path, head: dict, skipped: list[dict],
             records: list[dict], start: float, shown: BatchProgress) -> None:
    """Submit every job; add their records to ``records`` as they finish (the summary kept
    up to date, also when the batch is interrupted)."""
    futures: dict[Future, Job] = {pool.submit(run_job, job): job for job in todo}
    pending = set(futures)
    try:
        while pending:
            ended, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            for future in ended:
                record = _record_of(future, futures[future])
                records.append(record)
                shown.finished(record, running=min(len(pending), pool.slots))
                _write_summary(out, head, skipped, records, start, "running")
            shown.update(running=min(len(pending), pool.slots))
    finally:
        shown.close()


def _record_of(future: Future, job: Job) -> dict:
    """The job's record, or a failure record where its worker was lost (retries spent)."""
    try:
        return future.result()
    except Exception as ex:  # noqa: BLE001 - a lost worker fails its job, not the batch
        record = dict(name=job.name, command=job.command, scene=job.scene, status="failed",
                      error=f"the worker running this job was lost: {type(ex).__name__}: {ex}")
        io.write_json(Path(job.folder) / FAILED, record)
        return record


def _read_record(job: Job) -> dict:
    return json.loads(Path(job.folder, DONE).read_text(encoding="utf-8"))


def _write_summary(out: Path, head: dict, skipped: list[dict], records: list[dict],
                   start: float, state: str) -> dict:
    """``batch.json``: the settings, counts, throughput and every job's record (by name)."""
    wall = time.perf_counter() - start
    done = [r for r in records if r["status"] == "done"]
    failed = [r for r in records if r["status"] != "done"]
    summary = dict(
        head, state=state, wall_s=round(wall, 3),
        counts={"done": len(done), "failed": len(failed), "skipped": len(skipped)},
        fits_per_hour=round(len(done) / wall * 3600, 1) if done and wall > 0 else None,
        compile_s_total=round(sum(r.get("compile_s", 0.0) for r in records), 3),
        failed=[r["name"] for r in sorted(failed, key=lambda r: r["name"])],
        jobs=sorted(skipped + records, key=lambda r: r["name"]))
    io.write_json(out / SUMMARY, summary)
    return summary
