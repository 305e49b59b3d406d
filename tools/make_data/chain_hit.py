"""Generate examples/chain_hit: a ball thrown at a hanging chain of four capsule links (MuJoCo).

Four links hang from hinges (axes (0, -1, 0)) 20 cm apart below (0, 0, 1.2) m; a ball thrown
from the left at 3.2 m/s, 40 degrees up, strikes the lowest link and falls away. Ball-link
contacts are hard, elastic and frictionless (direct solref spring, no damping, condim 1),
integrated at 5 us. Recorded 2 s at 100 Hz: the centres of the ball and links
(trajectory.csv, 2 mm) and the four hinge angles (joints.csv, 5 mrad). Three variants: without
hinge damping (examples/chain_hit), with hidden hinge damping (examples/chain_hit/damped:
0.002 N m s/rad, which no fit of the naive scene brings below 15σ: refine's case) and with a
slight hidden damping (examples/chain_hit/damped_light: 3e-5 N m s/rad, a link's swing decays
with a time constant of about 30 s: MAP's case of a small unmodelled effect; at 1e-4 the
naive scene's best fit is already 2.72σ).
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from mjgen import EXAMPLES, add_noise, mjcf, rollout, write_angles, write_positions, write_truth

NAME = "chain_hit"
N_LINKS = 4
LINKS = tuple(f"link{i}" for i in range(1, N_LINKS + 1))
HINGES = tuple(f"hinge{i}" for i in range(1, N_LINKS + 1))
SPEED, ANGLE = 3.2, math.radians(40.0)
TRUTH = {
    "scene": NAME,
    "unknowns": {"m_link": 0.08, "ball.position": [-0.8, 0.0, 0.3], "speed": SPEED,
                 "launch_angle": ANGLE},
    "physical_parameters": {
        "top_hinge_m": [0.0, 0.0, 1.2], "link_pitch_m": 0.2, "link_radius_m": 0.015,
        "link_mass_kg": 0.08, "ball_radius_m": 0.03, "ball_mass_kg": 0.15,
        "ball_initial_position_m": [-0.8, 0.0, 0.3],
        "ball_initial_velocity_m_s": [SPEED * math.cos(ANGLE), 0.0, SPEED * math.sin(ANGLE)],
        "hinge_damping_N_m_s_per_rad": 0.0, "duration_s": 2.0,
        "contact": "ball-link: elastic, frictionless; links do not touch each other",
    },
    "noise": {"sigma_position_m": 0.002, "sigma_angle_rad": 0.005, "rate_hz": 100.0, "seed": 2101},
    "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 5e-6,
                  "integrator": "implicitfast", "contact_solref": [-1e8, 0.0],
                  "contact_solimp": [0.99, 0.99, 0.001, 0.5, 2]},
}
TRUTH["parameters"] = TRUTH["unknowns"]  # (the benchmarks' name for the true values)
DAMPED = {**TRUTH, "hidden_effect": {"effect": "joint_damping", "target": "hinge1..hinge4",
                                     "law": "torque -b * (d angle / dt) about each hinge axis"},
          "physical_parameters": {**TRUTH["physical_parameters"],
                                  "hinge_damping_N_m_s_per_rad": 0.002},
          "noise": {**TRUTH["noise"], "seed": 2102}}
LIGHT = {**DAMPED, "physical_parameters": {**TRUTH["physical_parameters"],
                                           "hinge_damping_N_m_s_per_rad": 3e-5},
         "noise": {**TRUTH["noise"], "seed": 2103}}


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    p, sim = truth["physical_parameters"], truth["simulator"]
    hx, hy, hz = p["top_hinge_m"]
    pitch, rl, ml = p["link_pitch_m"], p["link_radius_m"], p["link_mass_kg"]
    damping = p["hinge_damping_N_m_s_per_rad"]

    def link(i):
        return f"""<joint name="hinge{i}" type="hinge" axis="0 -1 0" damping="{damping}"/>
        <geom name="link{i}" type="capsule" fromto="0 0 {-rl} 0 0 {-(pitch - rl)}" size="{rl}" mass="{ml}"/>
        <site name="link{i}" pos="0 0 {-pitch / 2}"/>"""

    chain = ""
    for i in range(N_LINKS, 0, -1):  # innermost first
        pos = f"{hx} {hy} {hz}" if i == 1 else f"0 0 {-pitch}"
        chain = f'<body name="link{i}" pos="{pos}">{link(i)}{chain}</body>'
    bx, by, bz = p["ball_initial_position_m"]
    body = chain + f"""
    <body name="ball" pos="{bx} {by} {bz}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{p['ball_radius_m']}" mass="{p['ball_mass_kg']}"/>
      <site name="ball"/>
    </body>"""
    solref = " ".join(str(v) for v in sim["contact_solref"])
    solimp = " ".join(str(v) for v in sim["contact_solimp"])
    contact = "".join(f'<pair geom1="ball" geom2="{name}" condim="1" solref="{solref}" '
                      f'solimp="{solimp}"/>' for name in LINKS)
    model = mujoco.MjModel.from_xml_string(
        mjcf(body, timestep=sim["timestep_s"], integrator=sim["integrator"], contact=contact))
    data = mujoco.MjData(model)
    data.qvel[N_LINKS:N_LINKS + 3] = p["ball_initial_velocity_m_s"]  # free joint after hinges
    return model, data


def simulate(truth: dict):
    """Noise-free samples: times, hinge angles {hinge_i: (N,)}, centres {ball, link_i: (N, 3)}."""
    model, data = build(truth)

    def record(d):
        out = {name: d.site(name).xpos.copy() for name in ("ball", *LINKS)}
        out.update({h: np.array(d.joint(h).qpos[0]) for h in HINGES})
        return out

    t, rec = rollout(model, data, truth["physical_parameters"]["duration_s"], record)
    return t, {h: rec[h] for h in HINGES}, {k: rec[k] for k in ("ball", *LINKS)}


def write(folder, truth: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    t, angles, positions = simulate(truth)
    rng = np.random.default_rng(truth["noise"]["seed"])
    write_positions(folder / "trajectory.csv", t,
                    add_noise(positions, truth["noise"]["sigma_position_m"], rng))
    write_angles(folder / "joints.csv", t, add_noise(angles, truth["noise"]["sigma_angle_rad"], rng))
    write_truth(folder / "truth.json", truth)


def main() -> None:
    write(EXAMPLES / NAME, TRUTH)
    write(EXAMPLES / NAME / "damped", DAMPED)
    write(EXAMPLES / NAME / "damped_light", LIGHT)


if __name__ == "__main__":
    main()
