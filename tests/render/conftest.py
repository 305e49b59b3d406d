"""Shared helpers of the rendering tests: the MuJoCo-rendered corpus frames copied into data/."""
from pathlib import Path

import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.observe.image import load_frames
from physdsl.render.camera_json import load_camera_json

DATA = Path(__file__).parent / "data"
FRAME_RATE = 1.0 / 0.03  # measured; see ball_case


@pytest.fixture(scope="session")
def ball_case():
    """Bouncing ball: camera spec and the first 15 frames (free fall from 1.2 m, no bounce yet).

    camera.json says 30 frames/s, but the frames are every third 100 Hz sample (84 frames over
    the 2.5 s of trajectory.csv): frame i is at t = 0.03 i. test_frame_interval measures it.
    """
    spec = load_camera_json(DATA / "bouncing_ball_01" / "camera.json")
    times, frames = load_frames(str(DATA / "bouncing_ball_01" / "frames" / "*.png"),
                                rate=FRAME_RATE)
    return spec, times, frames


@pytest.fixture(scope="session")
def pendulum_case():
    spec = load_camera_json(DATA / "pendulum_01" / "camera.json")
    times, frames = load_frames(str(DATA / "pendulum_01" / "frames" / "*.png"), rate=FRAME_RATE)
    return spec, times, frames
