"""Import expansion and the effect library: stdlib effect declarations plus a file's imports.

Imports resolve against ``stdlib/`` first, then relative to the importing file, and only to
``.phys`` files inside the scene's bounds (syntax/bounds.py); a missing, outside or cyclic
import is a PhysImportError naming the chain. Every stdlib effect is known to every
scene; importing a stdlib file again is harmless.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from ..errors import PhysError, PhysErrors, PhysImportError, PhysNameError
from ..registry import EFFECT_DECLARATIONS
from . import ast
from .bounds import Bounds
from .parser import parse
from .shipped import STDLIB_DIR


@dataclass
class Loaded:
    """Everything imported: effect declarations and top-level params, with their files."""

    effect_types: dict[str, tuple[ast.EffectType, str]] = field(default_factory=dict)
    params: dict[str, tuple[ast.Param, str]] = field(default_factory=dict)
    seen: set[Path] = field(default_factory=set)
    sources: dict[str, str] = field(default_factory=dict)  # file name -> text, for errors


def display_name(path: Path) -> str:
    """A file name for messages: relative to the working folder when below it."""
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def find_import(path: str, importer_dir: Path | None, bounds: Bounds) -> Path | None:
    """stdlib first, then relative to the importing file; only files inside ``bounds`` (a file
    outside is never looked at, so an error cannot tell whether it exists)."""
    for base in (STDLIB_DIR, importer_dir):
        if base is None:
            continue
        cand = (base / path)
        if bounds.inside(cand) and cand.is_file():
            return cand.resolve()
    return None


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def expand(module: ast.Module, module_dir: Path | None, loaded: Loaded, chain: tuple[Path, ...],
           errors: list[PhysError], source: str, bounds: Bounds) -> None:
    """Load ``module``'s imports (recursively) and declarations into ``loaded``."""
    for item in module.items:
        if isinstance(item, ast.Import):
            target = find_import(item.path, module_dir, bounds)
            if target is None and module_dir is not None and not bounds.inside(module_dir / item.path):
                errors.append(bounds.outside(module_dir / item.path, "import", item.path, item.span,
                                             source))
                continue
            if target is not None and target.suffix != ".phys":
                errors.append(PhysImportError(
                    f"import \"{item.path}\" is not a .phys file", item.span,
                    hint="an import names a .phys library (effect_type, param and import lines)",
                    source=source))
                continue
            if target is None:
                where = f"stdlib/ or {module_dir}" if module_dir else "stdlib/"
                errors.append(PhysImportError(
                    f"cannot find import \"{item.path}\"", item.span,
                    hint=f"looked in {where}; stdlib effects need no import", source=source))
                continue
            if target in chain:
                names = " -> ".join(p.name for p in chain + (target,))
                errors.append(PhysImportError(f"cyclic import: {names}", item.span,
                                              hint="remove one of these imports", source=source))
                continue
            if target in loaded.seen:
                continue
            loaded.seen.add(target)
            try:
                text = _read(target)
                sub = parse(text, display_name(target))
            except PhysError as ex:
                errors.append(ex)
                continue
            except OSError as ex:
                errors.append(PhysImportError(f"cannot read import \"{item.path}\": {ex.strerror}",
                                              item.span, source=source))
                continue
            loaded.sources[display_name(target)] = text
            if sub.scene is not None:
                errors.append(PhysImportError(
                    f"imported file \"{item.path}\" holds a scene", item.span,
                    hint="an imported file may only hold effect_type, param and import lines",
                    source=source))
                continue
            expand(sub, target.parent, loaded, chain + (target,), errors, text, bounds)
        elif isinstance(item, ast.EffectType):
            old = loaded.effect_types.get(item.name)
            if old is not None and old[0].span != item.span:
                errors.append(PhysNameError(
                    f"effect '{item.name}' is declared twice (first at {old[0].span})",
                    item.span, source=source))
                continue
            loaded.effect_types[item.name] = (item, source)
        elif isinstance(item, ast.Param):
            old = loaded.params.get(item.name)
            if old is not None and old[0].span != item.span:
                errors.append(PhysNameError(
                    f"param '{item.name}' is defined twice (first at {old[0].span})", item.span,
                    source=source))
                continue
            loaded.params[item.name] = (item, source)


@lru_cache(maxsize=4)
def _stdlib_cached(stamp: tuple, plugins: tuple = ()) -> Loaded:
    loaded = Loaded()
    errors: list[PhysError] = []
    for f in sorted((STDLIB_DIR / "effects").glob("*.phys")):
        root = ast.Module((ast.Import(f"effects/{f.name}", None),), (), "<stdlib>")
        expand(root, STDLIB_DIR, loaded, (), errors, "", Bounds((STDLIB_DIR.resolve(),)))
    for name, text in plugins:  # plug-ins' effects: declared in their own modules
        try:
            expand(parse(text, f"<effect {name}>"), None, loaded, (), errors, text, Bounds(()))
        except PhysError as ex:
            errors.append(ex)
    if errors:
        raise errors[0] if len(errors) == 1 else PhysErrors(errors)
    return loaded


def stdlib() -> Loaded:
    """The standard library's effects and those of plug-ins (``registry.EFFECT_DECLARATIONS``,
    entry-point group ``physdsl.effects``); cached, reloaded when a stdlib file changes."""
    files = sorted((STDLIB_DIR / "effects").glob("*.phys"))
    stamp = tuple((str(f), f.stat().st_mtime_ns) for f in files)
    return _stdlib_cached(stamp, tuple(sorted(EFFECT_DECLARATIONS.items())))


def load_library(module: ast.Module, module_dir: Path | None, source: str,
                 errors: list[PhysError], self_path: Path | None = None,
                 bounds: Bounds | None = None) -> Loaded:
    """The stdlib plus ``module``'s own imports and declarations (found inside ``bounds``,
    by default the folder tree of ``module_dir``)."""
    if bounds is None:
        bounds = Bounds.around(module_dir if module_dir is not None else Path.cwd())
    base = stdlib()
    loaded = Loaded(dict(base.effect_types), dict(base.params), set(base.seen), dict(base.sources))
    chain = (self_path.resolve(),) if self_path is not None else ()
    expand(module, module_dir, loaded, chain, errors, source, bounds)
    return loaded
