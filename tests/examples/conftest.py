"""Paths and loaders shared by the example-data tests (all relative to this file)."""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
HIDDEN = EXAMPLES / "hidden-effect"
MAKE_DATA = ROOT / "tools" / "make_data"
CORPUS_FIXTURES = Path(__file__).resolve().parents[1] / "data" / "corpus"

if str(MAKE_DATA) not in sys.path:  # the generators are scripts, importable by module name
    sys.path.insert(0, str(MAKE_DATA))
