"""The bundled data agree with their truth.json: MuJoCo re-simulation from the stated truth
reproduces each CSV to within its stated noise, the noise level is the stated one, the data
pin down the unknowns, and each hidden effect is visible above the noise."""
from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, HIDDEN

import ball_chain
import cart_pole
import chain_hit
import dh_arm
import double_pendulum
from mjgen import read_long, rollout

G = 9.81


def _load(folder):
    return json.loads((folder / "truth.json").read_text())


def _rms_over_sigma(data: np.ndarray, model: np.ndarray, sigma: float) -> float:
    return float(np.sqrt(np.mean((data - model) ** 2)) / sigma)


# --- MuJoCo-made examples: re-simulate from truth.json ---------------------------------------

def _double_pendulum(truth):
    t, ang, pos = double_pendulum.simulate(truth)
    return t, ang, pos


def _cart_pole(truth):
    t, q = cart_pole.simulate(truth)
    return t, q, {}


def _ball_chain(truth):
    t, pos = ball_chain.simulate(truth)
    return t, {}, pos


def _dh_arm(truth):
    return dh_arm.simulate(truth)


# folder, simulate, joint sigma key(s) {joint: key}, position sigma key, a perturbation of the
# physical parameters (key, new value) that the data must reject
GENERATED = {
    "double_pendulum": (EXAMPLES / "double_pendulum", _double_pendulum,
                        {"shoulder": "sigma_angle_rad", "elbow": "sigma_angle_rad"}, "sigma_position_m",
                        ("link2_mass_kg", 0.27)),
    "cart_pole": (EXAMPLES / "cart_pole", _cart_pole,
                  {"cart_slider": "sigma_slider_m", "pole_hinge": "sigma_angle_rad"}, None,
                  ("cart_mass_kg", 1.05)),
    "cart_pole_friction": (HIDDEN / "cart_pole_friction", _cart_pole,
                           {"cart_slider": "sigma_slider_m", "pole_hinge": "sigma_angle_rad"}, None,
                           ("rail_friction_N", 0.0)),
    "ball_chain": (EXAMPLES / "ball_chain", _ball_chain, {}, "sigma_position_m", ("link_mass_kg", 0.11)),
    "chain_hit": (EXAMPLES / "chain_hit", chain_hit.simulate,
                  {h: "sigma_angle_rad" for h in chain_hit.HINGES}, "sigma_position_m",
                  ("link_mass_kg", 0.07)),
    "chain_hit_damped": (EXAMPLES / "chain_hit" / "damped", chain_hit.simulate,
                         {h: "sigma_angle_rad" for h in chain_hit.HINGES}, "sigma_position_m",
                         ("hinge_damping_N_m_s_per_rad", 0.0)),
    "chain_hit_damped_light": (EXAMPLES / "chain_hit" / "damped_light", chain_hit.simulate,
                               {h: "sigma_angle_rad" for h in chain_hit.HINGES}, "sigma_position_m",
                               ("hinge_damping_N_m_s_per_rad", 0.0)),
    "dh_arm": (EXAMPLES / "dh_arm", _dh_arm, {j: "sigma_angle_rad" for j in dh_arm.JOINTS}, "sigma_position_m",
               ("payload_mass_kg", 0.33)),
}


def _params(truth):
    return truth.get("physical_parameters", truth.get("parameters"))


def _fit_ratios(folder, truth, simulate, joint_sigma, pos_sigma):
    """RMS(data - simulation) / sigma for every observed series."""
    t, ang, pos = simulate(truth)
    ratios = {}
    if joint_sigma:
        tj, data = read_long(folder / "joints.csv", "joint", ("angle",))
        np.testing.assert_allclose(tj, t, atol=1e-6)
        for j, key in joint_sigma.items():
            ratios[j] = _rms_over_sigma(data[j][:, 0], ang[j], truth["noise"][key])
    if pos_sigma:
        tp, data = read_long(folder / "trajectory.csv", "body", ("x", "y", "z"))
        np.testing.assert_allclose(tp, t, atol=1e-6)
        for b, xyz in pos.items():
            ratios[b] = _rms_over_sigma(data[b], xyz, truth["noise"][pos_sigma])
    return ratios


