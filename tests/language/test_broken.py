"""Every broken file fails lint with exit 2 and its golden message, never a traceback."""
from __future__ import annotations

import pytest

from .conftest import DATA, first_error

BROKEN = sorted(p for p in (DATA / "broken").glob("*.phys") if not p.name.startswith("cyc_"))


def test_there_are_at_least_40_broken_files():
    assert len(BROKEN) >= 40
    assert all(p.with_suffix(".expected").is_file() for p in BROKEN)


@pytest.mark.parametrize("path", BROKEN, ids=lambda p: p.stem)
def test_broken_file_reports_golden_error(path, cli, monkeypatch):
    monkeypatch.chdir(path.parent)
    code, out, err = cli("lint", "-q", path.name)
    assert code == 2
    assert "Traceback" not in err and "internal error" not in err
    assert first_error(err) == path.with_suffix(".expected").read_text()


def test_independent_errors_are_all_reported(cli, monkeypatch):
    monkeypatch.chdir(DATA / "broken")
    code, _, err = cli("lint", "multi_errors.phys")
    assert code == 2
    assert err.rstrip().endswith("3 errors found")
    assert "'radius' needs a length" in err and "'mass' needs a mass" in err
    assert "'velocity' needs 3 numbers" in err
