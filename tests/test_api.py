"""physdsl's api floor (physdsl/api.py): each function on a small scene, against a known truth.

A ball thrown through air with linear drag (c = 0.3 kg/s); the naive scene knows no drag, and
``add_effect`` writes the drag scene. Data are simulated by physdsl from the drag scene at the
truth with 5 mm noise (seed 3), as in tests/infer; the two scenes' fits are shared by the tests.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

import physdsl
from physdsl.cli import main

NAIVE = """\
scene toss {
  world { timestep: 10 ms  duration: 0.6 s }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
    color: (0.9, 0.2, 0.1)
  }
  camera cam { position: (1, -4, 1.2) m  look_at: (1, 0, 1.2) m  up: (0, 0, 1)  fov: 50 deg
               size: (32, 24) }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""
TRUTH = {"ball.velocity": np.array([3.2, 0.0, 4.3]), "linear_drag@ball.coefficient": np.array(0.3)}
TIMES = np.linspace(0.0, 0.6, 31)
NOISE = 0.005
FIT = dict(backend="map", chains=2, warmup=100, samples=100, seed=0, progress=False)


def _csv(path, values):
    rows = [f"{t:.6f},ball,{x:.9g},{y:.9g},{z:.9g}" for t, (x, y, z) in zip(TIMES, values)]
    path.write_text("t,body,x,y,z\n" + "\n".join(rows) + "\n")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """naive.phys and drag.phys (``add_effect``'s) beside data.csv simulated from drag.phys."""
    root = tmp_path_factory.mktemp("api")
    (root / "naive.phys").write_text(NAIVE)
    _csv(root / "data.csv", np.zeros((len(TIMES), 3)))  # placeholder data: the scenes load
    drag = physdsl.add_effect(physdsl.load(root / "naive.phys"), "linear_drag", "ball")
    (root / "drag.phys").write_text(drag.source)
    pred = np.asarray(physdsl.compile(drag).predict(TRUTH)["ball.position"])
    _csv(root / "data.csv", pred + np.random.default_rng(3).normal(0, NOISE, pred.shape))
    return root


@pytest.fixture(scope="module")
def naive(folder):
    model = physdsl.compile(physdsl.load(folder / "naive.phys"))
    return model, physdsl.infer(model, **FIT)


@pytest.fixture(scope="module")
def drag(folder):
    model = physdsl.compile(folder / "drag.phys")
    return model, physdsl.infer(model, **FIT)


def test_load_gives_a_scene_and_compile_a_model(folder):
    scene = physdsl.load(folder / "naive.phys")
    assert isinstance(scene, physdsl.Scene) and scene.name == "toss"
    assert [u.name for u in scene.unknowns] == ["ball.velocity"]
    from_text = physdsl.load(NAIVE.replace('"data.csv"', f'"{folder / "data.csv"}"'),
                             allowed_paths=[folder])
    assert [u.name for u in from_text.unknowns] == ["ball.velocity"]
    model = physdsl.compile(scene)
    assert isinstance(model, physdsl.Model) and model.unknown_names == ("ball.velocity",)
    assert physdsl.compile(str(folder / "naive.phys")).compiled is model.compiled  # one structure
    for name in ("infer", "check", "diagnose", "export"):  # later stages are functions, not methods
        assert not hasattr(model, name)


def test_add_effect_then_infer_recovers_the_drag(naive, drag):
    scene = naive[0].scene
    with_drag = physdsl.add_effect(scene, "linear_drag", "ball")
    assert "linear_drag@ball.coefficient" in {u.name for u in with_drag.unknowns}
    assert "linear_drag on ball" in with_drag.source
    assert drag[0].unknown_names == physdsl.compile(with_drag).unknown_names
    post = drag[1].posterior
    c = np.asarray(post["linear_drag@ball.coefficient"]).ravel()
    assert abs(c.mean() - 0.3) < max(3 * c.std(), 0.02)
    v = np.asarray(post["ball.velocity"]).reshape(-1, 3).mean(axis=0)
    assert np.allclose(v, TRUTH["ball.velocity"], atol=0.05)
    with pytest.raises(physdsl.PhysNameError, match="did you mean linear_drag"):
        physdsl.add_effect(scene, "linear_dreg", "ball")


