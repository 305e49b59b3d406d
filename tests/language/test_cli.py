"""CLI: lint over every example (exit 0, unknowns table), the check-syntax alias, bad paths."""
from __future__ import annotations

import pytest

from .conftest import DATA, REPO

EXAMPLES = sorted((REPO / "examples").glob("**/*.phys"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: str(p.relative_to(REPO)))
def test_lint_examples(path, cli):
    code, out, err = cli("lint", path)
    assert code == 0, err
    assert "ok: scene" in out


def test_lint_prints_unknowns_table(cli):
    code, out, _ = cli("check-syntax", DATA / "good" / "all_constructs.phys")
    assert code == 0
    for word in ("name", "prior", "support", "shape", "unit", "used in", "quadratic_drag@ball.coefficient",
                 "pole.shape.length"):
        assert word in out


def test_lint_many_files_and_missing_file(cli):
    code, out, err = cli("lint", DATA / "good" / "all_constructs.phys", DATA / "nope.phys")
    assert code == 2 and "ok: scene" in out and "file not found" in err and "Traceback" not in err
