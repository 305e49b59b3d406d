"""Shared pieces of the diagnosis tests: tiny scenes with one hidden effect, data simulated by
physdsl itself, fits shared within a module.

A case is a scene text with the hidden effect written in (``truth_text``) and the same scene
without it (``naive_text``). Data: the truth scene is compiled against placeholder data at
the measurement times, rolled out at known values, and seeded Gaussian noise is added; the
naive scene is then fitted to those data (MAP + Laplace, the fast backend ``diagnose``
itself refits with). Compiling the physics dominates the cost, so every fit is made once per
module (fixtures) and the suite's persistent XLA cache (tests/conftest.py) lets identical
computations of separately loaded copies of a scene reuse their executables.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import physdsl  # noqa: F401 - float64


def write_csv(path: Path, times, values, name: str) -> Path:
    """``t,body,x,y,z`` rows for (N, 3) values, or ``t,joint,angle`` rows for (N, 1)."""
    values = np.asarray(values)
    if values.shape[1] == 3:
        lines = ["t,body,x,y,z"] + [f"{t:.6f},{name},{a:.10g},{b:.10g},{c:.10g}"
                                     for t, (a, b, c) in zip(times, values)]
    else:
        lines = ["t,joint,angle"] + [f"{t:.6f},{name},{a:.10g}" for t, (a,) in zip(times, values)]
    path.write_text("\n".join(lines) + "\n")
    return path


@dataclass(frozen=True)
class Data:
    """One observation's data file: ``file`` holds ``quantity`` of ``name``."""

    file: str
    name: str  # body or joint
    quantity: str  # "position" | "angle"
    noise: float  # SI standard deviation of the added noise


def load_scene(folder: Path, text: str, name: str = "scene.phys"):
    """Write ``text`` as ``folder/name`` and load it (the data files are already there)."""
    from physdsl.syntax import load

    path = folder / name
    path.write_text(text)
    return load(path)


def fit(model, seed: int = 0):
    """The fast posterior used throughout: MAP from two starts with a Laplace approximation,
    random-walk Metropolis where the Laplace step fails (``fit_with_fallback``, as diagnose's
    own refits: a contact scene's start can end on a kink, e.g. a resting ball's vertical speed)."""
    from physdsl.infer.fit import fit_with_fallback

    return fit_with_fallback(model, "map", chains=2, warmup=200, samples=200, seed=seed,
                             progress=False)


def physical_order(diag) -> list[str]:
    """``effect@target`` of the physical candidates in the order of their score tests."""
    rows = sorted((r for r in diag.ranking if r.kind == "effect"),
                  key=lambda r: (r.log_p, -r.statistic))
    return [f"{r.effect}@{r.target}" for r in rows]


def interval(idata, name: str, q=(0.05, 0.95)) -> tuple[float, float]:
    """Central 90% interval of a scalar unknown's posterior."""
    v = np.asarray(idata.posterior[name].values).ravel()
    return float(np.quantile(v, q[0])), float(np.quantile(v, q[1]))


def run_cli(args, capsys) -> tuple[int, str, str]:
    """Run ``physdsl ARGS`` in-process; (exit code, stdout, stderr)."""
    from physdsl.cli import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


# -- cases: a naive scene, the truth with one hidden effect, and its data -------------------

