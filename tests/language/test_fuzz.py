"""Fuzzing: mutated valid files and random text raise only PhysError (never anything else)."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from physdsl.errors import PhysError
from physdsl.syntax import format_source, loads, parse
from physdsl.syntax.ast import strip_spans

from .conftest import DATA, REPO

SEEDS = [p for p in sorted((REPO / "examples").glob("**/*.phys"))] + [DATA / "good" / "all_constructs.phys"]
TEXTS = [(p, p.read_text()) for p in SEEDS]
PIECES = ["{", "}", "(", ")", ",", ":", "~", "->", "==", '"', "#", " m/s", " kg", " deg", "^", "*",
          "/", "-", "+", ".", "\n", "body", "joint", "effect", "world", "param", "scene", "1e9",
          "-0", "nan", "normal(", "half_normal(-1)", "uniform(2, 1)", "euler(", "quat(0,0,0,0)",
          "mesh(\"x.obj\")", "sphere(radius: 0)", "observe", "from", "where", "at", "0/0",
          "Hz", "import \"x.phys\"", "\\", "\t", "é", "\x00", "9" * 400]


def mutate(text: str, ops) -> str:
    for kind, pos, piece, length in ops:
        i = pos % (len(text) + 1)
        if kind == 0:
            text = text[:i] + piece + text[i:]
        elif kind == 1:
            text = text[:i] + text[i + length:]
        else:
            text = text[:i] + piece + text[i + length:]
    return text


def check(text: str, base: Path) -> None:
    try:
        loads(text, "fuzz.phys", base)
    except PhysError as ex:
        ex.render()  # rendering must not fail either
        return
    # a text that loads also formats and round-trips
    again = format_source(text)
    assert strip_spans(parse(again)) == strip_spans(parse(text))


ops = st.lists(st.tuples(st.integers(0, 2), st.integers(0, 10**6), st.sampled_from(PIECES),
                         st.integers(1, 12)), min_size=1, max_size=4)


def _mutations(max_examples: int):
    @settings(max_examples=max_examples, deadline=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(seed=st.integers(0, len(TEXTS) - 1), ops=ops)
    def run(seed, ops):
        path, text = TEXTS[seed]
        check(mutate(text, ops), path.parent)
    return run


def _random(max_examples: int):
    @settings(max_examples=max_examples, deadline=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(st.one_of(st.text(max_size=200),
                     st.lists(st.sampled_from(PIECES + ["a", "b", "x1", "2", "3.5"]), max_size=60)
                     .map(" ".join)))
    def run(text):
        check(text, DATA / "good")
    return run


def test_fuzz_mutations_fast():
    _mutations(150)()


def test_fuzz_random_text_fast():
    _random(80)()


@pytest.mark.slow
def test_fuzz_mutations_many():
    _mutations(3000)()


@pytest.mark.slow
def test_fuzz_random_text_many():
    _random(2000)()
