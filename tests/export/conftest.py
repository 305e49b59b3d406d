"""The export tests write proto-programs and sampled scenes into tmp folders that read the toss
recording in tests/export/data: outside their own folder, so allowed explicitly, as a user
does with ``--allow-path`` (syntax/bounds.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from physdsl.syntax.bounds import allowing

DATA = Path(__file__).parent / "data"


@pytest.fixture(autouse=True, scope="module")
def _allow_the_toss_data():
    with allowing([DATA]):
        yield
