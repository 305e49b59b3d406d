"""Progress per stage (compile, starts, warmup, Laplace, sampling, predictions, fit quality)
on stderr: a rich bar with elapsed time (and iterations per second) on a terminal; elsewhere
(a log, a pipe) one line as a stage begins and one as it ends, with its elapsed time."""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                           TimeElapsedColumn)


class _Stage:
    def __init__(self, stages, progress, task, name, total):
        self.stages, self.progress, self.task, self.name = stages, progress, task, name
        self.total = total
        self.start = time.perf_counter()
        self.count = 0
        self.note = ""
        self.finished = False

    def advance(self, n: int = 1) -> None:
        self.count += n
        if self.progress is not None:
            rate = self.count / max(time.perf_counter() - self.start, 1e-9)
            self.progress.update(self.task, advance=n, rate=f"{rate:,.1f} it/s")

    def done(self, note: str) -> None:
        self.note = note

    def say(self, what: str) -> None:
        """What the stage is doing now (e.g. which start it optimises), with the time so far."""
        if self.progress is not None:
            self.progress.update(self.task, rate=what)
        elif self.stages.plain:
            self.stages.say(f"{self.name}: {what} ({self.elapsed:.1f} s)")

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def stop(self) -> None:
        """End the stage early (an error or an interruption)."""
        if self.finished:
            return
        self.finished = True
        if self.progress is not None:
            self.progress.stop()
        elif self.stages.plain:
            self.stages.say(f"{self.name}: stopped after {self.elapsed:.1f} s")

    def finish(self) -> None:
        """End the stage (idempotent): the bar completes, or the plain 'done' line is printed."""
        if self.finished:
            return
        self.finished = True
        if self.progress is not None:
            if self.total is None:
                self.progress.update(self.task, total=1, completed=1, rate=self.note)
            self.progress.stop()
        elif self.stages.plain:
            note = f": {self.note}" if self.note else ""
            self.stages.say(f"{self.name}: done in {self.elapsed:.1f} s{note}")


class Stages:
    """One progress line per stage on stderr (``enabled``: a bar on a terminal, plain lines
    elsewhere; off: nothing)."""

    def __init__(self, enabled: bool = True, prefix: str = ""):
        self.enabled = enabled
        self.bars = enabled and sys.stderr.isatty()
        self.plain = enabled and not self.bars
        self.prefix = prefix
        self.console = Console(stderr=True)

    def say(self, line: str) -> None:
        print(f"{self.prefix}{line}", file=sys.stderr, flush=True)

    def start(self, name: str, total: int | None = None, completed: int = 0) -> _Stage:
        """Begin a stage; end it with ``finish()`` (or use ``stage`` as a context manager)."""
        if not self.bars:
            if self.plain:
                of = f" ({completed}/{total})" if total is not None and completed else \
                    (f" ({total})" if total is not None else "")
                self.say(f"{name}: started{of}")
            st = _Stage(self, None, None, name, total)
            st.count = completed
            return st
        columns = [TextColumn(f"[bold]{self.prefix}{{task.description:>11}}")]
        columns += [BarColumn(), MofNCompleteColumn()] if total is not None else [SpinnerColumn()]
        columns += [TextColumn("{task.fields[rate]}"), TimeElapsedColumn()]
        progress = Progress(*columns, console=self.console, transient=False)
        progress.start()
        task = progress.add_task(name, total=total, completed=completed, rate="")
        st = _Stage(self, progress, task, name, total)
        st.count = completed
        return st

    @contextmanager
    def stage(self, name: str, total: int | None = None, completed: int = 0):
        st = self.start(name, total, completed)
        try:
            yield st
        except BaseException:
            st.stop()
            raise
        st.finish()


@contextmanager
def stage(name: str, enabled: bool = True, total: int | None = None):
    """One stage of its own (``Stages(enabled).stage(name, total)``): for commands that run a
    single long step, e.g. a check's rollouts or a diagnosis's refits."""
    with Stages(enabled).stage(name, total) as st:
        yield st