@pytest.mark.parametrize("name", sorted(GENERATED))
def test_generated_data_match_truth_at_stated_noise(name):
    folder, simulate, joint_sigma, pos_sigma, _ = GENERATED[name]
    truth = _load(folder)
    ratios = _fit_ratios(folder, truth, simulate, joint_sigma, pos_sigma)
    assert ratios
    for series, r in ratios.items():  # ~1 for the stated sigma; N >= 100 samples per series
        assert 0.8 < r < 1.2, f"{name}/{series}: RMS/sigma = {r:.3f}"


@pytest.mark.parametrize("name", sorted(GENERATED))
def test_generated_data_reject_a_perturbed_truth(name):
    folder, simulate, joint_sigma, pos_sigma, (key, value) = GENERATED[name]
    truth = _load(folder)
    _params(truth)[key] = value
    ratios = _fit_ratios(folder, truth, simulate, joint_sigma, pos_sigma)
    assert max(ratios.values()) > 1.5, f"{name}: data do not distinguish {key} = {value}: {ratios}"


def test_cart_pole_controls_are_the_stated_sequence():
    for folder in (EXAMPLES / "cart_pole", HIDDEN / "cart_pole_friction"):
        rows = np.loadtxt(folder / "controls.csv", delimiter=",", skiprows=1)
        t, f = rows[:, 0], rows[:, 1]
        np.testing.assert_allclose(np.diff(t), 1 / cart_pole.CONTROL_RATE_HZ, atol=1e-6)
        expected = 3.0 * np.sin(2 * np.pi * 0.7 * t) + 1.5 * np.sin(2 * np.pi * 1.9 * t + 0.5)
        np.testing.assert_allclose(f, expected, atol=6e-5)


def test_dh_table_places_the_end_effector():
    """Forward kinematics of the DH table at q = 0 and at another pose agrees with MuJoCo."""
    truth = _load(EXAMPLES / "dh_arm")
    p = truth["parameters"]
    model, data = dh_arm.build(truth)
    for q in ([0.0, 0.0, 0.0, 0.0], [0.4, -0.7, 1.1, 0.2]):
        F = dh_arm.dh_frames(p["dh_a_m"], np.radians(p["dh_alpha_deg"]), p["dh_d_m"],
                             np.radians(p["dh_theta_offset_deg"]) + np.array(q))
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(data.site("payload").xpos, F[4][:3, 3], atol=1e-12)
    np.testing.assert_allclose(dh_arm.dh_frames([0, .3, .25, .1], np.radians([90, 0, 0, 0]), [.3, 0, 0, 0],
                                                [0, 0, 0, 0])[4][:3, 3], [0.65, 0, 0.3], atol=1e-12)


# --- corpus-made examples: re-simulate the stored MJCF ----------------------------------------

def _corpus_init(name, p):
    """Initial state of the corpus MJCF (not in the XML): {qpos index: value}, {qvel index: value}."""
    if name == "thrown_ball":
        return {}, dict(enumerate(p["initial_velocity_m_s"]))
    if name == "sliding_block":
        return {}, dict(enumerate(p["initial_velocity_m_s"]))
    if name == "pendulum":
        return {0: math.radians(p["initial_angle_deg"])}, {}
    if name == "spring_mass":
        return {0: p["initial_height_of_centre_m"]}, {}
    if name == "bouncing_ball":
        return {}, {}
    raise KeyError(name)


def _resim_corpus(name, before_step_factory=None, init=None):
    """Re-simulate a corpus example's stored MJCF; RMS/sigma per tracked body."""
    folder = EXAMPLES / name
    truth = _load(folder)
    model = mujoco.MjModel.from_xml_string(truth["simulator"]["mjcf_with_hidden_effect"])
    data = mujoco.MjData(model)
    if init is not None:
        init(data, truth["physical_parameters"])
    before = before_step_factory(model, truth) if before_step_factory else None
    tdata, pos = read_long(folder / "trajectory.csv", "body", ("x", "y", "z"))
    sites = list(pos)
    t, sim = rollout(model, data, float(tdata[-1]), lambda d: {s: d.site(s).xpos.copy() for s in sites},
                     before_step=before, rate_hz=truth["noise"]["rate_hz"])
    return truth, {s: _rms_over_sigma(pos[s], sim[s], truth["noise"]["sigma_position_m"]) for s in sites}


