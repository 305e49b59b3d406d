"""``physdsl infer`` in-process: bad input is a located error (exit 2, no traceback); a tiny
scene runs end to end and writes posterior.nc, summary.csv and run.json."""
from __future__ import annotations

import csv
import hashlib
import json
import shutil

import numpy as np
import pytest

from .conftest import PROJECTILE_TRUTH, interval_contains, projectile_text

GOOD_ROWS = "t,body,x,y,z\n0,ball,0,0,1\n0.1,ball,0.3,0,1.35\n0.2,ball,0.6,0,1.6\n"

# case -> (data file text, where-name in the scene, expected row, expected column)
BAD_DATA = {
    "missing column": ("t,body,x,y\n0,ball,0,0\n0.1,ball,0.3,0\n", "ball", 1, "z"),
    "non-numeric cell": ("t,body,x,y,z\n0,ball,0,0,1\n0.1,ball,0.3,abc,1.3\n", "ball", 3, "y"),
    "unsorted times": ("t,body,x,y,z\n0,ball,0,0,1\n0.2,ball,0.6,0,1.6\n0.1,ball,0.3,0,1.3\n",
                       "ball", 4, "t"),
    "duplicate times": ("t,body,x,y,z\n0,ball,0,0,1\n0.1,ball,0.3,0,1.3\n0.1,ball,0.3,0,1.3\n",
                        "ball", 4, "t"),
}


def _scene(folder, data_text, where="ball"):
    folder.mkdir(parents=True, exist_ok=True)
    text = projectile_text().replace('where body == "ball"', f'where body == "{where}"')
    (folder / "scene.phys").write_text(text)
    (folder / "data.csv").write_text(data_text)
    return folder / "scene.phys"


def _assert_clean_error(code, err, *needles):
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    for needle in needles:
        assert needle in err, f"{needle!r} not in {err!r}"


@pytest.mark.parametrize("case", list(BAD_DATA))
def test_bad_data_is_located(tmp_path, cli, case):
    data, where, row, column = BAD_DATA[case]
    scene = _scene(tmp_path, data, where)
    code, _, err = cli("infer", scene, "-o", tmp_path / "run")
    _assert_clean_error(code, err, "data.csv", f"row {row}", f"column '{column}'")
    assert not (tmp_path / "run" / "posterior.nc").exists()


def test_no_rows_for_the_body(tmp_path, cli):
    scene = _scene(tmp_path, "t,body,x,y,z\n0,rock,0,0,1\n")
    code, _, err = cli("infer", scene, "-o", tmp_path / "run")
    _assert_clean_error(code, err, "data.csv", "column 'body'", "rock")


def test_unknown_backend_lists_known_ones(tmp_path, cli):
    scene = _scene(tmp_path, GOOD_ROWS)
    code, _, err = cli("infer", scene, "-o", tmp_path / "run", "--backend", "gibbs")
    _assert_clean_error(code, err, "gibbs", "nuts", "hmc", "rmh", "numpyro-nuts", "map")


def test_non_empty_output_needs_force(tmp_path, cli):
    scene = _scene(tmp_path, GOOD_ROWS)
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    code, _, err = cli("infer", scene, "-o", out, "--backend", "map")
    _assert_clean_error(code, err, "not empty", "--force")
    assert (out / "notes.txt").read_text() == "keep me"


def test_resume_with_nothing_to_resume(tmp_path, cli):
    scene = _scene(tmp_path, GOOD_ROWS)
    for out in (tmp_path / "absent", tmp_path / "empty"):
        if out.name == "empty":
            out.mkdir()
        code, _, err = cli("infer", scene, "-o", out, "--resume")
        _assert_clean_error(code, err, "nothing to resume")


def test_infer_end_to_end(projectile_scene, tmp_path, cli):
    """The CLI on the tiny projectile (NUTS): every output, readable and consistent."""
    from physdsl.infer import posterior_data

    folder = tmp_path / "case"
    shutil.copytree(projectile_scene.parent, folder)
    scene = folder / "scene.phys"
    out = tmp_path / "run"
    code, stdout, err = cli("infer", scene, "-o", out, "--backend", "nuts", "--chains", "2",
                            "--warmup", "100", "--samples", "200", "--seed", "4",
                            "--diagonal-mass")
    assert code == 0, err
    assert "Traceback" not in err
    assert "linear_drag@ball.coefficient" in stdout and "wrote" in stdout

    idata = posterior_data.read(out / "posterior.nc")
    for group in ("posterior", "sample_stats", "posterior_predictive", "observed_data",
                  "log_likelihood"):
        assert group in posterior_data.group_names(idata), group
    post = posterior_data.group(idata, "posterior")
    assert post.sizes["chain"] == 2 and post.sizes["draw"] == 200
    assert post["ball.velocity"].shape == (2, 200, 3)
    assert np.all(interval_contains(post["ball.velocity"].values, PROJECTILE_TRUTH["ball.velocity"]))
    obs = idata.observed_data["obs:ball.position"].values
    measured = np.loadtxt(folder / "data.csv", delimiter=",", skiprows=1, usecols=(2, 3, 4))
    np.testing.assert_allclose(obs, measured)
    assert idata.posterior_predictive["pred:ball.position"].shape == (2, 200, 11, 3)
    assert idata.log_likelihood["obs:ball.position"].shape == (2, 200, 11)
    assert np.all(np.isfinite(idata.log_likelihood["obs:ball.position"].values))

    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["name"] for r in rows] == ["ball.velocity[0]", "ball.velocity[1]",
                                         "ball.velocity[2]", "linear_drag@ball.coefficient"]
    assert rows[3]["unit"] == "kg/s"
    assert {r["intervals"] for r in rows} == {"robust"}  # the default: posterior_robust
    drag = idata.posterior_robust["linear_drag@ball.coefficient"].values
    assert float(rows[3]["mean"]) == pytest.approx(float(drag.mean()), rel=1e-9)
    assert float(rows[3]["q5"]) < 0.3 < float(rows[3]["q95"])

    run = json.loads((out / "run.json").read_text())
    assert run["scene_sha256"] == hashlib.sha256(scene.read_text().encode()).hexdigest()
    data_hash = hashlib.sha256((folder / "data.csv").read_bytes()).hexdigest()
    assert list(run["data_sha256"].values()) == [data_hash]
    assert run["backend"] == "nuts" and run["seed"] == 4
    assert run["settings"]["chains"] == 2 and run["settings"]["samples"] == 200
    assert run["settings"]["dense_mass"] is False  # --diagonal-mass reached the sampler
    assert {"physdsl", "jax", "numpyro", "blackjax", "arviz", "python"} <= set(run["versions"])
    assert not (out / "checkpoint.pkl").exists()
    stats = idata.sample_stats
    assert {"acceptance_rate", "diverging", "n_steps"} <= set(stats.data_vars)
    assert stats["acceptance_rate"].shape == (2, 200)

    # a second run into the same folder is refused, with --force it is redone identically
    code, _, err = cli("infer", scene, "-o", out, "--backend", "map")
    assert code == 2 and "not empty" in err
