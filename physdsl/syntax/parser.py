"""Text -> ``ast.Module`` with the LALR grammar in ``grammar/phys.lark``.

Syntax errors are reported in words ("expected '}' to close the block 'body ball' opened at
line 3"), never with Lark's token names; comments are collected separately so the printer
can put them back.
"""
from __future__ import annotations

import re
from functools import lru_cache

from lark import Lark, Token, Transformer, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from ..errors import PhysSyntaxError, Span
from . import ast
from .shipped import GRAMMAR_DIR


@lru_cache(maxsize=1)
def _lark() -> Lark:
    return Lark.open(str(GRAMMAR_DIR / "phys.lark"), parser="lalr", propagate_positions=True,
                     cache=True, start=["start", "field_only"])


def _span(file: str, meta) -> Span | None:
    if getattr(meta, "empty", True):
        return None
    return Span(file, meta.line, meta.column, meta.end_line, meta.end_column)


def _tspan(file: str, tok: Token) -> Span:
    return Span(file, tok.line, tok.column, tok.end_line, tok.end_column)


def unquote(text: str) -> str:
    return re.sub(r'\\(.)', r'\1', text[1:-1])


@v_args(meta=True)
class _ToAst(Transformer):
    """Lark tree -> ast nodes (bottom-up)."""

    def __init__(self, file: str):
        super().__init__()
        self.f = file

    def _s(self, meta):
        return _span(self.f, meta)

    # items
    def start(self, meta, ch):
        return tuple(ch)

    def field_only(self, meta, ch):
        return ch[0]

    def import_(self, meta, ch):
        return ast.Import(unquote(ch[0]), self._s(meta))

    def scene(self, meta, ch):
        return ast.SceneDecl(str(ch[0]), tuple(ch[1:]), self._s(meta))

    def world(self, meta, ch):
        return ast.WorldItem(ch[0], self._s(meta))

    def param_value(self, meta, ch):
        return ast.Param(str(ch[0]), ch[1], self._s(meta))

    param_dist = param_value

    def body(self, meta, ch):
        return ast.BodyItem("body", str(ch[0]), ch[1], self._s(meta))

    def ground(self, meta, ch):
        return ast.BodyItem("ground", str(ch[0]), ch[1], self._s(meta))

    def joint(self, meta, ch):
        return ast.JointItem(str(ch[0]), str(ch[1]), str(ch[2]), str(ch[3]), ch[4], self._s(meta))

    def contact(self, meta, ch):
        return ast.ContactItem(str(ch[0]), str(ch[1]), ch[2], self._s(meta))

    def effect(self, meta, ch):
        return ast.EffectItem(str(ch[0]), ch[1], ch[2], self._s(meta))

    def target_one(self, meta, ch):
        return (str(ch[0]),)

    def target_pair(self, meta, ch):
        return (str(ch[0]), str(ch[1]))

    def control(self, meta, ch):
        src = ch[2]
        file, cols = (src if src is not None else (None, ()))
        if isinstance(file, ast.Dotted):  # a manifest column naming each recording's file
            return ast.ControlItem(str(ch[0]), str(ch[1]), None, cols, ch[3], self._s(meta),
                                   ".".join(file.parts))
        return ast.ControlItem(str(ch[0]), str(ch[1]), file, cols, ch[3], self._s(meta))

    def control_source(self, meta, ch):
        cols = tuple(unquote(c) if c.type == "STRING" else str(c) for c in ch[1:])
        return (ch[0] if isinstance(ch[0], ast.Dotted) else unquote(ch[0]), cols)

    def camera(self, meta, ch):
        return ast.CameraItem(str(ch[0]), ch[1], self._s(meta))

    def light(self, meta, ch):
        return ast.LightItem(ch[0], self._s(meta))

    def observe(self, meta, ch):
        return ast.ObserveItem(str(ch[0]), str(ch[1]), unquote(ch[2]), ch[3], ch[4], ch[5], ch[6],
                               self._s(meta))

    def marker(self, meta, ch):
        return ast.MarkerItem(str(ch[0]), str(ch[1]), ch[2], self._s(meta))

    def alias(self, meta, ch):
        return ast.AliasItem(str(ch[0]), str(ch[1]), self._s(meta))

    def loop(self, meta, ch):
        start, stop = (int(x) for x in str(ch[1]).split(".."))
        return ast.ForLoop(str(ch[0]), start, stop, tuple(ch[2:]), self._s(meta))

    def goal(self, meta, ch):
        return ast.GoalItem(tuple(ch), self._s(meta))

    def goal_reach(self, meta, ch):
        target, quantity = str(ch[0]).split(".")
        return ast.ReachTerm(target, quantity, ch[1], ch[2], ch[3], self._s(meta))

    def goal_hold(self, meta, ch):
        target, quantity = str(ch[0]).split(".")
        return ast.HoldTerm(target, quantity, ch[1], ch[2], ch[3], ch[4], self._s(meta))

    def goal_field(self, meta, ch):
        return ast.GoalField(str(ch[0]), tuple(ch[1:]), self._s(meta))

    def where(self, meta, ch):
        value = unquote(ch[1]) if ch[1].type == "STRING" else str(ch[1])
        return (str(ch[0]), value)

    def rate(self, meta, ch):
        return ch[0]

    def times(self, meta, ch):
        return unquote(ch[0])

    def block(self, meta, ch):
        return ast.Block(tuple(ch), self._s(meta))

    def field_value(self, meta, ch):
        return ast.Field(str(ch[0]), ch[1], self._s(meta))

    field_dist = field_value

    def material(self, meta, ch):
        return ast.MaterialBlock(ch[0], self._s(meta))

    def dist(self, meta, ch):
        return ast.Dist(str(ch[1]), tuple(a for a in ch[2:] if a is not None), self._s(meta),
                        ch[0] is not None)

    def experiments(self, meta, ch):
        return ast.ExperimentsItem(str(ch[0]), unquote(ch[1]), self._s(meta))

    # library declarations
    def effect_type(self, meta, ch):
        name = str(ch[0])
        kinds, doc, params = [], "", []
        for c in ch[1:]:
            if isinstance(c, Token):
                kinds.append(str(c))
            elif isinstance(c, tuple) and c[0] == "doc":
                doc = c[1]
            elif isinstance(c, ast.ParamDecl):
                params.append(c)
        return ast.EffectType(name, tuple(kinds), doc, tuple(params), self._s(meta))

    def doc(self, meta, ch):
        if str(ch[0]) != "doc":
            raise PhysSyntaxError(f"unknown field '{ch[0]}' in an effect_type", _tspan(self.f, ch[0]),
                                  hint="an effect_type holds 'doc: \"...\"' and 'param' lines")
        return ("doc", unquote(ch[1]))

    def param_decl(self, meta, ch):
        units, opts = [], {}
        for c in ch[2:]:
            if isinstance(c, tuple):
                if c[0] == "unit":
                    units.append(c[1])
                else:
                    opts[c[0]] = c[1]
        return ast.ParamDecl(str(ch[0]), tuple(units), ch[1] is not None, opts.get("default"),
                             opts.get("prior"), opts.get("off"), opts.get("strength"),
                             self._s(meta))

    def unit_spec(self, meta, ch):
        return ("unit", str(ch[0]))

    def default(self, meta, ch):
        return ("default", ch[0])

    def prior(self, meta, ch):
        return ("prior", ch[0])

    def off(self, meta, ch):
        return ("off", ch[0])

    def strength(self, meta, ch):
        return ("strength", str(ch[0]) if ch[0] is not None else "either")

    # expressions
    def _bin(op):  # noqa: N805
        def f(self, meta, ch):
            return ast.BinOp(op, ch[0], ch[1], self._s(meta))
        return f

    add, sub, mul, div, pow = _bin("+"), _bin("-"), _bin("*"), _bin("/"), _bin("^")

    def neg(self, meta, ch):
        return ast.Neg(ch[0], self._s(meta))

    def with_unit(self, meta, ch):
        return ast.WithUnit(ch[0], str(ch[1]), self._s(meta), _tspan(self.f, ch[1]))

    def number(self, meta, ch):
        return ast.Num(str(ch[0]), _tspan(self.f, ch[0]))

    def name(self, meta, ch):
        return ast.Name(str(ch[0]), _tspan(self.f, ch[0]))

    def string(self, meta, ch):
        return ast.Str(unquote(ch[0]), _tspan(self.f, ch[0]))

    def vector(self, meta, ch):
        return ast.Vector(tuple(ch), self._s(meta))

    def record(self, meta, ch):
        fields = tuple(ast.Arg(str(ch[i]), ch[i + 1], _tspan(self.f, ch[i]))
                       for i in range(0, len(ch), 2))
        return ast.Record(fields, self._s(meta))

    def dotted(self, meta, ch):
        return ast.Dotted(tuple(str(c) for c in ch), self._s(meta))

    def call(self, meta, ch):
        return ast.Call(str(ch[0]), tuple(a for a in ch[1:] if a is not None), self._s(meta))

    def arg_pos(self, meta, ch):
        return ast.Arg(None, ch[0], self._s(meta))

    def arg_kw(self, meta, ch):
        return ast.Arg(str(ch[0]), ch[1], self._s(meta))


