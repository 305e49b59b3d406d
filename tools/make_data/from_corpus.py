"""Copy dev-corpus cases into examples/ and write their truth.json in physdsl's names.

Usage: python tools/make_data/from_corpus.py CORPUS_DEV_DIR
The corpus cases were made with MuJoCo (their truth.json keeps the MJCF); this script only
copies the measurement files and maps each case's true values onto the unknowns of the
example's .phys file (``ball.velocity``, ``joint_damping@hinge.coefficient``, ...).
"""
from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def _thrown(p):
    return {"ball.position": p["initial_position_m"], "ball.velocity": p["initial_velocity_m_s"]}


def _bouncing(p):
    return {"h0": p["initial_height_of_centre_m"]}


def _sliding(p):
    pos, n, v = p["initial_position_m"], (-0.25882, 0.0, 0.96593), p["initial_speed_up_slope_m_s"]
    up = (0.96593, 0.0, 0.25882)
    s0 = sum((pos[i] - 0.05 * n[i]) * up[i] for i in range(3))
    return {"s0": round(s0, 4), "v0": v}


def _pendulum(p):
    return {"L": p["length_pivot_to_bob_centre_m"], "hinge.initial": math.radians(p["initial_angle_deg"])}


def _spring(p):
    return {
        "spring@block.stiffness": p["spring_stiffness_N_m"],
        "spring@block.rest_length": p["spring_rest_length_m"],
        "guide.initial": round(p["initial_height_of_centre_m"] - 1.0, 12),
    }


def _billiards(p):
    x0, v0 = p["cue_initial_position_m"], p["cue_initial_velocity_m_s"]
    return {"x0": x0[0], "y0": x0[1], "vx": v0[0], "vy": v0[1], "object.mass": p["object_mass_kg"]}


# example name -> (corpus case, naive unknowns, hidden effect (name, target, unknown, value from truth))
CASES = {
    "thrown_ball": ("thrown_ball_01", _thrown,
                    ("quadratic_drag", "ball", lambda t: t["parameters"]["drag_constant_c_kg_m"])),
    "bouncing_ball": ("bouncing_ball_01", _bouncing,
                      ("restitution", "floor,ball",
                       lambda t: t["effective_values_measured_on_the_simulation"]["restitution_mean"])),
    "sliding_block": ("sliding_block_01", _sliding,
                      ("contact_friction", "ramp,block", lambda t: t["parameters"]["friction_coefficient_mu"])),
    "pendulum": ("pendulum_01", _pendulum,
                 ("joint_damping", "hinge", lambda t: t["parameters"]["hinge_damping_N_m_s_per_rad"])),
    "spring_mass": ("spring_mass_01", _spring,
                    ("damper", "block", lambda t: t["parameters"]["spring_damping_N_s_m"])),
    # two hidden effects, material-level: one cloth coefficient on both ball-table pairs
    "billiards": ("billiards_01", _billiards,
                  [("contact_friction", "table,*", lambda t: t["parameters"]["table_sliding_friction_mu"]),
                   ("rolling_resistance", "table,*", lambda t: t["parameters"]["table_rolling_resistance_m"])]),
}
STRENGTH = {"quadratic_drag": "coefficient", "restitution": "coefficient", "contact_friction": "coefficient",
            "joint_damping": "coefficient", "damper": "coefficient", "rolling_resistance": "coefficient"}


def _strength_key(eff: str, target: str) -> str:
    """The unknown holding the effect's strength once diagnose adds it: ``EFFECT@TARGET.coefficient``,
    or for a material-level target ``FIXED,*`` the shared param ``FIXED_EFFECT``."""
    fixed, _, rest = target.partition(",")
    return f"{fixed}_{eff}" if rest == "*" else f"{eff}@{target}.{STRENGTH[eff]}"


def _noise(truth: dict) -> dict:
    m = truth["measurement"]
    return {k: v for k, v in m.items() if k.startswith("sigma_")} | {"rate_hz": m["rate_hz"], "seed": m["noise_seed"]}


def _copy_data(src: Path, dst: Path) -> None:
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(src.glob("*.csv")):
        shutil.copyfile(f, dst / f.name)


def _write(path: Path, obj: dict) -> None:
    path.write_text(json.dumps(obj, indent=2) + "\n")


def main(corpus: Path) -> None:
    for name, (case, naive, hidden) in CASES.items():
        truth = json.loads((corpus / case / "truth.json").read_text())
        src = f"physdsl dev corpus case {case} ({truth['simulator']['engine']})"
        unknowns = naive(truth["parameters"])
        full = dict(unknowns)
        if name == "thrown_ball":  # the full example infers Cd, not c
            full["Cd"] = truth["parameters"]["drag_coefficient_Cd"]
        elif hidden is not None and not isinstance(hidden, list):
            eff, target, value = hidden
            full[f"{eff}@{target}.{STRENGTH[eff]}"] = value(truth)
        common = {"source": src, "noise": _noise(truth), "physical_parameters": truth["parameters"],
                  "simulator": truth["simulator"]}
        _copy_data(corpus / case, EXAMPLES / name)
        _write(EXAMPLES / name / "truth.json", {"scene": name, "unknowns": full} | common)
        if hidden is None:
            continue
        hidden = hidden if isinstance(hidden, list) else [hidden]
        _copy_data(corpus / case, EXAMPLES / "hidden-effect" / name)
        params = dict(unknowns) | {_strength_key(eff, target): value(truth) for eff, target, value in hidden}
        effects = [{"effect": eff, "target": target} for eff, target, _ in hidden]
        head = effects[0] | {"law": truth["hidden_effect"]["law"]}
        also = {"also_hidden": effects[1:]} if len(effects) > 1 else {}
        _write(EXAMPLES / "hidden-effect" / name / "truth.json",
               {"hidden_effect": head} | also | {"parameters": params, "naive_unknowns": sorted(unknowns)}
               | common)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(Path(sys.argv[1]))
