"""XLA CPU options physdsl adds to ``XLA_FLAGS`` before JAX starts its CPU backend.

JAX >= 0.7 runs a compiled loop on the CPU as one call per operation (its thunk runtime): a
rollout step of a small scene is a few dozen such calls, each dearer than its arithmetic, and
on a 2-core machine they are handed between threads. XLA compiles a whole loop into one kernel
instead when the loop reads and writes less than a byte threshold (1 kB by default) and holds
no library call; physdsl raises that threshold, and turns off the YNNPACK fusions, which count
as library calls and would keep every loop with a matrix product out. Measured side by side
(``docs/physics.md``, "Fourth pass"): a pendulum's RK4 step 5.6 -> 0.75 us, its gradient
23.7 -> 2.3 us; a chain of 10 hinges unchanged.

Opt-in, ``PHYSDSL_XLA_FLAGS=on``: with them, two test processes of one CI run (jaxlib 0.10.2)
died of a segmentation fault inside JAX's persistent compile cache (serialising one compiled
program, reading another back), where no run without them ever had; not reproduced alone. Options
the user already gives in ``XLA_FLAGS`` (the same flag) are left as they are. Takes effect only
where JAX has not yet computed anything in the process (XLA reads its flags once, when the
backend starts): ``import physdsl`` first.
"""
from __future__ import annotations

import os

# bytes a loop may read and write (counted over one pass of its body) and still be compiled
# as one kernel: every rollout loop of a scene, batches of draws included
SMALL_LOOP_BYTES = 1_000_000_000
OPTIONS = {
    "--xla_backend_extra_options":
        f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}",
    "--xla_cpu_experimental_ynn_fusion_type": "",
}
ENV = "PHYSDSL_XLA_FLAGS"


def with_options(flags: str) -> str:
    """``flags`` (an ``XLA_FLAGS`` value) with each of ``OPTIONS`` that it does not set."""
    given = {f.split("=", 1)[0] for f in flags.split()}
    extra = [f"{k}={v}" for k, v in OPTIONS.items() if k not in given]
    return " ".join([flags.strip(), *extra]).strip()


def in_effect(environ=os.environ) -> bool:
    """Whether ``XLA_FLAGS`` holds every one of ``OPTIONS`` (physdsl's or the user's values):
    rollout loops without a library call then run as one kernel each."""
    flags = environ.get("XLA_FLAGS", "")
    return with_options(flags) == flags.strip()


def configure(environ=os.environ) -> None:
    """Add ``OPTIONS`` to ``environ["XLA_FLAGS"]`` where ``PHYSDSL_XLA_FLAGS=on``."""
    if environ.get(ENV, "").strip().lower() not in ("on", "1", "true", "yes"):
        return
    environ["XLA_FLAGS"] = with_options(environ.get("XLA_FLAGS", ""))
