"""Safe output: atomic writes and output folders that are never silently overwritten."""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .errors import UsageError


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (readers never see a half-written file)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON atomically."""
    return write_text(path, json.dumps(obj, indent=2, sort_keys=False, default=_json_default) + "\n")


def _json_default(obj: Any):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def prepare_outdir(path: str | Path, force: bool = False, resume: bool = False) -> Path:
    """Create output folder ``path``; refuse a non-empty one unless ``force`` or ``resume``."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UsageError(f"output '{path}' exists and is not a folder",
                         hint="choose another -o path")
    if path.exists() and any(path.iterdir()) and not (force or resume):
        raise UsageError(f"output folder '{path}' is not empty",
                         hint="pass --force to overwrite it, --resume to continue a run, "
                              "or choose another -o folder")
    path.mkdir(parents=True, exist_ok=True)
    return path


def refuse_overwrite(path: str | Path, force: bool = False) -> Path:
    """Refuse to replace an existing file unless ``force``."""
    path = Path(path)
    if path.exists() and not force:
        raise UsageError(f"'{path}' exists", hint="pass --force to overwrite it")
    return path
