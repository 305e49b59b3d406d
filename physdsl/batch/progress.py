"""A batch's progress on stderr: jobs done / running / failed and the time left.

On a terminal a rich bar (with an ETA from the jobs finished so far); elsewhere (a log, a pipe)
one line per finished job with the same counts. A failed job's error is printed as it fails.
"""
from __future__ import annotations

import time

from rich.console import Console
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                           TimeElapsedColumn, TimeRemainingColumn)


class BatchProgress:
    """Counts of a running batch, shown on stderr (``enabled=False``: silent)."""

    def __init__(self, total: int, skipped: int = 0, enabled: bool = True):
        self.total, self.skipped = total, skipped
        self.done = self.failed = self.running = 0
        self.start = time.perf_counter()
        self.console = Console(stderr=True, highlight=False)
        self.enabled = enabled
        self._bar = None
        if enabled and self.console.is_terminal and total:
            self._bar = Progress(
                TextColumn("batch"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[state]}"), TimeElapsedColumn(), TextColumn("ETA"),
                TimeRemainingColumn(), console=self.console, transient=False)
            self._task = self._bar.add_task("batch", total=total, state=self.state())
            self._bar.start()
        elif enabled:
            self.say(f"batch: {total} jobs to run" + (f", {skipped} finished before (skipped)"
                                                      if skipped else ""))

    def state(self) -> str:
        return f"done {self.done}  running {self.running}  failed {self.failed}"

    def eta(self) -> float | None:
        """Seconds left, from the mean time per finished job (None before the first)."""
        finished = self.done + self.failed
        if not finished:
            return None
        return (time.perf_counter() - self.start) / finished * (self.total - finished)

    def say(self, text: str) -> None:
        if self.enabled:
            self.console.print(text, markup=False, soft_wrap=True)

    def update(self, running: int) -> None:
        self.running = running
        if self._bar is not None:
            self._bar.update(self._task, state=self.state())

    def finished(self, record: dict, running: int) -> None:
        """One job ended (``record``: its record); ``running``: jobs still running."""
        ok = record["status"] == "done"
        self.done += ok
        self.failed += not ok
        self.running = running
        if ok:
            line = (f"{record['name']}: done in {record.get('wall_s', 0):.1f} s "
                    f"(compile {record.get('compile_s', 0):.1f} s)")
        else:
            line = f"{record['name']}: FAILED\n{record.get('error') or 'no error text'}"
        if self._bar is not None:
            self._bar.update(self._task, advance=1, state=self.state())
            if not ok:
                self._bar.console.print(line, markup=False, soft_wrap=True)
            return
        eta = self.eta()
        left = f", ETA {eta:.0f} s" if eta is not None and self.done + self.failed < self.total else ""
        self.say(f"[{self.state()}, {self.done + self.failed}/{self.total}{left}] {line}")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
