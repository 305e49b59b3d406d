"""Contact pairs the recording rules out (physics/ruled_out.py) leave the likelihood, exactly.

A ball flying high above the ground: the ground pair is left out of the likelihood's
simulator, and the fit equals the fit with every contact (same modes, same intervals). Where
the recording does not rule a pair out (the ball lands; the data stop early; the noise is an
unknown) it stays. Where a fit without a pair comes
within its reach, the fit runs again with every contact and gives that fit's numbers.
"""
from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl.compile import Model, compile as compile_phys
from physdsl.physics.ruled_out import ruled_out_pairs

from .conftest import simulated_scene

GROUND = """\
  ground floor {
    normal: (0, 0, 1)
    point: (0, 0, 0) m
  }
"""

TOSS = """\
scene toss {
  world {
    timestep: 10 ms
    duration: 0.5 s
  }
GROUND  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, HEIGHT) m
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  effect linear_drag on ball { coefficient ~ half_normal(0.5 kg/s) }
  observe ball.position from "data.csv" where body == "ball" { noise: NOISE }
}
"""
TRUTH = {"ball.velocity": np.array([3.2, 0.4, 4.3]), "linear_drag@ball.coefficient": np.array(0.3)}
TIMES = np.linspace(0.0, 0.5, 11)


def toss_text(height="1", noise="10 mm") -> str:
    return TOSS.replace("GROUND", GROUND).replace("HEIGHT", height).replace("NOISE", noise)


@pytest.fixture(scope="module")
def high_toss(tmp_path_factory):
    return simulated_scene(tmp_path_factory.mktemp("high"), toss_text(), TRUTH, TIMES, 0.01, 5)


def _summary(idata) -> dict:
    post = idata.posterior
    return {k: (np.asarray(post[k].mean(("chain", "draw"))), np.asarray(post[k].std(("chain", "draw"))))
            for k in TRUTH}


