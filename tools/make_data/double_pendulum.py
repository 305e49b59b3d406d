"""Generate examples/double_pendulum: two capsule links on hinges, swinging freely (MuJoCo).

Link 1 hangs from a hinge at (0, 0, 1.5) m, link 2 from an elbow hinge at the end of link 1;
both axes (0, -1, 0), so positive angles swing towards +x; the elbow angle is relative to
link 1. Released from rest; recorded 3 s at 100 Hz: joint angles and link 2's centre.
"""
from __future__ import annotations

import mujoco
import numpy as np

from mjgen import mjcf, rollout, write_angle_example

NAME = "double_pendulum"
TRUTH = {
    "scene": NAME,
    "unknowns": {"shoulder.initial": 1.0, "elbow.initial": -0.5, "link2.mass": 0.25},
    "parameters": {
        "pivot_m": [0.0, 0.0, 1.5], "link1_length_m": 0.4, "link2_length_m": 0.3,
        "link1_radius_m": 0.02, "link2_radius_m": 0.015, "link1_mass_kg": 0.4, "link2_mass_kg": 0.25,
        "shoulder_initial_rad": 1.0, "elbow_initial_rad": -0.5, "duration_s": 3.0,
    },
    "noise": {"sigma_angle_rad": 0.002, "sigma_position_m": 0.002, "rate_hz": 100.0, "seed": 201},
    "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 1e-4, "integrator": "RK4"},
}


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    p = truth["parameters"]
    px, py, pz = p["pivot_m"]
    l1, l2 = p["link1_length_m"], p["link2_length_m"]
    body = f"""
    <body name="link1" pos="{px} {py} {pz}">
      <joint name="shoulder" type="hinge" axis="0 -1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 {-l1}" size="{p['link1_radius_m']}" mass="{p['link1_mass_kg']}"/>
      <site name="link1" pos="0 0 {-l1 / 2}"/>
      <body name="link2" pos="0 0 {-l1}">
        <joint name="elbow" type="hinge" axis="0 -1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 {-l2}" size="{p['link2_radius_m']}" mass="{p['link2_mass_kg']}"/>
        <site name="link2" pos="0 0 {-l2 / 2}"/>
      </body>
    </body>"""
    model = mujoco.MjModel.from_xml_string(mjcf(body, timestep=truth["simulator"]["timestep_s"]))
    data = mujoco.MjData(model)
    data.qpos[:] = [p["shoulder_initial_rad"], p["elbow_initial_rad"]]
    return model, data


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noise-free samples: times, joint angles {name: (N,)}, body centres {name: (N, 3)}."""
    model, data = build(truth)

    def record(d):
        return {"shoulder": d.qpos[0].copy(), "elbow": d.qpos[1].copy(), "link2": d.site("link2").xpos.copy()}

    t, s = rollout(model, data, truth["parameters"]["duration_s"], record)
    return t, {"shoulder": s["shoulder"], "elbow": s["elbow"]}, {"link2": s["link2"]}


def main() -> None:
    write_angle_example(NAME, TRUTH, simulate)


if __name__ == "__main__":
    main()
