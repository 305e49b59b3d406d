"""The fields of a ``contact a, b { ... }`` block and the pair effect each one writes.

``contact floor, ball { friction: 0.3 }`` is sugar for the effect ``contact_friction`` on the
pair with ``coefficient: 0.3``. This is the one table of that sugar: the resolver expands it,
export and the scene editor read it to find and rewrite such fields.
"""
from __future__ import annotations

# field of a contact block -> the pair effect it adds (its parameter is ``coefficient``)
CONTACT_SUGAR = {"friction": "contact_friction", "restitution": "restitution",
                 "rolling_resistance": "rolling_resistance"}
# pair effect -> the contact-block field that writes it
SUGAR_FIELD = {effect: key for key, effect in CONTACT_SUGAR.items()}
# the parameter every sugared effect takes
SUGAR_PARAM = "coefficient"
