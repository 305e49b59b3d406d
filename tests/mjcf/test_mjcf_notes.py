"""What physdsl cannot express is listed atop the imported scene and on stderr (golden text),
never dropped silently; without MuJoCo the commands fail with exit 2 and the install hint."""
import builtins
import sys

from physdsl.cli import main
from physdsl.syntax import format_source

from helpers import DATA

GOLDEN = DATA / "unsupported.notes.txt"


def test_unsupported_features_are_listed(tmp_path, capsys):
    out = tmp_path / "scene.phys"
    assert main(["import", str(DATA / "unsupported.xml"), "-o", str(out)]) == 0
    text = out.read_text()
    head = [ln[len("#   - "):] for ln in text.splitlines() if ln.startswith("#   - ")]
    assert head == GOLDEN.read_text().splitlines()
    err = capsys.readouterr().err
    assert [ln[len("  - "):] for ln in err.splitlines() if ln.startswith("  - ")] == head
    assert format_source(text) == text
    assert main(["lint", str(out)]) == 0  # what could be expressed still forms a valid scene
    assert "effect joint_friction on swing { torque: 0.05 N*m }" in text


def test_without_mujoco(tmp_path, monkeypatch, capsys):
    """`import mujoco` failing: exit 2, a message naming MuJoCo and `pip install physdsl[mjcf]`."""
    real_import = builtins.__import__

    def no_mujoco(name, *args, **kwargs):
        if name == "mujoco" or name.startswith("mujoco."):
            raise ImportError("No module named 'mujoco'")
        return real_import(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, "mujoco", raising=False)
    monkeypatch.setattr(builtins, "__import__", no_mujoco)
    assert main(["import", str(DATA / "chain.xml"), "-o", str(tmp_path / "x.phys")]) == 2
    err = capsys.readouterr().err
    assert "MJCF/URDF import and export need MuJoCo, which is not installed" in err
    assert "hint: pip install physdsl[mjcf]" in err
    assert not (tmp_path / "x.phys").exists()
