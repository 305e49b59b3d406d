"""Inverse rendering from one image: shape, pose, size, colour by Metropolis-within-Gibbs."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl.render import make_camera, make_light, make_objects, project, render
from physdsl.render.inverse import (DIM, SHAPES, Context, decode, default_prior, grid,
                                    render_grid, sample, shape_size)
from physdsl.render.types import BOX, CYLINDER, SPHERE, Objects


def _join(a, b):
    return Objects(*(jnp.concatenate([x, y]) for x, y in zip(a, b)))


def test_shared_sizes_keep_the_extent_across_shapes():
    la = jnp.log(jnp.array([0.02, 0.08, 0.04]))
    assert np.allclose(shape_size(la, BOX), [0.02, 0.08, 0.04])
    assert np.allclose(shape_size(la, CYLINDER), [0.04, 0.04, 0])
    assert np.allclose(shape_size(la, SPHERE), [(0.02 * 0.08 * 0.04) ** (1 / 3), 0, 0])
    theta = jnp.zeros(DIM).at[:3].set(jnp.array([0.1, 0.2, 0.3])).at[6:9].set(la)
    obj, tilt = decode(theta, 2)
    assert int(obj.kind[0]) == SHAPES[2] == BOX
    assert np.allclose(obj.pos[0], [0.1, 0.2, 0.3]) and np.allclose(obj.quat[0], [1, 0, 0, 0])
    assert np.allclose(obj.color[0], 0.5) and np.allclose(tilt, 0)


def test_grid_places_images_side_by_side():
    a, b = np.zeros((4, 5, 3)), np.full((4, 5, 3), 0.5)
    g = grid([a, b, a], pad=1)
    assert g.shape == (6, 19, 3)
    assert np.all(g[1:5, 1:6] == 0) and np.all(g[1:5, 7:12] == 0.5) and np.all(g[0] == 1)
    g2 = grid([a, b, a], pad=1, columns=2)
    assert g2.shape == (11, 13, 3)


@pytest.mark.slow  # about 1.5 minutes on 2 cores
def test_box_recovered_from_one_rendered_image():
    cam = make_camera([0, -1.0, 0.3], [0, 0, 0.05], fovy=0.5, width=40, height=40)
    light = make_light([0.3, 0.5, -1.0])
    ground = make_objects(["plane"], [[0, 0, 0]], [[0, 0, 1]], [[0.6, 0.6, 0.6]])
    ctx = Context(cam, light, jnp.array([0.7, 0.8, 0.9]), ground)
    q = np.array([np.cos(0.3), 0, 0, np.sin(0.3)])
    true_pos = np.array([0.02, 0.03, 0.06])
    truth = make_objects(["box"], [true_pos], [[0.04, 0.03, 0.05]], [[0.2, 0.3, 0.8]], quat=[q])
    target = np.asarray(render(_join(ground, truth), light, cam, ctx.background, 0.5))
    target = np.round(target * 255) / 255  # an 8-bit image
    d = sample(target, ctx, default_prior([0, 0, 0.05]), jax.random.PRNGKey(0), chains=3,
               warmup=300, samples=300)
    assert np.mean(d.shape == SHAPES.index(BOX)) > 0.5  # the box in most draws
    boxes = d.theta[d.shape == SHAPES.index(BOX)]
    pos = boxes[:, :3]
    # 1 pixel is 13 mm at 1 m: across the view within 2 mm, along it (depth) within 1.5 cm
    assert abs(pos[:, 0].mean() - true_pos[0]) < 2e-3
    assert abs(pos[:, 2].mean() - true_pos[2]) < 3e-3
    assert abs(pos[:, 1].mean() - true_pos[1]) < 1.5e-2
    # colour up to the brightness that light and material share: its chromaticity (measured
    # 0.19, 0.25, 0.56 against 0.15, 0.23, 0.62: the random walk on 16 dimensions has not
    # fully mixed the colour in 300 draws)
    rgb = 1 / (1 + np.exp(-boxes[:, 9:12].mean(0)))
    assert np.allclose(rgb / rgb.sum(), np.array([0.2, 0.3, 0.8]) / 1.3, atol=0.08), rgb
    g = render_grid(d, target, ctx, n=4)
    assert g.shape == (44, 5 * 42 + 2, 3)


@pytest.mark.slow  # about 1.5 minutes on 2 cores
def test_mujoco_ball_frame_posterior_contains_the_truth(ball_case):
    spec, _, frames = ball_case
    # half resolution (2x2 means of the 96x96 frame) for speed: 30 mm pixels at 2.2 m
    target = frames[0].reshape(48, 2, 48, 2, 3).mean(axis=(1, 3))
    cam = spec.camera.__class__(spec.camera.position, spec.camera.look_at, spec.camera.up,
                                spec.camera.fovy, 48, 48)
    ground = make_objects(["plane"], [[0, 0, 0]], [[0, 0, 1]], [spec.ground])
    ctx = Context(cam, spec.light, jnp.asarray(spec.background), ground)
    prior = default_prior([0.0, 0.0, 1.0], center_sd=0.2)
    d = sample(target, ctx, prior, jax.random.PRNGKey(1), chains=3, warmup=300, samples=300)
    assert np.mean(d.shape == SHAPES.index(SPHERE)) > 0.5
    pos = d.theta[..., :3].reshape(-1, 3)
    truth = np.array([0.0, 0.0, 1.2])
    lo, hi = np.percentile(pos, 0.5, axis=0), np.percentile(pos, 99.5, axis=0)
    # in the image plane the posterior is sharp: within a third of a pixel (1 cm) of truth
    uv = np.asarray(project(cam, jnp.asarray(pos.mean(0)))[0])
    uv_true = np.asarray(project(cam, jnp.asarray(truth))[0])
    assert np.linalg.norm(uv - uv_true) < 0.35, (uv, uv_true)
    # depth trades against size: the truth lies inside the posterior's range
    assert lo[1] - 0.01 <= truth[1] <= hi[1] + 0.01, (lo, hi)


@pytest.mark.slow  # HMC moves through the renderer's gradient (about 1.5 minutes on 2 cores)
def test_hmc_moves_recover_position_and_colour():
    cam = make_camera([0, -1.0, 0.3], [0, 0, 0.05], fovy=0.5, width=32, height=32)
    light = make_light([0.3, 0.5, -1.0])
    ground = make_objects(["plane"], [[0, 0, 0]], [[0, 0, 1]], [[0.6, 0.6, 0.6]])
    ctx = Context(cam, light, jnp.array([0.7, 0.8, 0.9]), ground)
    true_pos = np.array([0.02, 0.03, 0.06])
    truth = make_objects(["sphere"], [true_pos], [[0.04, 0, 0]], [[0.2, 0.3, 0.8]])
    target = np.asarray(render(_join(ground, truth), light, cam, ctx.background, 0.5))
    target = np.round(target * 255) / 255
    d = sample(target, ctx, default_prior([0, 0, 0.05]), jax.random.PRNGKey(0), chains=2,
               warmup=100, samples=100, continuous="hmc")
    assert np.all((d.accept > 0.4) & (d.accept < 0.95)), d.accept  # adapted towards 0.75
    assert np.mean(d.shape == SHAPES.index(SPHERE)) > 0.5
    pos = d.theta[..., :3].reshape(-1, 3)
    # measured: x within 1 mm (sd 1.2 mm); depth y and height z trade against size along the
    # line of sight (sd 27 mm and 6 mm), the truth within 1.5 sd
    assert abs(pos[:, 0].mean() - true_pos[0]) < 2e-3
    assert np.all(np.abs(pos.mean(0) - true_pos) < 3 * pos.std(0) + 1e-3), (pos.mean(0),
                                                                            pos.std(0))
    # colour chromaticity: measured within 0.01 (the random walk: 0.08 in 300 draws)
    rgb = 1 / (1 + np.exp(-d.theta[..., 9:12].reshape(-1, 3).mean(0)))
    assert np.allclose(rgb / rgb.sum(), np.array([0.2, 0.3, 0.8]) / 1.3, atol=0.04), rgb
    with pytest.raises(ValueError, match="'rw' or 'hmc'"):
        sample(target, ctx, default_prior([0, 0, 0.05]), jax.random.PRNGKey(0),
               continuous="nuts")
