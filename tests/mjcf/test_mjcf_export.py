"""MJCF out: an imported scene written back with `--format mjcf` loads in MuJoCo and rolls out
as physdsl does (RK4 on both sides, float64)."""
import numpy as np
import pytest

import physdsl
from physdsl.cli import main
from physdsl.mjcf import scene_to_mjcf
from physdsl.physics import build_simulator

from mjcf_helpers import DATA, import_scene, joints, mujoco_rollout


def test_chain_round_trip(tmp_path):
    """MJCF chain -> .phys -> MJCF: over 1 s (500 RK4 steps of 2 ms) physdsl's rollout of the
    imported scene and MuJoCo's rollout of the exported file both stay within 1e-6 rad (in
    fact ~1e-13) of MuJoCo's rollout of the original file."""
    scene_path = import_scene(tmp_path, "chain.xml", "--key", "bent")
    text = scene_path.read_text()
    assert "# Everything in the model is expressed in this scene." in text
    assert main(["lint", str(scene_path)]) == 0
    names = [f"hinge{i}" for i in range(1, 7)]
    original = mujoco_rollout((DATA / "chain.xml").read_text(), 500)
    scene = physdsl.load(scene_path)
    sim = build_simulator(scene)
    ours = joints(sim, sim.simulate({}), names)
    xml, notes = scene_to_mjcf(scene, {})
    assert notes == []
    back = mujoco_rollout(xml, 500)
    np.testing.assert_allclose(ours, original, atol=1e-9)
    np.testing.assert_allclose(back, original, atol=1e-6)
    np.testing.assert_allclose(back, ours, atol=1e-9)
    assert np.ptp(original, axis=0).min() > 0.3  # every link really swings


def _controls(tmp_path, dt=0.02, n=50, seed=1):
    rng = np.random.default_rng(seed)
    times = np.arange(n) * dt
    force = rng.normal(0, 1.5, size=n)
    rows = "\n".join(f"{t:.3f},{float(f)!r}" for t, f in zip(times, force))
    (tmp_path / "controls.csv").write_text("t,push\n" + rows + "\n")
    return times, force


@pytest.mark.slow
def test_cart_pole_fit_and_export(tmp_path):
    """Imported cart-pole, pole mass unknown (uniform 0.05..1 kg): a MAP fit to 1 s of MuJoCo's
    encoder readings (2 mm, 3 mrad noise) recovers 0.2 kg within 3 sd (and 5%); the fitted scene
    exported as MJCF rolls out in MuJoCo as physdsl's rollout at the posterior medians (1e-9).
    Slow: 41 CPU s (two compilations of the physics and the fit's)."""
    times, force = _controls(tmp_path)
    scene_path = import_scene(tmp_path, "cart_pole.xml", "--key", "start", "--controls", "controls.csv")
    dt, T = 0.002, 500
    ctrl = lambda k: [force[min(int(k * dt / 0.02 + 1e-9), len(times) - 1)]]  # noqa: E731
    Q = mujoco_rollout((DATA / "cart_pole.xml").read_text(), T, ctrl=ctrl)
    rng = np.random.default_rng(7)
    rows = ["t,joint,angle"]
    for k in range(0, T + 1, 5):  # 100 Hz
        rows.append(f"{k * dt:.3f},rail,{float(Q[k, 0] + rng.normal(0, 0.002))!r}")
        rows.append(f"{k * dt:.3f},hinge,{float(Q[k, 1] + rng.normal(0, 0.003))!r}")
    (tmp_path / "joints.csv").write_text("\n".join(rows) + "\n")
    text = scene_path.read_text()
    assert text.count("mass: 0.2 kg") == 1
    text = text.replace("mass: 0.2 kg", "mass ~ uniform(0.05 kg, 1 kg)").rstrip()[:-1] + (
        '  observe rail.angle from "joints.csv" where joint == "rail" { noise: 2 mm }\n'
        '  observe hinge.angle from "joints.csv" where joint == "hinge" { noise: 3 mrad }\n}\n')
    scene_path.write_text(text)
    run = tmp_path / "run"
    assert main(["infer", str(scene_path), "-o", str(run), "--backend", "map", "--chains", "1",
                 "--samples", "200", "--seed", "0"]) == 0
    from physdsl.infer.output import load_run
    idata, _ = load_run(run)
    draws = np.asarray(idata.posterior["pole.mass"].values).ravel()
    med, sd = float(np.median(draws)), float(draws.std())
    assert abs(med - 0.2) < max(3 * sd, 1e-4) and abs(med - 0.2) < 0.01, (med, sd)

    fitted = tmp_path / "fitted.xml"
    assert main(["export", str(scene_path), "--posterior", str(run), "--format", "mjcf",
                 "-o", str(fitted)]) == 0
    xml = fitted.read_text()
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(fitted))
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pole")
    assert m.body_mass[pole] == pytest.approx(med, rel=1e-12)
    back = mujoco_rollout(xml, T, ctrl=ctrl)
    scene = physdsl.load(scene_path)
    sim = build_simulator(scene)
    ours = joints(sim, sim.simulate({"pole.mass": np.asarray(med)}), ["rail", "hinge"])
    np.testing.assert_allclose(back, ours, atol=1e-9)


