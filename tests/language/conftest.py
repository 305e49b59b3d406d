"""Shared helpers for the language tests: data folders and an in-process CLI runner."""
from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).resolve().parent.parent.parent


def run_cli(args, capsys) -> tuple[int, str, str]:
    """Run ``physdsl ARGS`` in-process; (exit code, stdout, stderr)."""
    from physdsl.cli import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def first_error(stderr: str) -> str:
    """The first error block of a rendered report (up to the first blank line)."""
    return stderr.strip("\n").split("\n\n")[0].rstrip() + "\n"


@pytest.fixture
def cli(capsys):
    return lambda *args: run_cli(args, capsys)
