"""Many recordings in one fit (``experiments``): the pooled drag interval against one throw's,
and the memory of the rollout vectorised over recordings.

Data: examples/many_throws (20 throws of one ball at 3-20 m/s with quadratic drag, 25 Hz,
1 cm noise). Prints ``name: value`` lines:

- ``pooled_interval_ratio.drag``: width of the drag's 90% interval (MAP + Laplace) from throw
  09 alone (11.9 m/s, the median speed) over the width from all 20 throws pooled;
  ``.drag_vs_fastest``: the same against the fastest throw (19, 20 m/s) alone;
- ``pooled_drag``: the pooled fit's median and 90% interval (truth 0.0057 kg/m); wall seconds;
- ``memory.rollout_bytes_per_recording``: one recording's rollout as the likelihood reads it;
  ``memory.temp_bytes.chunk_C.recordings_R``: XLA's temporary buffers of the compiled
  value-and-gradient of the pooled log density with C recordings per vmapped call.

Run: nice .venv/bin/python benchmarks/pooled.py  (or through benchmarks/batch.py --pooled)
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import physdsl  # noqa: E402
from physdsl import pooled  # noqa: E402
from physdsl.infer.problem import model_problem, prior_draws_unconstrained  # noqa: E402
from tests.experiments.helpers import EXAMPLE, drag_fit, single, throws  # noqa: E402

ALL = [f"{i:02d}" for i in range(20)]


def interval_figures(tmp: Path) -> None:
    t0 = time.perf_counter()
    (lo, hi), idata = drag_fit(EXAMPLE / "scene.phys")
    wall = time.perf_counter() - t0
    med = float(np.median(idata.posterior["quadratic_drag@ball.coefficient"].values))
    print(f"pooled_drag: {med:.6g} [{lo:.6g}, {hi:.6g}] kg/m (20 throws, {wall:.0f} s wall)")
    for key, name in (("drag", "09"), ("drag_vs_fastest", "19")):
        (slo, shi), _ = drag_fit(single(tmp, name))
        print(f"single_drag.{name}: [{slo:.6g}, {shi:.6g}] kg/m")
        print(f"pooled_interval_ratio.{key}: {(shi - slo) / (hi - lo):.1f}")


def memory_figures(tmp: Path) -> None:
    model = physdsl.compile(throws(tmp / "mem", ALL))
    print(f"memory.rollout_bytes_per_recording: {pooled.rollout_bytes_per_recording(model)}")
    problem = model_problem(model)
    x = jnp.asarray(prior_draws_unconstrained(problem, jax.random.PRNGKey(0), 1)[0])
    for chunk in (4, 20):
        pooled.CHUNK = chunk
        fn = jax.jit(jax.value_and_grad(problem.logdensity))
        mem = fn.lower(x, problem.data).compile().memory_analysis()
        print(f"memory.temp_bytes.chunk_{chunk}.recordings_20: {mem.temp_size_in_bytes}")


def main() -> None:
    print(f"load_before: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="physdsl-pooled-bench-") as tmp:
        memory_figures(Path(tmp))
        interval_figures(Path(tmp))
    print(f"load_after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
