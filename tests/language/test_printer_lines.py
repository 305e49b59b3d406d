"""Printer: blank lines are kept between items, never put between fields of one source line."""
from __future__ import annotations

from physdsl.syntax import format_source, parse
from physdsl.syntax.ast import strip_spans


def test_a_one_line_block_after_a_blank_line_opens_without_blank_lines_inside():
    src = ("scene s {\n  param a: 1\n\n  joint j: slider(world -> b) { axis: (1, 0, 0)  "
           "limits: (-1, 1) m  initial_velocity: 0.1 m/s }\n  body b { mass: 1 kg }\n}\n")
    out = format_source(src)
    assert out == ("scene s {\n  param a: 1\n\n  joint j: slider(world -> b) {\n"
                   "    axis: (1, 0, 0)\n    limits: (-1, 1) m\n    initial_velocity: 0.1 m/s\n"
                   "  }\n  body b { mass: 1 kg }\n}\n")
    assert strip_spans(parse(out)) == strip_spans(parse(src)) and format_source(out) == out