def comments(text: str, file: str) -> tuple[ast.Comment, ...]:
    """Every ``#`` comment outside strings, in order."""
    out = []
    for lineno, line in enumerate(text.splitlines(), 1):
        in_str = False
        i = 0
        while i < len(line):
            c = line[i]
            if in_str:
                if c == "\\":
                    i += 1
                elif c == '"':
                    in_str = False
            elif c == '"':
                in_str = True
            elif c == "#":
                body = line[i:].rstrip()
                out.append(ast.Comment(body, Span(file, lineno, i + 1, lineno, len(line) + 1)))
                break
            i += 1
    return tuple(out)


def parse(text: str, filename: str = "<string>") -> ast.Module:
    """Parse .phys text into a Module; raise PhysSyntaxError (in words) on bad syntax."""
    try:
        items = _ToAst(filename).transform(_lark().parse(text, start="start"))
    except UnexpectedInput as ex:
        raise syntax_error(ex, text, filename) from None
    except PhysSyntaxError as ex:
        ex.source = text
        raise
    except Exception as ex:  # lark wraps transformer errors
        inner = getattr(ex, "orig_exc", None)
        if isinstance(inner, PhysSyntaxError):
            inner.source = text
            raise inner from None
        raise
    return ast.Module(tuple(items), comments(text, filename), filename)


