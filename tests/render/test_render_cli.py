"""``physdsl render``: frames of a scene, refusal to overwrite, posterior draws as a grid."""
import cv2
import numpy as np
import pytest

from physdsl.cli import main
from physdsl.infer import posterior_data

from scene_helpers import TOSS

SCENE = TOSS.format(duration=0.3, params="param h0 ~ normal(1.0 m, 0.1 m)\n  param v0: 2.0 m/s",
                    w=32, h=24, observe="")


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli")
    path = folder / "toss.phys"
    path.write_text(SCENE)
    return path


def _ball_row(img):
    red = np.clip(img[..., 2].astype(float) - img[..., 0] - 10, 0, None)  # BGR: R - B
    rows = np.arange(img.shape[0])[:, None]
    return (red * rows).sum() / red.sum()


@pytest.mark.slow  # three CLI runs, each compiling simulation and rendering (about a minute)
def test_render_frames_at_prior_median_and_given_param(scene_file, tmp_path, capsys):
    out = tmp_path / "frames"
    assert main(["render", str(scene_file), "--fps", "10", "-o", str(out)]) == 0
    pngs = sorted(out.glob("frame_*.png"))
    assert len(pngs) == 4  # t = 0, 0.1, 0.2, 0.3
    first = cv2.imread(str(pngs[0]))
    assert first.shape == (24, 32, 3)
    assert "4 frames (32x24)" in capsys.readouterr().out
    # refuses a non-empty folder, overwrites with --force
    assert main(["render", str(scene_file), "--fps", "10", "-o", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["render", str(scene_file), "--fps", "10", "--param", "h0=1.3", "-o", str(out),
                 "--force"]) == 0
    higher = cv2.imread(str(out / "frame_0000.png"))
    assert _ball_row(higher) < _ball_row(first) - 1.0  # the ball starts higher: rows go up


def test_render_rejects_unknown_param_and_camera(scene_file, tmp_path, capsys):
    assert main(["render", str(scene_file), "--param", "nope=1", "-o", str(tmp_path / "a")]) == 2
    assert "names no unknown" in capsys.readouterr().err
    assert main(["render", str(scene_file), "--camera", "top", "-o", str(tmp_path / "b")]) == 2
    assert "no camera called 'top'" in capsys.readouterr().err


@pytest.mark.slow  # compiles simulation and rendering (about 30 s on 2 cores)
def test_render_posterior_grid(scene_file, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    draws = {"h0": np.linspace(0.9, 1.3, 6).reshape(2, 3)}
    posterior_data.write(posterior_data.from_dict({"posterior": draws}), run / "posterior.nc")
    out = tmp_path / "grid.png"
    assert main(["render", str(scene_file), "--posterior", str(run), "--draws", "4",
                 "--time", "0", "-o", str(out)]) == 0
    img = cv2.imread(str(out))
    assert img.shape == (24 + 4, 4 * 34 + 2, 3)
    rows = [_ball_row(img[2:26, 2 + 34 * i:2 + 34 * i + 32]) for i in range(4)]
    assert np.all(np.diff(rows) < 0)  # draws in order of h0: the ball climbs
    assert main(["render", str(scene_file), "--posterior", str(run), "-o", str(out)]) == 2