def test_export_format_usage(tmp_path, capsys):
    """--format mjcf refuses proto-program options, an unknown format is named; exit 2, no file."""
    scene, run = str(DATA / "chain.xml"), str(tmp_path / "run")
    assert main(["export", scene, "--posterior", run, "--format", "mjcf", "--widen", "2",
                 "-o", str(tmp_path / "x.xml")]) == 2
    assert "--format mjcf writes the posterior medians" in capsys.readouterr().err
    assert main(["export", scene, "--posterior", run, "--format", "urdf",
                 "-o", str(tmp_path / "x.xml")]) == 2
    err = capsys.readouterr().err
    assert "error: unknown --format 'urdf'" in err and "hint: use phys or mjcf" in err
    assert not (tmp_path / "x.xml").exists()


@pytest.mark.slow
def test_chain_fit_and_export(tmp_path):
    """Imported 6-link chain, the last link's mass unknown (uniform 0.05..1 kg): a MAP fit to 1 s
    of MuJoCo's hinge angles (3 mrad noise, 100 Hz) recovers 0.3 kg within 3 sd; the exported
    MJCF rolls out in MuJoCo as physdsl does at the posterior median (1e-9 rad) and within
    1e-2 rad of the original file's rollout."""
    scene_path = import_scene(tmp_path, "chain.xml", "--key", "bent")
    dt, T = 0.002, 500
    Q = mujoco_rollout((DATA / "chain.xml").read_text(), T)
    rng = np.random.default_rng(11)
    rows = ["t,joint,angle"]
    for k in range(0, T + 1, 5):
        for i in range(6):
            rows.append(f"{k * dt:.3f},hinge{i + 1},{float(Q[k, i] + rng.normal(0, 0.003))!r}")
    (tmp_path / "joints.csv").write_text("\n".join(rows) + "\n")
    text = scene_path.read_text()
    assert text.count("mass: 0.3 kg") == 1
    text = text.replace("mass: 0.3 kg", "mass ~ uniform(0.05 kg, 1 kg)").rstrip()[:-1] + "".join(
        f'  observe hinge{i}.angle from "joints.csv" where joint == "hinge{i}" {{ noise: 3 mrad }}\n'
        for i in range(1, 7)) + "}\n"
    scene_path.write_text(text)
    run = tmp_path / "run"
    assert main(["infer", str(scene_path), "-o", str(run), "--backend", "map", "--chains", "1",
                 "--samples", "200", "--seed", "0"]) == 0
    from physdsl.infer.output import load_run
    idata, _ = load_run(run)
    draws = np.asarray(idata.posterior["link6.mass"].values).ravel()
    med, sd = float(np.median(draws)), float(draws.std())
    assert abs(med - 0.3) < max(3 * sd, 1e-4), (med, sd)
    fitted = tmp_path / "fitted.xml"
    assert main(["export", str(scene_path), "--posterior", str(run), "--format", "mjcf",
                 "-o", str(fitted)]) == 0
    back = mujoco_rollout(fitted.read_text(), T)
    sim = build_simulator(physdsl.load(scene_path))
    ours = joints(sim, sim.simulate({"link6.mass": np.asarray(med)}), [f"hinge{i}" for i in range(1, 7)])
    np.testing.assert_allclose(back, ours, atol=1e-9)
    np.testing.assert_allclose(back, Q, atol=1e-2)
