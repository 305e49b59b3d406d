"""XLA CPU options physdsl adds to ``XLA_FLAGS`` before JAX starts its CPU backend.

JAX >= 0.7 runs a compiled loop on the CPU as one call per operation (its thunk runtime): a
rollout step of a small scene is a few dozen such calls, each dearer than its arithmetic, and
on a 2-core machine they are handed between threads. XLA compiles a whole loop into one kernel
instead when the loop reads and writes less than a byte threshold (1 kB by default) and holds
no library call; physdsl raises that threshold, and turns off the YNNPACK fusions, which count
as library calls and would keep every loop with a matrix product out. Measured side by side
(``docs/physics.md``, "Fourth pass"): a pendulum's RK4 step 5.6 -> 0.75 us, its gradient
23.7 -> 2.3 us.

On by default; ``PHYSDSL_XLA_FLAGS=off`` leaves ``XLA_FLAGS`` alone (every loop a call per
operation, as JAX ships). One CI run of session 16 (jaxlib 0.10.2) lost two test processes to
a segmentation fault inside JAX's persistent compile cache with the options on; the op-by-op
compiles behind one of them are gone, and the next six fresh-clone CI runs with the options
on passed (``docs/physics.md``, "Sixth pass"). Options the user already gives in
``XLA_FLAGS`` (the same flag) are left as they are. Takes effect only where JAX has not yet
computed anything in the process (XLA reads its flags once, when the backend starts):
``import physdsl`` first.
"""
from __future__ import annotations

import os
import sys

# bytes a loop may read and write (counted over one pass of its body) and still be compiled
# as one kernel: every rollout loop of a scene, batches of draws included
SMALL_LOOP_BYTES = 1_000_000_000
OPTIONS = {
    "--xla_backend_extra_options":
        f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}",
    "--xla_cpu_experimental_ynn_fusion_type": "",
}
ENV = "PHYSDSL_XLA_FLAGS"
OFF = ("off", "0", "false", "no")  # values of ENV that leave XLA_FLAGS alone


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


def backend_started() -> bool:
    """Whether JAX has started a backend in this process (it then reads no more flags)."""
    bridge = sys.modules.get("jax._src.xla_bridge")  # private: read only if JAX has it
    started = getattr(bridge, "backends_are_initialized", None)
    return bool(started and started())


def configure(environ=os.environ) -> None:
    """Add ``OPTIONS`` to ``environ["XLA_FLAGS"]`` unless ``PHYSDSL_XLA_FLAGS`` is off, or JAX
    has started already (then they could not act, and ``in_effect`` must not say they do)."""
    if environ.get(ENV, "").strip().lower() in OFF or backend_started():
        return
    environ["XLA_FLAGS"] = with_options(environ.get("XLA_FLAGS", ""))
