"""Generate examples/no-effect: 20 MuJoCo recordings with nothing hidden, and their naive scenes.

The false-positive check of the diagnosis (issue 14): each case's naive scene is the whole
physics of its data, so ``refine`` should add nothing (an effect added in at most ~2 of 20,
the nominal rate of its tests). Four kinds, five cases each, settings drawn per case from a
seeded generator: a ball thrown in vacuum, an undamped pendulum, a block on a frictionless
tilted rail, a block on a vertical spring. Recorded at 100 Hz for 2-3 s with Gaussian noise.

Usage: python tools/make_data/no_effect.py   (rewrites examples/no-effect/*)
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from mjgen import EXAMPLES, mjcf, rollout, write_recording
from scene_files import write_scene

OUT = EXAMPLES / "no-effect"
KINDS = ("throw", "pendulum", "rail", "spring")
PER_KIND = 5
SIM = {"engine": f"MuJoCo {mujoco.__version__}", "integrator": "RK4"}


def case_truth(kind: str, index: int) -> dict:
    """The true settings of case ``index`` (1-based) of ``kind``, drawn from a seeded generator."""
    seed = 1000 + 100 * KINDS.index(kind) + index
    rng = np.random.default_rng(seed)
    u = lambda lo, hi: float(round(rng.uniform(lo, hi), 4))
    if kind == "throw":
        speed, elev, azim = u(5.0, 10.0), math.radians(u(30.0, 70.0)), math.radians(u(-20.0, 20.0))
        v = [round(speed * math.cos(elev) * math.cos(azim), 4), round(speed * math.cos(elev) * math.sin(azim), 4),
             round(speed * math.sin(elev), 4)]
        p = {"radius_m": u(0.03, 0.12), "mass_kg": u(0.1, 0.5), "position_m": [0.0, 0.0, u(1.2, 2.0)],
             "velocity_m_s": v, "duration_s": 1.5}
        params = {"ball.position": p["position_m"], "ball.velocity": v}
        noise = {"sigma_position_m": 0.005}
        timestep = 1e-3
    elif kind == "pendulum":
        p = {"length_m": u(0.35, 0.8), "bob_radius_m": 0.04, "bob_mass_kg": u(0.2, 0.5), "rod_mass_kg": 0.01,
             "rod_radius_m": 0.005, "pivot_m": [0.0, 0.0, 1.2], "initial_rad": math.radians(u(15.0, 60.0)),
             "duration_s": 3.0}
        params = {"L": p["length_m"], "hinge.initial": p["initial_rad"]}
        noise = {"sigma_position_m": 0.002, "sigma_angle_rad": 0.003}
        timestep = 1e-4
    elif kind == "rail":
        p = {"incline_deg": u(5.0, 25.0), "mass_kg": u(0.2, 1.0), "half_side_m": 0.05,
             "origin_m": [0.0, 0.0, 0.5], "initial_m": u(-0.1, 0.1), "initial_velocity_m_s": u(0.8, 2.0),
             "duration_s": 2.0}
        params = {"rail.initial": p["initial_m"], "rail.initial_velocity": p["initial_velocity_m_s"]}
        noise = {"sigma_position_m": 0.003, "sigma_angle_rad": 0.001}  # the rail's encoder, in m
        timestep = 1e-3
    else:
        p = {"mass_kg": 0.5, "anchor_m": [0.0, 0.0, 1.6], "half_side_m": 0.05, "reference_m": [0.0, 0.0, 1.0],
             "stiffness_N_m": u(20.0, 120.0), "rest_length_m": u(0.25, 0.45), "initial_m": u(-0.1, -0.04),
             "duration_s": 3.0}
        params = {"spring@block.stiffness": p["stiffness_N_m"], "spring@block.rest_length": p["rest_length_m"],
                  "guide.initial": p["initial_m"]}
        noise = {"sigma_position_m": 0.001}
        timestep = 1e-4
    return {"scene": f"{kind}_{index:02d}", "kind": kind, "hidden_effect": None,
            "naive_unknowns": list(params), "parameters": params, "physical_parameters": p,
            "noise": {**noise, "rate_hz": 100.0, "seed": seed},
            "simulator": {**SIM, "timestep_s": timestep}}


def pendulum_xml(p: dict, joint_attrs: str = "") -> str:
    """MJCF of a rod-and-bob pendulum on a hinge at ``pivot_m`` (axis -y), the bob ``length_m`` below."""
    px, py, pz = p["pivot_m"]
    L, r = p["length_m"], p["bob_radius_m"]
    return f"""<body name="pendulum" pos="{px} {py} {pz}">
      <joint name="hinge" type="hinge" axis="0 -1 0" {joint_attrs}/>
      <geom type="capsule" fromto="0 0 0 0 0 {-(L - r)}" size="{p['rod_radius_m']}" mass="{p['rod_mass_kg']}"/>
      <geom type="sphere" pos="0 0 {-L}" size="{r}" mass="{p['bob_mass_kg']}"/>
      <site name="bob" pos="0 0 {-L}"/></body>"""


def pendulum_scene(name: str, p: dict, header: str, length_prior: str, angle_prior: str) -> str:
    """The rigid pendulum of ``pendulum_xml`` as a naive scene: unknown L and release angle."""
    return f"""{header}

