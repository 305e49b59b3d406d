"""Suite-wide check: with PHYSDSL_EXPECT_INSTALLED=1 (set by .ci/run) the physdsl under test
must be the installed wheel, not this checkout (a wheel missing its grammar would otherwise
pass here and fail for every user)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

import physdsl

CHECKOUT = Path(__file__).resolve().parent.parent


def pytest_report_header(config):
    return f"physdsl under test: {Path(physdsl.__file__).parent}"


def pytest_sessionstart(session):
    if os.environ.get("PHYSDSL_EXPECT_INSTALLED") == "1":
        package = Path(physdsl.__file__).resolve().parent
        if package.is_relative_to(CHECKOUT):
            pytest.exit(f"PHYSDSL_EXPECT_INSTALLED=1 but physdsl is imported from the checkout "
                        f"({package}); install the wheel outside the source tree", returncode=3)