CORPUS_MADE = ("pendulum", "sliding_block", "spring_mass", "thrown_ball")


@pytest.mark.parametrize("name", CORPUS_MADE)
def test_corpus_examples_match_their_mujoco_model(name):
    def init(d, p):
        qpos, qvel = _corpus_init(name, p)
        for i, v in qpos.items():
            d.qpos[i] = v
        for i, v in qvel.items():
            d.qvel[i] = v

    _, ratios = _resim_corpus(name, init=init)
    assert all(0.85 < r < 1.15 for r in ratios.values()), ratios


# --- hidden effects are visible: the best naive model misses the data --------------------------

def _lstsq_rms(A, y):
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(np.sqrt(np.mean((A @ coef - y) ** 2))), coef


def test_thrown_ball_best_parabola_misses_by_many_sigma():
    folder = HIDDEN / "thrown_ball"
    sigma = _load(folder)["noise"]["sigma_position_m"]
    t, pos = read_long(folder / "trajectory.csv", "body", ("x", "y", "z"))
    xyz = pos["ball"] + np.outer(0.5 * G * t**2, [0, 0, 1])  # remove gravity: straight line is left
    A = np.stack([np.ones_like(t), t], axis=1)
    rms = math.sqrt(np.mean([_lstsq_rms(A, xyz[:, k])[0] ** 2 for k in range(3)]))
    assert rms / sigma > 2  # 87 samples: chi^2 ~ 640 against ~ 87 expected
    # with drag the horizontal speed falls: a quadratic term in x is clearly negative
    _, c = _lstsq_rms(np.stack([np.ones_like(t), t, t**2], axis=1), pos["ball"][:, 0])
    assert c[2] < -0.2


def test_sliding_block_frictionless_incline_cannot_fit():
    folder = HIDDEN / "sliding_block"
    truth = _load(folder)
    sigma = truth["noise"]["sigma_position_m"]
    t, pos = read_long(folder / "trajectory.csv", "body", ("x", "y", "z", "qw", "qx", "qy", "qz"))
    up = np.array([0.96593, 0.0, 0.25882])
    s = pos["block"][:, :3] @ up
    a_free = -G * math.sin(math.radians(15.0))
    rms, _ = _lstsq_rms(np.stack([np.ones_like(t), t], axis=1), s - 0.5 * a_free * t**2)
    assert rms / sigma > 5
    # with friction mu: a_up = -g (sin + mu cos), a_down = -g (sin - mu cos); recover mu
    turn = int(np.argmax(s))
    up_fit = np.polyfit(t[:turn - 5], s[:turn - 5], 2)
    down_fit = np.polyfit(t[turn + 5:], s[turn + 5:], 2)
    mu = (down_fit[0] - up_fit[0]) * 2 / (2 * G * math.cos(math.radians(15.0)))
    assert mu == pytest.approx(truth["parameters"]["contact_friction@ramp,block.coefficient"], abs=0.01)
    # the orientation stays flat on the ramp (qy = -sin 7.5 deg) within the rotation noise
    assert np.mean(pos["block"][:, 5]) == pytest.approx(-math.sin(math.radians(7.5)), abs=2e-3)


def test_spring_mass_best_undamped_oscillator_misses():
    folder = HIDDEN / "spring_mass"
    truth = _load(folder)
    sigma = truth["noise"]["sigma_position_m"]
    t, pos = read_long(folder / "trajectory.csv", "body", ("x", "y", "z"))
    z = pos["block"][:, 2]
    k, m = truth["parameters"]["spring@block.stiffness"], 0.5
    best = min(
        _lstsq_rms(np.stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)], axis=1), z)[0]
        for w in np.linspace(0.95, 1.05, 401) * math.sqrt(k / m))
    assert best / sigma > 5
    # a decaying envelope e^{-c t / 2m} recovers the damper coefficient
    seg = [(t >= a) & (t < a + 1.0) for a in (0.0, 5.0)]
    amp = [np.sqrt(2 * np.mean((z[s] - np.mean(z[s])) ** 2)) for s in seg]
    c = 2 * m * math.log(amp[0] / amp[1]) / 5.0
    assert c == pytest.approx(truth["parameters"]["damper@block.coefficient"], rel=0.15)