def parse_field(text: str, filename: str = "<edit>") -> ast.Field:
    """Parse one field (``key: value`` or ``key ~ dist(..)``)."""
    try:
        return _ToAst(filename).transform(_lark().parse(text, start="field_only"))
    except UnexpectedInput as ex:
        raise syntax_error(ex, text, filename) from None


# ---- syntax errors in words ------------------------------------------------------------------

_WORDS = {
    "KEY": "a field name followed by ':'",
    "NAME": "a name",
    "TNAME": "a name",
    "TKEY": "a field name followed by ':'",
    "RANGE": "a range of whole numbers like 1..6",
    "UNIT": "a unit",
    "NUMBER": "a number",
    "STRING": "a string in double quotes",
    "$END": "the end of the file",
    "SIDE": "'above' or 'below'",
    "VECTOR": "'vector'",
    "GOAL_TARGET": "a goal term ('ITEM.QUANTITY at ...' or 'ITEM.QUANTITY from ...')",
}
_VALUE_START = {"NUMBER", "NAME", "LPAR", "MINUS", "PLUS", "STRING"}
_VALUE_WORDS = "a value (number, vector, name or '~ dist(...)')"
_ITEM_WORDS = {"scene", "world", "param", "body", "ground", "joint", "contact", "effect",
               "control", "camera", "light", "observe", "import", "effect_type", "marker",
               "for", "alias", "goal", "experiments"}


