"""Shared helpers of the rendering tests: the MuJoCo-rendered corpus frames copied into data/."""
from pathlib import Path

import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.observe.image import load_frames
from physdsl.render.camera_json import load_camera_json

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def ball_case():
    """Bouncing ball: camera spec and the first 15 frames (free fall from 1.2 m, no bounce yet)."""
    spec = load_camera_json(DATA / "bouncing_ball_01" / "camera.json")
    times, frames = load_frames(str(DATA / "bouncing_ball_01" / "frames" / "*.png"),
                                rate=spec.frame_rate)
    return spec, times, frames


@pytest.fixture(scope="session")
def pendulum_case():
    spec = load_camera_json(DATA / "pendulum_01" / "camera.json")
    times, frames = load_frames(str(DATA / "pendulum_01" / "frames" / "*.png"),
                                rate=spec.frame_rate)
    return spec, times, frames
