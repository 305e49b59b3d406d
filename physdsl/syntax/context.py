"""The state of resolving one scene: its field sources, resolved on demand by dotted path
(``ball.mass``, ``rod.shape.radius``, ``L``) so fields may refer to each other in any order
(a cycle is an error), the names it knows, and the errors collected so far.

The builders (``bodies``, ``joints``, ``effects``, ``observations``, ...) are functions of a
``Resolver``; ``resolve.py`` runs them in order.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import expr as E
from ..errors import PhysError, PhysErrors, PhysNameError, PhysStructureError, PhysTypeError, Span
from ..scene import Body, EffectDecl, Joint, Marker, Unknown
from . import ast
from .bounds import Bounds
from .checks import check
from .expressions import PI, R, Scope, to_expr
from .library import Loaded
from .priors import make_unknown
from .schema import Spec
from .units import Dim
from .words import close


class Poisoned(PhysError):
    """A reference to a field that already failed: not reported again."""


class AnyKey:
    """Accepts every key (effect params are checked against the declaration later)."""

    def __contains__(self, key):
        return True

    def __iter__(self):
        return iter(())


class Resolver:
    """Resolves one scene module (with its library) into a Scene: the shared state."""

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
        self.supports: dict[str, str] = {}  # unknown -> words for its support
        self.resolved_order: list[str] = []
        self.items_by_name: dict[str, str] = {}  # body/joint/camera name -> kind
        self.scope = Scope(self.lookup, self.is_param, self.err)
        self.lib: Loaded | None = None
        # the library's effects and the dimensions their parameters accept
        self.effect_library: dict[str, EffectDecl] = {}
        self.param_dims: dict[tuple[str, str], tuple[Dim, ...]] = {}
        # declared items (ast), their fields by key, and the built ones by name
        self.bodies: list[ast.BodyItem] = []
        self.joints: list[ast.JointItem] = []
        self.cameras: list[ast.CameraItem] = []
        self.markers: list[ast.MarkerItem] = []
        self.body_fields: dict[str, dict] = {}
        self.joint_fields: dict[str, dict] = {}
        self.body_index: dict[str, Body] = {}
        self.joint_index: dict[str, Joint] = {}
        self.marker_index: dict[str, Marker] = {}
        self.pair_order: dict[frozenset, tuple[str, str]] = {}
        # experiments (syntax/experiments.py): the first recording's folder, settings' names
        self.observation_base: Path | None = None
        self.setting_names: set[str] = set()
        self.experiments_name: str | None = None  # its NAME, even when reading it failed
        self.recording_sources: list = []  # the recordings as listed (experiments.Source)
        self.recording_tables: dict[str, list] = {}  # per-recording arrays (controls) by key

    def err(self, cls, msg, span, hint=None, source=None):
        """The error ``cls(msg, span, hint)`` with the text of the file ``span`` lies in."""
        return cls(msg, span, hint, source=source if source is not None else self._text_for(span))

    def _text_for(self, span: Span | None) -> str | None:
        if span is None:
            return None
        if span.file == self.m.filename:
            return self.source
        return self.lib.sources.get(span.file) if self.lib is not None else None

    def collect(self, fn, *args):
        """Run ``fn``; record a PhysError instead of raising it (one item's failure)."""
        try:
            return fn(*args)
        except Poisoned:
            return None
        except PhysErrors as ex:
            self.errors.extend(ex.errors)
        except PhysError as ex:
            if ex.source is None:
                ex.source = self._text_for(ex.span)
            self.errors.append(ex)
        return None

    def register(self, path: str, node, spec_: Spec | None):
        """Field ``path`` is written as ``node`` and accepts ``spec_`` (resolved on demand)."""
        self.sources[path] = (node, spec_, "")

    def value(self, path: str, span: Span | None = None) -> R:
        """The resolved value of field ``path`` (memoised; a reference cycle is an error)."""
        if path in self.memo:
            return self.memo[path]
        if path in self.failed:
            raise Poisoned("")
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
            return make_unknown(self, path, node, dim, shape, spec_)
        if isinstance(node, R):  # a known per-recording setting (syntax/experiments.py)
            return node
        if isinstance(node, E.Const):  # a default already in SI
            return R(node, spec_.dims[0] if spec_ else None, np.shape(node.value))
        r = self.expr(node)
        if spec_ is None:
            return r
        return self.check(r, spec_, label, node)

    def check(self, r: R, spec_: Spec, label: str, node) -> R:
        """``r`` held to ``spec_`` (``checks.check``)."""
        return check(r, spec_, label, node, self.err)

    def expr(self, node) -> R:
        """The R of an expression written in this scene (``expressions.to_expr``)."""
        return to_expr(node, self.scope)

    def lookup(self, node) -> R:
        """The R a name or dotted path of the scene refers to (resolved on demand)."""
        return self.name(node) if isinstance(node, ast.Name) else self.dotted(node)

    def is_param(self, word: str) -> bool:
        """Whether ``word`` is the name of a param (or library param)."""
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
                           "only fields written in the scene (and shape sizes) can be referred to"
                           if self.items_by_name[head] != "experiments" else "its fields are "
                           "the manifest's setting columns: " + (", ".join(fields) or "none"))
        names = list(self.items_by_name) + [p for p in self.sources if "." not in p]
        raise self.err(PhysNameError, f"unknown name '{head}'{close(head, names)}", node.span)

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
        """Register the fields of item ``name``'s block that ``table`` lists; return all of them."""
        fs = self.fields_of(block, table, f"{what} '{name}'", extra)
        for k, f in fs.items():
            if k in table:
                self.register(f"{name}.{k}", f.value, table[k])
        return fs

    def opt(self, path: str) -> E.Expr | None:
        """The Expr of field ``path``, None when not written (or when it failed: recorded)."""
        if path not in self.sources:
            return None
        r = self.collect(self.value, path)
        return r.expr if r is not None else None

    def flag(self, fs: dict, key: str, default: bool) -> bool:
        """The true/false field ``key`` of ``fs`` (``default`` when absent)."""
        f = fs.get(key)
        if f is None:
            return default
        if isinstance(f.value, ast.Name) and f.value.name in ("true", "false"):
            return f.value.name == "true"
        self.errors.append(self.err(PhysTypeError, f"'{key}' is true or false", f.value.span
                                    if hasattr(f.value, "span") else f.span))
        return default

    def data_file(self, name: str, span: Span | None, what: str = "data file",
                  base: Path | None = None) -> Path:
        """``name`` relative to the scene's folder (or ``base``), refused when it lies outside
        the bounds."""
        base = self.base if base is None else base
        self.bounds.check(base / name, what, name, span, self._text_for(span))
        return base / name

    def raise_errors(self):
        """Raise the errors collected so far (one, or all as PhysErrors)."""
        if not self.errors:
            return
        for e in self.errors:
            if e.source is None:
                e.source = self._text_for(e.span)
        raise self.errors[0] if len(self.errors) == 1 else PhysErrors(self.errors)
