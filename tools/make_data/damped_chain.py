"""Generate examples/hidden-effect/damped_chain: a 4-link chain with viscous damping in every
hinge (MuJoCo ``damping``, the same b in each), released curled and swinging to rest.

Four capsule links hang one below the other from hinges (axes (0, -1, 0)) at 1.2, 1.0, 0.8 and
0.6 m; each hinge starts at the same angle relative to the link above (the chain curls) and
the chain is released from rest. Recorded 3 s at 100 Hz: the four hinge encoders.
The naive scene (a ``for`` loop) has no damping: refine should name the group candidate,
joint_damping on every hinge.

Usage: python tools/make_data/damped_chain.py
"""
from __future__ import annotations

import math
import textwrap

import mujoco
import numpy as np

from mjgen import EXAMPLES, add_noise, mjcf, rollout, write_angles, write_truth
from scene_files import write_scene

NAME = "damped_chain"
LINKS = 4
JOINTS = tuple(f"hinge{i}" for i in range(1, LINKS + 1))
DAMPING = 0.003  # N m s/rad, every hinge
TRUTH = {
    "scene": NAME,
    "hidden_effect": {"effect": "joint_damping", "target": "hinge1",
                      "law": "torque -b * (d angle / dt) in every hinge, the same b",
                      "mujoco": "joint damping on each of the four hinges"},
    "also_hidden": [{"effect": "joint_damping", "target": j} for j in JOINTS[1:]],
    "parameters": {"a": math.radians(20.0), **{f"joint_damping@{j}.coefficient": DAMPING for j in JOINTS}},
    "naive_unknowns": ["a"],
    "physical_parameters": {"top_hinge_m": [0.0, 0.0, 1.2], "link_pitch_m": 0.2, "link_radius_m": 0.01,
                            "link_mass_kg": 0.1, "initial_relative_angle_rad": math.radians(20.0),
                            "damping_N_m_s_per_rad": DAMPING, "duration_s": 3.0},
    "noise": {"sigma_angle_rad": 0.003, "rate_hz": 100.0, "seed": 1405},
    "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 1e-4, "integrator": "RK4"},
}
README = ("damped_chain: every hinge of a chain is damped",
          "A chain of four 20 cm links is released curled (each hinge at 20 degrees) and its four hinge "
          "encoders are logged for 3 s. The swing dies away faster than an ideal chain's: the hidden "
          f"effect is viscous damping in every hinge, the same b = {DAMPING} N m s/rad in each (MuJoCo "
          "`damping`). Refine should name the group candidate: joint_damping on every hinge.")


def build(truth: dict, damping: float | None = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The chain with each hinge damped by ``damping`` (default: the truth's)."""
    p = truth["physical_parameters"]
    b = p["damping_N_m_s_per_rad"] if damping is None else damping
    pitch, rl, ml = p["link_pitch_m"], p["link_radius_m"], p["link_mass_kg"]
    hx, hy, hz = p["top_hinge_m"]
    xml = ""
    for i in range(LINKS, 0, -1):  # innermost first
        pos = f"{hx} {hy} {hz}" if i == 1 else f"0 0 {-pitch}"
        xml = f"""<body name="link{i}" pos="{pos}">
      <joint name="hinge{i}" type="hinge" axis="0 -1 0" damping="{b}"/>
      <geom type="capsule" fromto="0 0 {-rl} 0 0 {-(pitch - rl)}" size="{rl}" mass="{ml}"/>
      <site name="link{i}" pos="0 0 {-pitch / 2}"/>{xml}</body>"""
    model = mujoco.MjModel.from_xml_string(mjcf(xml, timestep=truth["simulator"]["timestep_s"]))
    data = mujoco.MjData(model)
    data.qpos[:] = p["initial_relative_angle_rad"]
    return model, data


def simulate(truth: dict, damping: float | None = None):
    """Noise-free samples: times, hinge angles {hinge_i: (N,)}, and the chain's energy (N,)."""
    model, data = build(truth, damping)

    def record(d):
        return {**{j: d.qpos[k].copy() for k, j in enumerate(JOINTS)}, "energy": d.energy.sum().copy()}

    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    t, s = rollout(model, data, truth["physical_parameters"]["duration_s"], record)
    return t, {j: s[j] for j in JOINTS}, s["energy"]


OBSERVE = "".join(f'  observe {j}.angle from "joints.csv" where joint == "{j}" {{ noise: 3 mrad }}\n'
                  for j in JOINTS)
SCENE = f"""# A chain of four capsule links (20 cm apart, 100 g each) hangs from hinges at 1.2, 1.0, 0.8
# and 0.6 m (axes along -y; link0 is the world). Each hinge starts at the same angle a relative
# to the link above (the chain curls) and the chain is released from rest. The four hinge
# encoders are logged at 100 Hz for 3 s (joints.csv, 3 mrad).
# First model: an ideal chain. Unknown: the starting angle a.

scene {NAME} {{
  world {{ timestep: 1 ms  integrator: rk4 }}

  param a ~ normal(20 deg, 5 deg)

  alias link0 = world
  for i in 1..{LINKS} {{
    body link{{i}} {{
      shape: capsule(radius: 1 cm, length: 18 cm)
      mass: 100 g
      position: (0, 0, 1.3 - 0.2 * i) m
    }}
    joint hinge{{i}}: hinge(link{{i - 1}} -> link{{i}}) {{
      axis: (0, -1, 0)
      anchor: (0, 0, 1.4 - 0.2 * i) m
      initial: a
      initial_velocity: 0 rad/s
    }}
  }}

{OBSERVE}}}
"""


def main() -> None:
    out = EXAMPLES / "hidden-effect" / NAME
    out.mkdir(parents=True, exist_ok=True)
    t, angles, _ = simulate(TRUTH)
    rng = np.random.default_rng(TRUTH["noise"]["seed"])
    write_angles(out / "joints.csv", t, add_noise(angles, TRUTH["noise"]["sigma_angle_rad"], rng))
    write_scene(out / "naive.phys", SCENE)
    (out / "README.md").write_text(f"# {README[0]}\n\n{textwrap.fill(README[1], 95)}\n")
    write_truth(out / "truth.json", TRUTH)


if __name__ == "__main__":
    main()
