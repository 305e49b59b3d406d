"""Canonical .phys text from the AST, keeping comments and single blank lines.

Rules: two-space indent; one item or field per line; a block with at most two plain fields
and no comments inside is written on one line (``{ noise: 2 mm }``), and so is a loop of one
such item (up to 120 columns); operators get spaces
except ``^``; numbers and units are printed as written. Comments stay where they were:
whole-line comments before the next node, end-of-line comments after their line. A blank
line in the source before a node (or a comment) is kept as one blank line.
"""
from __future__ import annotations

import re

from .. import expr as E
from . import ast

INDENT = "  "
MAX_INLINE = 100
LOOP_INLINE = 120  # a loop of one one-line item (``for i in 1..6 { observe .. }``) stays whole
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


# ---- expressions ---------------------------------------------------------------------------

def _q(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _level(node) -> int:
    if isinstance(node, ast.BinOp):
        return {"+": 1, "-": 1, "*": 2, "/": 2, "^": 4}[node.op]
    if isinstance(node, ast.Neg):
        return 3
    if isinstance(node, ast.WithUnit):
        return 5
    return 6


def _wrap(node, need: int) -> str:
    text = format_expr(node)
    return f"({text})" if _level(node) < need else text


def _args(args) -> str:
    return ", ".join((f"{a.name}: " if a.name is not None else "") + format_expr(a.value)
                     for a in args)


def format_expr(node) -> str:
    """Text of an expression (or a Dist, written ``~ name(..)``)."""
    if isinstance(node, ast.Num):
        return node.text
    if isinstance(node, ast.Str):
        return _q(node.value)
    if isinstance(node, ast.Name):
        return node.name
    if isinstance(node, ast.Dotted):
        return ".".join(node.parts)
    if isinstance(node, ast.Vector):
        return "(" + ", ".join(format_expr(i) for i in node.items) + ")"
    if isinstance(node, ast.Record):
        return "(" + _args(node.fields) + ")"
    if isinstance(node, ast.Call):
        return f"{node.func}({_args(node.args)})"
    if isinstance(node, ast.Neg):
        return "-" + _wrap(node.operand, 3)
    if isinstance(node, ast.WithUnit):
        v = node.value
        inner = format_expr(v) if isinstance(v, (ast.Num, ast.Vector, ast.Call)) else f"({format_expr(v)})"
        return f"{inner} {node.unit}"
    if isinstance(node, ast.BinOp):
        if node.op == "^":
            left = format_expr(node.left)
            if _level(node.left) < 6:
                left = f"({left})"
            return f"{left}^{_wrap(node.right, 3)}"
        lv = _level(node)
        return f"{_wrap(node.left, lv)} {node.op} {_wrap(node.right, lv + 1)}"
    if isinstance(node, ast.Dist):
        per = "per_experiment " if node.per_experiment else ""
        return f"{per}{node.name}({_args(node.args)})"
    raise TypeError(f"not an expression: {node!r}")


def format_field(f) -> str:
    if isinstance(f, ast.MaterialBlock):
        return "material " + _inline_block(f.block)
    if isinstance(f.value, ast.Dist):
        return f"{f.key} ~ {format_expr(f.value)}"
    return f"{f.key}: {format_expr(f.value)}"


def _inline_block(b: ast.Block) -> str:
    if not b.fields:
        return "{}"
    return "{ " + "  ".join(format_field(f) for f in b.fields) + " }"


def format_value_expr(e: E.Expr) -> str:
    """Text of a resolved (SI) expression, for reports."""
    if isinstance(e, E.Const):
        v = e.value
        return f"{v:.4g}" if isinstance(v, float) else "(" + ", ".join(
            format_value_expr(E.Const(x)) for x in v) + ")"
    if isinstance(e, E.Ref):
        return e.name
    if isinstance(e, E.Unary):
        return f"-{format_value_expr(e.operand)}"
    if isinstance(e, E.Binary):
        return f"({format_value_expr(e.left)} {e.op} {format_value_expr(e.right)})"
    if isinstance(e, E.Call):
        return f"{e.func}({', '.join(format_value_expr(a) for a in e.args)})"
    if isinstance(e, E.Vec):
        return "(" + ", ".join(format_value_expr(i) for i in e.items) + ")"
    return "?"


def format_prior(p) -> str:
    args = [format_value_expr(a) for a in p.args] + [f"{k}: {format_value_expr(v)}" for k, v in p.kwargs]
    return f"{p.dist}({', '.join(args)})"


def format_goal_term(t) -> str:
    """One line of a ``goal`` block: a reach, a hold, or ``key: value, ...``."""
    if isinstance(t, ast.ReachTerm):
        return (f"{t.target}.{t.quantity} at {format_expr(t.at)} -> {format_expr(t.point)} "
                f"within {format_expr(t.within)}")
    if isinstance(t, ast.HoldTerm):
        return (f"{t.target}.{t.quantity} from {format_expr(t.start)} to {format_expr(t.end)} "
                f"-> {format_expr(t.value)} within {format_expr(t.within)}")
    return f"{t.key}: " + ", ".join(format_expr(v) for v in t.values)


# ---- items with comments -------------------------------------------------------------------

def _start(node):
    s = getattr(node, "span", None)
    return (s.line, s.column) if s else None


def _end(node):
    s = getattr(node, "span", None)
    return (s.end_line, s.end_column) if s and s.end_line else None


class _Printer:
    def __init__(self, module: ast.Module, source: str | None):
        self.comments = sorted(module.comments, key=lambda c: (c.span.line, c.span.column)) \
            if all(c.span for c in module.comments) else list(module.comments)
        self.ci = 0
        self.src = source.splitlines() if source else []
        self.out: list[str] = []
        self.tails: dict[int, str] = {}  # output line index -> its end-of-line comment
        self.last_line = 0  # the source line of the last node asked for a blank line before it

    # comments and blank lines
    def _blank_before(self, line: int | None):
        if line is None or not self.src or line < 2 or line - 2 >= len(self.src):
            return
        if line == self.last_line:  # not the first node on its source line
            return
        self.last_line = line
        if self.src[line - 2].strip() == "" and self.out and self.out[-1] != "" \
                and not self.out[-1].endswith("{"):
            self.out.append("")

    def flush(self, upto, indent: str):
        """Emit whole-line comments that come before position ``upto`` (all if None)."""
        while self.ci < len(self.comments):
            c = self.comments[self.ci]
            pos = (c.span.line, c.span.column) if c.span else None
            if upto is not None and pos is not None and pos >= upto:
                break
            self._blank_before(c.span.line if c.span else None)
            self.out.append(indent + c.text)
            self.ci += 1

    def trailing(self, end):
        """Attach the comment on the node's last line, after it, to the last output line."""
        if end is None or self.ci >= len(self.comments):
            return
        c = self.comments[self.ci]
        if c.span and c.span.line == end[0] and c.span.column >= end[1] - 1:
            self.tails[len(self.out) - 1] = c.text
            self.ci += 1

    def has_comments_in(self, node) -> bool:
        s, e = _start(node), _end(node)
        if s is None or e is None:
            return False
        return any(s < (c.span.line, c.span.column) < e for c in self.comments[self.ci:] if c.span)

    # nodes
    def leaf(self, text: str, node, indent: str):
        start, end = _start(node), _end(node)
        if end is not None:
            self.flush(end, indent)
        self._blank_before(start[0] if start else None)
        self.out.append(indent + text)
        self.trailing(end)

    def block_item(self, header: str, block: ast.Block | None, node, indent: str, force_multi=False):
        if block is None:
            self.leaf(header, node, indent)
            return
        fields = block.fields
        inline = (not force_multi and len(fields) <= 2
                  and not any(isinstance(f, ast.MaterialBlock) for f in fields)
                  and not self.has_comments_in(block))
        text = f"{header} {_inline_block(block)}"
        if inline and len(indent + text) <= MAX_INLINE:
            self.leaf(text, node, indent)
            return
        start = _start(node)
        if start is not None:
            self.flush(start, indent)
            self._blank_before(start[0])
        self.out.append(f"{indent}{header} {{")
        inner = indent + INDENT
        bstart = _start(block)
        if bstart is not None:
            self.trailing((bstart[0], bstart[1] + 1))
        for f in fields:
            if isinstance(f, ast.MaterialBlock):
                self.block_item("material", f.block, f, inner)
            else:
                self.leaf(format_field(f), f, inner)
        end = _end(block)
        if end is not None:
            self.flush((end[0], end[1] - 1), inner)
        self.out.append(f"{indent}}}")
        self.trailing(end)

    def item(self, it, indent: str):
        if isinstance(it, ast.Import):
            self.leaf(f"import {_q(it.path)}", it, indent)
        elif isinstance(it, ast.Param):
            self.leaf("param " + format_field(ast.Field(it.name, it.value)), it, indent)
        elif isinstance(it, ast.WorldItem):
            self.block_item("world", it.block, it, indent)
        elif isinstance(it, ast.BodyItem):
            self.block_item(f"{it.kind} {it.name}", it.block, it, indent)
        elif isinstance(it, ast.JointItem):
            self.block_item(f"joint {it.name}: {it.kind}({it.parent} -> {it.child})", it.block, it,
                            indent)
        elif isinstance(it, ast.ContactItem):
            self.block_item(f"contact {it.a}, {it.b}", it.block, it, indent)
        elif isinstance(it, ast.EffectItem):
            target = it.target[0] if len(it.target) == 1 else f"({it.target[0]}, {it.target[1]})"
            self.block_item(f"effect {it.effect} on {target}", it.block, it, indent)
        elif isinstance(it, ast.ControlItem):
            head = f"control {it.name} on {it.target}"
            if it.file is not None or it.setting is not None:
                cols = [c if _NAME_RE.match(c) else _q(c) for c in it.columns]
                col = cols[0] if len(cols) == 1 and _NAME_RE.match(it.columns[0]) else \
                    ("(" + ", ".join(cols) + ")" if len(cols) > 1 else cols[0])
                src = _q(it.file) if it.file is not None else it.setting
                head += f" from {src} column {col}"
            self.block_item(head, it.block, it, indent)
        elif isinstance(it, ast.CameraItem):
            self.block_item(f"camera {it.name}", it.block, it, indent)
        elif isinstance(it, ast.LightItem):
            self.block_item("light", it.block, it, indent)
        elif isinstance(it, ast.ObserveItem):
            head = f"observe {it.target}.{it.quantity} from {_q(it.file)}"
            if it.where:
                head += f" where {it.where[0]} == {_q(it.where[1])}"
            if it.rate is not None:
                head += f" at {format_expr(it.rate)}"
            if it.times is not None:
                head += f" times {_q(it.times)}"
            self.block_item(head, it.block, it, indent)
        elif isinstance(it, ast.MarkerItem):
            self.block_item(f"marker {it.name} on {it.body}", it.block, it, indent)
        elif isinstance(it, ast.AliasItem):
            self.leaf(f"alias {it.name} = {it.target}", it, indent)
        elif isinstance(it, ast.ExperimentsItem):
            self.leaf(f"experiments {it.name} from {_q(it.source)}", it, indent)
        elif isinstance(it, ast.ForLoop):
            self.loop(it, indent)
        elif isinstance(it, ast.GoalItem):
            self.container("goal", it.terms, it, indent)
        elif isinstance(it, (ast.ReachTerm, ast.HoldTerm, ast.GoalField)):
            self.leaf(format_goal_term(it), it, indent)
        elif isinstance(it, ast.SceneDecl):
            self.container(f"scene {it.name}", it.items, it, indent)
        elif isinstance(it, ast.EffectType):
            self.effect_type(it, indent)
        else:
            raise TypeError(f"cannot print {it!r}")

    def loop(self, it: ast.ForLoop, indent: str):
        """A loop of one short item and no comments on one line, else as a container."""
        header = f"for {it.var} in {it.start}..{it.stop}"
        if len(it.items) == 1 and not self.has_comments_in(it):
            one = _Printer(ast.Module(()), None)
            one.item(it.items[0], "")
            text = f"{header} {{ {one.out[0]} }}" if len(one.out) == 1 else ""
            if text and len(indent + text) <= LOOP_INLINE:
                self.leaf(text, it, indent)
                return
        self.container(header, it.items, it, indent)

    def container(self, header: str, items, node, indent: str):
        start = _start(node)
        if start is not None:
            self.flush(start, indent)
            self._blank_before(start[0])
        self.out.append(f"{indent}{header} {{")
        for it in items:
            self.item(it, indent + INDENT)
        end = _end(node)
        if end is not None:
            self.flush((end[0], end[1] - 1), indent + INDENT)
        self.out.append(f"{indent}}}")
        self.trailing(end)

    def effect_type(self, it: ast.EffectType, indent: str):
        start = _start(it)
        if start is not None:
            self.flush(start, indent)
            self._blank_before(start[0])
        self.out.append(f"{indent}effect_type {it.name} on {' or '.join(it.acts_on)} {{")
        inner = indent + INDENT
        self.out.append(f"{inner}doc: {_q(it.doc)}")
        for p in it.params:
            text = f"param {p.name}: " + ("vector " if p.vector else "") + " | ".join(p.units)
            if p.default is not None:
                text += f" = {format_expr(p.default)}"
            if p.prior is not None:
                text += f" ~ {format_expr(p.prior)}"
            if p.off is not None:
                text += f" off {format_expr(p.off)}"
            if p.strength is not None:
                text += " strength" + ("" if p.strength == "either" else f" {p.strength}")
            self.leaf(text, p, inner)
        end = _end(it)
        if end is not None:
            self.flush((end[0], end[1] - 1), inner)
        self.out.append(f"{indent}}}")
        self.trailing(end)


def format_module(module: ast.Module, source: str | None = None) -> str:
    """Canonical text of a module; ``source`` (the text it was parsed from) keeps blank lines."""
    p = _Printer(module, source)
    for i, it in enumerate(module.items):
        if i and isinstance(it, (ast.SceneDecl, ast.EffectType)) and p.out and p.out[-1] != "":
            start = _start(it)
            first_comment = p.comments[p.ci] if p.ci < len(p.comments) else None
            if start is None or first_comment is None or \
                    (first_comment.span.line, first_comment.span.column) >= start:
                p.out.append("")
        p.item(it, "")
    p.flush(None, "")
    return "\n".join(_align(p.out, p.tails)).rstrip("\n") + "\n"


def _align(lines: list[str], tails: dict[int, str]) -> list[str]:
    """Attach end-of-line comments, aligned within runs of consecutive commented lines."""
    out = list(lines)
    i = 0
    while i < len(lines):
        if i not in tails:
            i += 1
            continue
        j = i
        while j + 1 in tails:
            j += 1
        col = max(len(lines[k]) for k in range(i, j + 1)) + 2
        for k in range(i, j + 1):
            out[k] = lines[k].ljust(col) + tails[k]
        i = j + 1
    return out
