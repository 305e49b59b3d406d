"""Traced programs kept on disk: a second process loads a program instead of tracing it again.

JAX's persistent cache (``physdsl/cache.py``) keeps compiled executables, but finds them by the
traced program itself, so every process still traces and lowers each program first (the
pendulum's second ``infer``: about 5 s of tracing and 2 s of lowering). A ``Program`` with an
``identity`` (the scene's structure key and the program's name: ``compile.Compiled``) is traced
once, exported as StableHLO (``jax.export``) and written to ``<cache folder>/traces``; another
process with the same key deserializes it, and XLA's compile of it is a persistent-cache hit.

A stored program is found by a hash of: its identity, its arguments' tree and types, the
source of physdsl and of every plug-in module in its registries, the jax and jaxlib versions,
the x64 flag and the ``PHYSDSL_*``, ``JAX_*`` and ``XLA_*`` environment (``xla_flags.in_effect``
decides some traces). That is what a trace may depend on, as long as a program's name says
what it computes (as in one process, where ``Model.cached`` shares programs by name); a
module constant changed at run time (as tests patch them) is not seen: tests run without it.
A program that cannot be exported (a host callback) runs as ``jax.jit`` does; an entry that
cannot be written is kept for this process alone. ``PHYSDSL_TRACE_CACHE=off`` (or the
persistent cache off) turns this off.
"""
from __future__ import annotations

import functools
import hashlib
import logging
import os
import pickle
import sys
from pathlib import Path
from typing import NamedTuple, Optional

import jax
import jaxlib

from . import cache
from .io import write_bytes
from .registry import Registry

ENV = "PHYSDSL_TRACE_CACHE"
OFF = ("off", "0", "false", "no")
FORMAT = 1  # of a stored entry (pickled dict): bump when its layout changes
PACKAGE = Path(__file__).resolve().parent
# this process's programs loaded, exported and not exportable (tests read them)
COUNTS = {"loaded": 0, "exported": 0, "not_exportable": 0}
# environment variables that change nothing traced
_UNTRACED_ENV = ("PHYSDSL_CACHE_DIR", "PHYSDSL_THREADS", "PHYSDSL_COMPILE_AHEAD",
                 "JAX_COMPILATION_CACHE_DIR", "JAX_LOG_COMPILES", ENV)
log = logging.getLogger(__name__)


def folder() -> Optional[Path]:
    """Where traced programs are kept: ``traces`` in the persistent cache's folder, or None."""
    if os.environ.get(ENV, "").strip().lower() in OFF:
        return None
    root = cache.current()
    return None if root is None else root / "traces"


@functools.lru_cache(maxsize=None)
def _file_hash(path: str, mtime_ns: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _source_hash(files) -> str:
    h = hashlib.sha256()
    for f in sorted(set(files)):
        p = Path(f)
        if p.is_file():
            h.update(str(p.relative_to(PACKAGE) if p.is_relative_to(PACKAGE) else p.name).encode())
            h.update(_file_hash(str(p), p.stat().st_mtime_ns).encode())
    return h.hexdigest()


def _plugin_files() -> list[str] | None:
    """Source files of the modules outside physdsl that registered an entry (plug-ins); None
    where one has no file to read (its code could change unseen)."""
    files = []
    for reg in Registry.instances:
        for origin in set(reg._origin.values()):
            if origin.startswith("physdsl"):
                continue
            path = getattr(sys.modules.get(origin), "__file__", None)
            if not path:
                return None
            files.append(path)
    return files


def fingerprint() -> str | None:
    """What every stored program depends on besides its own key (see the module docstring);
    None where that cannot be known (a plug-in without a source file)."""
    plugins = _plugin_files()
    if plugins is None:
        return None
    env = sorted((k, v) for k, v in os.environ.items()
                 if k.startswith(("PHYSDSL_", "JAX_", "XLA_")) and k not in _UNTRACED_ENV)
    h = hashlib.sha256(repr((FORMAT, jax.__version__, jaxlib.__version__,
                             bool(jax.config.jax_enable_x64), env)).encode())
    h.update(_package_hash().encode())
    h.update(_source_hash(plugins).encode())
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def _package_hash() -> str:
    """physdsl's own source (read once a process)."""
    return _source_hash(PACKAGE.rglob("*.py"))


class Stored(NamedTuple):
    """A loaded program: ``call`` (jitted, over the flat argument leaves) and the output tree."""

    call: object
    out_tree: object

    def run(self, executable, dynamic):
        """The output tree of ``executable`` (this program's, or its compiled form) at
        ``dynamic``."""
        out = executable(*jax.tree_util.tree_leaves(dynamic))
        return jax.tree_util.tree_unflatten(self.out_tree, out)


def entry_key(identity: str, signature: tuple) -> str | None:
    """The file name (a hash) of the program ``identity`` for arguments of ``signature``; None
    where the fingerprint cannot be known."""
    common = fingerprint()
    if common is None:
        return None
    h = hashlib.sha256(common.encode())
    h.update(repr((identity, str(signature[0]), signature[1], repr(signature[2]))).encode())
    return h.hexdigest()


def load_or_export(identity: str, fn, dynamic, signature: tuple) -> Optional[Stored]:
    """``fn(*dynamic)`` as a stored program: read from the trace folder, or traced, exported and
    written there; None where tracing cannot be skipped (the folder off, no export)."""
    where = folder()
    key = None if where is None else entry_key(identity, signature)
    if key is None:
        return None
    path = where / f"{key}.trace"
    if path.exists():
        try:
            entry = pickle.loads(path.read_bytes())
            exported = jax.export.deserialize(bytearray(entry["exported"]))
            COUNTS["loaded"] += 1
            return Stored(jax.jit(exported.call), entry["out_tree"])
        except Exception as exc:  # a damaged or foreign entry: trace again and replace it
            log.info("trace cache entry %s unreadable (%s): tracing again", path.name, exc)
    leaves, in_tree = jax.tree_util.tree_flatten(dynamic)
    out_tree = []

    def flat(*xs):
        out, tree = jax.tree_util.tree_flatten(fn(*jax.tree_util.tree_unflatten(in_tree, xs)))
        out_tree.append(tree)
        return out

    try:
        exported = jax.export.export(jax.jit(flat))(*leaves)
        blob = pickle.dumps({"exported": bytes(exported.serialize()), "out_tree": out_tree[0]})
    except Exception as exc:  # host callbacks, effects: not exportable; jit traces it as ever
        COUNTS["not_exportable"] += 1
        log.info("program %s not exported (%s)", identity, exc)
        return None
    try:
        write_bytes(path, blob)
    except OSError as exc:  # a full or read-only folder: the next process traces it again
        log.info("trace cache entry %s not written (%s)", path.name, exc)
    COUNTS["exported"] += 1
    return Stored(jax.jit(exported.call), out_tree[0])
