"""Contact against MuJoCo (slow): the dev-corpus MJCF of each case, re-run noise-free, against
physdsl's example scene at the case's true unknowns.

MuJoCo's contact is soft (a stiff spring-damper reached through its solver, restitution
emerging from solref); ours is a hard LCP with Newton restitution at the time of impact within
a 1 ms step, and flight between bounces advanced exactly under gravity. Stated tolerances
(measured: impacts 0, 1, 1 ms apart; apexes 0.5 and 0.03 mm; height RMS 1.7 mm over 2.5 s;
block 1.8 mm; before the time-of-impact split: 1, 3, 4 ms and 7 ms with the split alone): the
first three bounce times within 2 ms, apex heights within 2 mm, the height within 3 mm RMS
(the data's noise is 5 mm); the sliding block (4-edge friction
pyramid, which is exact for sliding along a tangent as here, against MuJoCo's elliptic cone)
within 3 mm (the data's noise) along its whole path.
"""
import dataclasses
import json
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

import physdsl
from physdsl.physics import build_simulator

HERE = Path(__file__).resolve().parent
CORPUS = HERE.parent / "data" / "corpus"
EXAMPLES = HERE.parents[1] / "examples"


def mujoco_positions(case: str, times, velocity=(0.0, 0.0, 0.0)):
    """Noise-free body-centre positions (len(times), 3) of the case's only free body, launched
    with world ``velocity`` (the corpus sets it on qvel; the MJCF starts at rest)."""
    truth = json.loads((CORPUS / case / "truth.json").read_text())
    m = mujoco.MjModel.from_xml_string(truth["simulator"]["mjcf_with_hidden_effect"])
    d = mujoco.MjData(m)
    d.qvel[:3] = velocity
    mujoco.mj_forward(m, d)
    out = []
    for t in times:
        while d.time < t - 0.5 * m.opt.timestep:
            mujoco.mj_step(m, d)
        out.append(d.qpos[:3].copy())
    return np.array(out)


def physdsl_rollout(example: str, integrator: str | None = None):
    """The example's rollout at its true unknowns; ``integrator`` replaces the scene's."""
    path = EXAMPLES / example / f"{example}.phys"
    truth = json.loads((path.parent / "truth.json").read_text())
    scene = physdsl.load(path)
    if integrator is not None:
        scene = dataclasses.replace(scene, world=dataclasses.replace(scene.world,
                                                                     integrator=integrator))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = build_simulator(scene)
    return sim, sim.simulate(truth["unknowns"]), truth


def impacts_and_apexes(t, z):
    """Times of the local minima (impacts) and heights of the local maxima of z(t)."""
    lo = np.nonzero((z[1:-1] < z[:-2]) & (z[1:-1] <= z[2:]))[0] + 1
    hi = np.nonzero((z[1:-1] > z[:-2]) & (z[1:-1] >= z[2:]))[0] + 1
    return t[lo], z[hi]


@pytest.mark.slow
@pytest.mark.parametrize("integrator", [None, "rk4"])
def test_bouncing_ball_matches_mujoco(integrator):
    """As written (semi-implicit Euler) and with RK4 between the bounces."""
    sim, out, truth = physdsl_rollout("bouncing_ball", integrator)
    t = np.asarray(out.t)
    z = np.asarray(out.body_pos[:, sim.body_names.index("ball"), 2])
    zm = mujoco_positions("bouncing_ball_01", t)[:, 2]
    ti, ha = impacts_and_apexes(t, z)
    tim, ham = impacts_and_apexes(t, zm)
    assert len(ti) >= 3 and len(tim) >= 3, (ti, tim)
    np.testing.assert_allclose(ti[:3], tim[:3], atol=2e-3)
    assert np.sqrt(np.mean((z - zm) ** 2)) < 3e-3
    assert len(ha) >= 2 and len(ham) >= 2
    np.testing.assert_allclose(ha[:2], ham[:2], atol=2e-3)
    assert ha[0] < truth["unknowns"]["h0"] - 0.1  # restitution < 1: it loses height


@pytest.mark.slow
def test_sliding_block_matches_mujoco():
    sim, out, _ = physdsl_rollout("sliding_block")
    t = np.asarray(out.t)
    x = np.asarray(out.body_pos[:, sim.body_names.index("block")])
    case = json.loads((CORPUS / "sliding_block_01" / "truth.json").read_text())
    xm = mujoco_positions("sliding_block_01", t, case["parameters"]["initial_velocity_m_s"])
    up = np.array([0.96593, 0.0, 0.25882])
    s = (x - x[0]) @ up
    assert s.max() > 0.3 and s[-1] < s.max() - 0.1  # it slides up, stops and slides back
    np.testing.assert_allclose(x, xm, atol=3e-3)
