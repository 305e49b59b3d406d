"""The .phys language: parse text to an AST, resolve it to a checked Scene, print it back.

``parse`` -> ``ast.Module``; ``load``/``loads`` -> ``physdsl.scene.Scene``; ``format_source``
-> canonical text; ``unknowns_table`` -> the unknowns as a text table.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import expr as E
from ..errors import PhysImportError
from ..scene import Scene
from . import ast, dists
from .parser import parse
from .printer import format_module, format_prior
from .resolve import resolve

__all__ = ["ast", "parse", "load", "loads", "format_source", "unknowns_table", "unknowns_rows"]


def loads(text: str, filename: str = "<string>", base_dir: str | Path | None = None,
          allowed_paths=()) -> Scene:
    """The checked Scene of .phys ``text``; data files and imports are found in ``base_dir``
    and below it (or the stdlib, or below a folder of ``allowed_paths``)."""
    module = parse(text, filename)
    base = Path(base_dir) if base_dir is not None else Path(".")
    path = Path(filename) if filename and not filename.startswith("<") else None
    return resolve(module, text, base, path, allowed_paths)


def load(path: str | Path, allowed_paths=()) -> Scene:
    """Read, parse and resolve a .phys file (data paths relative to the file, inside its folder
    tree unless ``allowed_paths`` names other folders)."""
    p = Path(path)
    if p.suffix != ".phys":  # a parse error would print a line of whatever file this is
        raise PhysImportError(f"{p} is not a .phys file", hint="a scene is a .phys file")
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PhysImportError(f"file not found: {p}", hint="check the path") from None
    except (OSError, UnicodeDecodeError) as ex:
        raise PhysImportError(f"cannot read {p}: {ex}") from None
    return loads(text, str(path), p.parent, allowed_paths)


def format_source(text: str, filename: str = "<string>") -> str:
    """Canonical text of a .phys source (comments kept)."""
    return format_module(parse(text, filename), text)


def unknowns_rows(scene: Scene) -> list[tuple[str, str, str, str, str, str]]:
    """(name, prior, support, shape, unit, used in) for each unknown."""
    rows = []
    for u in scene.unknowns:
        support = _support(u)
        shape = "scalar" if u.shape == () else "x".join(map(str, u.shape))
        if u.per_experiment and scene.experiments is not None:  # one per recording
            shape = f"{shape} per experiment ({len(scene.experiments.recordings)})"
        rows.append((u.name, format_prior(u.prior), support, shape, u.unit, ", ".join(u.used_in)))
    return rows


def _support(u) -> str:
    obj = dists.find(u.prior.dist)
    if obj is None:
        return "?"
    try:
        args = [np.asarray(E.evaluate(a, {}) if E.is_constant(a) else 1.0) for a in u.prior.args]
        kwargs = {k: np.asarray(E.evaluate(v, {}) if E.is_constant(v) else 1.0)
                  for k, v in u.prior.kwargs}
    except Exception:  # noqa: BLE001
        return "?"
    return ("discrete, " if u.discrete else "") + dists.draw_info(obj, args, kwargs)[2]


def unknowns_table(scene: Scene) -> str:
    """The unknowns as an aligned plain-text table."""
    head = ("name", "prior", "support", "shape", "unit", "used in")
    rows = [head] + unknowns_rows(scene)
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
