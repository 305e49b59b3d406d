"""Markers: a point fixed in a body frame is where the rotating body carries it, and can be fitted."""
from __future__ import annotations

import physdsl

import numpy as np
import pytest

from physdsl.compile import compile_scene
from physdsl.syntax import loads

PENDULUM = """
scene pendulum {
  world { timestep: 2 ms  duration: 0.4 s }
  body pole {
    shape: capsule(radius: 1 cm, length: 50 cm)
    mass: 1 kg
    position: (0, 0, 0.75) m
  }
  joint pole_hinge: hinge(world -> pole) {
    axis: (0, 1, 0)
    anchor: (0, 0, 1) m
    initial: ANGLE
    initial_velocity: 1 rad/s
  }
  marker tip on pole { position: (0.1, 0.02, -0.25) m }
%s
}
"""


def _rotation(axis, angle):
    """Rodrigues' rotation matrix about the unit ``axis``."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_marker_is_the_point_carried_by_the_rotating_body():
    scene = loads(PENDULUM.replace("ANGLE", "30 deg") % "")
    assert [(m.name, m.body) for m in scene.markers] == [("tip", "pole")]
    model = compile_scene(scene)
    out = model.simulate({})
    theta, omega = np.asarray(out.joint_pos[:, 0]), np.asarray(out.joint_vel[:, 0])
    assert np.ptp(theta) > 0.5  # it swings
    anchor, axis = np.array([0, 0, 1.0]), np.array([0, 1.0, 0])
    ref = np.array([0, 0, 0.75]) + np.array([0.1, 0.02, -0.25])  # the tip at angle 0
    want_p = np.stack([anchor + _rotation(axis, a) @ (ref - anchor) for a in theta])
    want_v = omega[:, None] * np.cross(axis, want_p - anchor)
    np.testing.assert_allclose(np.asarray(out.marker_pos[:, 0]), want_p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(out.marker_vel[:, 0]), want_v, rtol=0, atol=1e-12)


@pytest.fixture(scope="module")
def tip_data(tmp_path_factory):
    """The tip's track of a pendulum released at 30 deg, with 1 mm noise."""
    truth = loads(PENDULUM.replace("ANGLE", "30 deg") % "")
    out = compile_scene(truth).simulate({})
    rows = np.arange(0, len(out.t), 10)
    rng = np.random.default_rng(0)
    pos = np.asarray(out.marker_pos[rows, 0]) + rng.normal(0, 1e-3, (len(rows), 3))
    folder = tmp_path_factory.mktemp("tip")
    lines = ["t,body,x,y,z"] + [f"{out.t[r]:.6f},pole_tip,{p[0]:.9f},{p[1]:.9f},{p[2]:.9f}"
                                for r, p in zip(rows, pos)]
    (folder / "tip.csv").write_text("\n".join(lines) + "\n")
    return folder


@pytest.mark.slow  # ~11 s
def test_a_marker_track_fits_the_release_angle(tip_data):
    # the data labels the point 'pole_tip'; the scene calls it 'tip' (name mapping)
    text = (PENDULUM.replace("ANGLE", "a0").replace("scene pendulum {", "scene pendulum {\n"
            "  param a0 ~ uniform(0 deg, 60 deg)")
            % '  observe tip.position from "tip.csv" where body == "pole_tip" { noise: 1 mm }')
    scene = loads(text, "fit.phys", tip_data)
    model = compile_scene(scene)
    idata = physdsl.infer(model, backend="map", chains=1, samples=200, progress=False)
    a0 = np.asarray(idata.posterior["a0"]).ravel()
    assert abs(np.median(a0) - np.deg2rad(30)) < 3 * np.std(a0) + 1e-4
    assert np.std(a0) < np.deg2rad(0.5)
    report = physdsl.check(model, idata)  # residuals of the marker track: at the noise (1 mm)
    assert 0.7 < report.rms_sigma < 1.3


def test_a_coloured_marker_is_drawn_as_a_dot():
    from physdsl.render.camera import project
    from physdsl.render.scene import render_frames, scene_camera

    camera = '  camera cam { position: (0, -2, 0.75) m  look_at: (0, 0, 0.75) m  size: (64, 64) }'
    plain = loads(PENDULUM.replace("ANGLE", "0 deg") % camera)
    dotted = loads(PENDULUM.replace("ANGLE", "0 deg").replace(
        "marker tip on pole { position: (0.1, 0.02, -0.25) m }",
        "marker tip on pole { position: (0.1, 0.02, -0.25) m  color: (1, 0, 0)  radius: 2 cm }")
        % camera)
    images = []
    for scene in (plain, dotted):
        model = compile_scene(scene)
        rollout = model.simulate({})
        images.append(np.asarray(render_frames(scene, model.simulator, rollout, {}, "cam", [0.0]))[0])
    cam, _ = scene_camera(dotted, "cam", {})
    u, v = np.asarray(project(cam, np.array([0.1, 0.02, 0.5]))[0])  # the tip at angle 0
    pixel = [int(round(float(v))), int(round(float(u)))]
    assert np.allclose(images[0][pixel[0], pixel[1]], 0.0, atol=0.05)  # background: no dot
    red = images[1][pixel[0], pixel[1]]  # lit from above, seen from the side: ambient red
    assert red[0] > 0.25 and red[0] > 10 * max(red[1], red[2])
    changed = np.argwhere(np.abs(images[1] - images[0]).max(axis=-1) > 1e-3)
    assert np.abs(changed - pixel).max() <= 5  # the dot (soft edges) changes nothing else
