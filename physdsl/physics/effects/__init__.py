"""Physical effects, one module each, registered in ``EFFECTS`` by ``@register``: every module
of this package is imported here (a new effect is one new file), and plug-ins come through
the entry-point group ``physdsl.effects`` (``physdsl.registry``)."""
import importlib
import pkgutil

from .base import EFFECTS, Ctx, Effect, Load, register, zero_load

for _m in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_m.name}")

__all__ = ["EFFECTS", "Ctx", "Effect", "Load", "register", "zero_load"]
