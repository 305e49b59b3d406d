"""Generate the law-discrimination cases of examples/hidden-effect (MuJoCo): which law, not
only which target.

- ``hinge_viscous`` / ``hinge_coulomb``: one pendulum, the same naive scene, with viscous
  damping (MuJoCo ``damping``) or dry Coulomb friction (``frictionloss``) in its hinge, each
  taking about half the swing in 3 s (exponential against linear decay of the amplitude).
- ``drag_linear`` / ``drag_quadratic``: a ball thrown steeply up at 20 m/s in air, tracked
  for 3 s while its speed spans about 2-20 m/s, with linear drag -b v or quadratic drag
  -c |v| v applied as a force on the ball before every step (``xfrc_applied``).

Usage: python tools/make_data/laws.py
"""
from __future__ import annotations

import math
import textwrap

import mujoco
import numpy as np

from mjgen import EXAMPLES, mjcf, rollout, write_recording
from no_effect import pendulum_scene, pendulum_xml
from scene_files import write_scene

HIDDEN = EXAMPLES / "hidden-effect"
SIM = {"engine": f"MuJoCo {mujoco.__version__}", "integrator": "RK4"}
# dry friction as a stiff constraint (MuJoCo's default time constant 0.02 s lets the joint creep
# at the turning points, a softer law than Coulomb's)
SOLREF_FRICTION = "0.0005 1"

PENDULUM = {"length_m": 0.5, "bob_radius_m": 0.04, "bob_mass_kg": 0.3, "rod_mass_kg": 0.01,
            "rod_radius_m": 0.005, "pivot_m": [0.0, 0.0, 1.2], "initial_rad": math.radians(45.0),
            "duration_s": 3.0}
BALL = {"radius_m": 0.11, "mass_kg": 0.43, "position_m": [0.0, 0.0, 1.5], "velocity_m_s": [2.0, 0.0, 19.9],
        "duration_s": 3.0}

CASES = {
    "hinge_viscous": {
        "kind": "hinge", "hidden_effect": {"effect": "joint_damping", "target": "hinge",
                                           "law": "torque -b * (d angle / dt) about the hinge axis",
                                           "mujoco": "joint damping"},
        "strength": {"joint_damping@hinge.coefficient": 0.035}, "seed": 1401,
        "readme": ("hinge_viscous: the swing dies away exponentially",
                   "A pendulum released at 45 degrees is tracked for 3 s; its amplitude halves. The hidden "
                   "law is viscous damping in the hinge (joint_damping, b = 0.035 N m s/rad, MuJoCo "
                   "`damping`). Its twin `hinge_coulomb` loses as much by dry friction: refine must name "
                   "the right law, not only the hinge.")},
    "hinge_coulomb": {
        "kind": "hinge", "hidden_effect": {"effect": "joint_friction", "target": "hinge",
                                           "law": "torque -T sign(d angle / dt) about the hinge axis",
                                           "mujoco": "joint frictionloss (dry friction constraint)"},
        "strength": {"joint_friction@hinge.torque": 0.06}, "seed": 1402,
        "readme": ("hinge_coulomb: the swing dies away linearly",
                   "A pendulum released at 45 degrees is tracked for 3 s; its amplitude falls by the same "
                   "step every swing. The hidden law is dry Coulomb friction in the hinge (joint_friction, "
                   "T = 0.06 N m, MuJoCo `frictionloss`). Its twin `hinge_viscous` loses as much by "
                   "viscous damping: refine must name the right law, not only the hinge.")},
    "drag_linear": {
        "kind": "drag", "hidden_effect": {"effect": "linear_drag", "target": "ball", "law": "force -b v",
                                          "mujoco": "xfrc_applied = -b v before every step"},
        "strength": {"linear_drag@ball.coefficient": 0.1}, "seed": 1403,
        "readme": ("drag_linear: a steep throw slowed by linear drag",
                   "A ball thrown up at 20 m/s is tracked for 3 s (speeds about 2-20 m/s). The hidden law "
                   "is linear drag F = -b v (b = 0.1 kg/s, applied in MuJoCo as a force): far above Stokes "
                   "drag in air, a law-discrimination check, not a physical ball. Its twin "
                   "`drag_quadratic` has quadratic drag: refine must name the right law.")},
    "drag_quadratic": {
        "kind": "drag", "hidden_effect": {"effect": "quadratic_drag", "target": "ball", "law": "force -c |v| v",
                                          "mujoco": "xfrc_applied = -c |v| v before every step"},
        "strength": {"quadratic_drag@ball.coefficient": 0.0107}, "seed": 1404,
        "readme": ("drag_quadratic: a steep throw slowed by quadratic drag",
                   "A football-sized ball thrown up at 20 m/s is tracked for 3 s (speeds about 2-20 m/s). "
                   "The hidden law is quadratic drag F = -c |v| v (c = 0.0107 kg/m: C_d 0.47 in air, "
                   "applied in MuJoCo as a force). Its twin `drag_linear` has linear drag: refine must "
                   "name the right law.")},
}


