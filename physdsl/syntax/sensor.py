"""Sensor terms of an ``observe`` block (``offset``, ``gain``, ``delay`` and any plug-in sensor
fault): checked and turned into a ``scene.Sensor``. What terms exist, their units and
constraints are the sensor faults' own (``observe.sensor.SENSOR_FAULTS``); whether a quantity
takes offset and gain is its observation kind's (``observe.kinds``). Each term is a value or a
prior like any field, so a prior makes it an unknown that is fitted with the rest
(``hinge.angle.offset``)."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysTypeError
from ..observe.kinds import OBSERVATION_KINDS
from ..observe.sensor import SENSOR_FAULTS, SensorFault
from ..scene import Sensor
from .schema import Spec
from .units import DIMLESS, parse_unit


def sensor_fields() -> tuple[str, ...]:
    """The names of the sensor terms an ``observe`` block may hold (built-ins and plug-ins)."""
    return tuple(SENSOR_FAULTS)


def _spec(fault: SensorFault, qdim) -> Spec:
    """What the term accepts: its own unit, or the quantity's; one number or one per axis."""
    dim = qdim if fault.unit is None else DIMLESS if fault.unit == "1" else parse_unit(fault.unit)[1]
    return Spec((dim,), None if fault.per_axis else ())


def resolve_sensor(res, item, name: str, qdim, dim: int, fs) -> Sensor | None:
    """The Sensor of observation ``name`` from its block's fields ``fs`` (None without terms).

    ``res`` is the Resolver (register/value/err), ``qdim`` the quantity's dimension, ``dim``
    its number of axes: a per-axis term (an offset) is one number or one per axis."""
    present = [k for k in SENSOR_FAULTS if k in fs]
    if not present:
        return None
    kind = OBSERVATION_KINDS[item.quantity]
    if not kind.affine:  # a rotation: no offset or gain
        allowed = [k for k in SENSOR_FAULTS if SENSOR_FAULTS[k].rotations]
        bad = [k for k in present if k not in allowed]
        if bad:
            raise res.err(PhysTypeError, f"an {item.quantity} has no {bad[0]}", fs[bad[0]].span,
                          f"{item.quantity} sensors take only {' or '.join(allowed)}")
    out = []
    for k in present:
        fault, path = SENSOR_FAULTS[k], f"{name}.{k}"
        res.register(path, fs[k].value, _spec(fault, qdim))
        r = res.value(path)
        if fault.per_axis and r.shape not in ((), (dim,)):
            raise res.err(PhysTypeError, f"{k} is one number or one per axis ({dim})",
                          fs[k].span)
        if fault.positive and isinstance(r.expr, E.Const) and np.any(r.expr.array() <= 0):
            raise res.err(PhysTypeError, f"{k} must be positive", fs[k].span,
                          f"{k}: {fault.off:g} is an exact sensor")
        out.append((k, r.expr))
    return Sensor(tuple(out))
