"""Registries of extension points: name -> entry, one per kind of thing a package may add.

Each registry is filled by a decorator in the module that defines the thing (physdsl's own
modules register themselves when imported) and, on first look-up, by the Python entry points
of its group: a third-party package adds, say, an effect with one module that calls the
decorator and one line of packaging::

    [project.entry-points."physdsl.effects"]
    my_effect = "my_package.my_effect"

Loading the entry point imports the module (which registers its entries); an entry point that
names an object (``module:attr``) not registered by then is registered under the entry
point's name. Names are unique: a second entry under a taken name is refused.

A registry may also name its built-in entries as entry points of its own (``builtins``: name ->
module). Their names are known without importing anything (``names()``), so a lower floor can
check a name (the language checks ``world { contact: NAME }`` against the contact models
without importing physics); the module is imported on the first look-up of its entry.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib import import_module
from importlib.metadata import entry_points
from typing import Generic, TypeVar

from .errors import UsageError

T = TypeVar("T")


class RegistryError(UsageError):
    """Two entries under one name, or an entry point that cannot be loaded."""


class Registry(Mapping[str, T], Generic[T]):
    """Entries by name, filled by ``add`` (from decorators) and by the entry points of
    ``group``, which are loaded once, on the first look-up."""

    instances: list["Registry"] = []  # every registry made (``traces`` hashes their plug-ins)

    def __init__(self, group: str, what: str, builtins: Mapping[str, str] | None = None):
        Registry.instances.append(self)
        self.group = group
        self.what = what  # "effect", "inference backend", ... (for messages)
        self.builtins = dict(builtins or {})  # name -> module that registers it when imported
        self._entries: dict[str, T] = {}
        self._origin: dict[str, str] = {}  # name -> module that registered it
        self._discovered = False

    def add(self, name: str, entry: T, origin: str = "") -> T:
        """Register ``entry`` under ``name``; a name taken by another module is refused."""
        if name in self._entries and self._origin[name] != origin:
            raise RegistryError(
                f"{self.what} '{name}' is registered twice ({self._origin[name] or '?'} and "
                f"{origin or '?'})",
                hint=f"rename one of them; every {self.what} of group '{self.group}' needs its "
                     "own name")
        self._entries[name] = entry
        self._origin[name] = origin
        return entry

    def origin(self, name: str) -> str:
        """The module that registered ``name``."""
        self._discover()
        return self._origin[name]

    def names(self) -> tuple[str, ...]:
        """Every name the registry answers to, in order (built-ins, then those registered, then
        the entry points'), without importing any module."""
        plugged = [ep.name for ep in entry_points(group=self.group)]
        return tuple(dict.fromkeys([*self.builtins, *self._entries, *plugged]))

    def _load_builtin(self, name: str) -> None:
        """Import the module of built-in ``name`` (it registers itself)."""
        if name in self.builtins and name not in self._entries:
            import_module(self.builtins[name])

    def _discover(self) -> None:
        """Import the built-ins and load the entry points of ``group`` (once)."""
        if self._discovered:
            return
        self._discovered = True
        for name in self.builtins:
            self._load_builtin(name)
        for ep in entry_points(group=self.group):
            try:
                obj = ep.load()
            except Exception as exc:  # a broken plug-in: say which, never a bare traceback
                raise RegistryError(f"cannot load {self.what} '{ep.name}' ({ep.value}): {exc}",
                                    hint=f"entry point group '{self.group}'; fix or uninstall "
                                         "the package that declares it") from exc
            if ep.attr is not None and ep.name not in self._entries:
                self.add(ep.name, obj, ep.module)

    def rediscover(self) -> None:
        """Look at the entry points again at the next look-up (after installing a package)."""
        self._discovered = False

    def __getitem__(self, name: str) -> T:
        self._load_builtin(name)
        if name not in self._entries:
            self._discover()
        return self._entries[name]

    def __contains__(self, name: object) -> bool:
        if isinstance(name, str):
            self._load_builtin(name)
        if name not in self._entries:
            self._discover()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        self._discover()
        return iter(list(self._entries))

    def __len__(self) -> int:
        self._discover()
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.group!r}, {len(self._entries)} entries)"


# The .phys declarations (``effect_type ... on ... { param ... }``) of effects that have no file
# in ``stdlib/effects`` (plug-ins), filled by ``physics.effects.register(..., declaration=)``
# and read by the language's library (``syntax/library.py``), which cannot import physics.
EFFECT_DECLARATIONS: Registry[str] = Registry("physdsl.effects", "effect declaration")

# Contact models (``world { contact: NAME }``): step functions registered by
# ``physics.contact_models.contact_model``. The registry lives here so the language can check a
# name (``names()``) without importing physics; the built-ins' step functions are imported on
# their first look-up.
CONTACT_MODELS: Registry = Registry("physdsl.contact_models", "contact model",
                                    builtins={"lcp": "physdsl.physics.integrate",
                                              "compliant": "physdsl.physics.integrate"})
