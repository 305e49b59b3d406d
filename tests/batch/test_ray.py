"""``physdsl batch --executor ray`` on a real Ray cluster: a head started here (``ray start
--head`` on 127.0.0.1, 2 CPUs, stopped at the end). The same batch gives the same numbers as
the local pool; a worker killed while it runs a job has that job retried by Ray, and every job
completes exactly once."""
from __future__ import annotations

import os
import secrets
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from .conftest import CLI, FIT, N_SCENES, estimates, run_cli, summary

pytest.importorskip("ray", reason="ray is not installed: pip install 'physdsl[ray]' "
                                  "(.ci/run installs it)")


AUTH = ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def ray_head(tmp_path_factory):
    """A Ray head on this machine (``ray start --head --block``); its address HOST:PORT.

    With a token of its own (Ray's token authentication, set in this process's environment,
    which the head, its workers and the batches started here inherit; older Rays ignore it)."""
    saved = {k: os.environ.get(k) for k in AUTH}
    os.environ.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    os.environ.pop("RAY_AUTH_TOKEN_PATH", None)
    port = _free_port()
    log = tmp_path_factory.mktemp("ray") / "head.log"
    with open(log, "w") as sink:
        head = subprocess.Popen(
            [sys.executable, "-m", "ray.scripts.scripts", "start", "--head", "--block",
             "--port", str(port), "--node-ip-address", "127.0.0.1", "--num-cpus", "2",
             "--include-dashboard=false", "--disable-usage-stats",
             "--object-store-memory", str(200 * 2**20)],
            stdout=sink, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        deadline = time.time() + 180
        while "--block" not in log.read_text() or "Ray runtime started" not in log.read_text():
            assert head.poll() is None and time.time() < deadline, log.read_text()[-3000:]
            time.sleep(0.5)
        yield f"127.0.0.1:{port}"
    finally:
        head.send_signal(signal.SIGTERM)  # --block: the head stops every process it started
        try:
            head.wait(timeout=90)
        except subprocess.TimeoutExpired:
            head.kill()
        for key, value in saved.items():
            os.environ.pop(key, None) if value is None else os.environ.update({key: value})


def _ray_batch(scenes: Path, out: Path, address: str) -> list[str]:
    return ["batch", "infer", "--scenes", str(scenes / "toss-*" / "scene.phys"), "-o", str(out),
            "--executor", "ray", "--address", address, *FIT]


@pytest.mark.slow  # the killed-worker test below checks the same numbers (and more)
def test_ray_gives_the_local_pool_results(ray_head, scenes, local_batch, tmp_path):
    out = tmp_path / "ray"
    done = run_cli(*_ray_batch(scenes, out, ray_head))
    assert done.returncode == 0, done.stderr
    record = summary(out)
    assert record["executor"]["executor"] == "ray"
    assert record["counts"] == {"done": N_SCENES, "failed": 0, "skipped": 0}
    for i in range(N_SCENES):
        a, b = estimates(out / f"toss-{i}"), estimates(local_batch[0] / f"toss-{i}")
        assert sorted(a) == sorted(b)
        np.testing.assert_allclose([a[k] for k in sorted(a)], [b[k] for k in sorted(b)],
                                   rtol=1e-9)


def _kill_a_running_job(out: Path, batch: subprocess.Popen) -> str:
    """Freeze the worker of the first job seen running (not finished) and kill it; its name."""
    attempts = out / ".batch" / "attempts"
    deadline = time.time() + 300
    seen: set[Path] = set()
    while time.time() < deadline and batch.poll() is None:
        for marker in sorted(attempts.glob("*/*")) if attempts.is_dir() else []:
            if marker in seen or marker.name.startswith("."):
                continue
            seen.add(marker)
            pid = int(marker.name.split("-")[-2])
            try:
                os.kill(pid, signal.SIGSTOP)  # frozen: it cannot finish while we look
            except ProcessLookupError:
                continue
            if (out / marker.parent.name / "job.json").exists():
                os.kill(pid, signal.SIGCONT)  # finished already: try the next job
                continue
            os.kill(pid, signal.SIGKILL)
            return marker.parent.name
        time.sleep(0.02)
    out_, err = batch.communicate(timeout=600)
    raise AssertionError(f"no job was caught running (exit {batch.returncode}):\n{out_}\n{err}")


def test_a_killed_worker_job_is_retried_and_every_job_completes_once(ray_head, scenes,
                                                                     local_batch, tmp_path):
    out = tmp_path / "killed"
    batch = subprocess.Popen([sys.executable, "-c", CLI, *_ray_batch(scenes, out, ray_head)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = _kill_a_running_job(out, batch)
    stdout, stderr = batch.communicate(timeout=600)
    assert batch.returncode == 0, stderr
    record = summary(out)
    assert record["counts"] == {"done": N_SCENES, "failed": 0, "skipped": 0}
    assert sorted(j["name"] for j in record["jobs"]) == [f"toss-{i}" for i in range(N_SCENES)]
    for i in range(N_SCENES):
        name = f"toss-{i}"
        runs = [p for p in (out / ".batch" / "attempts" / name).iterdir()
                if not p.name.startswith(".")]
        job = next(j for j in record["jobs"] if j["name"] == name)
        assert len(runs) == job["attempt"] == (2 if name == killed else 1), (name, killed)
        a, b = estimates(out / name), estimates(local_batch[0] / name)
        np.testing.assert_allclose([a[k] for k in sorted(a)], [b[k] for k in sorted(b)],
                                   rtol=1e-9)