def _term_words(name: str) -> str:
    if name in _WORDS:
        return _WORDS[name]
    for t in _lark().terminals:
        if t.name == name and t.pattern.type == "str":
            return f"'{t.pattern.value}'"
    return name.lower()


def _found(tok) -> str:
    if tok is None or getattr(tok, "type", None) == "$END":
        return "the end of the file"
    text = str(tok)
    if tok.type == "STRING":
        return f"the string {text}"
    return f"'{text}'"


def _describe_expected(expected: set[str]) -> str:
    names = set(expected)
    parts = []
    if names & _VALUE_START and ("NUMBER" in names or "LPAR" in names):
        parts.append(_VALUE_WORDS)
        names -= _VALUE_START | {"TILDE"}
    if {"KEY", "RBRACE"} <= names:
        parts.append("a field (like 'mass: 1 kg') or '}'")
        names -= {"KEY", "RBRACE", "MATERIAL"}
    if "SCENE" in names:
        parts.append("'scene NAME { ... }', 'import', 'param' or 'effect_type'")
        names -= {"SCENE", "IMPORT", "PARAM", "EFFECT_TYPE", "$END"}
    ops = {"PLUS", "MINUS", "STAR", "SLASH", "CIRCUMFLEX", "UNIT", "DOT", "LPAR"}
    if len(names & ops) >= 3:
        names -= ops
    keywords = sorted(n for n in names if _term_words(n).strip("'") in _ITEM_WORDS)
    if len(keywords) >= 4:
        parts.append("a scene item (body, joint, effect, observe, ...)")
        names -= set(keywords)
    parts += sorted(_term_words(n) for n in names)
    if not parts:
        return "something else"
    if len(parts) > 6:
        parts = parts[:6] + ["..."]
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " or " + parts[-1]


_OPEN_RE = re.compile(r'"(?:[^"\\\n]|\\.)*"|#[^\n]*|[{}]|\n')


def _open_block(text: str, upto: int) -> tuple[str, int] | None:
    """The innermost '{' block still open at offset ``upto``: (its header words, its line)."""
    stack = []
    line = 1
    for m in _OPEN_RE.finditer(text, 0, upto):
        tok = m.group()
        if tok == "\n":
            line += 1
        elif tok == "{":
            head = text[:m.start()].rsplit("\n", 1)[-1]
            head = head.split("#")[0].strip().rstrip("{").strip()
            words = re.findall(r"[A-Za-z_][A-Za-z0-9_]*", head)
            if words and words[0] in _ITEM_WORDS | {"material"}:
                label = " ".join(words[:2]) if words[0] not in ("world", "light", "material") else words[0]
            else:
                label = head[:30] or "{"
            stack.append((label, line))
        elif tok == "}" and stack:
            stack.pop()
    return stack[-1] if stack else None


def _offset(text: str, line: int, column: int) -> int:
    rows = text.split("\n")
    return sum(len(r) + 1 for r in rows[: max(line - 1, 0)]) + max(column - 1, 0)


_GOAL_TERMS = ("goal terms, one after another without commas: 'BODY.position at T -> (x, y, z) m "
               "within TOL', 'JOINT.angle from T0 to T1 -> VALUE within TOL', 'effort: W', "
               "'decide: NAME, ...'")


def _goal_syntax_error(tok, expected: set[str], found: str, span: Span,
                       text: str) -> PhysSyntaxError | None:
    """The error in words for a mistake in or around a ``goal`` block (None: not one)."""
    if tok is not None and str(tok) == "goal" and "GOAL" not in expected:
        return PhysSyntaxError("a goal block sits directly in the scene, not inside another "
                               "item or a loop", span, "move 'goal { ... }' to the scene's top "
                               "level", source=text)
    if "GOAL_TARGET" in expected:
        return PhysSyntaxError(f"expected a goal term or '}}', found {found}", span, _GOAL_TERMS,
                               source=text)
    if "WITHIN" in expected and len(expected - {"WITHIN", "UNIT"}) <= 6:
        return PhysSyntaxError(f"expected 'within', found {found}", span, "a goal term ends "
                               "with its tolerance: ... -> VALUE within 1 cm", source=text)
    return None


