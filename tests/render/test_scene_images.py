"""Scenes to images (scene_objects, cameras, light) and images as measurements of a scene."""
import physdsl
import cv2
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl.compile import Model
from physdsl.errors import DataError
from physdsl.observe import image as image_obs
from physdsl.render import project
from physdsl.render.scene import scene_camera, scene_kinds, scene_light, scene_objects

from scene_helpers import TOSS, load, write_frames

TRUTH = {"h0": 1.1, "v0": 2.0}
FRAME_TIMES = np.arange(6) * 0.1


def _toss(tmp_path, params, observe="", size=32):
    return load(TOSS.format(duration=0.5, params=params, w=size, h=size, observe=observe),
                tmp_path)


def _known(tmp_path):
    return _toss(tmp_path, "param h0: 1.1 m\n  param v0: 2.0 m/s")


def _unknown(tmp_path, noise="0.05"):
    return _toss(tmp_path, "param h0 ~ normal(1.0 m, 0.2 m)\n  param v0 ~ normal(1.5 m/s, 1 m/s)",
                 f'observe cam.image from "frames/*.png" at 10 Hz {{ noise: {noise} }}')


@pytest.fixture(scope="module")
def toss(tmp_path_factory):
    """A folder with truth frames of the known toss, the known scene, its model and rollout."""
    folder = tmp_path_factory.mktemp("toss")
    scene = _known(folder)
    model = Model(scene)
    images = write_frames(scene, {}, "cam", FRAME_TIMES, folder / "frames")
    return folder, scene, model, model.simulate({}), images


def test_scene_objects_follow_the_rollout(toss):
    _, scene, model, rollout, _ = toss
    times = np.array([0.0, 0.105, 0.5])  # a grid time, between grid times, the last one
    objs = scene_objects(scene, model.simulator, rollout, {}, times)
    assert scene_kinds(scene) == (4, 0)  # floor plane, ball sphere
    assert objs.pos.shape == (3, 2, 3) and objs.size.shape == (3, 2, 3)
    # free flight, semi-implicit Euler at dt = 10 ms: x = x0 + vx t, z = z0 + v0 t - g t (t + dt)
    # / 2 on the grid (linear interpolation between grid points is within g dt^2 / 8)
    t = times
    assert np.allclose(objs.pos[:, 1, 0], -0.4 + 1.5 * t, atol=1e-9)
    assert np.allclose(objs.pos[:, 1, 2], 1.1 + 2.0 * t - 0.5 * 9.81 * t * (t + 0.01),
                       atol=2e-4)
    mid = 0.5 * (rollout.body_pos[10] + rollout.body_pos[11])
    assert np.allclose(objs.pos[1, 1], mid[model.simulator.body_names.index("ball")])
    assert np.allclose(objs.size[0, 1], [0.08, 0, 0]) and np.allclose(objs.size[0, 0], [0, 0, 1])
    assert np.allclose(objs.color[0, 1], [0.9, 0.2, 0.1])
    cam, bg = scene_camera(scene, "cam", {})
    assert (cam.width, cam.height) == (32, 32) and np.allclose(bg, [0.55, 0.7, 0.9])
    assert np.isclose(cam.fovy, np.deg2rad(45))
    light = scene_light(scene, {})
    assert np.allclose(light.ambient, 0.4) and np.allclose(light.direction, [0.3, 0.4, -1])


def test_frames_show_the_ball_where_the_camera_projects_it(toss):
    _, scene, _, _, images = toss
    cam, bg = scene_camera(scene, "cam", {})
    rows, cols = np.mgrid[:32, :32]
    for t, img in zip(FRAME_TIMES, images):
        red = np.clip(img[..., 0] - img[..., 2] - 0.05, 0, None)  # sky and ground are not red
        x = -0.4 + 1.5 * t
        z = 1.1 + 2.0 * t - 0.5 * 9.81 * t * (t + 0.01)
        uv = np.asarray(project(cam, jnp.array([x, 0.0, z]))[0])
        centre = np.array([(red * cols).sum(), (red * rows).sum()]) / red.sum()
        assert red.sum() > 0.1 and np.hypot(*(centre - uv)) < 0.5, (t, centre, uv)


