"""Every shipped .phys file (examples and the standard library) is in the form ``physdsl fmt``
prints: the project's own files are the canonical form a user's files are compared with."""
from __future__ import annotations

import pytest

from .conftest import REPO

SHIPPED = sorted((REPO / "examples").glob("**/*.phys")) + sorted((REPO / "stdlib").glob("**/*.phys"))


def test_there_are_shipped_files():
    assert len(SHIPPED) >= 30


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(REPO)))
def test_fmt_check_passes(path, cli):
    code, out, err = cli("fmt", "--check", path)
    assert code == 0, f"{err}(physdsl fmt --write {path.relative_to(REPO)})"
    assert out == ""
