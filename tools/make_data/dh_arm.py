"""Generate examples/dh_arm: a 4-DOF arm given by classic Denavit-Hartenberg parameters (MuJoCo).

DH rows (a, alpha, d, theta offset) for joints 1..4: (0, 90 deg, 0.3 m, 0), (0.3 m, 0, 0, 0),
(a3, 0, 0, 0), (0.1 m, 0, 0, 0); base frame = world. Joint i turns about z_{i-1}: joint 1 about
world z at the origin, joints 2-4 about (0, -1, 0) through (0, 0, 0.3), (0.3, 0, 0.3) and
(0.3 + a3, 0, 0.3) m at q = 0, where the arm points along +x. A payload sphere sits at the
end-effector (DH frame 4's origin). The unpowered arm is released with the base turning and
falls under gravity against viscous joint damping. Recorded 2 s at 100 Hz: joint angles
(joints.csv) and the end-effector position (trajectory.csv).
"""
from __future__ import annotations

import mujoco
import numpy as np

from mjgen import mjcf, rollout, write_angle_example

NAME = "dh_arm"
JOINTS = ("j1", "j2", "j3", "j4")
TRUTH = {
    "scene": NAME,
    "unknowns": {"a3": 0.25, "payload.mass": 0.3},
    "parameters": {
        "dh_a_m": [0.0, 0.3, 0.25, 0.1], "dh_alpha_deg": [90.0, 0.0, 0.0, 0.0], "dh_d_m": [0.3, 0.0, 0.0, 0.0],
        "dh_theta_offset_deg": [0.0, 0.0, 0.0, 0.0],
        "link_radius_m": [0.04, 0.03, 0.025, 0.02], "link_mass_kg": [1.0, 0.8, 0.5, 0.2],
        "payload_radius_m": 0.03, "payload_mass_kg": 0.3,
        "joint_damping_N_m_s_rad": 0.3,
        "initial_q_rad": [0.0, 0.6, -0.8, 0.3], "initial_qdot_rad_s": [1.5, 0.0, 0.0, 0.0],
        "duration_s": 2.0,
    },
    "noise": {"sigma_angle_rad": 0.002, "sigma_position_m": 0.002, "rate_hz": 100.0, "seed": 205},
    "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 1e-4, "integrator": "RK4"},
}


def dh_frames(a, alpha, d, theta) -> list[np.ndarray]:
    """World poses (4x4) of DH frames 0..n: T_i = Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    frames = [np.eye(4)]
    for ai, al, di, th in zip(a, alpha, d, theta):
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = np.array([[ct, -st * ca, st * sa, ai * ct], [st, ct * ca, -ct * sa, ai * st],
                      [0, sa, ca, di], [0, 0, 0, 1]])
        frames.append(frames[-1] @ T)
    return frames


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Nested MuJoCo bodies placed at the DH frames of q = 0 (all in world coordinates)."""
    p = truth["parameters"]
    F = dh_frames(p["dh_a_m"], np.radians(p["dh_alpha_deg"]), p["dh_d_m"], np.radians(p["dh_theta_offset_deg"]))
    b = p["joint_damping_N_m_s_rad"]
    xml, close = "", ""
    prev = np.zeros(3)
    for i in range(4):
        o0, o1, z = F[i][:3, 3], F[i + 1][:3, 3], F[i][:3, 2]
        rel = o0 - prev  # bodies carry no rotation: positions relative to the parent's origin
        seg = " ".join(f"{v:.12g}" for v in (*np.zeros(3), *(o1 - o0)))
        xml += f"""
      <body name="link{i + 1}" pos="{rel[0]:.12g} {rel[1]:.12g} {rel[2]:.12g}">
        <joint name="{JOINTS[i]}" type="hinge" axis="{z[0]:.12g} {z[1]:.12g} {z[2]:.12g}" damping="{b}"/>
        <geom type="capsule" fromto="{seg}" size="{p['link_radius_m'][i]}" mass="{p['link_mass_kg'][i]}"/>"""
        close += "</body>"
        prev = o0
    ee = F[4][:3, 3] - prev
    xml += f"""
        <body name="payload" pos="{ee[0]:.12g} {ee[1]:.12g} {ee[2]:.12g}">
          <geom type="sphere" size="{p['payload_radius_m']}" mass="{p['payload_mass_kg']}"/>
          <site name="payload"/>
        </body>""" + close
    model = mujoco.MjModel.from_xml_string(mjcf(xml, timestep=truth["simulator"]["timestep_s"]))
    data = mujoco.MjData(model)
    data.qpos[:] = p["initial_q_rad"]
    data.qvel[:] = p["initial_qdot_rad_s"]
    return model, data


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noise-free samples: times, joint angles {j1..j4: (N,)}, end-effector {payload: (N, 3)}."""
    model, data = build(truth)

    def record(d):
        return {**{j: d.qpos[i].copy() for i, j in enumerate(JOINTS)}, "payload": d.site("payload").xpos.copy()}

    t, s = rollout(model, data, truth["parameters"]["duration_s"], record)
    return t, {j: s[j] for j in JOINTS}, {"payload": s["payload"]}


def main() -> None:
    write_angle_example(NAME, TRUTH, simulate)


if __name__ == "__main__":
    main()
