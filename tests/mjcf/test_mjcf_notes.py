"""What physdsl cannot express is listed atop the imported scene and on stderr (golden text),
never dropped silently; without MuJoCo the commands fail with exit 2 and the install hint."""
import builtins
import sys

from physdsl.cli import main
from physdsl.syntax import format_source

from mjcf_helpers import DATA

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


def test_contact_filters(tmp_path):
    """MuJoCo tests floor-ball (friction max(0.8, 0.5)), floor-arm (max(0.8, 1)) and the explicit
    pair floor-hand (0.3); it filters arm-hand (parent), ball-arm (exclude), the ghost (other
    contype group) and hand's other pairs (contype 0). The scene has a contact statement per
    MuJoCo pair, the ghost does not collide, and every pair only physdsl tests is listed."""
    import physdsl

    out = tmp_path / "scene.phys"
    assert main(["import", str(DATA / "contacts.xml"), "-o", str(out)]) == 0
    scene = physdsl.load(out)
    pairs = {frozenset(p) for p in scene.contact_pairs}
    mujoco_pairs = {frozenset(("floor", "ball")): 0.8, frozenset(("floor", "arm")): 1.0,
                    frozenset(("floor", "hand")): 0.3}
    assert set(mujoco_pairs) <= pairs
    friction = {frozenset(u.target): float(u.params["coefficient"].value)
                for u in scene.effects if u.effect == "contact_friction"}
    assert friction == mujoco_pairs
    assert not any("ghost" in p for p in pairs)
    text = out.read_text()
    listed = {frozenset(ln.split("contact ")[1].split(":")[0].split(", "))
              for ln in text.splitlines() if ln.startswith("#   - contact ") and "physdsl tests" in ln}
    assert listed == pairs - set(mujoco_pairs) == {frozenset(("arm", "ball")), frozenset(("ball", "hand"))}


def test_bad_model_and_key(tmp_path, capsys):
    """A model MuJoCo refuses, or an unknown keyframe: exit 2 with MuJoCo's reason or the
    keyframes there are, no traceback, nothing written."""
    bad = tmp_path / "bad.xml"
    bad.write_text('<mujoco><worldbody><geom type="sphere"/><body><joint type="twist"/>'
                   "</body></worldbody></mujoco>")
    assert main(["import", str(bad), "-o", str(tmp_path / "a.phys")]) == 2
    err = capsys.readouterr().err
    assert f"error: {bad}: MuJoCo cannot load this model:" in err and "twist" in err
    assert main(["import", str(DATA / "chain.xml"), "-o", str(tmp_path / "b.phys"), "--key", "up"]) == 2
    err = capsys.readouterr().err
    assert "error: no keyframe 'up' in the model" in err and "hint: keyframes: bent" in err
    assert "Traceback" not in err and not list(tmp_path.glob("*.phys"))
