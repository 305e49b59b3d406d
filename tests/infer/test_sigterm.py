"""Stopping means stopping: SIGINT/SIGTERM end a run within seconds of compiled work, leave a
checkpoint, and ``--resume`` continues to exactly the draws of an uninterrupted run, however
the draws were cut into calls; a second signal acts at once."""
from __future__ import annotations

import physdsl

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from physdsl.infer import get_backend
from physdsl.infer.interrupt import Interrupted, critical, termination

ROOT = Path(__file__).parents[2]
SETTINGS = dict(backend="rmh", chains=2, warmup=40, samples=300, seed=5, progress=False)


def test_a_signal_inside_a_checkpoint_update_waits_for_its_end():
    # the handlers in force before (a pytest-xdist worker ignores SIGINT)
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with termination():
        with pytest.raises(Interrupted) as ex:
            with critical():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.05)
                reached = True  # not interrupted inside the section
        assert reached and ex.value.signum == signal.SIGTERM
        # the first signal restored the handlers in force before: a second acts at once
        assert signal.getsignal(signal.SIGINT) == before[0]
    assert signal.getsignal(signal.SIGTERM) == before[1]


def test_sigterm_while_sampling_resumes_to_the_same_draws(projectile_model, tmp_path, monkeypatch):
    """SIGTERM arrives during the third sampling call: the run stops there (that call's draws
    are dropped), the checkpoint holds the calls before; resumed, the calls are cut anew by
    measured time, and the draws equal those of a run never stopped."""
    reference = physdsl.infer(projectile_model, outdir=tmp_path / "reference", **SETTINGS)

    algo = get_backend("rmh")
    real = algo.sample
    calls = []

    def sample(*args, **kwargs):
        out = real(*args, **kwargs)
        calls.append(args[4])
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGTERM)
        return out

    monkeypatch.setattr(algo, "sample", sample)
    out = tmp_path / "stopped"
    with pytest.raises(Interrupted) as ex:
        physdsl.infer(projectile_model, outdir=out, **SETTINGS)
    assert ex.value.signum == signal.SIGTERM and "--resume" in ex.value.note
    assert (out / "checkpoint.pkl").exists() and not (out / "posterior.nc").exists()
    monkeypatch.undo()

    resumed = physdsl.infer(projectile_model, outdir=out, resume=True, **SETTINGS)
    assert not (out / "checkpoint.pkl").exists()
    for name in projectile_model.unknown_names:
        np.testing.assert_array_equal(resumed.posterior[name].values,
                                      reference.posterior[name].values)
    np.testing.assert_array_equal(resumed.sample_stats["acceptance_rate"].values,
                                  reference.sample_stats["acceptance_rate"].values)


def _bouncing_ball(folder: Path) -> Path:
    """The bouncing-ball example cut to its first second (one bounce): a contact scene."""
    src = ROOT / "examples" / "bouncing_ball"
    shutil.copy(src / "bouncing_ball.phys", folder / "bouncing_ball.phys")
    rows = (src / "trajectory.csv").read_text().splitlines()[:102]
    (folder / "trajectory.csv").write_text("\n".join(rows) + "\n")
    return folder / "bouncing_ball.phys"


def _infer(scene: Path, out: str, *extra, env, wait=True):
    cmd = [sys.executable, "-c", "import sys; from physdsl.cli import main; sys.exit(main())",
           "infer", scene.name, "-o", out, "--backend", "rmh",
           "--chains", "2", "--warmup", "20", "--samples", "300", "--seed", "1", *extra]
    proc = subprocess.Popen(cmd, cwd=scene.parent, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    if wait:
        proc.communicate(timeout=900)
    return proc


@pytest.mark.slow
def test_sigterm_stops_a_contact_scene_within_seconds(tmp_path):
    """`physdsl infer` of a contact scene in a subprocess, SIGTERM once it samples: it exits
    within 10 s with code 143 and a checkpoint; --resume gives the uninterrupted run's draws."""
    from physdsl.infer import posterior_data

    scene = _bouncing_ball(tmp_path)
    env = {**os.environ, "JAX_COMPILATION_CACHE_DIR": str(tmp_path / "xla"),
           "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0.5"}
    proc = _infer(scene, "stopped", env=env, wait=False)
    seen = []
    for line in proc.stderr:  # the stage lines (stderr is not a terminal here)
        seen.append(line)
        if line.startswith("sampling: started"):
            break
    assert seen and seen[-1].startswith("sampling: started"), "".join(seen)
    time.sleep(2.0)
    sent = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    waited = time.monotonic() - sent
    assert proc.returncode == 143, err
    assert waited < 10.0, f"exited {waited:.1f} s after SIGTERM"
    assert (tmp_path / "stopped" / "checkpoint.pkl").exists()
    assert "--resume" in err

    resumed = _infer(scene, "stopped", "--resume", env=env)
    assert resumed.returncode == 0
    whole = _infer(scene, "whole", env=env)
    assert whole.returncode == 0
    a, b = (posterior_data.group(posterior_data.read(tmp_path / run / "posterior.nc"), "posterior")
            for run in ("stopped", "whole"))
    for name in a.data_vars:
        np.testing.assert_array_equal(a[name].values, b[name].values)