def syntax_error(ex: UnexpectedInput, text: str, filename: str) -> PhysSyntaxError:
    """Turn a Lark error into a PhysSyntaxError that says what was expected, in words."""
    line = getattr(ex, "line", None) or 1
    column = getattr(ex, "column", None) or 1
    if isinstance(ex, UnexpectedCharacters):
        ch = text[ex.pos_in_stream] if ex.pos_in_stream < len(text) else "?"
        hint = None
        if ch == '"':
            hint = "a string must close with '\"' on the same line"
        elif ch in "@$%&!?;`'[]|=<>\\":
            hint = "names use letters, digits and '_'; strings go in double quotes"
        span = Span(filename, line, column, line, column + 1)
        return PhysSyntaxError(f"unexpected character {ch!r}", span, hint, source=text)
    tok = getattr(ex, "token", None)
    if isinstance(ex, UnexpectedEOF) or (tok is not None and tok.type == "$END"):
        rows = text.rstrip().split("\n")
        line, column = len(rows), len(rows[-1]) + 1 if rows else 1
        tok = None
    expected = set(getattr(ex, "accepts", None) or getattr(ex, "expected", None) or ())
    if tok is not None and tok.type != "$END":
        span = Span(filename, tok.line, tok.column, tok.end_line, tok.end_column)
    else:
        span = Span(filename, line, column, line, column + 1)
    found = _found(tok)
    goal = _goal_syntax_error(tok, expected, found, span, text)
    if goal is not None:
        return goal
    is_item_word = tok is not None and str(tok) in _ITEM_WORDS
    if "RBRACE" in expected and (tok is None or is_item_word):
        opened = _open_block(text, _offset(text, span.line, span.column))
        if opened:
            label, at = opened
            return PhysSyntaxError(
                f"expected '}}' to close the block '{label}' opened at line {at}, found {found}",
                span, f"add '}}' after the last field of '{label}'", source=text)
    hint = None
    before = text[:_offset(text, span.line, span.column)].rsplit("\n", 1)[-1]
    lone = re.fullmatch(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*", before)
    if tok is not None and tok.type == "COLON":
        word = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*$", before)
        if word and _VALUE_START & expected:
            return PhysSyntaxError(f"expected a value, found the field '{word.group(1)}:'", span,
                                   "a field needs a value after ':', e.g. 'mass: 1 kg'", source=text)
    if lone and tok is not None and lone.group(1) not in _ITEM_WORDS and (
            "KEY" not in expected or tok.type in ("NUMBER", "STRING", "LPAR", "MINUS")):
        w = lone.group(1)
        return PhysSyntaxError(f"expected ':' after '{w}', found {found}", span,
                               f"a field is written '{w}: value' or '{w} ~ dist(...)'", source=text)
    if tok is not None and tok.type in ("NUMBER", "NAME") and "COMMA" in expected and "RPAR" in expected:
        hint = "separate the items of a vector with ','"
    elif tok is not None and tok.type in ("NAME", "UNIT") and "KEY" in expected:
        hint = f"a field is written '{tok}: value' (with a colon) or '{tok} ~ dist(...)'"
    elif tok is not None and tok.type == "UNIT" and "/" in str(tok) or (
            tok is not None and tok.type == "UNIT" and "*" in str(tok)):
        hint = "a unit follows a number, a vector or a parenthesised expression"
    elif tok is not None and tok.type in ("NAME", "UNIT") and expected & {"PLUS", "STAR"}:
        hint = ("units follow numbers or parentheses ('2 m', '(L - r) m'); put spaces around "
                "operators ('2 m / L')")
    return PhysSyntaxError(f"expected {_describe_expected(expected)}, found {found}", span, hint,
                           source=text)
