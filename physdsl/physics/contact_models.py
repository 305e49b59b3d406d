"""Contact models by name (``world { contact: ... }``): each is one step function
``step(model, prm, state, t, h, forward_only) -> State`` for a scene with contact candidates,
registered with ``@contact_model(name)`` (built-ins: ``lcp`` and ``compliant`` in
``integrate.py``, named in ``registry.CONTACT_MODELS``' built-ins so the language knows them
without importing physics; plug-ins: entry-point group ``physdsl.contact_models``)."""
from __future__ import annotations

from ..registry import CONTACT_MODELS

__all__ = ["CONTACT_MODELS", "contact_model"]


def contact_model(name: str):
    """Decorator registering a contact step function under ``name``."""
    def deco(fn):
        return CONTACT_MODELS.add(name, fn, fn.__module__)
    return deco
