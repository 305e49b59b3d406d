"""``physdsl check | diagnose | refine | add-effect`` in-process on a tiny scene: exit 0 and
the documented files; bad inputs exit 2 with a located message and no traceback."""
from __future__ import annotations

import json
import shutil

import pytest

from physdsl.syntax import load

from .conftest import CASES, make_case

FIT = ("--backend", "map", "--chains", "2", "--warmup", "200", "--samples", "200")


@pytest.fixture(scope="module")
def throw(tmp_path_factory):
    """The steep throw with hidden quadratic drag: data, the naive scene and its MAP run."""
    from physdsl.cli import main

    folder = tmp_path_factory.mktemp("cli")
    make_case(folder, CASES["quadratic_drag"])
    scene = folder / "naive.phys"
    assert main(["infer", str(scene), "-o", str(folder / "run"), *FIT]) == 0
    return folder


def _clean_error(code, err, *needles):
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err, err
    for needle in needles:
        assert needle in err, f"{needle!r} not in {err!r}"


def test_check_writes_the_report(throw, cli):
    code, out, err = cli("check", throw / "naive.phys", "--posterior", throw / "run",
                         "-o", throw / "check")
    assert code == 0, err
    for name in ("report.json", "report.md", "index.html"):
        assert (throw / "check" / name).is_file()
    report = json.loads((throw / "check" / "report.json").read_text())
    assert report["consistent"] is False and report["rms_sigma"] > 1.5
    assert "ball.position" in out


def test_diagnose_writes_the_ranking(throw, cli):
    code, out, err = cli("diagnose", throw / "naive.phys", "--posterior", throw / "run",
                         "-o", throw / "diag", "--confirm", "0")
    assert code == 0, err
    d = json.loads((throw / "diag" / "diagnosis.json").read_text())
    physical = [r for r in d["ranking"] if r["kind"] == "effect"]
    assert (physical[0]["effect"], physical[0]["target"]) == ("quadratic_drag", "ball")
    assert [r["rank"] for r in d["ranking"]] == list(range(1, len(d["ranking"]) + 1))
    assert d["winner"] is None and "quadratic_drag on ball" in d["verdict"]
    assert (throw / "diag" / "diagnosis.md").read_text().startswith("# Diagnosis")
    assert not (throw / "diag" / "fix.phys").exists()  # nothing confirmed, nothing to paste
    assert "quadratic_drag on ball" in out
    # a second run into the same folder needs --force
    code, _, err = cli("diagnose", throw / "naive.phys", "--posterior", throw / "run",
                       "-o", throw / "diag", "--confirm", "0")
    _clean_error(code, err, "not empty", "--force")


def test_add_effect_then_refine_one_round(throw, cli):
    new = throw / "with_drag.phys"
    code, out, err = cli("add-effect", throw / "naive.phys", "quadratic_drag", "on", "ball",
                         "-o", new)
    assert code == 0, err
    scene = load(new)
    assert ("quadratic_drag", ("ball",)) in {(e.effect, tuple(e.target)) for e in scene.effects}
    assert "quadratic_drag@ball.coefficient" in {u.name for u in scene.unknowns}
    assert (throw / "naive.phys").read_text() != new.read_text()  # the input is untouched
    # the scene with the effect explains the data: refine stops after round 0
    code, out, err = cli("refine", new, "-o", throw / "refine", "--max-rounds", "1", *FIT)
    assert code == 0, err
    data = json.loads((throw / "refine" / "refine.json").read_text())
    assert set(data) == {"rounds"} and len(data["rounds"]) == 1
    r0 = data["rounds"][0]
    assert {"scene", "rms_sigma", "elpd", "added"} <= set(r0)
    assert r0["added"] is None and r0["rms_sigma"] <= 1.3 and isinstance(r0["elpd"], float)
    copied = load(throw / "refine" / "round-0" / "scene.phys")  # loads: the data came along
    assert [(e.effect, e.target, e.params) for e in copied.effects] == \
        [(e.effect, e.target, e.params) for e in scene.effects]
    for name in ("refine.md", "refine.png"):
        assert (throw / "refine" / name).is_file()


def test_missing_posterior_folder(throw, cli):
    for cmd in ("check", "diagnose"):
        code, _, err = cli(cmd, throw / "naive.phys", "--posterior", throw / "nowhere",
                           "-o", throw / f"bad-{cmd}")
        _clean_error(code, err, "nowhere", "physdsl infer")


def test_posterior_of_another_scene(throw, cli, tmp_path):
    other = tmp_path / "other.phys"
    other.write_text((throw / "naive.phys").read_text().replace(
        "velocity ~ normal((3, 0, 12) m/s, 2 m/s)", "velocity: (3, 0, 12) m/s").replace(
        "position: (0, 0, 1) m", "position ~ normal((0, 0, 1) m, 1 cm)"))
    shutil.copy(throw / "data.csv", tmp_path / "data.csv")
    code, _, err = cli("diagnose", other, "--posterior", throw / "run", "-o", tmp_path / "d")
    _clean_error(code, err, "ball.position")


def test_add_effect_unknown_effect_suggests_a_close_match(throw, cli, tmp_path):
    code, _, err = cli("add-effect", throw / "naive.phys", "quadratic_drug", "on", "ball",
                       "-o", tmp_path / "x.phys")
    _clean_error(code, err, "quadratic_drug", "did you mean", "quadratic_drag")
    assert not (tmp_path / "x.phys").exists()


def test_add_effect_refuses_to_overwrite_its_input(throw, cli):
    before = (throw / "naive.phys").read_text()
    code, _, err = cli("add-effect", throw / "naive.phys", "linear_drag", "on", "ball",
                       "-o", throw / "naive.phys")
    _clean_error(code, err, "new file")
    assert (throw / "naive.phys").read_text() == before


def test_add_effect_bad_target_and_bad_word(throw, cli, tmp_path):
    code, _, err = cli("add-effect", throw / "naive.phys", "linear_drag", "on", "rocket",
                       "-o", tmp_path / "a.phys")
    _clean_error(code, err, "rocket")
    code, _, err = cli("add-effect", throw / "naive.phys", "linear_drag", "to", "ball",
                       "-o", tmp_path / "b.phys")
    _clean_error(code, err, "'on'")


def test_refine_unknown_backend(throw, cli, tmp_path):
    code, _, err = cli("refine", throw / "naive.phys", "-o", tmp_path / "r", "--backend", "nuuts")
    _clean_error(code, err, "nuuts")
