"""The persistent compilation cache across processes: ``physdsl infer`` of one scene in a fresh
process with an empty cache, again in another fresh process, then on a copy whose measurements
are a new noise draw (same shape); then a first and a second with ``PHYSDSL_TRACE_CACHE=off``
(the second traces every program again and loads its executable: as before
physdsl/traces.py). Each run is a whole CLI command (import, compile, fit, write).

Run: .venv/bin/python benchmarks/cache.py [SCENE.phys] [--backend map]
(prints ``name: value`` lines; the default scene is examples/thrown_ball/thrown_ball.phys)
"""
from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CLI = "import sys; from physdsl.cli import main; sys.exit(main())"
NOISE = 0.005  # added to every measured coordinate for the changed-data run (m, rad, ...)


def _run(scene: Path, out: Path, cache: Path, backend: str, traces: bool = True
         ) -> tuple[float, float]:
    """(wall s, CPU s of the child) of one ``physdsl infer`` in a fresh process; ``traces``:
    with the traced programs kept (else it traces every program, loading only executables)."""
    env = {**os.environ, **({} if traces else {"PHYSDSL_TRACE_CACHE": "off"})}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CLI, "--cache-dir", str(cache), "infer",
                           str(scene), "--backend", backend, "-o", str(out)],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"physdsl infer failed ({done.returncode}):\n{done.stderr[-3000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _redraw(folder: Path, seed: int = 1) -> None:
    """Add fresh noise to every numeric column but ``t`` of the folder's CSV files."""
    rng = np.random.default_rng(seed)
    for path in folder.glob("*.csv"):
        rows = list(csv.reader(path.open()))
        for row in rows[1:]:
            for i, (name, cell) in enumerate(zip(rows[0], row)):
                try:
                    value = float(cell)
                except ValueError:
                    continue
                if name != "t":
                    row[i] = f"{value + rng.normal(0.0, NOISE):.6f}"
        with path.open("w", newline="") as f:
            csv.writer(f).writerows(rows)


def _entries(cache: Path) -> int:
    return sum(1 for p in cache.glob("*-cache")) if cache.exists() else 0


def _traces(cache: Path) -> int:
    """Traced programs kept (physdsl/traces.py): a second process loads them, traces nothing."""
    return sum(1 for p in cache.glob("traces/*.trace"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=ROOT / "examples/thrown_ball/thrown_ball.phys",
                        type=Path)
    parser.add_argument("--backend", default="map")
    args = parser.parse_args()
    print(f"load_before: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="physdsl-cache-bench-") as tmp:
        tmp = Path(tmp)
        cache = tmp / "cache"
        same = tmp / "same"
        shutil.copytree(args.scene.parent, same)
        changed = tmp / "changed"
        shutil.copytree(args.scene.parent, changed)
        _redraw(changed)
        name = args.scene.name
        walls = {}
        runs = (("first", same, True), ("second", same, True), ("changed_data", changed, True),
                # as before traces were kept: its programs' executables (other modules than
                # the exported ones) kept by a first run without traces, then a second
                ("first_tracing", same, False), ("second_tracing", same, False))
        for key, folder, traces in runs:
            entries, traced = _entries(cache), _traces(cache)
            wall, cpu = _run(folder / name, tmp / f"out_{key}", cache, args.backend, traces)
            walls[key] = wall
            print(f"{key}_wall_s: {wall:.1f}")
            print(f"{key}_cpu_s: {cpu:.1f}")
            print(f"{key}_new_entries: {_entries(cache) - entries}")
            print(f"{key}_new_traces: {_traces(cache) - traced}")
        print(f"second_over_first_wall: {walls['second'] / walls['first']:.3f}")
        print(f"changed_data_over_first_wall: {walls['changed_data'] / walls['first']:.3f}")
        print(f"second_over_second_tracing_wall: "
              f"{walls['second'] / walls['second_tracing']:.3f}")
    print(f"load_after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