def truth_of(name: str) -> dict:
    case = CASES[name]
    hinge = case["kind"] == "hinge"
    p = dict(PENDULUM if hinge else BALL)
    unknowns = ({"L": p["length_m"], "hinge.initial": p["initial_rad"]} if hinge else
                {"ball.position": p["position_m"], "ball.velocity": p["velocity_m_s"]})
    noise = {"sigma_position_m": 0.002, "sigma_angle_rad": 0.003} if hinge else {"sigma_position_m": 0.01}
    return {"scene": name, "kind": case["kind"], "hidden_effect": case["hidden_effect"],
            "parameters": {**unknowns, **case["strength"]}, "naive_unknowns": list(unknowns),
            "physical_parameters": p, "noise": {**noise, "rate_hz": 100.0, "seed": case["seed"]},
            "simulator": {**SIM, "timestep_s": 1e-4 if hinge else 1e-3,
                          **({"solreffriction": SOLREF_FRICTION} if hinge else {})}}


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noise-free samples: times, joint angles {hinge: (N,)} (pendulum) and centres {body: (N, 3)}."""
    p, ts = truth["physical_parameters"], truth["simulator"]["timestep_s"]
    effect = truth["hidden_effect"]["effect"]
    value = next(iter(v for k, v in truth["parameters"].items() if "@" in k))
    if truth["kind"] == "hinge":
        law = (f'damping="{value}"' if effect == "joint_damping" else
               f'frictionloss="{value}" solreffriction="{SOLREF_FRICTION}"')
        model = mujoco.MjModel.from_xml_string(mjcf(pendulum_xml(p, law), timestep=ts))
        data = mujoco.MjData(model)
        data.qpos[0] = p["initial_rad"]
        t, s = rollout(model, data, p["duration_s"],
                       lambda d: {"hinge": d.qpos[0].copy(), "bob": d.site("bob").xpos.copy()})
        return t, {"hinge": s["hinge"]}, {"bob": s["bob"]}
    x, y, z = p["position_m"]
    body = f"""<body name="ball" pos="{x} {y} {z}"><freejoint/>
      <geom type="sphere" size="{p['radius_m']}" mass="{p['mass_kg']}"/><site name="ball"/></body>"""
    model = mujoco.MjModel.from_xml_string(mjcf(body, timestep=ts))
    data = mujoco.MjData(model)
    data.qvel[:3] = p["velocity_m_s"]
    ball = model.body("ball").id

    def drag(d):  # the hidden law as an applied force at the centre of mass
        v = d.qvel[:3]
        d.xfrc_applied[ball, :3] = -value * v if effect == "linear_drag" else -value * np.linalg.norm(v) * v

    t, s = rollout(model, data, p["duration_s"], lambda d: {"ball": d.site("ball").xpos.copy(),
                                                           "speed": np.linalg.norm(d.qvel[:3])}, drag)
    return t, {}, {"ball": s["ball"]}


def naive_scene(truth: dict) -> str:
    name = truth["scene"]
    if truth["kind"] == "hinge":
        header = """# A pendulum (thin rod + 300 g bob) hangs from a hinge at (0, 0, 1.2) m and swings in the
# x-z plane after release from rest. Tracked at 100 Hz for 3 s: bob centre (trajectory.csv,
# 2 mm) and hinge encoder (joints.csv, 3 mrad). First model: an ideal rigid pendulum.
# Unknown: the length L and the release angle."""
        return pendulum_scene(name, truth["physical_parameters"], header, "normal(0.5 m, 5 cm)",
                              "normal(45 deg, 10 deg)")
    return f"""# A ball (11 cm radius, 430 g) is thrown steeply up at about 20 m/s in still air and tracked at
# 100 Hz for 3 s, up past its highest point and down again, before it lands (trajectory.csv,
# 10 mm per axis). First model: a projectile under gravity alone. Unknown: where the ball
# left the hand and how fast.

scene {name} {{
  world {{ timestep: 5 ms  integrator: rk4 }}

  body ball {{
    shape: sphere(radius: 11 cm)
    mass: 430 g
    position ~ normal((0, 0, 1.5) m, 10 cm)
    velocity ~ normal((2, 0, 20) m/s, 3 m/s)
    angular_velocity: (0, 0, 0) rad/s  # no spin
  }}

  observe ball.position from "trajectory.csv" where body == "ball" {{ noise: 10 mm }}
}}
"""


def write_case(name: str, root=HIDDEN) -> dict:
    truth = truth_of(name)
    out = root / name
    out.mkdir(parents=True, exist_ok=True)
    write_recording(out, truth, *simulate(truth))
    write_scene(out / "naive.phys", naive_scene(truth))
    title, body = CASES[name]["readme"]
    (out / "README.md").write_text(f"# {title}\n\n{textwrap.fill(body, 95)}\n")
    return truth


def main() -> None:
    for name in CASES:
        write_case(name)
        print(name)


if __name__ == "__main__":
    main()
