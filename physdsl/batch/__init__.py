"""Batches of independent jobs (one fit, refine or sampling per scene) on a local process pool
or a Ray cluster, each into its own folder, restartable; compiled once per scene structure
through JAX's persistent compilation cache shared by the workers (see docs/scale.md)."""
from __future__ import annotations

from .executors import EXECUTORS, Executor, LocalExecutor, RayExecutor, make_executor
from .jobs import DONE, Job, compile_clock, is_done, run_job
from .runner import COMMANDS, SUMMARY, find_scenes, job_names, plan, run_batch

__all__ = ["COMMANDS", "DONE", "EXECUTORS", "Executor", "Job", "LocalExecutor", "RayExecutor",
           "SUMMARY", "compile_clock", "find_scenes", "is_done", "job_names", "make_executor",
           "plan", "run_batch", "run_job"]
