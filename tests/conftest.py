"""Suite-wide check: with PHYSDSL_EXPECT_INSTALLED=1 (set by .ci/run) the physdsl under test
must be the installed wheel, not this checkout (a wheel missing its grammar would otherwise
pass here and fail for every user)."""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# Compiled programs go to a folder of this session (removed at exit), never the user's cache;
# set before physdsl is imported (it sets up JAX's persistent cache then: physdsl/cache.py).
if os.environ.get("PHYSDSL_CACHE_DIR", "").lower() != "off":
    os.environ["PHYSDSL_CACHE_DIR"] = tempfile.mkdtemp(prefix="physdsl-tests-cache-")
    atexit.register(shutil.rmtree, os.environ["PHYSDSL_CACHE_DIR"], ignore_errors=True)
# Traced programs are not kept across tests (physdsl/traces.py): tests patch module constants
# that decide what is traced (``tree.RECURSIVE_MAX``), which a stored program's key cannot see.
# The tests of that cache turn it on for themselves (tests/test_traces.py, tests/infer/test_cache.py).
os.environ.setdefault("PHYSDSL_TRACE_CACHE", "off")

import physdsl  # noqa: E402

CHECKOUT = Path(__file__).resolve().parent.parent


def pytest_report_header(config):
    return f"physdsl under test: {Path(physdsl.__file__).parent}"


def pytest_sessionstart(session):
    if os.environ.get("PHYSDSL_EXPECT_INSTALLED") == "1":
        package = Path(physdsl.__file__).resolve().parent
        if package.is_relative_to(CHECKOUT):
            pytest.exit(f"PHYSDSL_EXPECT_INSTALLED=1 but physdsl is imported from the checkout "
                        f"({package}); install the wheel outside the source tree", returncode=3)
