"""Experiments in the language: recordings from a glob or a manifest, per-recording and
shared unknowns, known settings from the manifest's columns, located errors (golden files)."""
from __future__ import annotations

import csv

import jax
import numpy as np
import pytest

import physdsl
from physdsl.cli import main
from physdsl.syntax.parser import parse
from physdsl.syntax.printer import format_module

DATA = __import__("pathlib").Path(__file__).parent / "data"
BROKEN = sorted(DATA.glob("exp_*.phys"))


def first_error(stderr: str) -> str:
    return stderr.strip("\n").split("\n\n")[0].rstrip() + "\n"


@pytest.mark.parametrize("path", BROKEN, ids=lambda p: p.stem)
def test_broken_file_reports_golden_error(path, capsys, monkeypatch):
    monkeypatch.chdir(path.parent)
    code = main(["lint", "-q", path.name])
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" not in err and "internal error" not in err
    assert first_error(err) == path.with_suffix(".expected").read_text()


def test_there_are_golden_files_for_the_data_and_the_scene():
    assert len(BROKEN) >= 12 and all(p.with_suffix(".expected").is_file() for p in BROKEN)
    texts = [p.with_suffix(".expected").read_text() for p in BROKEN]
    assert any(", row 3, column 'speed [m/s]'" in t for t in texts)  # file, row, column
    assert any("bad_throws/01/trajectory.csv, row 1: no column 'z'" in t for t in texts)
    assert any(", row 3, column 'push': no file 'throws/01/nope.csv'" in t for t in texts)


def test_glob_reads_every_recording_from_its_folder():
    scene = physdsl.load(DATA / "glob_scene.phys")
    ex = scene.experiments
    assert [r.name for r in ex.recordings] == ["00", "01"]
    first, second = (r.observations[0] for r in ex.recordings)
    assert first.file.parent.name == "00" and second.file.parent.name == "01"
    assert not np.allclose(first.values, second.values)  # each its own data
    assert scene.world.duration == pytest.approx(max(first.times[-1], second.times[-1]))
    per = {u.name: u.per_experiment for u in scene.unknowns}
    assert per == {"mass_mu": False, "ball.mass": True, "ball.position": True,
                   "ball.velocity": True, "quadratic_drag@ball.coefficient": False}


def test_format_keeps_experiments_and_per_experiment():
    text = (DATA / "glob_scene.phys").read_text()
    out = format_module(parse(text), text)
    assert out == text  # canonical already, and the printer writes both forms back
    assert 'experiments throws from "throws/*/trajectory.csv"' in out
    assert "mass ~ per_experiment normal(mass_mu, 20 g)" in out


def test_manifest_settings_reach_each_recordings_rollout():
    """speed [m/s] and angle [deg] columns: SI per recording, and each recording's rollout
    starts at its own launch velocity (speed cos angle, 0, speed sin angle)."""
    model = physdsl.compile(DATA / "manifest_scene.phys")
    assert model.recording_names == ("slow", "fast")
    np.testing.assert_allclose(model.settings["throws.speed"], [4.243, 7.071])
    np.testing.assert_allclose(model.settings["throws.angle"], np.deg2rad([45, 45]))
    roll = model.simulate({"ball.position": np.array([[0, 0, 1.8], [0, 0, 1.7]])})
    v0 = np.asarray(roll.body_vel)[:, 0, 0]  # (recording, body, xyz) at t = 0
    s, a = model.settings["throws.speed"], model.settings["throws.angle"]
    np.testing.assert_allclose(v0, np.stack([s * np.cos(a), 0 * s, s * np.sin(a)], 1), atol=1e-9)
    np.testing.assert_allclose(np.asarray(roll.body_pos)[:, 0, 0, 2], [1.8, 1.7])


def test_hierarchical_prior_is_a_plate_around_the_shared_mean():
    """mass ~ per_experiment normal(mass_mu, 20 g): one mass per recording drawn around the
    one shared mass_mu (numpyro.plate), not an independent mean per recording."""
    model = physdsl.compile(DATA / "glob_scene.phys")
    draws = model.sample_prior(jax.random.PRNGKey(0), 4000)
    mu, mass = draws["mass_mu"], draws["ball.mass"]
    assert mu.shape == (4000,) and mass.shape == (4000, 2)
    dev = mass - mu[:, None]
    assert abs(dev.mean()) < 0.002 and dev.std() == pytest.approx(0.02, rel=0.05)
    assert mu.std() == pytest.approx(0.1, rel=0.05)
    assert np.corrcoef(mass[:, 0], mass[:, 1])[0, 1] > 0.9  # they share the mean's spread
    assert draws["ball.velocity"].shape == (4000, 2, 3)


@pytest.mark.slow  # ~18 s
def test_cli_infer_writes_each_recordings_unknowns_by_name(tmp_path, capsys, monkeypatch):
    """physdsl infer of a manifest scene: exit 0, summary.csv rows per recording by name."""
    monkeypatch.chdir(DATA)
    code = main(["infer", "manifest_scene.phys", "-o", str(tmp_path / "run"), "--backend",
                 "map", "--chains", "1", "--samples", "50"])
    assert code == 0, capsys.readouterr().err
    rows = (tmp_path / "run" / "summary.csv").read_text().splitlines()
    names = [r.split(",")[0] for r in rows[1:]]
    assert names == [f"ball.position[{rec}][{i}]" for rec in ("slow", "fast") for i in range(3)]
    mean = {r["name"]: float(r["mean"]) for r in csv.DictReader(rows)}
    assert mean["ball.position[slow][2]"] == pytest.approx(1.8, abs=0.02)  # the data's start