scene {name} {{
  world {{ timestep: 1 ms  integrator: rk4 }}

  param L ~ {length_prior}  # hinge axis to bob centre
  param r: 4 cm

  body rod {{
    shape: capsule(radius: 5 mm, length: L - r)
    mass: 10 g
    position: (0, 0, 1.2 m - (L - r) / 2)
  }}
  body bob {{
    shape: sphere(radius: r)
    mass: {p['bob_mass_kg'] * 1000:g} g
    position: (0, 0, 1.2 m - L)
  }}

  joint hinge: hinge(world -> rod) {{
    axis: (0, -1, 0)  # positive angle: bob towards +x
    anchor: (0, 0, 1.2) m
    initial ~ {angle_prior}
    initial_velocity: 0 rad/s
  }}
  joint weld: fixed(rod -> bob)

  observe bob.position from "trajectory.csv" where body == "bob" {{ noise: 2 mm }}
  observe hinge.angle from "joints.csv" where joint == "hinge" {{ noise: 3 mrad }}
}}
"""


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The case's MuJoCo model and its initial state."""
    kind, p = truth["kind"], truth["physical_parameters"]
    ts = truth["simulator"]["timestep_s"]
    if kind == "throw":
        x, y, z = p["position_m"]
        body = f"""<body name="ball" pos="{x} {y} {z}"><freejoint/>
      <geom type="sphere" size="{p['radius_m']}" mass="{p['mass_kg']}"/><site name="ball"/></body>"""
        model = mujoco.MjModel.from_xml_string(mjcf(body, timestep=ts))
        data = mujoco.MjData(model)
        data.qvel[:3] = p["velocity_m_s"]
    elif kind == "pendulum":
        model = mujoco.MjModel.from_xml_string(mjcf(pendulum_xml(p), timestep=ts))
        data = mujoco.MjData(model)
        data.qpos[0] = p["initial_rad"]
    elif kind == "rail":
        a = math.radians(p["incline_deg"])
        ox, oy, oz = p["origin_m"]
        h = p["half_side_m"]
        body = f"""<body name="block" pos="{ox} {oy} {oz}">
      <joint name="rail" type="slide" axis="{math.cos(a)} 0 {math.sin(a)}"/>
      <geom type="box" size="{h} {h} {h}" mass="{p['mass_kg']}"/><site name="block"/></body>"""
        model = mujoco.MjModel.from_xml_string(mjcf(body, timestep=ts))
        data = mujoco.MjData(model)
        data.qpos[0], data.qvel[0] = p["initial_m"], p["initial_velocity_m_s"]
    else:
        rx, ry, rz = p["reference_m"]
        h = p["half_side_m"]
        # spring from the anchor to the top face: length = anchor_z - (rz + q + h)
        ref = p["anchor_m"][2] - rz - h - p["rest_length_m"]
        body = f"""<body name="block" pos="{rx} {ry} {rz}">
      <joint name="guide" type="slide" axis="0 0 1" stiffness="{p['stiffness_N_m']}" springref="{ref}"/>
      <geom type="box" size="{h} {h} {h}" mass="{p['mass_kg']}"/><site name="block"/></body>"""
        model = mujoco.MjModel.from_xml_string(mjcf(body, timestep=ts))
        data = mujoco.MjData(model)
        data.qpos[0] = p["initial_m"]
    return model, data


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noise-free samples: times, joint readings {joint: (N,)} and body centres {body: (N, 3)}."""
    model, data = build(truth)
    kind = truth["kind"]
    site = {"throw": "ball", "pendulum": "bob", "rail": "block", "spring": "block"}[kind]
    joint = {"pendulum": "hinge", "rail": "rail"}.get(kind)

    def record(d):
        out = {site: d.site(site).xpos.copy()}
        if joint:
            out[joint] = d.qpos[0].copy()
        return out

    t, s = rollout(model, data, truth["physical_parameters"]["duration_s"], record)
    return t, ({joint: s[joint]} if joint else {}), {site: s[site]}


def naive_scene(truth: dict) -> str:
    """The case's naive scene: the whole physics of the data, unknowns with honest priors."""
    kind, p, n = truth["kind"], truth["physical_parameters"], truth["noise"]
    mm = lambda s: f"{s * 1000:g} mm"
    if kind == "throw":
        v = p["velocity_m_s"]
        guess = tuple(round(c) for c in v)
        return f"""# A ball ({p['radius_m'] * 100:g} cm radius, {p['mass_kg'] * 1000:g} g) thrown in a vacuum chamber,
# tracked at 100 Hz for {p['duration_s']:g} s (trajectory.csv, {mm(n['sigma_position_m'])} per axis).
# Unknown: where it left the hand and how fast.

scene {truth['scene']} {{
  world {{ timestep: 1 ms  integrator: rk4  medium: vacuum }}

  body ball {{
    shape: sphere(radius: {p['radius_m'] * 100:g} cm)
    mass: {p['mass_kg'] * 1000:g} g
    position ~ normal((0, 0, {round(p['position_m'][2], 1):g}) m, 10 cm)
    velocity ~ normal(({guess[0]}, {guess[1]}, {guess[2]}) m/s, 2 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }}

  observe ball.position from "trajectory.csv" where body == "ball" {{ noise: {mm(n['sigma_position_m'])} }}
}}
"""
    if kind == "pendulum":
        header = f"""# A pendulum (thin rod + {p['bob_mass_kg'] * 1000:g} g bob) hangs from a hinge at (0, 0, 1.2) m and swings
# in the x-z plane after release from rest. Tracked at 100 Hz for {p['duration_s']:g} s: bob centre
# (trajectory.csv, 2 mm) and hinge encoder (joints.csv, 3 mrad). Unknown: L, the release angle."""
        return pendulum_scene(truth["scene"], p, header, f"normal({round(p['length_m'], 1):g} m, 10 cm)",
                              f"normal({round(math.degrees(p['initial_rad']) / 10) * 10:g} deg, 10 deg)")
    if kind == "rail":
        a = math.radians(p["incline_deg"])
        return f"""# A {p['mass_kg'] * 1000:g} g block runs on a straight rail tilted {p['incline_deg']:g} degrees up towards +x
# (air-bearing track: no friction), pushed up it at t = 0. Tracked at 100 Hz for {p['duration_s']:g} s:
# centre (trajectory.csv, 3 mm) and the rail's encoder (joints.csv, in m, 1 mm).
# Unknown: the start along the rail and the push speed.

scene {truth['scene']} {{
  world {{ timestep: 1 ms  integrator: rk4 }}

  body block {{
    shape: box(size: (10, 10, 10) cm)
    mass: {p['mass_kg'] * 1000:g} g
    position: (0, 0, 0.5) m  # the encoder's zero
  }}

  joint rail: slider(world -> block) {{
    axis: ({math.cos(a):.6f}, 0, {math.sin(a):.6f})
    initial ~ normal(0 m, 10 cm)
    initial_velocity ~ uniform(0.5 m/s, 2.5 m/s)
  }}

  observe block.position from "trajectory.csv" where body == "block" {{ noise: 3 mm }}
  observe rail.angle from "joints.csv" where joint == "rail" {{ noise: 1 mm }}
}}
"""
    return f"""# A 0.5 kg cube hangs from a coil spring attached at (0, 0, 1.6) m and runs on a vertical
# guide. Pulled down and released from rest; tracked at 100 Hz for {p['duration_s']:g} s (trajectory.csv, 1 mm).
# Unknown: the spring's stiffness and rest length and how far the block was pulled down.

scene {truth['scene']} {{
  world {{ timestep: 1 ms  integrator: rk4 }}

  body block {{
    shape: box(size: (10, 10, 10) cm)
    mass: 500 g
    position: (0, 0, 1.0) m
  }}

  joint guide: slider(world -> block) {{
    axis: (0, 0, 1)
    initial ~ normal(-7 cm, 3 cm)
    initial_velocity: 0 m/s
  }}

  effect spring on block {{
    stiffness ~ uniform(5 N/m, 200 N/m)
    rest_length ~ uniform(10 cm, 80 cm)
    anchor: (0, 0, 1.6) m
    attachment: (0, 0, 5) cm
  }}

  observe block.position from "trajectory.csv" where body == "block" {{ noise: 1 mm }}
}}
"""


def cases() -> list[dict]:
    return [case_truth(kind, i) for kind in KINDS for i in range(1, PER_KIND + 1)]


def write_case(truth: dict, root=OUT) -> None:
    """Simulate ``truth`` and write its data, naive scene and truth.json under ``root``."""
    out = root / truth["scene"]
    out.mkdir(parents=True, exist_ok=True)
    write_recording(out, truth, *simulate(truth))
    write_scene(out / "naive.phys", naive_scene(truth))


def main() -> None:
    for truth in cases():
        write_case(truth)
        print(truth["scene"])


if __name__ == "__main__":
    main()
