"""``physdsl sample``: concrete scenes equal to their draws, trajectories readable by observe."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from physdsl import syntax
from physdsl.cli import main
from physdsl.compile import compile_scene
from physdsl.errors import UsageError
from physdsl.expr import constant_value
from physdsl.infer import posterior_data
from physdsl.export import export
from physdsl.sample import sample

DATA = Path(__file__).resolve().parent / "data"
TOSS = DATA / "toss.phys"


def _posterior(seed=0):
    rng = np.random.default_rng(seed)
    y = rng.multivariate_normal([np.log(0.4), 1.2], [[0.0025, -0.0004], [-0.0004, 0.0001]], (2, 300))
    post = {"ball.mass": np.exp(y[..., 0]), "h0": y[..., 1],
            "ball.velocity": rng.normal([2.0, 0.0, 3.0], 0.05, (2, 300, 3)),
            "quadratic_drag@ball.coefficient": np.exp(rng.normal(np.log(0.004), 0.1, (2, 300)))}
    return posterior_data.from_dict({"posterior": post}, dims={"ball.velocity": ["axis"]})


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sample")
    proto = tmp / "proto.phys"
    proto.write_text(export(TOSS, _posterior(), out_path=proto))
    return proto, sample(proto, 3, seed=7, outdir=tmp / "gen")


def test_concrete_scene_has_the_drawn_values_and_no_unknowns(generated):
    _, result = generated
    assert [p.parent.name for p in result.scenes] == ["scene-0001", "scene-0002", "scene-0003"]
    table = list(csv.DictReader((result.outdir / "parameters.csv").open()))
    assert len(table) == 3
    assert set(result.names) == {"ball.mass", "h0", "ball.velocity[0]", "ball.velocity[1]",
                                 "ball.velocity[2]", "quadratic_drag@ball.coefficient"}
    for row, path in zip(table, result.scenes):
        scene = syntax.load(path)
        assert scene.unknowns == ()
        assert float(constant_value(scene.body("ball").mass)) == pytest.approx(float(row["ball.mass"]), rel=1e-9)
        pos = constant_value(scene.body("ball").position)
        assert pos[2] == pytest.approx(float(row["h0"]), rel=1e-9)
        vel = constant_value(scene.body("ball").velocity)
        np.testing.assert_allclose(vel, [float(row[f"ball.velocity[{i}]"]) for i in range(3)], rtol=1e-9)
    # the draws differ from scene to scene and follow the posterior roughly
    masses = np.array([float(r["ball.mass"]) for r in table])
    assert len(set(masses)) == 3 and np.all((masses > 0.2) & (masses < 0.8))


def test_generated_trajectory_is_read_back_by_observe_unchanged(generated):
    _, result = generated
    folder = result.scenes[0].parent
    rows = list(csv.DictReader((folder / "trajectory.csv").open()))
    assert list(rows[0]) == ["t", "body", "x", "y", "z", "qw", "qx", "qy", "qz"]
    scene = syntax.load(result.scenes[0])  # observes its own trajectory.csv
    obs = {o.target: o for o in scene.observations}
    ball = [r for r in rows if r["body"] == "ball"]
    np.testing.assert_allclose(obs["ball"].values, [[float(r[k]) for k in "xyz"] for r in ball])
    np.testing.assert_allclose(obs["ball"].times, [float(r["t"]) for r in ball])
    q = np.array([[float(r[k]) for k in ("qw", "qx", "qy", "qz")] for r in ball])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)


@pytest.mark.slow
def test_concrete_scene_simulates_to_its_generated_trajectory(generated):
    _, result = generated
    scene = syntax.load(result.scenes[1])
    obs = {o.target: o for o in scene.observations}
    rollout = compile_scene(scene).simulate({})  # a second physics compile: slow
    np.testing.assert_allclose(np.asarray(rollout.body_pos)[:, 0], obs["ball"].values, atol=1e-8)
    np.testing.assert_allclose(np.asarray(rollout.body_pos)[:, 1], obs["marker"].values, atol=1e-8)


def test_summary_and_refusing_a_non_empty_folder(generated):
    proto, result = generated
    text = result.summary()
    assert "ball.mass" in text and "95%" in text
    with pytest.raises(UsageError, match="not empty"):
        sample(proto, 1, outdir=result.outdir)


def test_cli_export_and_sample(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    posterior_data.write(_posterior(), run / "posterior.nc")
    (run / "run.json").write_text(json.dumps({"scene": str(TOSS), "scene_sha256": "abc",
                                              "data_sha256": {"toss.csv": "def"},
                                              "backend": "nuts", "seed": 3}))
    out = tmp_path / "proto.phys"
    args = ["export", str(TOSS), "--posterior", str(run), "-o", str(out), "--drop", "marker"]
    assert main(args) == 0
    text = out.read_text()
    assert "backend nuts, seed 3" in text and "data toss.csv sha256 def" in text
    assert "body marker" not in text
    assert main(args) == 2  # refuses to overwrite
    assert main(args + ["--force", "--widen", "2"]) == 0
    assert main(["sample", str(out), "-n", "2", "-o", str(tmp_path / "gen"), "--no-simulate"]) == 0
    assert (tmp_path / "gen" / "scene-0002" / "scene.phys").exists()
    assert main(["sample", str(out), "-n", "2", "-o", str(tmp_path / "gen"), "--no-simulate"]) == 2


SEEN = """
scene seen {{
  world {{ timestep: 10 ms  duration: 0.2 s }}
  param h0 ~ normal(1.0 m, 0.2 m)
  ground floor {{ normal: (0, 0, 1)  point: (0, 0, 0) m }}
  body ball {{ shape: sphere(radius: 8 cm)  mass: 200 g  position: (0, 0, h0)  collide: false
              color: (0.9, 0.2, 0.1) }}
  camera cam {{ position: (0, -3, 1) m  look_at: (0, 0, 1) m  up: (0, 0, 1)  fov: 45 deg
               size: (16, 20)  background: (0.55, 0.7, 0.9) }}
  {observe}
}}
"""


def _ball_row(path):
    import cv2

    img = cv2.imread(str(path)).astype(float)
    red = np.clip(img[..., 2] - img[..., 0] - 10, 0, None)  # BGR: R - B
    return (red * np.arange(img.shape[0])[:, None]).sum() / red.sum()


def test_scenes_with_a_camera_get_frames_that_observe_reads_back(tmp_path):
    src = tmp_path / "seen.phys"
    src.write_text(SEEN.format(observe=""))
    gen = sample(src, 2, seed=1, outdir=tmp_path / "gen")
    h0 = gen.table[:, list(gen.names).index("h0")]
    rows = []
    for path in gen.scenes:
        frames = path.parent / "frames-cam"
        pngs = sorted(frames.glob("*.png"))
        times = np.loadtxt(frames / "times.csv", skiprows=1)
        np.testing.assert_allclose(times, np.arange(7) / 30.0)  # 1/30 s over 0.2 s
        assert len(pngs) == 7
        rows.append(_ball_row(pngs[0]))
    assert (rows[0] < rows[1]) == (h0[0] > h0[1])  # the higher ball is drawn higher
    # a scene observing those frames: its draws observe their own frames at the same times
    observed = tmp_path / "observed.phys"
    observed.write_text(SEEN.format(observe='observe cam.image from "gen/scene-0001/frames-cam/'
                                            '*.png" times "gen/scene-0001/frames-cam/times.csv" '
                                            '{ noise: 0.05 }'))
    again = sample(observed, 1, seed=2, outdir=tmp_path / "again")
    scene = syntax.load(again.scenes[0])
    (obs,) = scene.observations
    assert obs.quantity == "image" and scene.unknowns == ()
    assert [p.parent.parent for p in obs.frames] == [again.scenes[0].parent] * 7
    np.testing.assert_allclose(obs.times, np.arange(7) / 30.0)
