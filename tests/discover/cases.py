"""The three hidden laws of issue 19, simulated by physdsl itself: the truth scene is the naive
scene plus a ``distilled_law`` holding the true law, rolled out at known values; seeded
Gaussian noise is added. Shared by tests/discover and benchmarks/discovery.py."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

BALL = """scene {name} {{
  world {{ timestep: 2 ms  integrator: rk4 }}
  body ball {{
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position ~ normal({p0} m, 5 cm)
    velocity ~ normal({v0} m/s, 2 m/s)
  }}
  observe ball.position from "data.csv" where body == "ball" {{ noise: {noise} mm }}
}}
"""

PENDULUM = """scene {name} {{
  world {{ timestep: 2 ms  integrator: rk4 }}
  body bob {{ shape: sphere(radius: 5 cm)  mass: 1 kg  position: (0, 0, -1) m }}
  joint hinge: hinge(world -> bob) {{
    anchor: (0, 0, 0) m
    axis: (0, 1, 0)
    initial ~ normal({q0} rad, 0.2 rad)
    initial_velocity: 0 rad/s
  }}
  observe hinge.angle from "data.csv" where joint == "hinge" {{ noise: {noise} mrad }}
}}
"""


@dataclass(frozen=True)
class LawCase:
    """A scene whose true physics adds one law outside the library."""

    name: str
    template: str
    fields: dict  # template fields (start values, noise in mm or mrad)
    target: str
    kind: str  # body | hinge
    law: dict  # true law: term -> coefficient (SI)
    truth: dict  # true values of the naive scene's unknowns
    duration: float
    samples: int
    noise: float  # SI
    center: tuple = (0.0, 0.0, 0.0)
    seed: int = 0
    extra: dict = field(default_factory=dict)

    def naive(self) -> str:
        return self.template.format(name=self.name, **self.fields)

    def law_text(self, values: dict | None = None) -> str:
        """The truth scene: naive + the law (its coefficients given)."""
        from physdsl.discover.phys_text import law_scene_text

        return law_scene_text(self.naive(), self.target, self.kind, self.law, self.center,
                              values=self.law if values is None else values)


CASES = {
    # F = -k sqrt|v| v on a ball thrown up at 21 m/s: speeds 0-21 m/s
    "sqrt_drag": LawCase("sqrt_drag", BALL, {"p0": "(0, 0, 0)", "v0": "(4, 0, 20)", "noise": 3},
                         "ball", "body", {"v_sqrt_speed": -0.012},
                         {"ball.position": (0.0, 0.0, 0.0), "ball.velocity": (4.0, 0.0, 20.0)},
                         3.0, 61, 0.003, seed=1),
    # F = -G d / |d|^3 towards a point under the flight (a magnet under the table)
    # passing 0.22 m above the point at (0, 0, 0.3), 1 m from it at the ends
    "inverse_square": LawCase("inverse_square", BALL,
                              {"p0": "(-1, 0, 0.3)", "v0": "(2.5, 0, 2.5)", "noise": 2},
                              "ball", "body", {"d_inv2": -0.03},
                              {"ball.position": (-1.0, 0.0, 0.3), "ball.velocity": (2.5, 0.0, 2.5)},
                              0.8, 41, 0.002, center=(0.0, 0.0, 0.3), seed=2),
    # tau = -k3 q^3 in the hinge of a 1 m pendulum swinging to 1.2 rad
    "cubic_spring": LawCase("cubic_spring", PENDULUM, {"q0": "1.2", "noise": 3},
                            "hinge", "hinge", {"q3": -4.0}, {"hinge.initial": 1.2},
                            3.0, 61, 0.003, seed=3),
}


def write_csv(path: Path, times, values, name: str, kind: str) -> None:
    values = np.asarray(values)
    if kind == "body":
        rows = ["t,body,x,y,z"] + [f"{t:.6f},{name},{a:.10g},{b:.10g},{c:.10g}"
                                   for t, (a, b, c) in zip(times, values)]
    else:
        rows = ["t,joint,angle"] + [f"{t:.6f},{name},{a:.10g}" for t, (a,) in zip(times, values)]
    path.write_text("\n".join(rows) + "\n")


def make(case: LawCase, folder: Path, law: bool = True, seed: int | None = None) -> Path:
    """Write the case's data (with the hidden law, or without: ``law=False``) and its naive
    scene into ``folder``; returns the naive scene's path."""
    from physdsl.compile import Model
    from physdsl.syntax import loads

    folder.mkdir(parents=True, exist_ok=True)
    times = np.linspace(0.0, case.duration, case.samples)
    write_csv(folder / "data.csv", times, np.zeros((len(times), 3 if case.kind == "body" else 1)),
              case.target, case.kind)
    text = case.law_text() if law else case.naive()
    model = Model(loads(text, filename=str(folder / "truth.phys"), base_dir=folder))
    values = {k: np.asarray(v, float) for k, v in case.truth.items()}
    pred = next(iter(model.predict(values).values()))
    rng = np.random.default_rng(case.seed if seed is None else seed)
    noisy = np.asarray(pred) + rng.normal(0.0, case.noise, np.shape(pred))
    write_csv(folder / "data.csv", times, noisy, case.target, case.kind)
    path = folder / "naive.phys"
    path.write_text(case.naive())
    return path
