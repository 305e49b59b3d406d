"""User-facing errors: every mistake in a scene or data file is a PhysError with a place and a hint.

Errors render like a compiler's: ``file:line:col: error: message``, the source line, a caret
under the spot, and a hint. The CLI prints them and exits 2 (input) or 1 (model/inference).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Span:
    """Where a thing sits in a source file (1-based lines and columns, end exclusive)."""

    file: str
    line: int
    column: int
    end_line: int | None = None
    end_column: int | None = None

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class PhysError(Exception):
    """Base of every error physdsl reports to a user; never shown as a traceback."""

    exit_code = 2
    kind = "error"

    def __init__(self, message: str, span: Span | None = None, hint: str | None = None,
                 source: str | None = None):
        super().__init__(message)
        self.message = message
        self.span = span
        self.hint = hint
        self.source = source  # the file's text, to show the line; read from disk if absent

    def render(self) -> str:
        """The error as a user sees it: place, message, source line with caret, hint."""
        head = f"{self.span}: " if self.span else ""
        lines = [f"{head}{self.kind}: {self.message}"]
        line_text = self._source_line()
        if line_text is not None and self.span is not None:
            num = str(self.span.line)
            pad = " " * len(num)
            lines.append(f"   {num} | {line_text}")
            start = max(self.span.column, 1)
            if self.span.end_line == self.span.line and self.span.end_column:
                width = max(self.span.end_column - start, 1)
            else:
                width = max(len(line_text.rstrip()) - start + 1, 1)
            lines.append(f"   {pad} | {' ' * (start - 1)}{'^' * width}")
        if self.hint:
            lines.append(f"hint: {self.hint}")
        return "\n".join(lines)

    def _source_line(self) -> str | None:
        if self.span is None:
            return None
        text = self.source
        if text is None:
            try:
                text = Path(self.span.file).read_text(encoding="utf-8", errors="replace")
            except OSError:
                return None
        rows = text.splitlines()
        if 1 <= self.span.line <= len(rows):
            return rows[self.span.line - 1].expandtabs(1)
        return None

    def __str__(self) -> str:
        return self.render()


class PhysSyntaxError(PhysError):
    """The text does not follow the .phys grammar."""


class PhysNameError(PhysError):
    """A name is unknown, duplicated or refers to the wrong kind of thing."""


class PhysUnitError(PhysError):
    """A unit is unknown or of the wrong dimension for the field."""


class PhysTypeError(PhysError):
    """A value has the wrong shape, kind or range (vector length, distribution argument, ...)."""


class PhysImportError(PhysError):
    """An import is missing or cyclic."""


class PhysStructureError(PhysError):
    """The scene's structure is wrong: joint cycles, two parents, missing parent, ..."""


class DataError(PhysError):
    """A measurement file is missing, malformed or disagrees with the scene; names file, row and column."""

    def __init__(self, message: str, file: str | Path, row: int | None = None,
                 column: str | None = None, hint: str | None = None, span: Span | None = None):
        where = str(file)
        if row is not None:
            where += f", row {row}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {message}", span=span, hint=hint)
        self.file = str(file)
        self.row = row
        self.column = column


class UsageError(PhysError):
    """The command line was used wrongly (bad option, output exists, unknown backend, ...)."""


class ModelError(PhysError):
    """The model cannot be built or simulated (unsupported contact pair, NaN everywhere, ...)."""

    exit_code = 1


class InferenceError(PhysError):
    """Inference failed (no valid initial point, all proposals rejected, ...)."""

    exit_code = 1


class PhysErrors(PhysError):
    """Several independent errors found in one pass; all are reported."""

    def __init__(self, errors: list[PhysError]):
        self.errors = list(errors)
        super().__init__(f"{len(self.errors)} errors", None, None)
        self.exit_code = max(e.exit_code for e in self.errors) if self.errors else 2

    def render(self) -> str:
        body = "\n\n".join(e.render() for e in self.errors)
        return f"{body}\n\n{len(self.errors)} error{'s' if len(self.errors) != 1 else ''} found"
