"""Contact models by name (``world { contact_model: ... }``): each is one step function
``step(model, prm, state, t, h, forward_only) -> State`` for a scene with contact candidates,
registered with ``@contact_model(name)`` (built-ins: ``lcp`` and ``compliant`` in
``integrate.py``; plug-ins: entry-point group ``physdsl.contact_models``)."""
from __future__ import annotations

from typing import Callable

from ..registry import Registry

CONTACT_MODELS: Registry[Callable] = Registry("physdsl.contact_models", "contact model")


def contact_model(name: str):
    """Decorator registering a contact step function under ``name``."""
    def deco(fn):
        return CONTACT_MODELS.add(name, fn, fn.__module__)
    return deco
