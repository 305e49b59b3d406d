"""Which files a scene may read: those in its own folder tree, the standard library's, and
those below folders the user allows (``--allow-path DIR``, ``allowed_paths=``).

A scene physdsl did not write (a shared service, a notebook server) must not read or echo
other files: an import or data path outside these folders is an error naming the path and
the flag, raised before the file is opened. Links are resolved before the check, so a link
inside the scene's folder that points elsewhere is outside.
"""
from __future__ import annotations

import contextvars
import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

from ..errors import PhysImportError, Span
from .shipped import STDLIB_DIR

# folders allowed for the whole of one command (the CLI's --allow-path), besides a call's own
_ALLOWED: contextvars.ContextVar[tuple[Path, ...]] = contextvars.ContextVar("allowed", default=())

HINT = ("a scene reads files in its own folder and below it, and the standard library; "
        "allow another folder with --allow-path DIR (Python: allowed_paths=[DIR])")


@contextmanager
def allowing(paths: Iterable[str | Path]) -> Iterator[None]:
    """Allow ``paths`` (folders) to every scene loaded inside the block."""
    token = _ALLOWED.set(_ALLOWED.get() + tuple(Path(p).resolve() for p in paths))
    try:
        yield
    finally:
        _ALLOWED.reset(token)


@dataclass(frozen=True)
class Bounds:
    """The folders one scene may read below (all resolved)."""

    roots: tuple[Path, ...]

    @classmethod
    def around(cls, scene_dir: str | Path, allowed_paths: Iterable[str | Path] = ()) -> Bounds:
        """The scene's folder, the standard library, ``allowed_paths`` and the command's."""
        extra = tuple(Path(p).resolve() for p in allowed_paths) + _ALLOWED.get()
        return cls((Path(scene_dir).resolve(), STDLIB_DIR.resolve()) + extra)

    def inside(self, path: Path) -> bool:
        real = path.resolve()
        return any(real.is_relative_to(root) for root in self.roots)

    def check(self, path: Path, what: str, written: str, span: Span | None,
              source: str | None) -> Path:
        """``path`` resolved, or the error naming it (as written) and the flag."""
        if self.inside(path):
            return path.resolve()
        raise self.outside(path, what, written, span, source)

    @staticmethod
    def outside(path: Path, what: str, written: str, span: Span | None,
                source: str | None) -> PhysImportError:
        """The error for ``path`` (written as ``written``) outside the bounds."""
        real = path.resolve()
        link = "" if Path(os.path.normpath(path.absolute())) == real else f" (a link to {real})"
        return PhysImportError(f"{what} \"{written}\" is outside the scene's folder{link}", span,
                               hint=HINT, source=source)
