"""``physdsl batch`` on the local process pool: every job fits its own scene, a broken scene is
reported with its error while the others finish, a restarted batch skips finished jobs, and
usage errors exit 2 before anything runs."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from physdsl.batch import job_names
from physdsl.cli import main

from .conftest import FIT, N_SCENES, estimates, run_cli, summary, truth


def test_every_job_fits_its_own_scene(local_batch):
    out, done = local_batch
    assert done.returncode == 1, done.stderr  # the broken scene failed
    record = summary(out)
    assert record["counts"] == {"done": N_SCENES, "failed": 1, "skipped": 0}
    for i in range(N_SCENES):
        fit = estimates(out / f"toss-{i}")
        for k in range(3):
            mean, sd = fit[f"ball.velocity[{k}]"]
            assert abs(mean - truth(i)[k]) < 5 * sd, (i, k, mean, sd)
        job = next(j for j in record["jobs"] if j["name"] == f"toss-{i}")
        assert job["status"] == "done" and job["attempt"] == 1
        assert (out / f"toss-{i}" / "job.json").is_file()


def test_a_broken_scene_is_reported_and_the_others_finish(local_batch):
    out, done = local_batch
    record = summary(out)
    assert record["failed"] == ["broken"]
    error = next(j for j in record["jobs"] if j["name"] == "broken")["error"]
    # the scene error as `physdsl lint` shows it: file, line, column, caret, hint
    assert "broken/scene.phys:2:" in error and "unknown unit 'parsecs'" in error
    assert "^" in error and "hint:" in error
    assert "unknown unit 'parsecs'" in done.stderr and "failed: broken" in done.stdout
    assert not (out / "broken" / "job.json").exists()  # not finished: a restart runs it again


def test_a_restarted_batch_skips_finished_jobs(local_batch, scenes, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(local_batch[0], out)
    markers = {i: (out / f"toss-{i}" / "job.json").stat().st_mtime_ns for i in range(N_SCENES)}
    again = run_cli("batch", "infer", "--scenes", str(scenes / "*" / "scene.phys"), "-o",
                    str(out), "--workers", "2", *FIT)
    assert again.returncode == 1, again.stderr  # the broken scene fails again
    record = summary(out)
    assert record["counts"] == {"done": 0, "failed": 1, "skipped": N_SCENES}
    assert all(j.get("skipped") for j in record["jobs"] if j["name"] != "broken")
    assert markers == {i: (out / f"toss-{i}" / "job.json").stat().st_mtime_ns
                       for i in range(N_SCENES)}  # untouched


def test_other_settings_into_the_same_folder_are_refused(local_batch, scenes, capsys):
    out, _ = local_batch
    code = main(["batch", "infer", "--scenes", str(scenes / "*" / "scene.phys"), "-o", str(out),
                 "--backend", "map", "--chains", "2"])
    assert code == 2
    assert "other settings" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--scenes", "no/such/*/scene.phys"], "no scene file matches"),
    (["--address", "127.0.0.1:6379"], "--address goes with --executor ray"),
    (["--executor", "dask"], "unknown executor 'dask'"),
])
def test_usage_errors_exit_2(scenes, tmp_path, capsys, args, message):
    if "--scenes" not in args:
        args = ["--scenes", str(scenes / "toss-0" / "scene.phys"), *args]
    code = main(["batch", "infer", "-o", str(tmp_path / "out"), *FIT, *args])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_job_names_follow_the_scene_folders():
    assert job_names([Path("/d/throws/01/scene.phys"), Path("/d/throws/02/scene.phys")]) == \
        ["01", "02"]
    assert job_names([Path("/d/a.phys"), Path("/d/sub/b.phys")]) == ["a", "sub/b"]
    assert job_names([Path("/d/x/scene.phys")]) == ["x"]
    assert len(set(job_names([Path("/d/a/s.phys"), Path("/d/b/s.phys"), Path("/d/b/t.phys")]))) == 3


@pytest.mark.slow
def test_results_do_not_depend_on_the_worker_count(local_batch, scenes, tmp_path):
    """One worker (each job after the first in a process that already compiled) gives the
    same numbers as two."""
    out, _ = local_batch
    one = tmp_path / "one"
    done = run_cli("batch", "infer", "--scenes", str(scenes / "toss-[01]" / "scene.phys"), "-o",
                   str(one), "--workers", "1", *FIT)
    assert done.returncode == 0, done.stderr
    for i in range(2):
        a, b = estimates(one / f"toss-{i}"), estimates(out / f"toss-{i}")
        np.testing.assert_allclose([a[k] for k in sorted(a)], [b[k] for k in sorted(b)],
                                   rtol=1e-9)
    jobs = summary(one)["jobs"]
    assert jobs[0]["pid"] == jobs[1]["pid"]  # the same worker ran both
