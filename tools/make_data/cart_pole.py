"""Generate examples/cart_pole and examples/hidden-effect/cart_pole_friction (MuJoCo).

A cart on a horizontal rail (slider along x at z = 0.5 m) carries a pole hanging from a hinge
at the cart centre (axis (0, -1, 0): 0 = hanging straight down, positive swings the pole's
lower end towards +x, as for a pendulum). A known
force sequence (controls.csv, 50 Hz, zero-order hold) pushes the cart. The hidden-effect
variant adds Coulomb friction in the rail with physdsl's law F = -T tanh(v / smoothing).
Recorded 3 s at 100 Hz: cart displacement and pole angle (joints.csv).
"""
from __future__ import annotations

import csv
import sys

import mujoco
import numpy as np

from mjgen import EXAMPLES, mjcf, rollout, write_angles, write_truth

CONTROL_RATE_HZ = 50.0


def make_truth(friction: bool) -> dict:
    params = {
        "rail_height_m": 0.5, "cart_size_m": [0.3, 0.2, 0.1], "cart_mass_kg": 1.0,
        "pole_radius_m": 0.015, "pole_length_m": 0.6, "pole_mass_kg": 0.2,
        "pole_initial_rad": 0.3, "duration_s": 3.0,
        "control": "F(t) = 3 sin(2 pi 0.7 t) + 1.5 sin(2 pi 1.9 t + 0.5) N sampled at 50 Hz, zero-order hold",
        "rail_friction_N": 0.8 if friction else 0.0, "rail_friction_smoothing_m_s": 0.01,
    }
    unknowns = {"cart.mass": 1.0, "pole.mass": 0.2, "pole_hinge.initial": 0.3}
    truth = {
        "scene": "cart_pole_friction" if friction else "cart_pole",
        "noise": {"sigma_slider_m": 0.002, "sigma_angle_rad": 0.003, "rate_hz": 100.0, "seed": 203 if friction else 202},
        "simulator": {"engine": f"MuJoCo {mujoco.__version__}", "timestep_s": 1e-4, "integrator": "Euler",
                      "note": "control force and rail friction applied through qfrc_applied before every step"},
        "parameters": params,
    }
    if friction:
        return {"hidden_effect": {"effect": "joint_friction", "target": "cart_slider",
                                  "law": "F = -T tanh(v / 0.01 m/s) along the rail"},
                "parameters": unknowns | {"joint_friction@cart_slider.torque": 0.8},
                "naive_unknowns": sorted(unknowns), "physical_parameters": params} | {
                    k: v for k, v in truth.items() if k != "parameters"}
    return truth | {"unknowns": unknowns}


def physical(truth: dict) -> dict:
    return truth.get("physical_parameters", truth.get("parameters"))


def controls(duration: float) -> tuple[np.ndarray, np.ndarray]:
    """The known push: times (s) and force values (N), held constant between samples."""
    t = np.arange(int(round(duration * CONTROL_RATE_HZ)) + 1) / CONTROL_RATE_HZ
    return t, np.round(3.0 * np.sin(2 * np.pi * 0.7 * t) + 1.5 * np.sin(2 * np.pi * 1.9 * t + 0.5), 4)


def build(truth: dict) -> tuple[mujoco.MjModel, mujoco.MjData]:
    p = physical(truth)
    sx, sy, sz = (s / 2 for s in p["cart_size_m"])
    L = p["pole_length_m"]
    body = f"""
    <body name="cart" pos="0 0 {p['rail_height_m']}">
      <joint name="cart_slider" type="slide" axis="1 0 0"/>
      <geom type="box" size="{sx} {sy} {sz}" mass="{p['cart_mass_kg']}"/>
      <body name="pole" pos="0 0 0">
        <joint name="pole_hinge" type="hinge" axis="0 -1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 {-L}" size="{p['pole_radius_m']}" mass="{p['pole_mass_kg']}"/>
        <site name="pole" pos="0 0 {-L / 2}"/>
      </body>
    </body>"""
    model = mujoco.MjModel.from_xml_string(
        mjcf(body, timestep=truth["simulator"]["timestep_s"], integrator=truth["simulator"]["integrator"]))
    data = mujoco.MjData(model)
    data.qpos[:] = [0.0, p["pole_initial_rad"]]
    return model, data


def simulate(truth: dict) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Noise-free samples: times and joint coordinates {cart_slider: (N,) m, pole_hinge: (N,) rad}."""
    p = physical(truth)
    model, data = build(truth)
    ct, cf = controls(p["duration_s"])
    T, s = p["rail_friction_N"], p["rail_friction_smoothing_m_s"]

    def before_step(d):
        k = int(np.searchsorted(ct, d.time + 1e-9, side="right")) - 1
        d.qfrc_applied[0] = cf[k] - T * np.tanh(d.qvel[0] / s)

    def record(d):
        return {"cart_slider": d.qpos[0].copy(), "pole_hinge": d.qpos[1].copy()}

    return rollout(model, data, p["duration_s"], record, before_step)


def main(friction: bool) -> None:
    truth = make_truth(friction)
    out = EXAMPLES / "hidden-effect" / "cart_pole_friction" if friction else EXAMPLES / "cart_pole"
    out.mkdir(parents=True, exist_ok=True)
    t, q = simulate(truth)
    rng = np.random.default_rng(truth["noise"]["seed"])
    noisy = {"cart_slider": q["cart_slider"] + rng.normal(0, truth["noise"]["sigma_slider_m"], q["cart_slider"].shape),
             "pole_hinge": q["pole_hinge"] + rng.normal(0, truth["noise"]["sigma_angle_rad"], q["pole_hinge"].shape)}
    write_angles(out / "joints.csv", t, noisy)
    ct, cf = controls(physical(truth)["duration_s"])
    with (out / "controls.csv").open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["t", "force"])
        w.writerows([f"{a:.6f}", f"{b:.4f}"] for a, b in zip(ct, cf))
    write_truth(out / "truth.json", truth)


if __name__ == "__main__":
    main(friction="--friction" in sys.argv[1:])
