"""Tracking the MuJoCo-rendered bouncing ball (free fall from 1.2 m in the first 15 frames)."""
import numpy as np
import pytest

from physdsl.render import project
from physdsl.track import Target, parse_plane, to_world, track_image


def _truth(times):
    z = 1.2 - 0.5 * 9.81 * np.asarray(times) ** 2
    return np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)


def test_centroids_within_a_pixel_of_projected_truth(ball_case):
    spec, times, frames = ball_case
    rows = track_image(times, frames, [Target("ball", tuple(spec.colors["ball"]))])
    assert len(rows) == len(frames)
    uv = np.array([[r[2], r[3]] for r in rows])
    truth_uv = np.asarray(project(spec.camera, _truth(times))[0])
    err = np.linalg.norm(uv - truth_uv, axis=1)
    assert err.max() < 1.0, err
    # the ball falls: v grows (rows go down) frame after frame
    assert np.all(np.diff(uv[:, 1]) > 0)


@pytest.mark.parametrize("how", ["plane", "radius"])
def test_world_positions(ball_case, how):
    spec, times, frames = ball_case
    rows = track_image(times, frames, [Target("ball", tuple(spec.colors["ball"]))])
    uv = np.array([[r[2], r[3]] for r in rows])
    area = np.array([r[4] for r in rows])
    if how == "plane":
        xyz = to_world(spec.camera, uv, area, plane=parse_plane("y=0"))
        assert np.abs(xyz - _truth(times)).max() < 0.01  # 1 px is 15 mm at 2.2 m
    else:
        xyz = to_world(spec.camera, uv, area, radius=0.05)
        # depth from a 35-pixel blob's area is coarse (area quantised in whole pixels)
        depth = xyz[:, 1] - np.asarray(spec.camera.position)[1]
        assert np.abs(depth / 2.2 - 1).max() < 0.15
        assert np.abs(xyz[:, 2] - _truth(times)[:, 2]).max() < 0.08


def test_frame_interval(ball_case):
    """Free fall z = 1.2 - g (k dt)^2 / 2 fitted to the tracked heights gives the frame interval."""
    spec, _, frames = ball_case
    k = np.arange(len(frames))
    rows = track_image(k.astype(float), frames, [Target("ball", tuple(spec.colors["ball"]))])
    uv = np.array([[r[2], r[3]] for r in rows])
    z = to_world(spec.camera, uv, None, plane=parse_plane("y=0"))[:, 2]
    dt2 = np.sum((1.2 - z) * 0.5 * 9.81 * k**2) / np.sum((0.5 * 9.81 * k**2) ** 2)
    assert abs(np.sqrt(dt2) - 0.03) < 0.0003  # not 1/30 s as camera.json states


def test_cli_track_writes_world_csv(tmp_path):
    from physdsl.cli import main
    from conftest import DATA

    out = tmp_path / "traj.csv"
    code = main(["track", str(DATA / "bouncing_ball_01" / "frames" / "*.png"),
                 "--color", "ball=0.85,0.15,0.1", "--camera",
                 str(DATA / "bouncing_ball_01" / "camera.json"), "--depth-plane", "y=0",
                 "--rate", "33.3333333333", "-o", str(out)])
    assert code == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "t,body,x,y,z" and len(lines) == 16
    z0 = float(lines[1].split(",")[4])
    assert abs(z0 - 1.2) < 0.01


def test_cli_track_bad_input_is_data_error(tmp_path, capsys):
    from physdsl.cli import main

    bad = tmp_path / "clip.mp4"
    bad.write_bytes(b"not a video")
    assert main(["track", str(bad), "--color", "1,0,0", "-o", str(tmp_path / "o.csv")]) == 2
    assert "clip.mp4" in capsys.readouterr().err
