"""Installing a plug-in at test time, as pip would leave it: its module and a .dist-info whose
entry_points.txt names it, on sys.path; the registries it fills are looked at again and put
back afterwards, so other tests see no plug-in (tests/test_plugin_*.py)."""
from __future__ import annotations

import sys
from contextlib import contextmanager


def install(folder, monkeypatch, module: str, source: str | None, entry_points: dict) -> None:
    """``module`` (its ``source``; None: already on a path) and a .dist-info declaring
    ``entry_points`` ({group: "name = target" line}) in ``folder``, put on sys.path."""
    if source is not None:
        (folder / f"{module}.py").write_text(source)
    dist = folder / f"{module}-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "".join(f"[{group}]\n{line}\n" for group, line in entry_points.items()))
    monkeypatch.syspath_prepend(str(folder))


@contextmanager
def looked_at_again(registries, modules=()):
    """The ``registries`` rediscover their entry points inside the block and are restored (and
    the plug-in ``modules`` forgotten) after it."""
    saved = [(r, {k: dict(v) if isinstance(v, dict) else v for k, v in vars(r).items()})
             for r in registries]
    for r, _ in saved:
        r.rediscover()
    try:
        yield
    finally:
        for r, state in saved:
            vars(r).update(state)
        for module in modules:
            sys.modules.pop(module, None)
