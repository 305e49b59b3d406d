"""contact_friction (mu) and restitution (e): per-pair coefficients read by the contact stage.

They produce no force of their own; without them a contact is frictionless (mu = 0) and
elastic (e = 1), which are also their off values.
"""
from .base import register


@register("contact_friction", ("pair",), stage="contact")
def contact_friction(model, site, p, ctx):  # pragma: no cover - never called as a force
    raise AssertionError


@register("restitution", ("pair",), stage="contact")
def restitution(model, site, p, ctx):  # pragma: no cover
    raise AssertionError
