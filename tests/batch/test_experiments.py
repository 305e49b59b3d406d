"""``physdsl batch infer|refine`` on scenes that declare ``experiments``: each job fits (or
refines) its own recordings, pooled, into its own folder; and the executor ``inline`` (this
process) that a diagnosis's refits use by default."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from physdsl.batch.executors import InlineExecutor
from physdsl.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "many_throws"
TRUTH = json.loads((EXAMPLE / "throws" / "truth.json").read_text())
# two labs, each a scene over two throws (0.4 s), in folders named alike so both jobs share
# one structure (and one compile): lab a holds throws 05 and 15, lab b throws 08 and 18
LABS = {"a": ("05", "15"), "b": ("08", "18")}


def lab(root: Path, name: str, drag: bool = True) -> Path:
    """``root/name/scene.phys`` over the lab's throws (as recordings r0, r1; first 0.4 s)."""
    folder = root / name
    for i, throw in enumerate(LABS[name]):
        rows = (EXAMPLE / "throws" / throw / "trajectory.csv").read_text().splitlines()
        keep = [rows[0]] + [r for r in rows[1:] if float(r.split(",")[0]) <= 0.4]
        (folder / "throws" / f"r{i}").mkdir(parents=True)
        (folder / "throws" / f"r{i}" / "trajectory.csv").write_text("\n".join(keep) + "\n")
    text = (EXAMPLE / "scene.phys").read_text()
    if not drag:
        text = "\n".join(ln for ln in text.splitlines() if "quadratic_drag" not in ln) + "\n"
    (folder / "scene.phys").write_text(text)
    return folder / "scene.phys"


def rows(folder: Path) -> dict:
    with open(folder / "summary.csv", newline="") as f:
        return {r["name"]: r for r in csv.DictReader(f)}


@pytest.mark.slow  # ~17 s; batches: tests/batch/test_local.py, pooled fits: tests/experiments
def test_batch_infer_fits_each_scenes_recordings_pooled(tmp_path, capsys):
    """Two experiments scenes in one batch (inline executor): each job's summary names its
    recordings' unknowns, its launch velocities are its own throws' (within 4 sd; the labs'
    throws differ by metres per second), and its shared drag's 90% interval covers the truth."""
    for name in LABS:
        lab(tmp_path / "labs", name)
    code = main(["batch", "infer", "--scenes", str(tmp_path / "labs" / "*" / "scene.phys"),
                 "-o", str(tmp_path / "fits"), "--executor", "inline", "--backend", "map",
                 "--chains", "1", "--samples", "200", "--quiet"])
    assert code == 0, capsys.readouterr().err
    record = json.loads((tmp_path / "fits" / "batch.json").read_text())
    assert record["counts"] == {"done": 2, "failed": 0, "skipped": 0}
    assert record["executor"]["executor"] == "inline"
    for name, throws in LABS.items():
        fit = rows(tmp_path / "fits" / name)
        for i, throw in enumerate(throws):
            for k in range(3):
                row = fit[f"ball.velocity[r{i}][{k}]"]
                truth = TRUTH["throws"][throw]["velocity"][k]
                assert abs(float(row["mean"]) - truth) < 4 * float(row["sd"]) + 1e-3, (name, k)
        drag = fit["quadratic_drag@ball.coefficient"]
        assert float(drag["q5"]) <= TRUTH["coefficient"] <= float(drag["q95"])


@pytest.mark.slow  # 300 s wall at load 15 (2 refines, each round 0 with its refits, 1 worker)
def test_batch_refine_adds_a_drag_to_each_experiments_scene(tmp_path):
    """The labs' scenes without drag, refined in a batch on the local pool: every job's round 0
    adds a drag law (quadratic or linear: two throws of 0.4 s barely tell them apart) and its
    round-1 folder holds the recordings it fitted."""
    for name in LABS:
        lab(tmp_path / "labs", name, drag=False)
    code = main(["batch", "refine", "--scenes", str(tmp_path / "labs" / "*" / "scene.phys"),
                 "-o", str(tmp_path / "refits"), "--workers", "1", "--backend", "map",
                 "--max-rounds", "1", "--quiet"])
    assert code == 0
    for name in LABS:
        rounds = json.loads((tmp_path / "refits" / name / "refine.json").read_text())["rounds"]
        assert rounds[1]["added"]["effect"] in ("quadratic_drag", "linear_drag")
        assert rounds[1]["rms_sigma"] < rounds[0]["rms_sigma"]
        for i in range(2):
            assert (tmp_path / "refits" / name / "round-1" / "throws" / f"r{i}"
                    / "trajectory.csv").is_file()


def test_inline_executor_runs_here_and_keeps_errors_in_the_future():
    pool = InlineExecutor()
    assert pool.submit(np.sqrt, 16.0).result() == 4.0
    failed = pool.submit(shutil.rmtree, "/nonexistent/physdsl-test-folder")
    assert isinstance(failed.exception(), FileNotFoundError)
