"""``observe TARGET.QUANTITY from "file" { noise: ... }``: the quantity checked against what
its target is (the observation kinds of ``observe.kinds.OBSERVATION_KINDS``, which say whether
a body, a marker or a joint has them; camera images), the noise model and sensor terms
resolved, the data read."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import expr as E
from ..errors import PhysNameError, PhysStructureError, PhysTypeError
from ..observe.kinds import OBSERVATION_KINDS as QUANTITIES
from ..scene import Noise, Observation
from . import ast
from .data import read_image_times, read_observation
from .mapping import check_label, unknown_target
from .schema import OBSERVE_FIELDS, Spec, spec
from .sensor import resolve_sensor, sensor_fields
from .units import DIMLESS, FREQ, Dim, parse_unit
from .words import close

NOISE_MODELS = ("normal", "student_t")


def quantity_dim(quantity: str, slider: bool = False) -> Dim:
    """The dimension of an observed trajectory quantity (a slider's joint moves in metres)."""
    unit = QUANTITIES[quantity].unit
    if slider:
        unit = unit.replace("rad", "m")
    return DIMLESS if unit == "1" else parse_unit(unit)[1]


def observe(res, item: ast.ObserveItem) -> Observation:
    """The Observation of ``item`` with its data read (CSV rows or image frames)."""
    q, t = item.quantity, item.target
    name = f"{t}.{q}"
    cols, qdim = _columns(res, item)
    fs = res.fields_of(item.block, OBSERVE_FIELDS | set(sensor_fields()), f"observe {name}")
    if "noise" not in fs:
        raise res.err(PhysStructureError, f"observation '{name}' needs a noise", item.span,
                      "e.g. { noise: 2 mm }  or  { noise ~ half_normal(5 mm) }")
    dim = max(len(cols), 1)
    noise = _noise(res, name, fs, qdim, dim)
    file = res.data_file(item.file, item.span, base=res.observation_base)
    if q == "image":
        return _images(res, item, name, fs, file, noise)
    if item.rate is not None or item.times is not None:
        raise res.err(PhysStructureError, "'at' and 'times' are for image observations; "
                      "a CSV file has its own column t", item.span)
    check_label(res, item, file, res.items_by_name)  # the label may differ from t
    times, values, mask = read_observation(file, cols, item.where, item.span)
    sensor = resolve_sensor(res, item, name, qdim, dim, fs)
    return Observation(name, t, q, file, times, values, mask, tuple(cols), noise, (), item.span,
                       sensor)


def _columns(res, item: ast.ObserveItem) -> tuple[tuple[str, ...], Dim]:
    """(data columns, dimension) of the observed quantity; an error where the target is no
    item that has it."""
    q, t = item.quantity, item.target
    kind = QUANTITIES[q].target if q != "image" and q in QUANTITIES else None
    if kind == "body":
        on_markers = QUANTITIES[q].marker_source is not None
        if t in res.marker_index and on_markers:
            pass
        elif t not in res.body_index:
            markers = " and markers" if on_markers else ""
            names = list(res.body_index) + (list(res.marker_index) if markers else [])
            raise unknown_target(res, item, "body", names, f"bodies{markers}")
        return QUANTITIES[q].columns, quantity_dim(q)
    if kind == "joint":
        if t not in res.joint_index:
            raise unknown_target(res, item, "joint", res.joint_index, "joints")
        return QUANTITIES[q].columns, quantity_dim(q, res.joint_index[t].kind == "slider")
    if q == "image":
        if t not in {c for c, k in res.items_by_name.items() if k == "camera"}:
            raise res.err(PhysNameError, f"images are observed by cameras; unknown camera "
                          f"'{t}'", item.span)
        return (), DIMLESS
    opts = list(QUANTITIES) + ["image"]
    raise res.err(PhysNameError, f"unknown quantity '{q}'{close(q, opts)}", item.span,
                  "quantities: " + ", ".join(opts))


def _noise(res, name: str, fs: dict, qdim: Dim, dim: int) -> Noise:
    """The noise model of observation ``name``: a positive scale (one or one per axis) of
    the quantity's dimension, normal or student_t (df 4 unless given)."""
    res.register(f"{name}.noise", fs["noise"].value, Spec((qdim,), None))
    nr = res.value(f"{name}.noise")
    if nr.shape not in ((), (dim,)):
        raise res.err(PhysTypeError, f"noise is one number or one per axis ({dim})",
                      fs["noise"].span)
    if isinstance(nr.expr, E.Const) and np.any(nr.expr.array() <= 0):
        raise res.err(PhysTypeError, "noise must be positive", fs["noise"].span)
    kind = "normal"
    df = None
    if "model" in fs:
        node = fs["model"].value
        kind = node.name if isinstance(node, ast.Name) else ""
        if kind not in NOISE_MODELS:
            raise res.err(PhysNameError, f"unknown noise model '{kind}'"
                          f"{close(kind, list(NOISE_MODELS))}", fs["model"].span,
                          "model: normal | student_t")
    if "df" in fs:
        res.register(f"{name}.df", fs["df"].value, spec(DIMLESS))
        df = res.value(f"{name}.df").expr
    elif kind == "student_t":
        df = E.Const(4.0)
    return Noise(kind, nr.expr, df)


def _images(res, item: ast.ObserveItem, name: str, fs: dict, file: Path,
            noise: Noise) -> Observation:
    """A camera's image observation: its frames and their times (``at`` rate or ``times``)."""
    if any(k in fs for k in sensor_fields()):
        raise res.err(PhysStructureError, "images take no sensor terms", item.span,
                      f"{', '.join(sensor_fields())} are for trajectory observations")
    rate = None
    if item.rate is not None:
        res.register(f"{name}.rate", item.rate, spec(FREQ, (), True))
        rate = float(res.value(f"{name}.rate").expr.array())
    frames, times = read_image_times(res.base, item.file, rate,
                                     res.data_file(item.times, item.span)
                                     if item.times else None, item.span)
    for f in frames:
        if isinstance(f, Path):  # a frame file may be a link out of the folder
            res.bounds.check(f, "image file", f.name, item.span, res.source)
    return Observation(name, item.target, item.quantity, file, times, np.zeros((len(times), 0)),
                       np.zeros((len(times), 0), bool), (), noise, frames, item.span)


def scene_observations(res, items) -> list[Observation]:
    """The observations of the scene's ``items``; the same name from the same file twice is
    an error."""
    observations: list[Observation] = []
    for item in items:
        if isinstance(item, ast.ObserveItem):
            o = res.collect(observe, res, item)
            if o is not None:
                if any(x.name == o.name and x.file == o.file for x in observations):
                    res.errors.append(res.err(PhysNameError, f"'{o.name}' is observed twice "
                                              "from the same file", item.span))
                observations.append(o)
    return observations
