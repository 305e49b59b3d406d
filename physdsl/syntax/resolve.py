"""AST -> checked ``Scene``: names bound, units to SI, dimensions/shapes/structure checked, data read.

Fields are resolved lazily by dotted path (``ball.mass``, ``rod.shape.radius``, ``L``) so
fields may refer to each other in any order; a cycle is an error. Independent mistakes are
collected and raised together as PhysErrors.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import expr as E
from ..errors import (DataError, PhysError, PhysErrors, PhysNameError, PhysStructureError,
                      PhysTypeError, PhysUnitError, Span)
from ..media import MEDIA
from ..scene import (DH, Body, Camera, EffectDecl, EffectParam, EffectUse, Joint, Light, Material,
                     Noise, Observation, Prior, Scene, Shape, Unknown, World)
from . import ast, collide, dists
from .bounds import Bounds
from .checks import check
from .contact_sugar import CONTACT_SUGAR, SUGAR_PARAM
from .data import read_control, read_image_times, read_observation
from .expressions import PI, R, Scope, broadcast, to_expr
from .library import load_library
from .loops import annotate, expand, place
from .mapping import check_label, clash_hint, unknown_target
from .markers import MARKER_QUANTITIES, build_marker
from .schema import (BODY_FIELDS, BODY_FLAGS, CAMERA_FIELDS, CONTACT_MODELS, DH_FIELDS,
                     GROUND_FIELDS, INTEGRATORS, JOINT_KINDS, LIGHT_FIELDS, MARKER_FIELDS,
                     MATERIAL_FIELDS, OBSERVE_FIELDS, SHAPE_ARGS, WORLD_FIELDS, Spec, spec)
from .sensor import SENSOR_FIELDS, resolve_sensor
from .units import (ANGLE, ANGVEL, DIMLESS, FORCE, FREQ, LENGTH, TIME, TORQUE, VEL, Dim,
                    parse_unit)
from .words import close, fmt, shape_words

BODY_QUANTITIES = {"position": (("x", "y", "z"), LENGTH), "orientation": (("qw", "qx", "qy", "qz"), DIMLESS),
                   "velocity": (("vx", "vy", "vz"), VEL),
                   "angular_velocity": (("wx", "wy", "wz"), ANGVEL)}
JOINT_QUANTITIES = {"angle": ("angle",), "angular_rate": ("rate",)}


class _Poisoned(PhysError):
    """A reference to a field that already failed: not reported again."""



class Resolver:
    """Resolves one scene module (with its library) into a Scene."""

    def __init__(self, module: ast.Module, source: str, base_dir: Path, path: Path | None,
                 bounds: Bounds | None = None):
        self.m = module
        self.source = source
        self.base = base_dir
        self.path = path
        self.bounds = bounds if bounds is not None else Bounds.around(base_dir)
        self.errors: list[PhysError] = []
        self.sources: dict[str, tuple[object, Spec | None, str]] = {}  # path -> (node, spec, file text)
        self.memo: dict[str, R] = {}
        self.failed: set[str] = set()
        self.stack: list[str] = []
        self.unknowns: dict[str, Unknown] = {}
        self.resolved_order: list[str] = []
        self.items_by_name: dict[str, str] = {}  # body/joint/camera name -> kind
        self.src_of: dict[str, str] = {}
        self.scope = Scope(self.lookup, self.is_param, self.err)

    # ---- errors ----------------------------------------------------------------------------
    def err(self, cls, msg, span, hint=None, source=None):
        return cls(msg, span, hint, source=source if source is not None else self._text_for(span))

    def _text_for(self, span: Span | None) -> str | None:
        if span is None:
            return None
        if span.file == self.m.filename:
            return self.source
        return self.lib.sources.get(span.file) if hasattr(self, "lib") else None

    def collect(self, fn, *args):
        """Run ``fn``; record a PhysError instead of raising it (one item's failure)."""
        try:
            return fn(*args)
        except _Poisoned:
            return None
        except PhysErrors as ex:
            self.errors.extend(ex.errors)
        except PhysError as ex:
            if ex.source is None:
                ex.source = self._text_for(ex.span)
            self.errors.append(ex)
        return None

    # ---- lazily resolved fields ------------------------------------------------------------
    def register(self, path: str, node, spec_: Spec | None):
        self.sources[path] = (node, spec_, "")

    def value(self, path: str, span: Span | None = None) -> R:
        if path in self.memo:
            return self.memo[path]
        if path in self.failed:
            raise _Poisoned("")
        if path in self.stack:
            cycle = self.stack[self.stack.index(path):] + [path]
            raise self.err(PhysStructureError, "values refer to each other in a circle: "
                           + " -> ".join(cycle), span, "give one of them a value of its own")
        node, spec_, _ = self.sources[path]
        self.stack.append(path)
        try:
            r = self._resolve_field(path, node, spec_)
        except PhysError:
            self.failed.add(path)
            raise
        finally:
            self.stack.pop()
        self.memo[path] = r
        self.resolved_order.append(path)
        return r

    def _resolve_field(self, path: str, node, spec_: Spec | None) -> R:
        label = path.rsplit(".", 1)[-1]
        if isinstance(node, ast.Dist):
            dim = spec_.dims[0] if spec_ else None
            shape = spec_.shape if spec_ and spec_.shape is not None else None
            return self.make_unknown(path, node, dim, shape, spec_)
        if isinstance(node, E.Const):  # a default already in SI
            return R(node, spec_.dims[0] if spec_ else None, np.shape(node.value))
        r = self.expr(node)
        if spec_ is None:
            return r
        return self.check(r, spec_, label, node)

    def check(self, r: R, spec_: Spec, label: str, node) -> R:
        return check(r, spec_, label, node, self.err)

    # ---- expressions -------------------------------------------------------------------------
    def expr(self, node) -> R:
        """The R of an expression written in this scene (``expressions.to_expr``)."""
        return to_expr(node, self.scope)

    def lookup(self, node) -> R:
        """The R a name or dotted path of the scene refers to (resolved on demand)."""
        return self.name(node) if isinstance(node, ast.Name) else self.dotted(node)

    def is_param(self, word: str) -> bool:
        return word in self.sources and "." not in word

    def name(self, node: ast.Name) -> R:
        n = node.name
        if n in self.sources and "." not in n:
            return self.value(n, node.span)
        if n == "pi":
            return PI
        if n in self.items_by_name:
            kind = self.items_by_name[n]
            fields = sorted(p.split(".", 1)[1] for p in self.sources if p.startswith(n + "."))
            ex = f", e.g. {n}.{fields[0]}" if fields else ""
            raise self.err(PhysNameError, f"'{n}' is a {kind}, not a value", node.span,
                           f"refer to one of its fields{ex}")
        params = [p for p in self.sources if "." not in p and "@" not in p]
        raise self.err(PhysNameError, f"unknown name '{n}'{close(n, params + list(self.items_by_name))}",
                       node.span, "declare it with 'param NAME: value' or 'param NAME ~ dist(...)'")

    def dotted(self, node: ast.Dotted) -> R:
        path = ".".join(node.parts)
        if path in self.sources:
            return self.value(path, node.span)
        head = node.parts[0]
        if head in self.items_by_name:
            fields = [p for p in self.sources if p.startswith(head + ".")]
            raise self.err(PhysNameError, f"{self.items_by_name[head]} '{head}' has no field "
                           f"'{'.'.join(node.parts[1:])}'{close(path, fields)}", node.span,
                           "only fields written in the scene (and shape sizes) can be referred to")
        names = list(self.items_by_name) + [p for p in self.sources if "." not in p]
        raise self.err(PhysNameError, f"unknown name '{head}'{close(head, names)}", node.span)

    # ---- distributions and unknowns ----------------------------------------------------------
    def prior(self, node: ast.Dist, dim: Dim | None, own: str | None = None):
        """(Prior, draw shape, dim, discrete, support words) of ``~ name(args)``."""
        obj = dists.find(node.name)
        if obj is None:
            raise self.err(PhysNameError, f"unknown distribution '{node.name}'"
                           f"{close(node.name, dists.catalogue())}", node.span,
                           "any numpyro distribution by its snake_case name, e.g. normal, "
                           "half_normal, uniform, log_normal, beta, gamma")
        pos_names, kw_names = dists.arg_names(obj)
        bound: dict[str, tuple[ast.Arg, R]] = {}
        order: list[tuple[str | None, str]] = []
        npos = 0
        for a in node.args:
            if a.name is None:
                if npos >= len(pos_names):
                    raise self.err(PhysTypeError, f"{node.name} takes at most {len(pos_names)} "
                                   f"positional argument{'s' * (len(pos_names) != 1)} "
                                   f"({', '.join(pos_names)})", a.span,
                                   f"name the others, e.g. {kw_names[0]}: ..." if kw_names else None)
                name = pos_names[npos]
                npos += 1
            else:
                name = a.name
                if name not in pos_names + kw_names:
                    raise self.err(PhysNameError, f"{node.name} has no argument '{name}'"
                                   f"{close(name, pos_names + kw_names)}", a.span,
                                   f"its arguments: {', '.join(pos_names + kw_names)}")
            if name in bound:
                raise self.err(PhysTypeError, f"argument '{name}' of {node.name} given twice", a.span)
            bound[name] = (a, self.expr(a.value))
            order.append((a.name, name))
        missing = [n for n in dists.required_args(obj) if n not in bound]
        if missing:
            raise self.err(PhysTypeError, f"{node.name} needs argument '{missing[0]}'", node.span,
                           f"e.g. {node.name}({', '.join(n + ': ...' for n in missing)})")
        # dimensions
        log_space = node.name in dists.LOG_SPACE
        power = {n: dists.unit_power(node.name, n) for n in bound}
        target = dim
        if target is None:
            for n, (a, r) in bound.items():
                if r.dim is not None and power[n] is not None:
                    target = r.dim ** (1.0 / power[n])
                    break
        for n, (a, r) in bound.items():
            if r.dim is None:
                continue
            if power[n] is None:
                if not r.dim.dimensionless:
                    why = "lives in log space" if log_space else "is a plain number"
                    raise self.err(PhysUnitError, f"{node.name}'s '{n}' {why}; it takes no unit",
                                   a.value.span, "the unknown takes the field's unit (SI)")
            elif target is not None:
                want = target ** power[n]
                if not r.dim.same(want):
                    raise self.err(PhysUnitError, f"{node.name}'s '{n}' is {r.dim.name()}, but the "
                                   f"value needs {want.name()}", a.value.span,
                                   f"write it in {want.si_text()}")
        # constraints of constant arguments
        cons = dists.arg_constraints(obj, set(bound))
        for n, (a, r) in bound.items():
            c = cons.get(n)
            if c is not None and E.is_constant(r.expr):
                ok = dists.satisfies(c, r.expr.array())
                if ok is False:
                    raise self.err(PhysTypeError, f"{node.name}'s '{n}' must be "
                                   f"{dists.constraint_words(c)}, got {fmt(r.expr.array())}",
                                   a.value.span)
        if node.name == "uniform" and "low" in bound and "high" in bound:
            lo, hi = bound["low"][1].expr, bound["high"][1].expr
            if isinstance(lo, E.Const) and isinstance(hi, E.Const) and np.any(lo.array() >= hi.array()):
                raise self.err(PhysTypeError, "uniform needs low < high", node.span)
        # shape and support
        sample = {n: (r.expr.array() if isinstance(r.expr, E.Const) else np.ones(r.shape))
                  for n, (a, r) in bound.items()}
        args = [sample[n] for kw, n in order if kw is None]
        kwargs = {n: sample[n] for kw, n in order if kw is not None}
        shape, discrete, support = dists.draw_info(obj, args, kwargs)
        if shape is None:
            shape = ()
            for (a, r) in bound.values():
                shape = broadcast(shape, r.shape, node.span)
        prior = Prior(node.name, tuple(bound[n][1].expr for kw, n in order if kw is None),
                      tuple((n, bound[n][1].expr) for kw, n in order if kw is not None))
        return prior, shape, target, discrete, support

    def make_unknown(self, path: str, node: ast.Dist, dim: Dim | None, shape, spec_) -> R:
        prior, dshape, target, discrete, support = self.prior(node, dim)
        if shape is not None and dshape != shape:
            if dshape == ():
                dshape = shape
            else:
                label = path.rsplit(".", 1)[-1]
                raise self.err(PhysTypeError, f"the prior of '{label}' draws {shape_words(dshape)}, "
                               f"but '{label}' needs {shape_words(shape)}", node.span)
        if spec_ is not None and spec_.shape is None and dshape not in ((), (3,)):
            raise self.err(PhysTypeError, f"the prior draws {shape_words(dshape)}; "
                           "a single number or 3 numbers are needed", node.span)
        if spec_ is not None and spec_.constant:
            raise self.err(PhysTypeError, f"'{path.rsplit('.', 1)[-1]}' must be a known value, "
                           "not an unknown", node.span)
        unit = target.si_text() if target is not None else "1"
        self.unknowns[path] = Unknown(path, prior, tuple(dshape), unit, node.span, (), discrete)
        self.supports[path] = support
        return R(E.Ref(path), target, tuple(dshape))

    # ---- the scene ---------------------------------------------------------------------------
    def run(self) -> Scene:
        self.supports: dict[str, str] = {}
        self.lib = load_library(self.m, self.base, self.source, self.errors, self.path, self.bounds)
        scene = self.m.scene
        if scene is None:
            raise self.err(PhysStructureError, "no scene in this file", Span(self.m.filename, 1, 1),
                           "write 'scene NAME { ... }'")
        extra = [i for i in self.m.items if isinstance(i, ast.SceneDecl)][1:]
        for s in extra:
            self.errors.append(self.err(PhysStructureError, f"a file holds one scene; found a "
                                        f"second one, '{s.name}'", s.span))
        self.effect_library = {}
        self.param_dims: dict[tuple[str, str], tuple[Dim, ...]] = {}
        for name, (et, text) in self.lib.effect_types.items():
            decl = self.collect(self.effect_decl, et, text)
            if decl is not None:
                self.effect_library[name] = decl
        # library params
        for name, (p, text) in self.lib.params.items():
            self.register(name, p.value, None)
        scene = expand(scene, self.errors)  # loops unrolled, aliases applied (syntax/loops.py)
        self.declare(scene)
        built = self.build(scene)
        self._raise()
        return built

    def _raise(self):
        if not self.errors:
            return
        for e in self.errors:
            if e.source is None:
                e.source = self._text_for(e.span)
        raise self.errors[0] if len(self.errors) == 1 else PhysErrors(self.errors)

    def effect_decl(self, et: ast.EffectType, text: str) -> EffectDecl:
        kinds = ("body", "joint", "pair", "world")
        for k in et.acts_on:
            if k not in kinds:
                raise self.err(PhysNameError, f"an effect acts on {', '.join(kinds)}; not '{k}'",
                               et.span, source=text)
        params = []
        for p in et.params:
            dims = tuple(parse_unit(u)[1] for u in p.units)
            self.param_dims[(et.name, p.name)] = dims
            sp = Spec(dims, (3,) if p.vector else ())
            path = f"<decl {et.name}>.{p.name}"
            default = None
            if p.default is not None:
                default = self.check(self.expr(p.default), sp, p.name, p.default).expr
            prior = None
            if p.prior is not None:
                prior = self.prior(p.prior, dims[0])[0]
            off = None
            if p.off is not None:
                arr = np.atleast_1d(self.expr(p.off).expr.array())
                off = float(arr[0])
            sign = {"above": 1, "below": -1}.get(p.strength or "", 0)
            params.append(EffectParam(p.name, p.units[0], (3,) if p.vector else (), default, prior,
                                      off, p.strength is not None, sign))
            del path
        return EffectDecl(et.name, "|".join(et.acts_on), tuple(params), et.doc, et.span)

    def declare(self, scene: ast.SceneDecl):
        """Register names and field sources; check duplicates and unknown field names."""
        self.bodies: list[ast.BodyItem] = []
        self.joints: list[ast.JointItem] = []
        self.cameras: list[ast.CameraItem] = []
        self.markers: list[ast.MarkerItem] = []
        seen: dict[str, Span | None] = {}

        def unique(name, span, kind):
            if name in seen or name == "world":
                where = f" (first at {place(seen[name])})" if seen.get(name) else ""
                self.errors.append(self.err(PhysNameError, f"the name '{name}' is used twice{where}"
                                            if name != "world" else "'world' is a reserved name",
                                            span, clash_hint(name, kind)))
                return False
            seen[name] = span
            return True

        for item in scene.items:
            if isinstance(item, ast.Param):
                if unique(item.name, item.span, "param"):
                    self.register(item.name, item.value, None)
            elif isinstance(item, ast.BodyItem):
                if unique(item.name, item.span, item.kind):
                    self.items_by_name[item.name] = item.kind
                    self.bodies.append(item)
                    self.declare_body(item)
            elif isinstance(item, ast.JointItem):
                if unique(item.name, item.span, "joint"):
                    self.items_by_name[item.name] = "joint"
                    self.joints.append(item)
                    self.declare_joint(item)
            elif isinstance(item, ast.MarkerItem):
                if unique(item.name, item.span, "marker"):
                    self.items_by_name[item.name] = "marker"
                    self.markers.append(item)
                    self.declare_fields(item.name, item.block, MARKER_FIELDS, "marker")
            elif isinstance(item, ast.CameraItem):
                if unique(item.name, item.span, "camera"):
                    self.items_by_name[item.name] = "camera"
                    self.cameras.append(item)
                    self.declare_fields(item.name, item.block, CAMERA_FIELDS, "camera", {"size"})

    def fields_of(self, block: ast.Block | None, allowed, what: str, extra=()) -> dict:
        """Fields of a block by key; unknown or repeated keys are errors (recorded)."""
        out = {}
        if block is None:
            return out
        for f in block.fields:
            if isinstance(f, ast.MaterialBlock):
                if "material" in extra:
                    out["material"] = f
                else:
                    self.errors.append(self.err(PhysNameError, f"{what} has no 'material' block",
                                                f.span))
                continue
            if f.key not in allowed and f.key not in extra:
                opts = list(allowed) + [e for e in extra]
                self.errors.append(self.err(PhysNameError, f"{what} has no field '{f.key}'"
                                            f"{close(f.key, opts)}", f.span,
                                            "its fields: " + ", ".join(sorted(opts))))
                continue
            if f.key in out:
                self.errors.append(self.err(PhysNameError, f"field '{f.key}' is given twice", f.span))
                continue
            out[f.key] = f
        return out

    def declare_fields(self, name, block, table, what, extra=()):
        fs = self.fields_of(block, table, f"{what} '{name}'", extra)
        for k, f in fs.items():
            if k in table:
                self.register(f"{name}.{k}", f.value, table[k])
        return fs

    def declare_body(self, item: ast.BodyItem):
        if item.kind == "ground":
            fs = self.declare_fields(item.name, item.block, GROUND_FIELDS, "ground",
                                     {"material", "collide"})
        else:
            fs = self.declare_fields(item.name, item.block, BODY_FIELDS, "body",
                                     {"shape", "material"} | BODY_FLAGS)
            shape = fs.get("shape")
            if shape is not None:
                self.declare_shape(item.name, shape)
        mat = fs.get("material")
        if mat is not None:
            mfs = self.fields_of(mat.block, MATERIAL_FIELDS, "material")
            for k, f in mfs.items():
                self.register(f"{item.name}.material.{k}", f.value, MATERIAL_FIELDS[k])
        self.body_fields = getattr(self, "body_fields", {})
        self.body_fields[item.name] = fs

    def declare_shape(self, body: str, f: ast.Field):
        node = f.value
        if isinstance(node, ast.Name) and node.name in SHAPE_ARGS:
            node = ast.Call(node.name, (), node.span)
        if not isinstance(node, ast.Call) or node.func not in SHAPE_ARGS:
            name = node.func if isinstance(node, ast.Call) else None
            hint = "shapes: sphere(radius:), box(size:), cylinder(radius:, length:), " \
                   "capsule(radius:, length:), plane(normal:), mesh(\"file.obj\")"
            msg = (f"unknown shape '{name}'{close(name, SHAPE_ARGS)}" if name
                   else "'shape' needs a shape such as sphere(radius: 5 cm)")
            self.errors.append(self.err(PhysNameError if name else PhysTypeError, msg,
                                        getattr(node, "span", f.span), hint))
            return
        table = SHAPE_ARGS[node.func]
        order = list(table)
        for i, a in enumerate(node.args):
            if node.func == "mesh":
                continue
            key = a.name if a.name is not None else (order[i] if i < len(order) else None)
            if key is None or key not in table:
                self.errors.append(self.err(PhysNameError, f"{node.func} has no argument "
                                            f"'{a.name or i + 1}'{close(a.name or '', table)}",
                                            a.span, f"{node.func} takes {', '.join(order)}"))
                continue
            self.register(f"{body}.shape.{key}", a.value, table[key])

    def declare_joint(self, item: ast.JointItem):
        kind = item.kind
        if kind not in JOINT_KINDS:
            self.errors.append(self.err(PhysNameError, f"unknown joint kind '{kind}'"
                                        f"{close(kind, JOINT_KINDS)}", item.span,
                                        "joints: " + ", ".join(JOINT_KINDS)))
            return
        if kind == "slider":
            q, qd, lim = spec(LENGTH), spec(VEL), spec(LENGTH, (2,))
        elif kind == "ball":
            q, qd, lim = spec(DIMLESS, (4,)), spec(ANGVEL, (3,)), spec(ANGLE, (2,))
        else:
            q, qd, lim = spec(ANGLE), spec(ANGVEL), spec(ANGLE, (2,))
        table = {"axis": spec(DIMLESS, (3,)), "anchor": spec(LENGTH, (3,))}
        if kind in ("hinge", "slider", "ball"):
            table.update(initial=q, initial_velocity=qd, limits=lim)
        extra = {"dh"} if kind in ("hinge", "slider") else set()
        fs = self.declare_fields(item.name, item.block, table, f"{kind} joint '{item.name}'", extra)
        dh = fs.get("dh")
        if dh is not None:
            if not isinstance(dh.value, ast.Record):
                self.errors.append(self.err(PhysTypeError, "'dh' needs (a: .., alpha: .., d: .., "
                                            "theta: ..)", dh.span))
            else:
                for a in dh.value.fields:
                    if a.name not in DH_FIELDS:
                        self.errors.append(self.err(PhysNameError, f"dh has no parameter '{a.name}'"
                                                    f"{close(a.name, DH_FIELDS)}", a.span,
                                                    "dh: (a: .., alpha: .., d: .., theta: ..)"))
                        continue
                    self.register(f"{item.name}.dh.{a.name}", a.value, DH_FIELDS[a.name])
                missing = [k for k in DH_FIELDS if f"{item.name}.dh.{k}" not in self.sources]
                if missing:
                    self.errors.append(self.err(PhysTypeError, f"dh is missing "
                                                f"{', '.join(missing)}", dh.span))
        self.joint_fields = getattr(self, "joint_fields", {})
        self.joint_fields[item.name] = fs

    # ---- building --------------------------------------------------------------------------
    def opt(self, path: str) -> E.Expr | None:
        if path not in self.sources:
            return None
        r = self.collect(self.value, path)
        return r.expr if r is not None else None

    def flag(self, fs: dict, key: str, default: bool) -> bool:
        f = fs.get(key)
        if f is None:
            return default
        if isinstance(f.value, ast.Name) and f.value.name in ("true", "false"):
            return f.value.name == "true"
        self.errors.append(self.err(PhysTypeError, f"'{key}' is true or false", f.value.span
                                    if hasattr(f.value, "span") else f.span))
        return default

    def build(self, scene: ast.SceneDecl) -> Scene:
        world, gravity = self.build_world(scene)
        bodies = [b for b in (self.collect(self.build_body, it) for it in self.bodies) if b]
        body_names = {b.name for b in bodies}
        self.body_index = {b.name: b for b in bodies}
        joints = [j for j in (self.collect(self.build_joint, it) for it in self.joints) if j]
        self.collect(self.check_tree, joints)
        self.joint_index = {j.name: j for j in joints}
        markers = [m for m in (self.collect(build_marker, self, it) for it in self.markers) if m]
        self.marker_index = {m.name: m for m in markers}
        cameras = [c for c in (self.collect(self.build_camera, it) for it in self.cameras) if c]
        lights = [i for i in scene.items if isinstance(i, ast.LightItem)]
        light = self.collect(self.build_light, lights[0]) if lights else None
        for extra in lights[1:]:
            self.errors.append(self.err(PhysStructureError, "a scene has one light", extra.span))
        pairs = self.contact_pairs(bodies, joints, scene.items)
        self.pair_order = {frozenset(p): p for p in pairs}
        effects: list[EffectUse] = []
        keys: dict[str, Span | None] = {}

        def add(use):
            if use is None:
                return
            if use.key in keys:
                self.errors.append(self.err(PhysNameError, f"effect '{use.key}' is given twice",
                                            use.span, "merge the two into one"))
                return
            keys[use.key] = use.span
            effects.append(use)

        gravity_items = [i for i in scene.items if isinstance(i, ast.EffectItem)
                         and i.effect == "gravity"]
        if not gravity_items or gravity is not None:
            add(self.collect(self.effect_use, "gravity", ("world",),
                             {"acceleration": gravity} if gravity is not None else {},
                             gravity.span if gravity is not None else None))
        for item in scene.items:
            if isinstance(item, ast.EffectItem):
                fs = self.fields_of(item.block, None or _Any(), "effect")
                add(self.collect(self.effect_use, item.effect, item.target, fs, item.span))
            elif isinstance(item, ast.ContactItem):
                for use in self.collect(self.contact, item, body_names) or ():
                    add(use)
            elif isinstance(item, ast.ControlItem):
                add(self.collect(self.control, item))
        observations = []
        for item in scene.items:
            if isinstance(item, ast.ObserveItem):
                o = self.collect(self.observe, item)
                if o is not None:
                    if any(x.name == o.name and x.file == o.file for x in observations):
                        self.errors.append(self.err(PhysNameError, f"'{o.name}' is observed twice "
                                                    "from the same file", item.span))
                    observations.append(o)
        # every param is resolved (even unused), so its errors show
        for p in [p for p in self.sources if "." not in p]:
            self.collect(self.value, p)
        unknowns = []
        for name, u in self.unknowns.items():
            used = tuple(p for p in self.resolved_order
                         if name in E.references(self.memo[p].expr) and p != name)
            unknowns.append(Unknown(u.name, u.prior, u.shape, u.unit, u.span, used or (name,),
                                    u.discrete))
        return Scene(scene.name, world, tuple(bodies), tuple(joints), tuple(effects),
                     tuple(observations), tuple(cameras), tuple(unknowns), tuple(pairs), light,
                     dict(self.effect_library), self.path, self.source, tuple(markers))

    def build_world(self, scene):
        items = [i for i in scene.items if isinstance(i, ast.WorldItem)]
        for extra in items[1:]:
            self.errors.append(self.err(PhysStructureError, "a scene has one world block", extra.span))
        if not items:
            return World(), None
        fs = self.fields_of(items[0].block, WORLD_FIELDS, "world")
        kw = {}
        for key, sp in (("timestep", spec(TIME, (), True)), ("duration", spec(TIME, (), True))):
            if key in fs:
                self.register(f"world.{key}", fs[key].value, sp)
                r = self.collect(self.value, f"world.{key}")
                if r is not None:
                    v = float(r.expr.array())
                    if v <= 0:
                        self.errors.append(self.err(PhysTypeError, f"'{key}' must be positive",
                                                    fs[key].value.span))
                    kw[key] = v
        if "substeps" in fs:
            node = fs["substeps"].value
            if isinstance(node, ast.Num) and float(node.text).is_integer() and float(node.text) >= 1:
                kw["substeps"] = int(float(node.text))
            else:
                self.errors.append(self.err(PhysTypeError, "'substeps' is a whole number >= 1",
                                            getattr(node, "span", fs["substeps"].span)))
        for key, attr, choices in (("integrator", "integrator", INTEGRATORS),
                                   ("contact", "contact_model", CONTACT_MODELS),
                                   ("medium", "medium", tuple(MEDIA))):
            if key in fs:
                node = fs[key].value
                word = node.name if isinstance(node, ast.Name) else None
                if word not in choices:
                    self.errors.append(self.err(PhysNameError, f"unknown {key} "
                                                f"'{word or '?'}'{close(word or '', choices)}",
                                                getattr(node, "span", fs[key].span),
                                                f"choose {' or '.join(choices)}"))
                else:
                    kw[attr] = word
        return World(**kw), fs.get("gravity")

    def build_body(self, item: ast.BodyItem) -> Body | None:
        n = item.name
        fs = self.body_fields.get(n, {})
        mat = Material(self.opt(f"{n}.material.ambient"), self.opt(f"{n}.material.diffuse"))
        color = self.opt(f"{n}.color")
        if item.kind == "ground":
            normal = self.opt(f"{n}.normal") or E.Const((0.0, 0.0, 1.0))
            point = self.opt(f"{n}.point") or E.Const((0.0, 0.0, 0.0))
            return Body(n, Shape("plane", {"normal": normal}), position=point,
                        orientation=E.Const((1.0, 0.0, 0.0, 0.0)), color=color, material=mat,
                        fixed=True, span=item.span)
        shape = None
        if "shape" in fs:
            shape = self.build_shape(n, fs["shape"])
        fixed = self.flag(fs, "fixed", False) or (shape is not None and shape.kind == "plane")
        mass, density = self.opt(f"{n}.mass"), self.opt(f"{n}.density")
        if "mass" in fs and "density" in fs:
            self.errors.append(self.err(PhysStructureError, f"body '{n}' has both mass and density",
                                        fs["density"].span, "give one of them"))
        if not fixed and "mass" not in fs and "density" not in fs:
            self.errors.append(self.err(PhysStructureError, f"body '{n}' needs a mass or a density",
                                        item.span, "e.g. mass: 200 g  or  density: 1000 kg/m^3"))
        if not fixed and shape is None and "mass" in fs and "inertia" not in fs:
            self.errors.append(self.err(PhysStructureError, f"body '{n}' has no shape and no inertia",
                                        item.span, "give it a shape (or an inertia)"))
        return Body(n, shape, mass, density, self.opt(f"{n}.inertia"), self.opt(f"{n}.position"),
                    self.opt(f"{n}.orientation"), self.opt(f"{n}.velocity"),
                    self.opt(f"{n}.angular_velocity"), color, mat, fixed, item.span)

    def build_shape(self, body: str, f: ast.Field) -> Shape | None:
        node = f.value
        if isinstance(node, ast.Name):
            node = ast.Call(node.name, (), node.span)
        if not isinstance(node, ast.Call) or node.func not in SHAPE_ARGS:
            return None
        if node.func == "mesh":
            if len(node.args) != 1 or not isinstance(node.args[0].value, ast.Str):
                raise self.err(PhysTypeError, "mesh takes one file name: mesh(\"part.obj\")", node.span)
            file = node.args[0].value.value
            p = self.data_file(file, node.args[0].span, "mesh file")
            if not p.is_file():
                raise DataError("mesh file not found", p, span=node.args[0].span,
                                hint="the path is relative to the scene file")
            return Shape("mesh", {}, p)
        size = {}
        for key in SHAPE_ARGS[node.func]:
            e = self.opt(f"{body}.shape.{key}")
            if e is None and f"{body}.shape.{key}" not in self.sources:
                if node.func == "plane" and key == "normal":
                    e = E.Const((0.0, 0.0, 1.0))
                else:
                    raise self.err(PhysTypeError, f"{node.func} needs '{key}'", node.span,
                                   f"e.g. {node.func}({', '.join(k + ': ...' for k in SHAPE_ARGS[node.func])})")
            if e is not None:
                if isinstance(e, E.Const) and key in ("radius", "length", "size") and \
                        np.any(e.array() <= 0) and not (key == "length" and np.all(e.array() == 0)):
                    raise self.err(PhysTypeError, f"the {key} of a {node.func} must be positive",
                                   node.span)
                size[key] = e
        return Shape(node.func, size)

    def build_joint(self, item: ast.JointItem) -> Joint | None:
        if item.kind not in JOINT_KINDS:
            return None
        n = item.name
        for end, role in ((item.parent, "parent"), (item.child, "child")):
            if end == "world" and role == "parent":
                continue
            if end not in self.body_index:
                kind = self.items_by_name.get(end)
                msg = (f"the {role} of joint '{n}' is a {kind}, not a body" if kind else
                       f"joint '{n}': unknown {role} '{end}'"
                       f"{close(end, list(self.body_index) + (['world'] if role == 'parent' else []))}")
                raise self.err(PhysNameError, msg, item.span)
        if item.parent == item.child:
            raise self.err(PhysStructureError, f"joint '{n}' joins '{item.child}' to itself", item.span)
        child = self.body_index[item.child]
        if child.fixed:
            raise self.err(PhysStructureError, f"joint '{n}': the child '{item.child}' is fixed",
                           item.span, "a fixed body cannot move; remove 'fixed: true' or the joint")
        dh = None
        if f"{n}.dh.a" in self.sources:
            vals = [self.opt(f"{n}.dh.{k}") for k in DH_FIELDS]
            if all(v is not None for v in vals):
                dh = DH(*vals)
        axis = self.opt(f"{n}.axis")
        if item.kind in ("hinge", "slider") and axis is None and dh is None \
                and f"{n}.axis" not in self.sources:
            raise self.err(PhysStructureError, f"{item.kind} joint '{n}' needs an axis", item.span,
                           "e.g. axis: (0, 1, 0)")
        if isinstance(axis, E.Const) and not np.any(axis.array()):
            raise self.err(PhysTypeError, f"the axis of joint '{n}' is zero",
                           self.joint_fields[n]["axis"].span)
        lim = self.opt(f"{n}.limits")
        limits = None
        if lim is not None:
            if isinstance(lim, E.Const):
                lo, hi = lim.value
                if lo >= hi:
                    raise self.err(PhysTypeError, f"the limits of joint '{n}' need low < high",
                                   self.joint_fields[n]["limits"].span)
                limits = (E.Const(lo), E.Const(hi))
            else:
                limits = (lim.items[0], lim.items[1]) if isinstance(lim, E.Vec) else None
        return Joint(n, item.kind, item.parent, item.child, axis, self.opt(f"{n}.anchor"), limits,
                     self.opt(f"{n}.initial"), self.opt(f"{n}.initial_velocity"), dh, item.span)

    def check_tree(self, joints: list[Joint]):
        parent_of: dict[str, Joint] = {}
        for j in joints:
            if j.child in parent_of:
                other = parent_of[j.child]
                self.errors.append(self.err(PhysStructureError, f"body '{j.child}' has two parents: "
                                            f"joints '{other.name}' and '{j.name}'", j.span,
                                            "a body hangs from one joint; remove one"))
                continue
            parent_of[j.child] = j
        reported = set()
        for j in joints:
            chain, body = [j.name], j.parent
            while body in parent_of and len(chain) <= len(joints):
                nxt = parent_of[body]
                if nxt.name == j.name:
                    key = frozenset(chain)
                    if key not in reported:
                        reported.add(key)
                        self.errors.append(self.err(
                            PhysStructureError, "joints form a cycle: "
                            + " -> ".join(chain + [j.name]), j.span,
                            "joints form a tree rooted at 'world'; break the cycle"))
                    break
                chain.append(nxt.name)
                body = nxt.parent

    def build_camera(self, item: ast.CameraItem) -> Camera | None:
        n = item.name
        fs = self.fields_of(item.block, CAMERA_FIELDS, "", {"size"}) if False else \
            {f.key: f for f in item.block.fields if isinstance(f, ast.Field)}
        for key in ("position", "look_at"):
            if f"{n}.{key}" not in self.sources:
                raise self.err(PhysStructureError, f"camera '{n}' needs '{key}'", item.span)
        size = (64, 64)
        if "size" in fs:
            node = fs["size"].value
            ok = isinstance(node, ast.Vector) and len(node.items) == 2 and all(
                isinstance(i, ast.Num) and float(i.text).is_integer() and float(i.text) > 0
                for i in node.items)
            if not ok:
                raise self.err(PhysTypeError, "camera 'size' is (width, height) in whole pixels",
                               getattr(node, "span", fs["size"].span), "e.g. size: (64, 64)")
            size = (int(float(node.items[0].text)), int(float(node.items[1].text)))
        return Camera(n, self.opt(f"{n}.position"), self.opt(f"{n}.look_at"),
                      self.opt(f"{n}.up") or E.Const((0.0, 0.0, 1.0)),
                      self.opt(f"{n}.fov") or E.Const(float(np.deg2rad(45.0))), size,
                      self.opt(f"{n}.background"), item.span)

    def build_light(self, item: ast.LightItem) -> Light:
        fs = self.fields_of(item.block, LIGHT_FIELDS, "light")
        for k, f in fs.items():
            self.register(f"light.{k}", f.value, LIGHT_FIELDS[k])
        return Light(self.opt("light.direction") or E.Const((0.0, 0.0, -1.0)),
                     self.opt("light.ambient") or E.Const(0.3),
                     self.opt("light.diffuse") or E.Const(0.7))

    def contact_pairs(self, bodies: list[Body], joints: list[Joint],
                      items=()) -> list[tuple[str, str]]:
        """Default pairs (``collide.contact_pairs``); ``contact a, b`` items switch theirs on."""
        off = {n for n, fs in getattr(self, "body_fields", {}).items()
               if not self.flag(fs, "collide", True)}
        explicit = {frozenset((i.a, i.b)) for i in items if isinstance(i, ast.ContactItem)}
        return collide.contact_pairs(bodies, joints, off, explicit)

    # ---- effects -----------------------------------------------------------------------------
    def target_kind(self, target: tuple[str, ...], span) -> str:
        if target == ("world",):
            return "world"
        if len(target) == 2:
            for t in target:
                if t not in self.body_index:
                    raise self.err(PhysNameError, f"unknown body '{t}'{close(t, self.body_index)}",
                                   span)
            if target[0] == target[1]:
                raise self.err(PhysStructureError, "a pair needs two different bodies", span)
            return "pair"
        t = target[0]
        if t in self.body_index:
            return "body"
        if t in self.joint_index:
            return "joint"
        raise self.err(PhysNameError, f"unknown target '{t}'"
                       f"{close(t, list(self.body_index) + list(self.joint_index) + ['world'])}",
                       span, "an effect acts on a body, a joint, a pair (a, b) or world")

    def effect_use(self, name: str, target: tuple[str, ...], fields: dict, span) -> EffectUse:
        decl = self.effect_library.get(name)
        if decl is None:
            raise self.err(PhysNameError, f"unknown effect '{name}'{close(name, self.effect_library)}",
                           span, "effects: " + ", ".join(sorted(self.effect_library)))
        kind = self.target_kind(target, span)
        kinds = decl.acts_on.split("|")
        if kind not in kinds:
            raise self.err(PhysTypeError, f"effect '{name}' acts on a {' or '.join(kinds)}, but "
                           f"'{','.join(target)}' is a {kind}", span)
        if kind == "pair":
            target = self.pair_order.get(frozenset(target), target)
        key = f"{name}@{','.join(target)}"
        params: dict[str, E.Expr] = {}
        names = [p.name for p in decl.params]
        for k, f in fields.items():
            if k not in names:
                self.errors.append(self.err(PhysNameError, f"effect '{name}' has no parameter "
                                            f"'{k}'{close(k, names)}", f.span,
                                            f"its parameters: {', '.join(names)}"))
        for p in decl.params:
            path = f"{key}.{p.name}"
            dims = self.param_dims.get((name, p.name), (parse_unit(p.unit)[1],))
            if kind == "joint" and len(dims) > 1:
                jk = self.joint_index[target[0]].kind
                dims = (dims[1],) + dims[:1] if jk == "slider" else dims
            sp = Spec(dims, p.shape)
            if p.name in fields:
                f = fields[p.name]
                self.register(path, f.value, sp)
                r = self.collect(self.value, path)
                if r is not None:
                    params[p.name] = r.expr
            elif p.default is not None:
                params[p.name] = p.default
            elif p.prior is not None:
                self.unknowns[path] = Unknown(path, p.prior, p.shape, dims[0].si_text(), span, (), False)
                self.supports[path] = "positive" if p.sign else "real"
                self.memo[path] = R(E.Ref(path), dims[0], p.shape)
                self.resolved_order.append(path)
                params[p.name] = E.Ref(path)
            else:
                raise self.err(PhysStructureError, f"effect '{name}' needs '{p.name}'", span,
                               f"write {p.name}: value (in {p.unit})")
        return EffectUse(name, tuple(target), params, {}, span)

    def contact(self, item: ast.ContactItem, body_names) -> list[EffectUse]:
        fs = self.fields_of(item.block, CONTACT_SUGAR, f"contact {item.a}, {item.b}")
        self.target_kind((item.a, item.b), item.span)
        out = []
        for k, f in fs.items():
            fld = ast.Field(SUGAR_PARAM, f.value, f.span)
            use = self.collect(self.effect_use, CONTACT_SUGAR[k], (item.a, item.b),
                               {SUGAR_PARAM: fld}, item.span)
            if use is not None:
                out.append(use)
        return out

    def control(self, item: ast.ControlItem) -> EffectUse | None:
        kind = self.target_kind((item.target,), item.span)
        if kind not in ("body", "joint"):
            raise self.err(PhysTypeError, "a control acts on a body or a joint", item.span)
        width = 3 if kind == "body" else 1
        if kind == "body":
            vdim = FORCE
        else:
            vdim = FORCE if self.joint_index[item.target].kind == "slider" else TORQUE
        fs = self.fields_of(item.block, {"gain", "times", "values"}, f"control '{item.name}'")
        gain_fields = {"gain": fs["gain"]} if "gain" in fs else {}
        use = self.effect_use("control_force", (item.target,), gain_fields, item.span)
        key = use.key
        params = dict(use.params)
        if item.file is not None:
            if "times" in fs or "values" in fs:
                raise self.err(PhysStructureError, "a control reads its values from the file or "
                               "from the block, not both", item.span)
            if len(item.columns) != width:
                raise self.err(PhysTypeError, f"a control on a {kind} needs {width} column"
                               f"{'s' * (width > 1)}, got {len(item.columns)}", item.span,
                               "e.g. column (fx, fy, fz)" if width == 3 else "e.g. column torque")
            times, values = read_control(self.data_file(item.file, item.span), item.columns,
                                         item.span)
            return EffectUse(use.effect, use.target, params,
                             {"times": times, "values": values if width == 3 else values[:, 0]},
                             item.span)
        if "times" not in fs or "values" not in fs:
            raise self.err(PhysStructureError, f"control '{item.name}' needs 'times' and 'values' "
                           "(or 'from \"file.csv\" column COL')", item.span)
        self.register(f"{key}.times", fs["times"].value, Spec((TIME,), None, True))
        tr = self.value(f"{key}.times")
        times = np.atleast_1d(tr.expr.array())
        if times.ndim != 1 or len(times) < 1 or np.any(np.diff(times) <= 0):
            raise self.err(PhysTypeError, "control 'times' must be increasing", fs["times"].span)
        n = len(times)
        vshape = (n,) if width == 1 else (n, 3)
        self.register(f"{key}.values", fs["values"].value, Spec((vdim,), vshape))
        vr = self.value(f"{key}.values")
        if isinstance(vr.expr, E.Ref):
            params["values"] = vr.expr
            return EffectUse(use.effect, use.target, params, {"times": times}, item.span)
        if not isinstance(vr.expr, E.Const):
            params["values"] = vr.expr
            return EffectUse(use.effect, use.target, params, {"times": times}, item.span)
        return EffectUse(use.effect, use.target, params,
                         {"times": times, "values": vr.expr.array()}, item.span)

    def data_file(self, name: str, span: Span | None, what: str = "data file") -> Path:
        """``name`` relative to the scene's folder, refused when it lies outside the bounds."""
        self.bounds.check(self.base / name, what, name, span, self._text_for(span))
        return self.base / name

    # ---- observations ----------------------------------------------------------------------
    def observe(self, item: ast.ObserveItem):
        q, t = item.quantity, item.target
        name = f"{t}.{q}"
        if q in BODY_QUANTITIES:
            if t in self.marker_index and q in MARKER_QUANTITIES:
                pass
            elif t not in self.body_index:
                markers = " and markers" if q in MARKER_QUANTITIES else ""
                names = list(self.body_index) + (list(self.marker_index) if markers else [])
                raise unknown_target(self, item, "body", names, f"bodies{markers}")
            cols, qdim = BODY_QUANTITIES[q]
        elif q in JOINT_QUANTITIES:
            if t not in self.joint_index:
                raise unknown_target(self, item, "joint", self.joint_index, "joints")
            cols = JOINT_QUANTITIES[q]
            slider = self.joint_index[t].kind == "slider"
            qdim = (LENGTH if slider else ANGLE) if q == "angle" else (VEL if slider else ANGVEL)
        elif q == "image":
            if t not in {c for c, k in self.items_by_name.items() if k == "camera"}:
                raise self.err(PhysNameError, f"images are observed by cameras; unknown camera "
                               f"'{t}'", item.span)
            cols, qdim = (), DIMLESS
        else:
            opts = list(BODY_QUANTITIES) + list(JOINT_QUANTITIES) + ["image"]
            raise self.err(PhysNameError, f"unknown quantity '{q}'{close(q, opts)}", item.span,
                           "quantities: " + ", ".join(opts))
        fs = self.fields_of(item.block, OBSERVE_FIELDS, f"observe {name}")
        if "noise" not in fs:
            raise self.err(PhysStructureError, f"observation '{name}' needs a noise", item.span,
                           "e.g. { noise: 2 mm }  or  { noise ~ half_normal(5 mm) }")
        dim = max(len(cols), 1)
        self.register(f"{name}.noise", fs["noise"].value, Spec((qdim,), None))
        nr = self.value(f"{name}.noise")
        if nr.shape not in ((), (dim,)):
            raise self.err(PhysTypeError, f"noise is one number or one per axis ({dim})",
                           fs["noise"].span)
        if isinstance(nr.expr, E.Const) and np.any(nr.expr.array() <= 0):
            raise self.err(PhysTypeError, "noise must be positive", fs["noise"].span)
        kind = "normal"
        df = None
        if "model" in fs:
            node = fs["model"].value
            kind = node.name if isinstance(node, ast.Name) else ""
            if kind not in ("normal", "student_t"):
                raise self.err(PhysNameError, f"unknown noise model '{kind}'"
                               f"{close(kind, ['normal', 'student_t'])}", fs["model"].span,
                               "model: normal | student_t")
        if "df" in fs:
            self.register(f"{name}.df", fs["df"].value, spec(DIMLESS))
            df = self.value(f"{name}.df").expr
        elif kind == "student_t":
            df = E.Const(4.0)
        noise = Noise(kind, nr.expr, df)
        file = self.data_file(item.file, item.span)
        if q == "image":
            if any(k in fs for k in SENSOR_FIELDS):
                raise self.err(PhysStructureError, "images take no sensor terms", item.span,
                               "offset, gain and delay are for trajectory observations")
            rate = None
            if item.rate is not None:
                self.register(f"{name}.rate", item.rate, spec(FREQ, (), True))
                rate = float(self.value(f"{name}.rate").expr.array())
            frames, times = read_image_times(self.base, item.file, rate,
                                             self.data_file(item.times, item.span)
                                             if item.times else None, item.span)
            for f in frames:
                if isinstance(f, Path):  # a frame file may be a link out of the folder
                    self.bounds.check(f, "image file", f.name, item.span, self.source)
            return Observation(name, t, q, file, times, np.zeros((len(times), 0)),
                                np.zeros((len(times), 0), bool), (), noise, frames, item.span)
        if item.rate is not None or item.times is not None:
            raise self.err(PhysStructureError, "'at' and 'times' are for image observations; "
                           "a CSV file has its own column t", item.span)
        check_label(self, item, file, self.items_by_name)  # the label may differ from t
        times, values, mask = read_observation(file, cols, item.where, item.span)
        sensor = resolve_sensor(self, item, name, qdim, dim, fs)
        return Observation(name, t, q, file, times, values, mask, tuple(cols), noise, (), item.span,
                            sensor)


class _Any:
    """Accepts every key (effect params are checked against the declaration later)."""

    def __contains__(self, key):
        return True

    def __iter__(self):
        return iter(())


def resolve(module: ast.Module, source: str, base_dir: Path, path: Path | None = None,
            allowed_paths=()) -> Scene:
    """The checked Scene of a parsed module (``base_dir``: where data and imports are found;
    files outside it, the stdlib and ``allowed_paths`` are refused)."""
    try:
        return Resolver(module, source, Path(base_dir), path,
                        Bounds.around(base_dir, allowed_paths)).run()
    except PhysError as ex:  # errors inside loops name their iteration
        raise annotate(ex) from None