def test_pendulum_amplitude_decays_at_the_stated_rate():
    folder = HIDDEN / "pendulum"
    truth = _load(folder)
    t, ang = read_long(folder / "joints.csv", "joint", ("angle",))
    a = ang["hinge"][:, 0]
    first, last = np.abs(a[t < 2.0]).max(), np.abs(a[t > 8.0]).max()
    b = truth["parameters"]["joint_damping@hinge.coefficient"]
    L, r, m_bob, m_rod, rod = 0.6, 0.04, 0.3, 0.01, 0.56  # rod: thin, axis to top of the bob
    inertia = m_bob * (L**2 + 0.4 * r**2) + m_rod * rod**2 / 3  # about the hinge axis
    tau = 2 * inertia / b  # amplitude e-folding time of a lightly damped pendulum
    assert last / first == pytest.approx(math.exp(-8.0 / tau), abs=0.02)
    assert last / first < 0.9  # an undamped pendulum keeps its amplitude


def test_bouncing_ball_restitution_from_apex_heights():
    folder = HIDDEN / "bouncing_ball"
    truth = _load(folder)
    r = 0.05
    t, pos = read_long(folder / "trajectory.csv", "body", ("x", "y", "z"))
    z = pos["ball"][:, 2]
    flight = z > r + 0.03  # away from the floor: free-fall parabolas with known g
    edges = np.flatnonzero(np.diff(flight.astype(int)))
    bounds = [0, *edges + 1, len(t)]
    apex = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if flight[a] and b - a > 20:
            tt, zz = t[a:b], z[a:b] + 0.5 * G * t[a:b] ** 2
            _, (c0, c1) = _lstsq_rms(np.stack([np.ones_like(tt), tt], axis=1), zz)
            apex.append(c0 + c1**2 / (2 * G))  # z = c0 + c1 t - g t^2 / 2 peaks at c0 + c1^2 / 2g
    assert len(apex) >= 3
    e = [math.sqrt((h1 - r) / (h0 - r)) for h0, h1 in zip(apex[1:-1], apex[2:])]
    expected = truth["parameters"]["restitution@floor,ball.coefficient"]
    assert np.mean(e) == pytest.approx(expected, abs=0.01)
    assert max(e) < 0.97  # an elastic bounce would return to the same height


@pytest.mark.slow
def test_bouncing_ball_matches_its_mujoco_model():
    _, ratios = _resim_corpus("bouncing_ball")
    assert 0.85 < ratios["ball"] < 1.15


@pytest.mark.slow
def test_billiards_matches_its_mujoco_model():
    def factory(model, truth):
        p = truth["physical_parameters"]
        mu_r, g = p["table_rolling_resistance_m"], 9.81
        masses = {"cue": p["cue_mass_kg"], "object": p["object_mass_kg"]}
        ids = {b: model.body(b).id for b in masses}

        def before(d):  # rolling resistance as in the corpus: fades below |w| = 0.5 rad/s
            for b, m in masses.items():
                w = d.body(b).cvel[:3].copy()
                w[2] = 0.0
                n = float(np.linalg.norm(w))
                scale = min(n / 0.5, 1.0) / n if n > 0 else 0.0
                d.xfrc_applied[ids[b], 3:6] = -mu_r * m * g * w * scale
        return before

    def init(d, p):  # the cue ball starts rolling (body frame = world frame at t = 0)
        d.qvel[0:3] = p["cue_initial_velocity_m_s"]
        d.qvel[3:6] = p["cue_initial_angular_velocity_rad_s"]

    _, ratios = _resim_corpus("billiards", factory, init)
    assert all(0.85 < r < 1.15 for r in ratios.values()), ratios