def test_image_likelihood_prefers_the_truth_and_caches_frames(toss):
    model = Model(_unknown(toss[0]))
    (obs,) = model.images
    image_obs._FRAME_CACHE.clear()

    image_obs.observed_frames(obs)  # load outside the trace, as the compiled model does

    @jax.jit
    def _loglik(values):
        return model.image_log_likelihood(obs, model.simulator._simulate(values), values)

    def loglik(h0, v0):
        return float(_loglik({"h0": jnp.asarray(h0), "v0": jnp.asarray(v0)}))

    best = loglik(1.1, 2.0)
    assert len(image_obs._FRAME_CACHE) == 1
    for h0, v0 in [(1.12, 2.0), (1.08, 2.0), (1.1, 2.1), (1.1, 1.9)]:
        assert loglik(h0, v0) < best - 1.0
    assert len(image_obs._FRAME_CACHE) == 1  # loaded once


def test_a_video_is_an_image_observation_like_its_frames(toss):
    """``observe cam.image from "clip.avi"``: one entry per video frame, times from the
    video's own rate, the same likelihood as the PNG frames it holds (lossless FFV1)."""
    folder, _, _, rollout, images = toss
    writer = cv2.VideoWriter(str(folder / "clip.avi"), cv2.VideoWriter_fourcc(*"FFV1"), 10.0,
                             (32, 32))
    for img in images:
        writer.write(np.round(img[:, :, ::-1] * 255).astype(np.uint8))
    writer.release()
    known = "param h0: 1.1 m\n  param v0: 2.0 m/s"
    models = [Model(_toss(folder, known, f'observe cam.image from {src} {{ noise: 0.05 }}'))
              for src in ('"clip.avi"', '"frames/*.png" at 10 Hz')]
    video, pngs = (m.images[0] for m in models)
    assert len(video.frames) == len(images) and np.allclose(video.times, pngs.times)
    assert str(video.frames[2]).endswith("clip.avi (frame 2)")
    logliks = [float(m.image_log_likelihood(m.images[0], rollout, {})) for m in models]
    assert np.isclose(logliks[0], logliks[1], rtol=1e-12), logliks
    at = _toss(folder, known, 'observe cam.image from "clip.avi" at 20 Hz { noise: 0.05 }')
    assert np.allclose(at.observations[0].times, np.arange(len(images)) / 20.0)
    (folder / "broken.mp4").write_bytes(b"not a video")
    with pytest.raises(DataError, match="broken.mp4"):
        _toss(folder, known, 'observe cam.image from "broken.mp4" { noise: 0.05 }')
    with pytest.raises(DataError, match="frame times"):
        _toss(folder, known, 'observe cam.image from "frames/*.png" { noise: 0.05 }')


def test_frame_subset_is_even_and_bounded():
    assert list(image_obs.frame_subset(5, 16)) == [0, 1, 2, 3, 4]
    idx = image_obs.frame_subset(100, 16)
    assert len(idx) == 16 and idx[0] == 0 and idx[-1] == 99
    assert np.all(np.diff(idx) >= 6) and np.all(np.diff(idx) <= 7)


def test_frames_of_the_wrong_size_are_a_data_error(toss):
    scene = _toss(toss[0], "param h0: 1.1 m\n  param v0: 2.0 m/s",
                  'observe cam.image from "frames/*.png" at 10 Hz { noise: 0.05 }', size=24)
    model = Model(scene)
    rollout = toss[3]  # same bodies: no need to compile this scene's simulator
    with pytest.raises(DataError, match="frames are 32x32 pixels but camera 'cam' is 24x24"):
        model.image_log_likelihood(model.images[0], rollout, {})


