"""Stopping a run on SIGINT or SIGTERM: at once, except inside a checkpoint's update.

While a run is in ``termination()``, the first SIGINT or SIGTERM raises ``Interrupted`` (a
KeyboardInterrupt) at the next Python instruction: between two compiled calls, which the
samplers keep to about a second each (``blocks.Pacer``). Inside ``critical()`` (the few
lines that update a checkpoint's draws and states together) it waits for the section's end,
so a checkpoint is never half-updated. The first signal also restores the handlers that were
in force before, so a second Ctrl-C raises KeyboardInterrupt at once and a second SIGTERM
ends the process. The CLI exits 128 + the signal's number (130 for SIGINT, 143 for SIGTERM),
the shell's convention for a process stopped by a signal.
"""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """A run stopped by ``signum``; ``note`` says what was kept (e.g. a checkpoint)."""

    def __init__(self, signum: int, note: str = ""):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.note = note


_state = {"active": False, "critical": 0, "pending": None, "old": {}}


def _restore() -> None:
    for sig, old in _state["old"].items():
        signal.signal(sig, old)
    _state["old"] = {}


def _handler(signum, frame):
    _restore()  # a second signal acts at once
    if _state["critical"]:
        _state["pending"] = signum
        return
    raise Interrupted(signum)


@contextmanager
def termination():
    """SIGINT and SIGTERM raise ``Interrupted`` inside this block (main thread only; nested
    uses share the outer one's handlers)."""
    if _state["active"] or threading.current_thread() is not threading.main_thread():
        yield
        return
    _state.update(active=True, pending=None, old={s: signal.getsignal(s) for s in SIGNALS})
    for s in SIGNALS:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        _restore()
        _state.update(active=False, critical=0, pending=None)


@contextmanager
def critical():
    """A signal that arrives inside this block is acted on at its end."""
    _state["critical"] += 1
    try:
        yield
    finally:
        _state["critical"] -= 1
        pending = _state["pending"]
        if not _state["critical"] and pending is not None:
            _state["pending"] = None
            raise Interrupted(pending)


__all__ = ["Interrupted", "critical", "termination"]
