"""Generate examples/ball_chain: a ball flies into a hanging chain of three links (MuJoCo).

Three capsule links hang from hinges (axes (0, -1, 0)) at (0, 0, 1.0), (0, 0, 0.8) and
(0, 0, 0.6) m; a ball launched horizontally along +x strikes the lowest link. Contacts are
hard, elastic and frictionless: MuJoCo spring contacts (direct solref, no damping) lasting
about 0.3 ms, integrated at 5 us. Recorded 1 s at 100 Hz: the centres of the ball and links.
"""
from __future__ import annotations

import mujoco
import numpy as np

from mjgen import EXAMPLES, add_noise, mjcf, rollout, write_positions, write_truth

NAME = "ball_chain"
LINKS = ("link1", "link2", "link3")
TRUTH = {
    "scene": NAME,
    "unknowns": {"m_link": 0.1, "v_ball": 1.5},
    "parameters": {
        "top_hinge_m": [0.0, 0.0, 1.0], "link_pitch_m": 0.2, "link_radius_m": 0.01, "link_mass_kg": 0.1,
        "ball_radius_m": 0.03, "ball_mass_kg": 0.2, "ball_initial_position_m": [-0.2, 0.0, 0.555],
        "ball_initial_velocity_m_s": [1.5, 0.0, 0.0], "duration_s": 1.0,
        "contact": "elastic, frictionless (measured restitution ~0.999)",
    },
    "noise": {"sigma_position_m": 0.002, "rate_hz": 100.0, "seed": 204},
    "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 5e-6, "integrator": "implicitfast",
                  "contact_solref": [-1e8, 0.0], "contact_solimp": [0.99, 0.99, 0.001, 0.5, 2]},
}


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    p, sim = truth["parameters"], truth["simulator"]
    hx, hy, hz = p["top_hinge_m"]
    pitch, rl, ml = p["link_pitch_m"], p["link_radius_m"], p["link_mass_kg"]
    # each link's cylinder spans its hinge-to-hinge pitch less its two end caps
    link = lambda i: f"""<joint name="hinge{i}" type="hinge" axis="0 -1 0"/>
        <geom name="link{i}" type="capsule" fromto="0 0 {-rl} 0 0 {-(pitch - rl)}" size="{rl}" mass="{ml}"/>
        <site name="link{i}" pos="0 0 {-pitch / 2}"/>"""
    bx, by, bz = p["ball_initial_position_m"]
    body = f"""
    <body name="link1" pos="{hx} {hy} {hz}">{link(1)}
      <body name="link2" pos="0 0 {-pitch}">{link(2)}
        <body name="link3" pos="0 0 {-pitch}">{link(3)}
        </body>
      </body>
    </body>
    <body name="ball" pos="{bx} {by} {bz}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{p['ball_radius_m']}" mass="{p['ball_mass_kg']}"/>
      <site name="ball"/>
    </body>"""
    solref = " ".join(str(v) for v in sim["contact_solref"])
    solimp = " ".join(str(v) for v in sim["contact_solimp"])
    pair = lambda a, b: f'<pair geom1="{a}" geom2="{b}" condim="1" solref="{solref}" solimp="{solimp}"/>'
    contact = "".join(pair("ball", l) for l in LINKS) + pair("link1", "link3")
    model = mujoco.MjModel.from_xml_string(
        mjcf(body, timestep=sim["timestep_s"], integrator=sim["integrator"], contact=contact))
    data = mujoco.MjData(model)
    data.qvel[3:6] = p["ball_initial_velocity_m_s"]  # free joint: qvel[3:6] after 3 hinges
    return model, data


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Noise-free samples: times and centres {ball, link1, link2, link3: (N, 3)}."""
    model, data = build(truth)

    def record(d):
        return {name: d.site(name).xpos.copy() for name in ("ball", *LINKS)}

    return rollout(model, data, truth["parameters"]["duration_s"], record)


def main() -> None:
    out = EXAMPLES / NAME
    out.mkdir(parents=True, exist_ok=True)
    t, pos = simulate(TRUTH)
    rng = np.random.default_rng(TRUTH["noise"]["seed"])
    write_positions(out / "trajectory.csv", t, add_noise(pos, TRUTH["noise"]["sigma_position_m"], rng))
    write_truth(out / "truth.json", TRUTH)


if __name__ == "__main__":
    main()