PROJECTILE = """\
scene throw {
  world {
    timestep: 20 ms
    duration: 2 s
    integrator: rk4
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 12) m/s, 2 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""

PENDULUM = """\
scene swing {
  world {
    timestep: 10 ms
    duration: 2 s
    integrator: rk4
  }
  body bob {
    shape: sphere(radius: 3 cm)
    mass: 200 g
    position: (0, 0, 0.5) m
  }
  joint hinge: hinge(world -> bob) {
    axis: (0, -1, 0)
    anchor: (0, 0, 1) m
    initial ~ normal(40 deg, 10 deg)
    initial_velocity: 0 rad/s
  }
  observe hinge.angle from "joints.csv" where joint == "hinge" { noise: 3 mrad }
}
"""


# A ball dropped on a floor (bounces: restitution); semi-implicit Euler for contact.
BOUNCE = """\
scene bounce {
  world {
    timestep: 5 ms
    duration: 1.2 s
  }
  param h0 ~ normal(0.8 m, 5 cm)
  ground floor { normal: (0, 0, 1)  point: (0, 0, 0) m }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 60 g
    position: (0, 0, h0)
    velocity: (0, 0, 0) m/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 3 mm }
}
"""

# A block pushed along a floor (frictionless in the naive scene).
SLIDE = """\
scene slide {
  world {
    timestep: 5 ms
    duration: 0.8 s
  }
  ground floor { normal: (0, 0, 1)  point: (0, 0, 0) m }
  body block {
    shape: box(size: (10, 10, 10) cm)
    mass: 500 g
    position: (0, 0, 5) cm
    velocity ~ normal((2, 0, 0) m/s, 0.5 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  observe block.position from "data.csv" where body == "block" { noise: 2 mm }
}
"""

# A ball rolling on a floor with friction (it rolls without slipping).
ROLL = """\
scene roll {
  world {
    timestep: 5 ms
    duration: 1.5 s
  }
  ground floor { normal: (0, 0, 1)  point: (0, 0, 0) m }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 5) cm
    velocity ~ normal((1.5, 0, 0) m/s, 0.3 m/s)
    angular_velocity: (0, 30, 0) rad/s
  }
  contact floor, ball { friction: 0.5 }
  observe ball.position from "data.csv" where body == "ball" { noise: 2 mm }
}
"""

# A block on a vertical slider hanging from a spring (undamped in the naive scene).
SPRING = """\
scene bob {
  world {
    timestep: 10 ms
    duration: 3 s
    integrator: rk4
  }
  body block {
    shape: box(size: (10, 10, 10) cm)
    mass: 500 g
    position: (0, 0, 1) m
  }
  joint guide: slider(world -> block) {
    axis: (0, 0, 1)
    initial ~ normal(-7 cm, 3 cm)
    initial_velocity: 0 m/s
  }
  effect spring on block {
    stiffness: 40 N/m
    rest_length: 0.4 m
    anchor: (0, 0, 1.6) m
    attachment: (0, 0, 5) cm
  }
  observe block.position from "data.csv" where body == "block" { noise: 1 mm }
}
"""


@dataclass(frozen=True)
class Case:
    """A scene without the hidden effect and the values the data are simulated at.

    The truth scene is the naive one with ``effect`` on ``target`` added by ``with_effect``
    (its strength an unknown with the library prior): the very scene the refit uses, so the
    data are exactly what the corrected model can express, and its rollout compiles once.
    """

    naive: str
    effect: str
    target: tuple[str, ...]
    strength: float | tuple  # SI value of the hidden effect's strength parameter
    truth: dict  # values of the naive scene's unknowns
    times: tuple[float, ...]
    data: tuple[Data, ...]
    seed: int = 1

    @property
    def key(self) -> str:
        return f"{self.effect}@{','.join(self.target)}"


def _throw_times():
    return tuple(np.linspace(0.0, 2.0, 41))


def _swing_times():
    return tuple(np.linspace(0.0, 2.0, 101))


BALL = (Data("data.csv", "ball", "position", 0.005),)
HINGE = (Data("joints.csv", "hinge", "angle", 0.003),)
THROW = {"ball.velocity": (3.2, 0.3, 12.1)}

CASES = {
    "quadratic_drag": Case(PROJECTILE, "quadratic_drag", ("ball",), 4e-4, THROW, _throw_times(), BALL),
    "linear_drag": Case(PROJECTILE, "linear_drag", ("ball",), 4e-3, THROW, _throw_times(), BALL),
    "wind": Case(PROJECTILE, "wind", ("ball",), (0.0, 1.0, 0.0), THROW, _throw_times(), BALL),
    "joint_damping": Case(PENDULUM, "joint_damping", ("hinge",), 3e-3, {"hinge.initial": 0.7},
                          _swing_times(), HINGE, seed=2),
    "joint_friction": Case(PENDULUM, "joint_friction", ("hinge",), 3e-3, {"hinge.initial": 0.7},
                           _swing_times(), HINGE, seed=3),
    # a torsion spring 5% of gravity's stiffness (m g L = 0.98 N m/rad): the swing is faster
    "joint_spring": Case(PENDULUM, "joint_spring", ("hinge",), 0.05, {"hinge.initial": 0.7},
                         _swing_times(), HINGE, seed=8),
    # seed 4 drew noise that puts the truth 2.4 sd from the data's own best estimate
    # ((J^T J)^-1 J^T eps at the truth), so no correct 90% interval could hold it
    "restitution": Case(BOUNCE, "restitution", ("floor", "ball"), 0.8, {"h0": 0.8},
                        tuple(np.linspace(0.0, 1.2, 121)), (Data("data.csv", "ball", "position", 0.003),), seed=3),
    "contact_friction": Case(SLIDE, "contact_friction", ("floor", "block"), 0.2,
                             {"block.velocity": (2.1, 0.0, 0.0)}, tuple(np.linspace(0.0, 0.8, 81)),
                             (Data("data.csv", "block", "position", 0.002),), seed=5),
    "rolling_resistance": Case(ROLL, "rolling_resistance", ("floor", "ball"), 2e-3,
                               {"ball.velocity": (1.5, 0.0, 0.0)}, tuple(np.linspace(0.0, 1.5, 76)),
                               (Data("data.csv", "ball", "position", 0.002),), seed=6),
    "damper": Case(SPRING, "damper", ("block",), 0.08, {"guide.initial": -0.07},
                   tuple(np.linspace(0.0, 3.0, 151)), (Data("data.csv", "block", "position", 0.001),),
                   seed=7),
}

# Candidates that act exactly like the true one in a case (same column of the score test):
# linear drag on a pendulum bob or on a slider's block is joint damping, and along the spring
# line a damper is both.
EQUIVALENT = {
    "joint_damping": {"linear_drag@bob"},
    "damper": {"joint_damping@guide", "linear_drag@block"},
}


def truth_scene(folder: Path, case: Case):
    """The naive scene of ``case`` with the hidden effect added (strength unknown), loaded."""
    from physdsl.diagnose.edits import with_effect

    naive = load_scene(folder, case.naive, "naive.phys")
    return load_scene(folder, with_effect(naive, candidate(naive, case)), "truth.phys")


def candidate(naive, case: Case):
    """The diagnosis candidate for ``case``'s hidden effect (a damper gets the spring's anchors)."""
    from physdsl.diagnose.candidates import physics_candidates

    return next(c for c in physics_candidates(naive) if c.key == case.key)


def make_case(folder: Path, case: Case, extra: dict | None = None, **faults):
    """Write ``case``'s data into ``folder``; returns (naive Scene, truth Scene, truth values).

    ``extra`` adds or overrides truth values (e.g. a vector wind velocity); ``faults`` go to
    ``simulate_data`` (sensor offset / delay)."""
    from physdsl.compile import Model

    folder.mkdir(parents=True, exist_ok=True)
    for d in case.data:  # placeholders so the scenes load
        write_csv(folder / d.file, case.times, np.zeros((len(case.times),
                  3 if d.quantity == "position" else 1)), d.name)
    truth = truth_scene(folder, case)
    values = {k: np.asarray(v, float) for k, v in case.truth.items()}
    values[f"{case.key}.{truth.effect_library[case.effect].strength.name}"] = np.asarray(case.strength)
    values.update({k: np.asarray(v, float) for k, v in (extra or {}).items()})
    simulate_data(folder, Model(truth), values, case, **faults)
    return load_scene(folder, case.naive, "naive.phys"), values


def simulate_data(folder: Path, model, values: dict, case: Case, offset=None, delay=0.0) -> None:
    """Noisy data of ``model`` at ``values`` into ``case``'s files, seeded Gaussian noise.

    ``offset`` (observation name -> (D,) constant) and ``delay`` (seconds: the sensor reports
    the state at ``t - delay``) simulate sensor faults."""
    times = np.asarray(case.times)
    pred = {k: np.asarray(v) for k, v in model.predict(values).items()}
    rng = np.random.default_rng(case.seed)
    for d in case.data:
        key = f"{d.name}.{d.quantity}"
        clean = pred[key]
        if delay:
            clean = np.stack([np.interp(times - delay, times, clean[:, a]) for a in range(clean.shape[1])],
                             axis=1)
        noisy = clean + rng.normal(0.0, d.noise, clean.shape)
        if offset and key in offset:
            noisy = noisy + np.asarray(offset[key])
        write_csv(folder / d.file, times, noisy, d.name)


@dataclass
class Fitted:
    """A case fitted without its hidden effect: the Model, posterior, check report, diagnosis."""

    folder: Path
    case: Case
    values: dict
    model: object
    idata: object
    report: object
    diagnosis: object


def fit_case(folder: Path, case: Case, confirm_top: int = 0, extra=None, **faults) -> Fitted:
    """Simulate, fit the naive scene, check it and diagnose it (score tests; refits if asked)."""
    from physdsl.compile import Model
    from physdsl.diagnose.rank import diagnose
    from physdsl.diagnose.workflow import check_model

    naive, values = make_case(folder, case, extra, **faults)
    model = Model(naive)
    idata = fit(model)
    report = check_model(model, idata)
    diag = diagnose(model, idata, confirm_top=confirm_top, check_report=report)
    return Fitted(folder, case, values, model, idata, report, diag)


_FITTED: dict = {}


@pytest.fixture(scope="session")
def fitted(tmp_path_factory):
    """``fitted(name, confirm_top=0)``: ``CASES[name]`` fitted and diagnosed once per session."""
    def get(name: str, confirm_top: int = 0) -> Fitted:
        if (name, confirm_top) not in _FITTED:
            _FITTED[name, confirm_top] = fit_case(tmp_path_factory.mktemp(name), CASES[name],
                                                  confirm_top)
        return _FITTED[name, confirm_top]
    return get


@pytest.fixture
def cli(capsys):
    return lambda *args: run_cli(args, capsys)