def test_cli_add_effect_writes_what_the_api_returns(folder, tmp_path):
    out = tmp_path / "new.phys"
    assert main(["add-effect", str(folder / "naive.phys"), "wind", "on", "ball", "-o", str(out)]) == 0
    assert out.read_text() == physdsl.add_effect(physdsl.load(folder / "naive.phys"), "wind", "ball").source


def test_check_and_diagnose_find_the_missing_drag(naive):
    model, idata = naive
    report = physdsl.check(model, idata)
    assert not report.consistent and report.rms_sigma > 3  # the drag is missing
    diag = physdsl.diagnose(model, idata, confirm_top=0)
    top = diag.ranking[0]
    assert top.target == "ball" and "drag" in top.effect, diag.table()


def test_design_experiment_prefers_a_faster_throw(naive, drag):
    (p,) = physdsl.design_experiment(naive[0], drag[0], ["ball.velocity"], idata_a=naive[1],
                                     idata_b=drag[1], rng=(2.0, 12.0))
    assert p.field == "ball.velocity"
    assert p.setting > p.recorded and p.score > p.recorded_score  # drag grows with speed


def test_export_then_sample_draws_near_the_posterior(folder, naive, tmp_path):
    model, idata = naive
    text = physdsl.export(model, idata, observe=False, out_path=tmp_path / "proto.phys")
    (tmp_path / "proto.phys").write_text(text)
    result = physdsl.sample(tmp_path / "proto.phys", 40, seed=1, outdir=tmp_path / "s",
                            simulate=False)
    drawn = result.table[:, [result.names.index(f"ball.velocity[{i}]") for i in range(3)]]
    post = np.asarray(idata.posterior["ball.velocity"]).reshape(-1, 3)
    assert np.allclose(drawn.mean(axis=0), post.mean(axis=0), atol=4 * post.std(axis=0).max() + 1e-3)


def test_track_finds_drawn_discs(tmp_path):
    centres = [(10.0, 8.0), (14.5, 9.0), (19.0, 11.5)]
    for i, (u, v) in enumerate(centres):
        img = np.zeros((24, 32, 3), np.uint8)
        cv2.circle(img, (int(round(u * 4)), int(round(v * 4))), 12, (30, 40, 220), -1, shift=2)
        cv2.imwrite(str(tmp_path / f"frame_{i:04d}.png"), img)
    tracked = physdsl.track(str(tmp_path / "frame_*.png"), ["ball=220,40,30"], rate=10.0)
    assert tracked.found_in("ball") == 3
    uv = np.array([[r[2], r[3]] for r in tracked.rows])
    assert np.allclose(uv, centres, atol=0.3)
    assert [r[0] for r in tracked.rows] == pytest.approx([0.0, 0.1, 0.2])


@pytest.mark.slow  # compiles the renderer (about 30 s on 2 cores)
def test_render_and_refine(folder, naive, tmp_path):
    model, idata = naive
    frames = physdsl.render(model, {"ball.velocity": TRUTH["ball.velocity"]}, fps=5)
    assert frames.camera == "cam" and frames.images.shape == (4, 24, 32, 3)
    red = frames.images[..., 0] - frames.images[..., 2]
    cols = [(r * np.arange(32)).sum() / r.sum() for r in np.clip(red, 0, None)]
    assert np.all(np.diff(cols) > 0)  # the ball flies to +x, to the right of the image
    images, t = physdsl.render_draws(model, idata, draws=3, time=0.4)
    assert len(images) == 3 and t == 0.4
    rounds = physdsl.refine(folder / "naive.phys", tmp_path / "refine", max_rounds=1, echo=lambda s: None)
    assert rounds[-1].rms_sigma < 1.5 < rounds[0].rms_sigma
