"""Effects of a scene: the library's declarations checked, effect items and contact sugar
turned into ``EffectUse``s on their targets, controls, and the pairs that collide."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysNameError, PhysStructureError, PhysTypeError, Span
from ..scene import Body, EffectDecl, EffectParam, EffectUse, Joint, Unknown
from . import ast, collide, experiments
from .context import AnyKey
from .contact_sugar import CONTACT_SUGAR, SUGAR_PARAM
from .data import read_control
from .expressions import R
from .learned import param_shapes
from .priors import prior
from .schema import EFFECT_TARGETS, Spec
from .units import FORCE, TIME, TORQUE, parse_unit
from .words import close


def effect_decl(res, et: ast.EffectType, text: str) -> EffectDecl:
    """The declaration ``effect_type NAME on KINDS { param ... }`` (from ``text``) checked."""
    kinds = EFFECT_TARGETS
    for k in et.acts_on:
        if k not in kinds:
            raise res.err(PhysNameError, f"an effect acts on {', '.join(kinds)}; not '{k}'",
                          et.span, source=text)
    params = []
    for p in et.params:
        dims = tuple(parse_unit(u)[1] for u in p.units)
        res.param_dims[(et.name, p.name)] = dims
        sp = Spec(dims, (3,) if p.vector else ())
        default = None
        if p.default is not None:
            default = res.check(res.expr(p.default), sp, p.name, p.default).expr
        pr = None
        if p.prior is not None:
            pr = prior(res, p.prior, dims[0])[0]
        off = None
        if p.off is not None:
            arr = np.atleast_1d(res.expr(p.off).expr.array())
            off = float(arr[0])
        sign = {"above": 1, "below": -1}.get(p.strength or "", 0)
        params.append(EffectParam(p.name, p.units[0], (3,) if p.vector else (), default, pr,
                                  off, p.strength is not None, sign))
    return EffectDecl(et.name, "|".join(et.acts_on), tuple(params), et.doc, et.span)


def target_kind(res, target: tuple[str, ...], span) -> str:
    """What ``target`` names: 'world', 'pair', 'body' or 'joint' (an error if none)."""
    if target == ("world",):
        return "world"
    if len(target) == 2:
        for t in target:
            if t not in res.body_index:
                raise res.err(PhysNameError, f"unknown body '{t}'{close(t, res.body_index)}",
                              span)
        if target[0] == target[1]:
            raise res.err(PhysStructureError, "a pair needs two different bodies", span)
        return "pair"
    t = target[0]
    if t in res.body_index:
        return "body"
    if t in res.joint_index:
        return "joint"
    raise res.err(PhysNameError, f"unknown target '{t}'"
                  f"{close(t, list(res.body_index) + list(res.joint_index) + ['world'])}",
                  span, "an effect acts on a body, a joint, a pair (a, b) or world")


def effect_use(res, name: str, target: tuple[str, ...], fields: dict, span) -> EffectUse:
    """Effect ``name`` on ``target`` with parameter ``fields``: checked against its declaration;
    a parameter not written takes its default or, with a declared prior, becomes an unknown."""
    decl = res.effect_library.get(name)
    if decl is None:
        raise res.err(PhysNameError, f"unknown effect '{name}'{close(name, res.effect_library)}",
                      span, "effects: " + ", ".join(sorted(res.effect_library)))
    kind = target_kind(res, target, span)
    kinds = decl.acts_on.split("|")
    if kind not in kinds:
        raise res.err(PhysTypeError, f"effect '{name}' acts on a {' or '.join(kinds)}, but "
                      f"'{','.join(target)}' is a {kind}", span)
    if kind == "pair":
        target = res.pair_order.get(frozenset(target), target)
    key = f"{name}@{','.join(target)}"
    params: dict[str, E.Expr] = {}
    shapes = param_shapes(res, decl, fields, span)  # a learned effect's weights
    names = [p.name for p in decl.params]
    for k, f in fields.items():
        if k not in names:
            res.errors.append(res.err(PhysNameError, f"effect '{name}' has no parameter "
                                      f"'{k}'{close(k, names)}", f.span,
                                      f"its parameters: {', '.join(names)}"))
    for p in decl.params:
        path = f"{key}.{p.name}"
        dims = res.param_dims.get((name, p.name), (parse_unit(p.unit)[1],))
        if kind == "joint" and len(dims) > 1:
            jk = res.joint_index[target[0]].kind
            dims = (dims[1],) + dims[:1] if jk == "slider" else dims
        shape = shapes.get(p.name, p.shape)
        sp = Spec(dims, shape)
        if p.name in fields:
            f = fields[p.name]
            res.register(path, f.value, sp)
            r = res.collect(res.value, path)
            if r is not None:
                params[p.name] = r.expr
        elif p.default is not None:
            params[p.name] = p.default
        elif p.prior is not None:
            res.unknowns[path] = Unknown(path, p.prior, shape, dims[0].si_text(), span, (), False)
            res.supports[path] = "positive" if p.sign else "real"
            res.memo[path] = R(E.Ref(path), dims[0], shape)
            res.resolved_order.append(path)
            params[p.name] = E.Ref(path)
        else:
            raise res.err(PhysStructureError, f"effect '{name}' needs '{p.name}'", span,
                          f"write {p.name}: value (in {p.unit})")
    return EffectUse(name, tuple(target), params, {}, span)


def contact(res, item: ast.ContactItem, body_names) -> list[EffectUse]:
    """The pair effects of a ``contact a, b { friction: .. }`` block (``contact_sugar``)."""
    fs = res.fields_of(item.block, CONTACT_SUGAR, f"contact {item.a}, {item.b}")
    target_kind(res, (item.a, item.b), item.span)
    out = []
    for k, f in fs.items():
        fld = ast.Field(SUGAR_PARAM, f.value, f.span)
        use = res.collect(effect_use, res, CONTACT_SUGAR[k], (item.a, item.b),
                          {SUGAR_PARAM: fld}, item.span)
        if use is not None:
            out.append(use)
    return out


def contact_pairs(res, bodies: list[Body], joints: list[Joint],
                  items=()) -> list[tuple[str, str]]:
    """Default pairs (``collide.contact_pairs``); ``contact a, b`` items switch theirs on."""
    off = {n for n, fs in res.body_fields.items()
           if not res.flag(fs, "collide", True)}
    explicit = {frozenset((i.a, i.b)) for i in items if isinstance(i, ast.ContactItem)}
    return collide.contact_pairs(bodies, joints, off, explicit)


def control(res, item: ast.ControlItem) -> EffectUse | None:
    """A ``control`` item as a ``control_force`` effect: its times and values from a CSV file
    or from the block (values may be unknowns)."""
    kind = target_kind(res, (item.target,), item.span)
    if kind not in ("body", "joint"):
        raise res.err(PhysTypeError, "a control acts on a body or a joint", item.span)
    width = 3 if kind == "body" else 1
    if kind == "body":
        vdim = FORCE
    else:
        vdim = FORCE if res.joint_index[item.target].kind == "slider" else TORQUE
    fs = res.fields_of(item.block, {"gain", "times", "values"}, f"control '{item.name}'")
    gain_fields = {"gain": fs["gain"]} if "gain" in fs else {}
    use = effect_use(res, "control_force", (item.target,), gain_fields, item.span)
    key = use.key
    params = dict(use.params)
    if item.setting is not None:  # one file per recording, from the manifest's column
        if "times" in fs or "values" in fs:
            raise res.err(PhysStructureError, "a control reads its values from the files or "
                          "from the block, not both", item.span)
        if len(item.columns) != width:
            raise res.err(PhysTypeError, f"a control on a {kind} needs {width} column"
                          f"{'s' * (width > 1)}, got {len(item.columns)}", item.span)
        table = experiments.control_table(res, item, width)
        if table is None:
            return None
        times, ref = table
        params["values"] = E.Ref(ref)
        return EffectUse(use.effect, use.target, params, {"times": times}, item.span)
    if item.file is not None:
        if "times" in fs or "values" in fs:
            raise res.err(PhysStructureError, "a control reads its values from the file or "
                          "from the block, not both", item.span)
        if len(item.columns) != width:
            raise res.err(PhysTypeError, f"a control on a {kind} needs {width} column"
                          f"{'s' * (width > 1)}, got {len(item.columns)}", item.span,
                          "e.g. column (fx, fy, fz)" if width == 3 else "e.g. column torque")
        times, values = read_control(res.data_file(item.file, item.span), item.columns,
                                     item.span)
        return EffectUse(use.effect, use.target, params,
                         {"times": times, "values": values if width == 3 else values[:, 0]},
                         item.span)
    if "times" not in fs or "values" not in fs:
        raise res.err(PhysStructureError, f"control '{item.name}' needs 'times' and 'values' "
                      "(or 'from \"file.csv\" column COL')", item.span)
    res.register(f"{key}.times", fs["times"].value, Spec((TIME,), None, True))
    tr = res.value(f"{key}.times")
    times = np.atleast_1d(tr.expr.array())
    if times.ndim != 1 or len(times) < 1 or np.any(np.diff(times) <= 0):
        raise res.err(PhysTypeError, "control 'times' must be increasing", fs["times"].span)
    n = len(times)
    vshape = (n,) if width == 1 else (n, 3)
    res.register(f"{key}.values", fs["values"].value, Spec((vdim,), vshape))
    vr = res.value(f"{key}.values")
    if isinstance(vr.expr, E.Ref):
        params["values"] = vr.expr
        return EffectUse(use.effect, use.target, params, {"times": times}, item.span)
    if not isinstance(vr.expr, E.Const):
        params["values"] = vr.expr
        return EffectUse(use.effect, use.target, params, {"times": times}, item.span)
    return EffectUse(use.effect, use.target, params,
                     {"times": times, "values": vr.expr.array()}, item.span)


def scene_effects(res, items, gravity, body_names) -> list[EffectUse]:
    """Every effect of the scene's ``items`` in order: gravity (from ``world { gravity: }``
    or by default), effect items, contact sugar, controls; a key given twice is an error."""
    effects: list[EffectUse] = []
    keys: dict[str, Span | None] = {}

    def add(use):
        if use is None:
            return
        if use.key in keys:
            res.errors.append(res.err(PhysNameError, f"effect '{use.key}' is given twice",
                                      use.span, "merge the two into one"))
            return
        keys[use.key] = use.span
        effects.append(use)

    gravity_items = [i for i in items if isinstance(i, ast.EffectItem) and i.effect == "gravity"]
    if not gravity_items or gravity is not None:
        add(res.collect(effect_use, res, "gravity", ("world",),
                        {"acceleration": gravity} if gravity is not None else {},
                        gravity.span if gravity is not None else None))
    for item in items:
        if isinstance(item, ast.EffectItem):
            fs = res.fields_of(item.block, AnyKey(), "effect")
            add(res.collect(effect_use, res, item.effect, item.target, fs, item.span))
        elif isinstance(item, ast.ContactItem):
            for use in res.collect(contact, res, item, body_names) or ():
                add(use)
        elif isinstance(item, ast.ControlItem):
            add(res.collect(control, res, item))
    return effects
