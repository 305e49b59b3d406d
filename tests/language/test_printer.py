"""Printer: parse(fmt(x)) == parse(x) ignoring spans, fmt is idempotent, comments are kept."""
from __future__ import annotations

from pathlib import Path

import pytest

from physdsl.syntax import format_source, parse
from physdsl.syntax.ast import strip_spans

from .conftest import DATA, REPO

EXAMPLES = sorted((REPO / "examples").glob("**/*.phys"))
OWN = sorted((DATA / "good").glob("**/*.phys")) + sorted((REPO / "stdlib").glob("**/*.phys"))
ALL = EXAMPLES + OWN


@pytest.mark.parametrize("path", ALL, ids=lambda p: str(p.relative_to(REPO)))
def test_round_trip_and_idempotent(path: Path):
    text = path.read_text()
    once = format_source(text, path.name)
    assert strip_spans(parse(once)) == strip_spans(parse(text))
    assert format_source(once, path.name) == once
    comments = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("#")]
    for c in comments:
        assert c in once


def test_canonical_layout():
    src = ('# header\nscene s{body b{shape:sphere(radius:1 cm) mass:2*(1+ 2) kg  position:(0,0,-(1)) m}'
           '\neffect linear_drag on b{coefficient~half_normal(0.1 kg/s)} # drag\n}')
    assert format_source(src) == (
        "# header\n"
        "scene s {\n"
        "  body b {\n"
        "    shape: sphere(radius: 1 cm)\n"
        "    mass: 2 * (1 + 2) kg\n"
        "    position: (0, 0, -1) m\n"
        "  }\n"
        "  effect linear_drag on b { coefficient ~ half_normal(0.1 kg/s) }  # drag\n"
        "}\n")


@pytest.mark.parametrize("expr", [
    "a - (b - c)", "a / (b * c)", "(a + b) * c", "-(a + b)", "(-a)^2", "a^-b", "(2 m)^2",
    "((1, 2) m)", "(a) m", "x.y.z * 2", "2 * -a", "sqrt(a^2 + b^2) / 2", "-2 m",
])
def test_expressions_round_trip(expr):
    src = f"scene s {{ param p: {expr} }}"
    again = format_source(src)
    assert strip_spans(parse(again)) == strip_spans(parse(src))


def test_fmt_cli(tmp_path, cli):
    f = tmp_path / "x.phys"
    f.write_text("scene s{param a:1}\n")
    code, out, _ = cli("fmt", f)
    assert code == 0 and out == "scene s {\n  param a: 1\n}\n"
    assert cli("fmt", "--check", f)[0] == 1
    assert cli("fmt", "--write", f)[0] == 0
    assert f.read_text() == out
    assert cli("fmt", "--check", f)[0] == 0
    f.write_text("scene s { param a: }")
    code, _, err = cli("fmt", f)
    assert code == 2 and "expected a value" in err
