"""Where the language's own files are: the grammar and the standard library.

A wheel installs them inside the package (``physdsl/grammar``, ``physdsl/stdlib``; see
setup.py); in a checkout (and an editable install) they are at the repository root.
"""
from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent.parent


def shipped_dir(name: str) -> Path:
    """The folder ``name`` ("grammar" or "stdlib"): inside the installed package, else the checkout's."""
    installed = _PACKAGE / name
    return installed if installed.is_dir() else _PACKAGE.parent / name


GRAMMAR_DIR = shipped_dir("grammar")
STDLIB_DIR = shipped_dir("stdlib")