@pytest.mark.slow  # MAP fit through the renderer (about a minute on 2 cores)
def test_launch_recovered_from_frames_alone(toss):
    model = Model(_unknown(toss[0]))
    assert not model.observed  # nothing but the frames
    post = physdsl.infer(model, backend="map", chains=1, samples=200, progress=False).posterior
    h0, v0 = float(post["h0"].mean()), float(post["v0"].mean())
    # one pixel is 9 cm at the ball; sub-pixel fits from 6 frames of a 2-pixel ball
    assert abs(h0 - TRUTH["h0"]) < 0.01, h0
    assert abs(v0 - TRUTH["v0"]) < 0.05, v0
    # the Laplace spread covers the truth
    assert abs(h0 - TRUTH["h0"]) < 4 * float(post["h0"].std()) + 1e-3


def _trajectory_only_sd(times, sigma, prior_sd):
    """Posterior sd of (h0, vx, v0) from ball positions alone: z = h0 + v0 t - ..., x = x0 +
    vx t are linear in the unknowns, so the Gaussian posterior is exact."""
    t = np.asarray(times)
    info = np.zeros((3, 3))
    info[np.ix_([0, 2], [0, 2])] = np.stack([np.ones_like(t), t]) @ np.stack(
        [np.ones_like(t), t]).T / sigma**2  # z: h0, v0
    info[1, 1] = (t**2).sum() / sigma**2  # x: vx
    info += np.diag(1 / np.asarray(prior_sd) ** 2)
    return np.sqrt(np.diag(np.linalg.inv(info)))


@pytest.mark.slow  # MAP fit through rollout and renderer (about a minute on 2 cores)
def test_frames_plus_a_partial_trajectory(toss):
    """Frames over 0.5 s and the ball's measured positions over its first 0.1 s only: the fit
    recovers release height and launch velocity, more sharply than the positions alone."""
    folder, _, model, rollout, _ = toss
    ball = model.simulator.body_names.index("ball")
    grid = np.asarray(model.simulator.times)
    keep = grid <= 0.1 + 1e-9
    rng = np.random.default_rng(0)
    xyz = np.asarray(rollout.body_pos)[keep, ball] + rng.normal(0, 0.005, (keep.sum(), 3))
    lines = ["t,body,x,y,z"] + [f"{t:.3f},ball,{x:.5f},{y:.5f},{z:.5f}"
                                for t, (x, y, z) in zip(grid[keep], xyz)]
    (folder / "start.csv").write_text("\n".join(lines) + "\n")
    params = ("param h0 ~ normal(1.0 m, 0.2 m)\n  param vx ~ normal(1.0 m/s, 1 m/s)\n"
              "  param v0 ~ normal(1.5 m/s, 1 m/s)")
    observe = ('observe cam.image from "frames/*.png" at 10 Hz { noise: 0.05 }\n'
               '  observe ball.position from "start.csv" where body == "ball" { noise: 5 mm }')
    text = TOSS.format(duration=0.5, params=params, w=32, h=32, observe=observe)
    scene = load(text.replace("velocity: (1.5, 0, v0)", "velocity: (vx, 0, v0)"), folder)
    fit = Model(scene)
    assert len(fit.observed) == 1 and len(fit.images) == 1
    post = physdsl.infer(fit, backend="map", chains=1, samples=400, progress=False).posterior
    mean = np.array([float(post[k].mean()) for k in ("h0", "vx", "v0")])
    sd = np.array([float(post[k].std()) for k in ("h0", "vx", "v0")])
    truth = np.array([TRUTH["h0"], 1.5, TRUTH["v0"]])
    assert np.all(np.abs(mean - truth) < np.array([0.005, 0.05, 0.05])), mean
    assert np.all(np.abs(mean - truth) < 4 * sd + 1e-3), (mean, sd)
    alone = _trajectory_only_sd(grid[keep], 0.005, [0.2, 1.0, 1.0])
    # the frames add what 0.1 s of positions cannot: the launch velocity
    assert sd[2] < 0.7 * alone[2] and sd[1] < 0.7 * alone[1], (sd, alone)
