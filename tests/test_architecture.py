"""The house's rules, checked on the source: floors, no import cycles, imports at the top, small rooms.

The floors are written down once, here (docs/architecture.md draws the same plan). grimp builds
the import graph (every import, also those inside functions); ast finds imports placed inside
functions and measures files and functions.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "physdsl"

# Highest floor first. A module may import its own floor or lower floors, never a higher one.
FLOORS = (
    ("cli",),
    ("api", "batch"),
    ("diagnose", "design", "export", "sample", "control", "discover"),
    ("infer", "track"),
    ("compile", "mjcf", "pooled"),
    ("syntax", "physics", "observe", "render"),
    ("scene", "goal"),
    ("errors", "expr", "io", "media", "cache", "xla_flags", "ahead", "traces", "registry",
     "version"),
)

# Sibling packages on one floor that must not know each other.
INDEPENDENT = (("syntax", "physics"),)

# Third-party libraries that are optional extras or slow to import (arviz + xarray: over a second,
# which `physdsl lint` should not pay): these may be imported where used.
LAZY_LIBRARIES = {"mujoco", "cv2", "matplotlib", "ray", "trimesh", "playwright", "arviz", "xarray",
                  "pysindy"}

MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 80


@pytest.fixture(scope="module")
def graph():
    return grimp.build_graph("physdsl", exclude_type_checking_imports=True)


def _floor_of(module: str) -> int | None:
    parts = module.split(".")
    if len(parts) < 2:
        return None  # the package root re-exports the api: it stands above every floor
    for level, names in enumerate(FLOORS):
        if parts[1] in names:
            return level
    return None


def test_every_module_has_a_floor(graph):
    homeless = sorted(m for m in graph.modules
                      if m != "physdsl" and _floor_of(m) is None)
    assert not homeless, f"modules on no floor (add them to FLOORS): {homeless}"


def test_no_import_goes_up_a_floor(graph):
    upward = []
    for importer in sorted(graph.modules):
        low = _floor_of(importer)
        if low is None:
            continue
        for imported in graph.find_modules_directly_imported_by(importer):
            high = _floor_of(imported)
            if high is not None and high < low:  # a smaller index is a higher floor
                upward.append(f"{importer} -> {imported}")
    assert not upward, "imports from a lower floor to a higher one:\n  " + "\n  ".join(upward)


def test_independent_siblings_do_not_import_each_other(graph):
    found = []
    for a, b in INDEPENDENT:
        for x, y in ((a, b), (b, a)):
            for chain in graph.find_shortest_chains(importer=f"physdsl.{x}", imported=f"physdsl.{y}"):
                found.append(" -> ".join(chain))
    assert not found, "imports between independent packages:\n  " + "\n  ".join(found)


def test_no_import_cycles(graph):
    cycles = set()
    for importer in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(importer):
            back = graph.find_shortest_chain(importer=imported, imported=importer)
            if back:
                cycles.add(" -> ".join((importer, *back)))
    assert not cycles, "import cycles:\n  " + "\n  ".join(sorted(cycles))


def _sources():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, path.relative_to(PACKAGE.parent).as_posix(), ast.parse(path.read_text())


def _imported_roots(node) -> set[str]:
    if isinstance(node, ast.Import):
        return {a.name.split(".")[0] for a in node.names}
    if node.level:
        return {"physdsl"}
    return {(node.module or "").split(".")[0]}


def test_imports_sit_at_the_top_of_modules():
    """Outside cli/, an import inside a function hides a dependency (and often a cycle)."""
    inside = []
    for path, name, tree in _sources():
        if name.startswith("physdsl/cli/"):
            continue
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, (ast.Import, ast.ImportFrom)) \
                        and not _imported_roots(node) <= LAZY_LIBRARIES:
                    inside.append(f"{name}:{node.lineno} in {fn.name}()")
    assert not inside, f"{len(inside)} imports inside functions:\n  " + "\n  ".join(sorted(set(inside)))


def test_no_file_holds_more_than_one_rooms_worth():
    big = [f"{name}: {len(path.read_text().splitlines())} lines"
           for path, name, _ in _sources() if len(path.read_text().splitlines()) > MAX_FILE_LINES]
    assert not big, f"files over {MAX_FILE_LINES} lines:\n  " + "\n  ".join(big)


def test_no_function_is_longer_than_a_screen_and_a_half():
    long = []
    for _, name, tree in _sources():
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = fn.end_lineno - fn.lineno + 1
                if size > MAX_FUNCTION_LINES:
                    long.append(f"{name}:{fn.lineno} {fn.name}() {size} lines")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines:\n  " + "\n  ".join(long)


def _fresh(code: str) -> str:
    """stdout of ``code`` run by a fresh interpreter (import order under the test's control)."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, cwd=PACKAGE.parent)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_the_package_root_names_the_api_and_loads_it_on_first_use():
    """``physdsl.API`` is ``physdsl.api.__all__``; importing the command line pulls in neither
    the api nor the floors below it (``physdsl --help`` stays fast), ``physdsl.load`` does."""
    code = ("import sys, physdsl.cli; heavy = ('physdsl.api', 'physdsl.compile', 'physdsl.infer',"
            " 'physdsl.syntax', 'numpyro'); print(sorted(m for m in heavy if m in sys.modules));"
            " import physdsl; physdsl.load; print('physdsl.api' in sys.modules,"
            " physdsl.API == tuple(physdsl.api.__all__))")
    assert _fresh(code).splitlines() == ["[]", "True True"]


@pytest.mark.parametrize("first", ["physdsl", "physdsl.export.mjcf"])
def test_an_api_name_means_the_function_also_after_its_subpackage_is_imported(first):
    """``physdsl.export`` (compile, infer, diagnose, sample, render, track, control) is the api
    function whichever is imported first, the package or its subpackage of the same name; the
    subpackages stay reachable by ``from physdsl.export import mjcf``."""
    code = (f"import {first}\nimport physdsl\nimport physdsl.export.mjcf, physdsl.sample, "
            "physdsl.infer.run, physdsl.compile, physdsl.render, physdsl.track, physdsl.control, "
            "physdsl.diagnose.rank\nfrom physdsl.export import mjcf\n"
            "print(sorted(n for n in physdsl.API if getattr(physdsl, n) is not "
            "getattr(physdsl.api, n)), callable(physdsl.export), mjcf.__name__)")
    assert _fresh(code) == "[] True physdsl.export.mjcf"
