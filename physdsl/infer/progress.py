"""Progress per stage (compile, warmup, sampling) with iterations per second, via rich."""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


class _Stage:
    def __init__(self, progress, task, name):
        self.progress, self.task, self.name = progress, task, name
        self.start = time.perf_counter()
        self.count = 0
        self.note = ""

    def advance(self, n: int) -> None:
        self.count += n
        if self.progress is not None:
            rate = self.count / max(time.perf_counter() - self.start, 1e-9)
            self.progress.update(self.task, advance=n, rate=f"{rate:,.1f} it/s")

    def done(self, note: str) -> None:
        self.note = note


class Stages:
    """Context managers that show one progress line per stage on stderr."""

    def __init__(self, enabled: bool = True):
        self.enabled = enabled and sys.stderr.isatty()
        self.console = Console(stderr=True)

    @contextmanager
    def stage(self, name: str, total: int | None = None, completed: int = 0):
        if not self.enabled:
            st = _Stage(None, None, name)
            yield st
            return
        with Progress(TextColumn("[bold]{task.description:>9}"), BarColumn(),
                      MofNCompleteColumn(), TextColumn("{task.fields[rate]}"),
                      TimeElapsedColumn(), console=self.console, transient=False) as progress:
            task = progress.add_task(name, total=total, completed=completed, rate="")
            st = _Stage(progress, task, name)
            yield st
            if total is None:
                progress.update(task, total=1, completed=1, rate=st.note)
