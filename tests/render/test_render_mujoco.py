"""The renderer reproduces MuJoCo's frames of the dev corpus at the true parameters.

Softness 0.16 px is the logistic edge with the variance of a one-pixel box filter (MuJoCo's
multisample antialiasing); a pixel is in a silhouette when it differs from the empty scene
(ground and sky rendered by us) by more than 0.2 summed over RGB.
"""
import jax
import jax.numpy as jnp
import numpy as np

from physdsl.render import make_objects, project, render

from render_helpers import centroid, silhouette

SOFT = 0.16


def _ground(spec, objects=()):
    kinds = ["plane"] + [o[0] for o in objects]
    pos = [[0, 0, 0]] + [o[1] for o in objects]
    size = [[0, 0, 1]] + [o[2] for o in objects]
    color = [spec.ground] + [o[3] for o in objects]
    quat = [[1, 0, 0, 0]] + [o[4] if len(o) > 4 else [1, 0, 0, 0] for o in objects]
    return make_objects(kinds, pos, size, color, quat=quat)


def _with_and_without(spec, objs):
    """Images of the scene and of the empty scene (ground only): one compile (static kinds,
    the objects hidden by ``visible`` in the second)."""
    kinds = tuple(int(k) for k in objs.kind)
    shown = jnp.stack([jnp.ones(len(kinds)), jnp.zeros(len(kinds)).at[0].set(1.0)])
    imgs = jax.vmap(lambda v: render(objs._replace(visible=v), spec.light, spec.camera,
                                     spec.background, SOFT, kinds=kinds))(shown)
    return np.asarray(imgs[0]), np.asarray(imgs[1])


def test_bouncing_ball_frame0_matches_mujoco(ball_case):
    spec, _, frames = ball_case
    ball = ("sphere", [0, 0, 1.2], [0.05, 0, 0], spec.colors["ball"])
    img, empty = _with_and_without(spec, _ground(spec, [ball]))
    # outside the ball the two images agree to a grey level (sky, ground, horizon)
    ours, theirs = silhouette(img, empty, 0.2), silhouette(frames[0], empty, 0.2)
    iou = (ours & theirs).sum() / (ours | theirs).sum()
    assert iou > 0.9, iou
    assert np.linalg.norm(centroid(ours) - centroid(theirs)) < 1.0
    projected = np.asarray(project(spec.camera, np.array([0, 0, 1.2]))[0])
    assert np.linalg.norm(centroid(theirs) - projected) < 1.0
    away = ~(ours | theirs)
    assert np.median(np.abs(img - frames[0])[away]) < 1.5 / 255


def test_pendulum_frame0_matches_mujoco(pendulum_case):
    spec, _, frames = pendulum_case
    a = np.deg2rad(40.0)
    pivot = np.array([0, 0, 1.2])
    axis = np.array([np.sin(a), 0, -np.cos(a)])
    bob = pivot + 0.6 * axis
    th = np.pi - a  # rotation about +y taking local z to the rod direction
    rod_q = [np.cos(th / 2), 0, np.sin(th / 2), 0]
    objs = _ground(spec, [
        ("box", pivot, [0.03, 0.03, 0.015], spec.colors["pivot"]),
        ("capsule", pivot + 0.28 * axis, [0.005, 0.28, 0], spec.colors["rod"], rod_q),
        ("sphere", bob, [0.04, 0, 0], spec.colors["bob"]),
    ])
    img, empty = _with_and_without(spec, objs)
    ours, theirs = silhouette(img, empty, 0.2), silhouette(frames[0], empty, 0.2)
    iou = (ours & theirs).sum() / (ours | theirs).sum()
    assert iou > 0.75, iou  # the 1 cm rod is a fifth of a pixel wide: its coverage differs

    def orange(im):
        return (im[..., 0] - im[..., 2] > 0.3) & (im[..., 1] - im[..., 2] > 0.05)

    bob_ours, bob_theirs = orange(img), orange(frames[0])
    # the bob covers 8 pixels: one pixel is 12 % of its IoU
    assert (bob_ours & bob_theirs).sum() / (bob_ours | bob_theirs).sum() > 0.85
    assert np.linalg.norm(centroid(bob_ours) - centroid(bob_theirs)) < 1.0
    pivot_px = np.asarray(project(spec.camera, pivot)[0]).round().astype(int)
    assert ours[pivot_px[1], pivot_px[0]] and theirs[pivot_px[1], pivot_px[0]]