@pytest.mark.slow  # two full fits (~40 s); ruling pairs out and back in: the tests below
def test_a_ground_the_ball_never_nears_leaves_the_fit_unchanged(high_toss):
    model = compile_phys(high_toss)
    assert model.ruled_out == (0,)
    assert model.likelihood_simulator.model.ncon == 0 and model.simulator.model.ncon == 1
    full = model.with_every_contact()
    assert full.ruled_out == () and full.likelihood_simulator is full.simulator
    fits = [_summary(physdsl.infer(m, backend="map", progress=False)) for m in (model, full)]
    for k in TRUTH:
        np.testing.assert_allclose(fits[0][k][0], fits[1][k][0], rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(fits[0][k][1], fits[1][k][1], rtol=1e-5)
    assert not model.contact_reached({k: v[None] for k, v in TRUTH.items()}).any()
    # the ball dropped onto the ground: reached
    low = {"ball.velocity": np.array([[0.0, 0.0, -5.0]]), "linear_drag@ball.coefficient": np.array([0.3])}
    assert model.contact_reached(low).all()


def test_a_pair_stays_where_the_recording_does_not_rule_it_out(tmp_path):
    scene_path = simulated_scene(tmp_path / "high", toss_text(), TRUTH, TIMES, 0.01, 5)
    scene = physdsl.load(scene_path)
    pm = compile_phys(scene).simulator.model
    assert ruled_out_pairs(scene, pm) == (0,)
    # a fit up to a cut-off (leave-future-out) is forecast from the whole recording: its
    # draws are checked over the whole horizon all the same
    assert Model(scene, until=0.3).ruled_out == (0,)
    obs = scene.observations[0]
    late = dataclasses.replace(obs, times=obs.times[2:], values=obs.values[2:], mask=obs.mask[2:])
    assert ruled_out_pairs(dataclasses.replace(scene, observations=(late,)), pm) == ()
    short = dataclasses.replace(obs, times=obs.times[:-2], values=obs.values[:-2], mask=obs.mask[:-2])
    assert ruled_out_pairs(dataclasses.replace(scene, observations=(short,)), pm) == ()
    # 4 noise scales above the ground is not enough clearance with a noise of 30 cm
    noisy = physdsl.load(simulated_scene(tmp_path / "noisy", toss_text(noise="30 cm"), TRUTH,
                                         TIMES, 0.01, 5))
    assert ruled_out_pairs(noisy, pm) == ()
    # a ball that lands
    landing = simulated_scene(tmp_path / "landing", toss_text(), {
        **TRUTH, "ball.velocity": np.array([3.2, 0.4, -1.0])}, TIMES, 0.01, 5)
    assert compile_phys(landing).ruled_out == ()
    # an unknown noise scale cannot vouch for a clearance
    text = toss_text(noise="sigma").replace("  body ball", "  param sigma ~ half_normal(1 cm)\n  body ball")
    (tmp_path / "high" / "unknown_noise.phys").write_text(text)
    assert compile_phys(tmp_path / "high" / "unknown_noise.phys").ruled_out == ()


def test_a_fit_that_reaches_a_pair_left_out_runs_again_with_every_contact(tmp_path, monkeypatch,
                                                                          capsys):
    """The ball lands at about 0.33 s; a (wrong) forecast leaves the ground out; the fit's draws
    reach it, so the fit runs again with the ground and gives exactly that fit's numbers."""
    scene = simulated_scene(tmp_path, toss_text(height="0.3").replace("(3, 0, 4) m/s", "(3, 0, 0) m/s"),
                            {**TRUTH, "ball.velocity": np.array([3.2, 0.4, 0.3])}, TIMES, 0.01, 5)
    compile_module = importlib.import_module("physdsl.compile")  # (physdsl.compile: the function)
    monkeypatch.setattr(compile_module, "ruled_out_pairs", lambda scene, model: (0,))
    model = compile_phys(scene)
    assert model.ruled_out == (0,)
    again = physdsl.infer(model, backend="map", progress=True)
    assert "fitting again with every contact" in capsys.readouterr().err
    direct = physdsl.infer(model.with_every_contact(), backend="map", progress=False)
    for k in TRUTH:
        np.testing.assert_array_equal(again.posterior[k].values, direct.posterior[k].values)


CHAIN = Path(__file__).resolve().parents[2] / "examples" / "hidden-effect" / "damped_chain"


def _with_angles(scene, angles: dict):
    """``scene`` with each joint observation's values replaced by ``angles[joint]`` (N,)."""
    return dataclasses.replace(scene, observations=tuple(
        dataclasses.replace(o, values=np.asarray(angles[o.target], float)[:, None])
        if o.target in angles else o for o in scene.observations))


def test_a_chain_whose_measured_angles_keep_its_links_apart_leaves_their_pairs_out():
    """MuJoCo's 4-link chain: its links never come near the links they are not jointed to, so
    the three pairs leave the likelihood; with the data of a chain folded back on itself
    (hinge2 at 170 degrees) link1 and link3 stay paired."""
    model = compile_phys(CHAIN / "naive.phys")
    pm = model.simulator.model
    assert [(p.a, p.b) for p in pm.pairs] == [(0, 2), (0, 3), (1, 3)]
    assert model.ruled_out == (0, 1, 2) and model.likelihood_simulator.model.ncon == 0
    scene = model.scene
    angles = {o.target: o.values[:, 0] for o in scene.observations}
    folded = dict(angles, hinge2=np.full_like(angles["hinge2"], np.deg2rad(170.0)))
    left = ruled_out_pairs(_with_angles(scene, folded), pm)
    assert 0 not in left and 2 in left
    # one joint unmeasured: the links below it cannot be placed
    scene3 = dataclasses.replace(scene, observations=tuple(
        o for o in scene.observations if o.target != "hinge3"))
    assert ruled_out_pairs(scene3, pm) == ()


def test_the_links_placed_from_measured_angles_are_where_the_rollout_puts_them():
    """The positions the forecast reads off the angles (the model's kinematics) equal the
    rollout's own body positions at those angles: physdsl's noise-free rollout as the data."""
    from physdsl.physics.ruled_out import _jointed_sides

    model = compile_phys(CHAIN / "naive.phys")
    pm = model.simulator.model
    roll = model.simulate({"a": np.asarray(np.deg2rad(20.0))})
    times = model.scene.observations[0].times
    rows = np.rint(times / pm.dt).astype(int)
    angles = {name: np.asarray(roll.joint_pos)[rows, j] for j, name in enumerate(pm.joint_names)}
    sides = _jointed_sides(_with_angles(model.scene, angles), pm, pm.nsteps * pm.dt)
    assert sorted(sides) == [0, 1, 2, 3]
    for i, side in sides.items():
        np.testing.assert_allclose(side.track, np.asarray(roll.body_pos)[rows, i], atol=1e-12)
        assert side.radius == pytest.approx(0.1)
    # slack grows down the chain (each joint's 3 mrad noise on a longer lever)
    slack = [sides[i].slack for i in range(4)]
    assert all(a < b for a, b in zip(slack, slack[1:]))


@pytest.mark.slow  # two MAP fits of the chain (~3 min): with and without the pairs
def test_the_chains_fit_without_its_pairs_is_the_fit_with_them(monkeypatch):
    """The chain's fit without the pairs the recording rules out: its draws' predictions come
    from the expansion (the links' clearance, 17.7 cm at the mode, moves 26 um for 2e-4 rad
    of starting angle), no draw comes within reach (the exact rule), and its mode and sd are those of
    the fit with every pair."""
    from physdsl.infer import output

    calls: list = []
    every_draw = output.posterior_pass
    monkeypatch.setattr(output, "posterior_pass",
                        lambda m, p, flat, *a, **k: calls.append(len(flat)) or every_draw(m, p, flat, *a, **k))
    model = compile_phys(CHAIN / "naive.phys")
    fit = physdsl.infer(model, backend="map", progress=False)
    draws = fit.posterior["a"].values.ravel()
    assert draws.size not in calls  # (the starts' screening rolls out 64 prior draws)
    assert not model.contact_reached({"a": draws[[0, draws.argmin(), draws.argmax()]]}).any()
    full = physdsl.infer(model.with_every_contact(), backend="map", progress=False)
    np.testing.assert_allclose(float(fit.posterior["a"].mean()), float(full.posterior["a"].mean()),
                               rtol=1e-7)
    np.testing.assert_allclose(float(fit.posterior["a"].std()), float(full.posterior["a"].std()),
                               rtol=1e-3)
