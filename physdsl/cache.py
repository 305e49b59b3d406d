"""JAX's persistent compilation cache, on by default: a second run of the same scene structure
(new process, other data, cut-off or start values) loads its compiled programs from disk
instead of compiling them again.

Where: ``--cache-dir DIR`` (CLI) > ``PHYSDSL_CACHE_DIR`` > ``JAX_COMPILATION_CACHE_DIR`` (a
cache the user set up for JAX is kept) > the user's cache folder (platformdirs:
``$XDG_CACHE_HOME/physdsl/jax``, ``~/.cache/physdsl/jax``). ``off`` (or ``--no-cache``)
disables it. JAX writes each entry under a key that hashes the compiled program, the compile
options, the jax/XLA versions and the device, so a changed scene structure is a new entry,
never a stale hit. Entries are written atomically, so processes may share the folder.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

import jax
import platformdirs
from jax.experimental.compilation_cache import compilation_cache as cc

from .io import write_bytes

try:  # JAX's cache class, patched below to write entries atomically
    from jax._src import lru_cache
except ImportError:  # pragma: no cover - another jax layout: keep its own writes
    lru_cache = None

ENV = "PHYSDSL_CACHE_DIR"
OFF = ("off", "none", "0", "false", "no", "")

# Every program is written, however fast it compiled: with a time threshold, which programs are
# kept would depend on the machine's load, and a second run would still compile the rest.
MIN_COMPILE_S = 0.0


def default_dir() -> Path:
    """The per-user cache folder: ``<user cache dir>/physdsl/jax``."""
    return Path(platformdirs.user_cache_dir("physdsl", appauthor=False)) / "jax"


def resolve(cache_dir: Optional[str | os.PathLike] = None) -> Optional[Path]:
    """The folder to use, or None when caching is off (see the module docstring)."""
    choice = os.fspath(cache_dir) if cache_dir is not None else os.environ.get(ENV)
    if choice is None:
        jax_own = os.environ.get("JAX_COMPILATION_CACHE_DIR")
        return Path(jax_own) if jax_own else default_dir()
    if choice.strip().lower() in OFF:
        return None
    return Path(choice).expanduser()


def configure(cache_dir: Optional[str | os.PathLike] = None) -> Optional[Path]:
    """Point JAX's persistent cache at ``resolve(cache_dir)`` (or turn it off); return it.

    May be called again (the CLI's ``--cache-dir`` after the import-time default): JAX opens its
    cache lazily at the first compile, and is re-pointed here if it was already open.
    """
    path = resolve(cache_dir)
    if path == current():
        return path
    if path is None:
        jax.config.update("jax_enable_compilation_cache", False)
        jax.config.update("jax_compilation_cache_dir", None)
    else:
        jax.config.update("jax_enable_compilation_cache", True)
        jax.config.update("jax_compilation_cache_dir", os.fspath(path))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_S)
    cc.reset_cache()  # the next compile opens the cache at the new place (or none)
    _write_entries_atomically()
    return path


def _write_entries_atomically() -> None:
    """Make JAX's cache folder safe to share between processes.

    jax 0.10 writes an entry with ``Path.write_bytes`` (no lock unless a size limit is set and
    ``filelock`` is installed): another process may read it half written (JAX warns and
    compiles again), and a process killed while writing leaves a truncated entry that is never
    replaced. Entries are written to a temporary name and renamed instead (physdsl/io.py).
    Left alone where JAX's cache class is not the one this was written for.
    """
    if lru_cache is None:  # pragma: no cover
        return
    put = getattr(lru_cache.LRUCache, "put", None)
    suffix = getattr(lru_cache, "_CACHE_SUFFIX", None)
    if put is None or suffix is None or getattr(put, "physdsl_atomic", False):
        return

    def atomic_put(self, key: str, value: bytes) -> None:
        if getattr(self, "eviction_enabled", True) or not key:
            return put(self, key, value)  # JAX's own locked path (or its error)
        entry = self.path / f"{key}{suffix}"
        if not entry.exists():  # same key, same program: the first writer's copy is kept
            write_bytes(entry, value)

    atomic_put.physdsl_atomic = True
    lru_cache.LRUCache.put = atomic_put


def current() -> Optional[Path]:
    """The folder JAX's persistent cache uses now, or None when it is off."""
    if not jax.config.jax_enable_compilation_cache:
        return None
    folder = jax.config.jax_compilation_cache_dir
    return Path(folder) if folder else None
