"""Batches of independent fits (``physdsl batch infer``): throughput per executor and what the
shared compilation cache saves.

Jobs: N copies of the inference benchmark's scene (``benchmarks/inference_ball.phys``: a ball
thrown with quadratic drag, RK4 at 10 ms over 1 s, 101 positions, 5 unknowns), each with its
own data simulated at a different launch velocity (4.5 to 8 m/s forward), fitted with
``--backend map`` (the CLI's defaults otherwise). Every batch is a whole CLI command in a fresh
process (import, executor start, jobs, summary). Prints ``name: value`` lines:

- ``compile_s_first_job``: XLA compile seconds of one job in a fresh worker with an empty
  cache; ``compile_s_next_job``: the next job of the same structure in another fresh worker
  (another process, as on another machine sharing the folder, or a later batch) reading the
  cache the first left; ``compile_s_next_job_same_worker``: median of the jobs after the first
  in one worker (its in-memory caches); ``*_cache_hits/misses``: programs read / compiled;
  ``trace_s_*``: tracing and lowering (not cached by XLA's cache, paid per process);
- ``fits_per_hour.local_1``, ``.local_2`` (process pool of 1, 2 workers), ``.ray_2`` (Ray
  started on this machine with 2 CPUs): N jobs over the batch's wall time, with a warm cache;
  the wall time includes starting the workers (and Ray): ``wall_s.*``, ``job_wall_s.*``
  (mean seconds per job inside its worker);
- ``load_before``/``load_after``: the 1-minute load average (the machine is shared);
- with ``--pooled`` (or ``--pooled-only``): many recordings in one fit (``benchmarks/pooled.py``):
  ``pooled_interval_ratio.drag`` (one throw's 90% drag interval over the 20 pooled throws')
  and the memory per recording of the vectorised rollout.

Run: nice .venv/bin/python benchmarks/batch.py [--jobs 8] [--pooled]   (minutes on 2 loaded cores)
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

os.environ["PHYSDSL_CACHE_DIR"] = "off"  # this process simulates the data; the batches' cache starts empty
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.inference import NOISE, SCENE, TIMES, TRUTH  # noqa: E402
from tests.infer.conftest import simulated_scene  # noqa: E402

from benchmarks.pooled import main as pooled_main  # noqa: E402

CLI = "import sys; from physdsl.cli import main; sys.exit(main())"


def _throws(root: Path, n: int) -> str:
    """``root/throw-XX/scene.phys`` with data; the batch's glob."""
    for i in range(n):
        truth = dict(TRUTH, **{"ball.velocity": np.array([4.5 + 3.5 * i / max(n - 1, 1), 0.3, 5.8])})
        simulated_scene(root / f"throw-{i:02d}", SCENE.read_text(), truth, TIMES, NOISE, seed=i)
    return str(root / "throw-*" / "scene.phys")


def _batch(scenes: str, out: Path, cache: Path, *more: str) -> dict:
    """One ``physdsl batch infer`` in a fresh process; its batch.json."""
    done = subprocess.run([sys.executable, "-c", CLI, "--cache-dir", str(cache), "batch", "infer",
                           "--scenes", scenes, "-o", str(out), "--backend", "map", "--quiet",
                           *more], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.exit(f"batch failed ({done.returncode}):\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}")
    return json.loads((out / "batch.json").read_text())


def _compile_figures(root: Path, tmp: Path) -> None:
    """First job into an empty cache, then the next in a new process reading it."""
    cache = tmp / "cache"
    for key, i in (("first_job", 0), ("next_job", 1)):
        job = _batch(str(root / f"throw-{i:02d}" / "scene.phys"), tmp / f"compile_{key}",
                     cache, "--workers", "1")["jobs"][0]
        print(f"compile_s_{key}: {job['compile_s']:.2f}")
        print(f"trace_s_{key}: {job['trace_s']:.2f}")
        print(f"compile_{key}_cache_hits: {job['cache_hits']}")
        print(f"compile_{key}_cache_misses: {job['cache_misses']}")


def _throughput(scenes: str, tmp: Path, n: int) -> None:
    cache = tmp / "cache"  # warm: the compile runs filled it
    for key, more in (("local_1", ["--workers", "1"]), ("local_2", ["--workers", "2"]),
                      ("ray_2", ["--executor", "ray", "--workers", "2"])):
        summary = _batch(scenes, tmp / key, cache, *more)
        jobs = summary["jobs"]
        assert summary["counts"]["done"] == n, summary["counts"]
        print(f"fits_per_hour.{key}: {n / summary['wall_s'] * 3600:.0f}")
        print(f"wall_s.{key}: {summary['wall_s']:.1f}")
        print(f"job_wall_s.{key}: {statistics.mean(j['wall_s'] for j in jobs):.2f}")
        if key == "local_1":
            later = sorted(jobs, key=lambda j: j["started"])[1:]  # all but the worker's first
            print("compile_s_next_job_same_worker: "
                  f"{statistics.median(j['compile_s'] for j in later):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=8)
    parser.add_argument("--pooled", action="store_true", help="also the pooled-fit figures")
    parser.add_argument("--pooled-only", action="store_true", help="only the pooled figures")
    args = parser.parse_args()
    if args.pooled_only:
        return pooled_main()
    print(f"load_before: {os.getloadavg()[0]:.1f}")
    print(f"cpus: {os.cpu_count()}")
    print(f"jobs: {args.jobs}")
    with tempfile.TemporaryDirectory(prefix="physdsl-batch-bench-") as tmp:
        tmp = Path(tmp)
        scenes = _throws(tmp / "throws", args.jobs)
        _compile_figures(tmp / "throws", tmp)
        _throughput(scenes, tmp, args.jobs)
    print(f"load_after: {os.getloadavg()[0]:.1f}")
    if args.pooled:
        pooled_main()


if __name__ == "__main__":
    main()
