"""Sensor terms of an ``observe`` block (``offset``, ``gain``, ``delay``): checked and turned
into a ``scene.Sensor``. Each is a value or a prior like any field, so a prior makes it an
unknown that is fitted with the rest (``hinge.angle.offset``)."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysTypeError
from ..scene import Sensor
from .schema import Spec, spec
from .units import DIMLESS, TIME

SENSOR_FIELDS = ("offset", "gain", "delay")
# quantities whose geometry has no offset or gain (a rotation is not shifted by a vector)
NO_AFFINE = {"orientation"}


def resolve_sensor(res, item, name: str, qdim, dim: int, fs) -> Sensor | None:
    """The Sensor of observation ``name`` from its block's fields ``fs`` (None without terms).

    ``res`` is the Resolver (register/value/err), ``qdim`` the quantity's dimension, ``dim``
    its number of axes: an offset is one number or one per axis, gain and delay one number."""
    present = [k for k in SENSOR_FIELDS if k in fs]
    if not present:
        return None
    if item.quantity in NO_AFFINE:
        bad = [k for k in present if k != "delay"]
        if bad:
            raise res.err(PhysTypeError, f"an orientation has no {bad[0]}", fs[bad[0]].span,
                          "orientation sensors take only a delay")
    specs = {"offset": Spec((qdim,), None), "gain": spec(DIMLESS), "delay": spec(TIME)}
    out = {}
    for k in present:
        path = f"{name}.{k}"
        res.register(path, fs[k].value, specs[k])
        r = res.value(path)
        if k == "offset" and r.shape not in ((), (dim,)):
            raise res.err(PhysTypeError, f"offset is one number or one per axis ({dim})",
                          fs[k].span)
        if k == "gain" and isinstance(r.expr, E.Const) and np.any(r.expr.array() <= 0):
            raise res.err(PhysTypeError, "gain must be positive", fs[k].span,
                          "gain: 1 is an exact sensor")
        out[k] = r.expr
    return Sensor(**out)
