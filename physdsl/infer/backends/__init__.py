"""Built-in backends, one module each, registered by ``@register_backend``: every module of
this package is imported here (a new backend is one new file); plug-ins come through the
entry-point group ``physdsl.backends`` (``physdsl.registry``)."""
import importlib
import pkgutil

for _m in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_m.name}")
