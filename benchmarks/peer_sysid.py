"""Peer benchmark: identifying a correct model, ``physdsl infer --backend map`` vs ``mujoco.sysid``.

Side by side in one run, per case, on the same recording and the same unknowns:

- **physdsl**: the correct ``.phys`` scene (``examples/hidden-effect/CASE/naive.phys`` with its
  hidden effect added as ``refine`` adds it, ``hidden_cases``; the cart-pole's own scene),
  fitted by the whole command ``physdsl infer SCENE -o RUN --backend map`` (default settings,
  a fresh compile cache: the first run a user makes).
- **mujoco.sysid** (MuJoCo's Gauss-Newton/Levenberg-Marquardt toolbox, ``mujoco.minimize``
  with finite-difference Jacobians): the generating MJCF (``truth.json``) with sensors at the
  tracked points (``framepos`` of the tracked site, ``jointpos`` of an encoder), the same
  unknowns applied to the ``MjSpec`` and to the starting state (a custom rollout builds each
  candidate's initial ``qpos``/``qvel``), residuals divided by the stated noise (not sysid's
  default per-column scaling by the data's norm), its 90% intervals from
  ``sysid.calculate_intervals`` at the optimum. ``sysid_rollout`` stamps each sensor row one
  step late (``mj_step`` computes the sensors on the state it starts from, the row carries the
  time of the state it ends at): ``on_time`` moves the stamps back by one timestep, so the
  first row is the recording's first sample. Its whole script runs in its own process.

Both start from the prior's centre (normal: mean; uniform: midpoint; half-normal: median);
physdsl adds its own multistart. Cases: ``thrown_ball``, ``pendulum``, ``spring_mass`` (dev
corpus cases whose ``truth.json`` holds the generating MJCF) and ``cart_pole`` (made here:
MuJoCo, RK4 at 1 ms, a known 50 Hz force on the cart, 8 s of both encoders at 100 Hz).

Prints per case (``name: value`` lines): ``physdsl_over_sysid_wall.CASE`` (whole command over
whole script) and ``..._cpu.CASE``; for TOOL in physdsl, sysid (and physdsl_warm with
``--warm``): ``TOOL_wall_s.CASE``, ``TOOL_cpu_s.CASE``, ``TOOL_rms_sigma.CASE`` (residual RMS
in noise units at its fit: equal accuracy), ``TOOL_fit.CASE.UNKNOWN: value [5%, 95%] truth
t``; ``physdsl_stage_wall_s.CASE.STAGE`` (its progress lines); the load average; then a table.
CPU seconds are those of the child process (the quiet-machine time on a shared machine).

Run: .venv/bin/python benchmarks/peer_sysid.py [--case thrown_ball ...] [--timeout 1500]
(needs ``pip install -e '.[benchmark]'`` for ``mujoco.sysid``'s own imports)
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
HIDDEN = ROOT / "examples" / "hidden-effect"
CART_POLE_SCENE = ROOT / "examples" / "cart_pole" / "cart_pole.phys"
HALF_NORMAL_MEDIAN = 0.6744897501960817  # the median of half_normal(s) is this times s


@dataclass(frozen=True)
class Sensor:
    """A tracked point or encoder: an MJCF sensor and the CSV rows it is compared with."""
    name: str
    kind: str          # "framepos" (a site's world position) or "jointpos" (an encoder)
    target: str        # the site or the joint
    csv: str           # file in the case folder
    key: tuple         # (column, value) selecting the rows
    columns: tuple     # value columns, in the sensor's order
    sigma: float       # the scene's stated noise


@dataclass(frozen=True)
class Unknown:
    """One scalar unknown: physdsl's label, where sysid puts it, its start and sysid's box."""
    label: str
    start: float
    lo: float
    hi: float
    qpos: int | None = None    # index into the starting qpos (value + offset)
    qvel: int | None = None    # index into the starting qvel
    offset: float = 0.0
    spec: str = ""             # name of a spec setter in SETTERS


@dataclass(frozen=True)
class Case:
    name: str
    sensors: tuple
    unknowns: tuple


def _drag_coefficient(spec, c: float) -> None:
    """Quadratic drag c (F = -c|v|v) as the ball's blunt-drag fluidcoef: c / (rho pi r^2)."""
    geom = spec.geom("ball")
    coef = np.array(geom.fluid_coefs, dtype=float)
    coef[0] = c / (spec.option.density * math.pi * geom.size[0] ** 2)
    geom.fluid_coefs = coef


def _pendulum_length(spec, L: float) -> None:
    """Hinge axis to bob centre L: the rod reaches the top of the bob (radius 4 cm)."""
    r = spec.geom("bob").size[0]
    spec.geom("rod").fromto = [0, 0, 0, 0, 0, -(L - r)]
    spec.geom("bob").pos = [0, 0, -L]
    spec.site("bob").pos = [0, 0, -L]


def _set(kind: str, name: str, attr: str, fill: bool = False):
    """A setter of ``spec.KIND(NAME).ATTR``: a scalar, the first coefficient of a polynomial
    (MuJoCo 4's damping and stiffness: (linear, quadratic, cubic)), or every entry with
    ``fill`` (a tendon's springlength (lo, hi): both ends of its dead band)."""
    def setter(spec, v: float) -> None:
        obj = getattr(spec, kind)(name)
        old = getattr(obj, attr)
        if np.ndim(old):
            new = np.full(np.shape(old), v) if fill else np.array(old, dtype=float)
            new[0] = v
            setattr(obj, attr, new)
        else:
            setattr(obj, attr, v)
    return setter


SETTERS = {
    "drag": _drag_coefficient,
    "pendulum_length": _pendulum_length,
    "hinge_damping": _set("joint", "hinge", "damping"),
    "spring_stiffness": _set("tendon", "spring", "stiffness"),
    "spring_length": _set("tendon", "spring", "springlength", fill=True),
    "spring_damping": _set("tendon", "spring", "damping"),
    "cart_mass": _set("geom", "cart", "mass"),
    "pole_mass": _set("geom", "pole", "mass"),
}

_XYZ = ("x", "y", "z")
CASES = {
    "thrown_ball": Case("thrown_ball", (
        Sensor("ball", "framepos", "ball", "trajectory.csv", ("body", "ball"), _XYZ, 0.01),), (
        *(Unknown(f"ball.position[{i}]", s, s - 1.0, s + 1.0, qpos=i)
          for i, s in enumerate((0.0, 0.0, 1.8))),
        *(Unknown(f"ball.velocity[{i}]", s, s - 20.0, s + 20.0, qvel=i)
          for i, s in enumerate((6.0, 0.0, 6.0))),
        Unknown("quadratic_drag@ball.coefficient", HALF_NORMAL_MEDIAN * 0.022884, 0.0, 1.0,
                spec="drag"))),
    "pendulum": Case("pendulum", (
        Sensor("bob", "framepos", "bob", "trajectory.csv", ("body", "bob"), _XYZ, 0.002),
        Sensor("hinge", "jointpos", "hinge", "joints.csv", ("joint", "hinge"), ("angle",), 0.003)), (
        Unknown("L", 0.6, 0.3, 0.9, spec="pendulum_length"),
        Unknown("hinge.initial", math.radians(40), -math.pi, math.pi, qpos=0),
        Unknown("joint_damping@hinge.coefficient", HALF_NORMAL_MEDIAN * 0.263797, 0.0, 5.0,
                spec="hinge_damping"))),
    "spring_mass": Case("spring_mass", (
        Sensor("block", "framepos", "block", "trajectory.csv", ("body", "block"), _XYZ, 0.001),), (
        Unknown("spring@block.stiffness", 102.5, 5.0, 200.0, spec="spring_stiffness"),
        Unknown("spring@block.rest_length", 0.45, 0.1, 0.8, spec="spring_length"),
        # the scene's slider displacement is from (0, 0, 1) m; the MJCF's qpos is the height
        Unknown("guide.initial", -0.07, -0.5, 0.5, qpos=0, offset=1.0),
        Unknown("damper@block.coefficient", HALF_NORMAL_MEDIAN * 1.0, 0.0, 10.0,
                spec="spring_damping"))),
    "cart_pole": Case("cart_pole", (
        Sensor("cart_slider", "jointpos", "cart_slider", "joints.csv", ("joint", "cart_slider"),
               ("angle",), 0.002),
        Sensor("pole_hinge", "jointpos", "pole_hinge", "joints.csv", ("joint", "pole_hinge"),
               ("angle",), 0.003)), (
        Unknown("cart.mass", 1.6, 0.2, 3.0, spec="cart_mass"),
        Unknown("pole.mass", 0.525, 0.05, 1.0, spec="pole_mass"),
        Unknown("pole_hinge.initial", 0.0, -math.pi, math.pi, qpos=1))),
}

# The articulated case made here: examples/cart_pole's scene as MJCF (the pole's capsule
# length is its cylinder, caps included in its inertia, as in physdsl), driven by a known force.
CART_POLE_MJCF = """<mujoco model="cart_pole">
  <option timestep="0.001" integrator="RK4" gravity="0 0 -9.81"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="cart" pos="0 0 0.5">
      <joint name="cart_slider" type="slide" axis="1 0 0"/>
      <geom name="cart" type="box" size="0.15 0.1 0.05" mass="1.0"/>
      <body name="pole">
        <joint name="pole_hinge" type="hinge" axis="0 -1 0"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 -0.6" size="0.015" mass="0.2"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="cart_slider" gear="1"/></actuator>
</mujoco>
"""
CART_POLE_TRUTH = {"cart.mass": 1.0, "pole.mass": 0.2, "pole_hinge.initial": 0.3}
CART_POLE_SECONDS, CART_POLE_RATE_HZ, CART_POLE_CONTROL_HZ, CART_POLE_SEED = 8.0, 100.0, 50.0, 7


def cart_pole_force(t: np.ndarray) -> np.ndarray:
    """The known push (N): two tones off the pole's 0.8 Hz swing (examples/cart_pole's 0.7 Hz
    tone pumps the pole over the top within 8 s: a chaotic record no start-to-end fit follows),
    so the pole swings within 0.8 rad and the cart within 1.8 m."""
    return 2.0 * np.cos(2 * np.pi * 0.3 * t) + 1.5 * np.sin(2 * np.pi * 1.9 * t + 0.5)


# ------------------------------------------------------------------ the cases' files

def prepare(name: str, folder: Path) -> tuple[str, dict]:
    """Write the case's scene and data into ``folder``; return (MJCF text, truth by label)."""
    if name == "cart_pole":
        return CART_POLE_MJCF, _make_cart_pole(folder)
    from hidden_cases import scene_text

    src = HIDDEN / name
    for f in src.glob("*.csv"):
        shutil.copy(f, folder / f.name)
    (folder / "scene.phys").write_text(scene_text(src))
    truth = json.loads((src / "truth.json").read_text())
    labels = {}
    for key, value in truth["parameters"].items():
        flat = np.ravel(np.asarray(value, dtype=float))
        for i, v in enumerate(flat):
            labels[key if flat.size == 1 else f"{key}[{i}]"] = float(v)
    return truth["simulator"]["mjcf_with_hidden_effect"], labels


def _make_cart_pole(folder: Path) -> dict:
    """Simulate the cart-pole at its true values with a zero-order-held force; write
    controls.csv, joints.csv (noisy encoders) and scene.phys into ``folder``."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(CART_POLE_MJCF)
    data = mujoco.MjData(model)
    data.qpos[1] = CART_POLE_TRUTH["pole_hinge.initial"]
    dt = model.opt.timestep
    nstep = round(CART_POLE_SECONDS / dt)
    every = round(1.0 / (CART_POLE_RATE_HZ * dt))
    t_ctrl = np.arange(round(CART_POLE_SECONDS * CART_POLE_CONTROL_HZ) + 1) / CART_POLE_CONTROL_HZ
    force = np.round(cart_pole_force(t_ctrl), 4)
    rows = []
    for k in range(nstep + 1):
        if k % every == 0:
            rows.append((k * dt, data.qpos[0], data.qpos[1]))
        data.ctrl[0] = force[min(int(k * dt * CART_POLE_CONTROL_HZ + 1e-9), len(force) - 1)]
        mujoco.mj_step(model, data)
    rng = np.random.default_rng(CART_POLE_SEED)
    with open(folder / "controls.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "force"])
        w.writerows([f"{t:.6f}", f"{f:.4f}"] for t, f in zip(t_ctrl, force))
    sig = {s.target: s.sigma for s in CASES["cart_pole"].sensors}
    with open(folder / "joints.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "joint", "angle"])
        for t, x, a in rows:
            w.writerow([f"{t:.6f}", "cart_slider", f"{x + rng.normal(0, sig['cart_slider']):.6f}"])
            w.writerow([f"{t:.6f}", "pole_hinge", f"{a + rng.normal(0, sig['pole_hinge']):.6f}"])
    shutil.copy(CART_POLE_SCENE, folder / "scene.phys")
    return dict(CART_POLE_TRUTH)


# ------------------------------------------------------------------ the mujoco.sysid side

def with_sensors(mjcf: str, case: Case):
    """The MJCF's spec with one sensor per tracked point or encoder (named as the sensor)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(mjcf)
    for s in case.sensors:
        if s.kind == "framepos":
            spec.add_sensor(name=s.name, type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                            objtype=mujoco.mjtObj.mjOBJ_SITE, objname=s.target)
        else:
            spec.add_sensor(name=s.name, type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=s.target)
    return spec


def measured(case: Case, folder: Path, model, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(step index per sample, data (n, nsensordata) with NaN where a sensor has no sample,
    noise per column) from the case's CSV files."""
    import mujoco

    by_step: dict[int, dict[int, float]] = {}
    sigma = np.ones(model.nsensordata)
    for s in case.sensors:
        adr = model.sensor_adr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, s.name)]
        sigma[adr:adr + len(s.columns)] = s.sigma
        with open(folder / s.csv, newline="") as fh:
            for row in csv.DictReader(fh):
                if row[s.key[0]] != s.key[1]:
                    continue
                step = round(float(row["t"]) / dt)
                if abs(step * dt - float(row["t"])) > 1e-5:
                    raise ValueError(f"{s.csv}: t = {row['t']} is not on the {dt} s step grid")
                cols = by_step.setdefault(step, {})
                for j, c in enumerate(s.columns):
                    cols[adr + j] = float(row[c])
    steps = np.array(sorted(by_step))
    data = np.full((len(steps), model.nsensordata), np.nan)
    for i, k in enumerate(steps):
        for j, v in by_step[k].items():
            data[i, j] = v
    return steps, data, sigma


def on_time(traj):
    """``traj`` with its sensor rows stamped at the state they were computed from: one
    timestep earlier than ``sysid_rollout`` stamps them (row k holds the sensors of the state
    at k dt, stamped (k+1) dt, the time of the state after the step)."""
    from mujoco.sysid import TimeSeries

    s = traj.sensordata
    return traj.replace(sensordata=TimeSeries(s.times - traj.model.opt.timestep, s.data,
                                              s.signal_mapping))


def start_state(model, values: dict, case: Case) -> np.ndarray:
    """The full-physics initial state with the case's starting-state unknowns at ``values``."""
    from mujoco import sysid

    qpos, qvel = np.array(model.qpos0, dtype=float), np.zeros(model.nv)
    for u in case.unknowns:
        if u.qpos is not None:
            qpos[u.qpos] = values[u.label] + u.offset
        elif u.qvel is not None:
            qvel[u.qvel] = values[u.label]
    return sysid.create_initial_state(model, qpos, qvel)


def sysid_problem(name: str, mjcf: str, folder: Path):
    """(ParameterDict at the starts, residual function) of the case for ``sysid.optimize``:
    the spec with its sensors, the recording, the starting state built per candidate by a
    custom rollout whose sensor rows are stamped on time, residuals in noise units."""
    from mujoco import sysid

    case = CASES[name]
    spec = with_sensors(mjcf, case)
    model = spec.compile()
    dt = model.opt.timestep
    steps, data, sigma = measured(case, folder, model, dt)
    nstep = int(steps[-1]) + 1  # rows 0 .. last sample, after on_time
    ctrl = np.zeros((nstep + 1, model.nu))  # sysid drops the last control row
    if model.nu:
        ctrl[:, 0] = _held(folder / "controls.csv", np.arange(nstep + 1) * dt)
    mapping = sysid.TimeSeries.compute_all_sensor_mapping(model)
    seq = sysid.ModelSequences(
        name, spec, "recording", start_state(model, {u.label: u.start for u in case.unknowns}, case),
        sysid.TimeSeries(np.arange(nstep + 1) * dt, ctrl),
        sysid.TimeSeries(steps * dt, data, mapping))
    params = sysid.ParameterDict()
    for u in case.unknowns:
        setter = SETTERS.get(u.spec)
        params.add(sysid.Parameter(u.label, u.start, u.lo, u.hi, modifier=None if setter is None
                                   else (lambda sp, p, f=setter: f(sp, float(p.value[0])))))
    mask = np.isfinite(data)

    def rollout(*, models, datas, control_signal, initial_states, param_dicts,
                rollout_signal_mapping, rollout_state_mapping, ctrl_mapping):
        starts = [start_state(m, {k: float(p[k].value[0]) for k in p.keys()}, case)
                  for m, p in zip(models, param_dicts)]
        trajs = sysid.sysid_rollout(models, datas, control_signal, starts,
                                    rollout_signal_mapping, rollout_state_mapping, ctrl_mapping)
        return [on_time(t) for t in trajs]

    def residual(params, pred, meas, model, return_pred_all, state=None, **_):
        rows = np.round((meas.times - pred.times[0]) / dt).astype(int)
        p = pred.data[rows]
        r = (p - meas.data) / sigma
        return r[mask], sysid.TimeSeries(meas.times, p, meas.signal_mapping), meas

    return params, sysid.build_residual_fn(models_sequences=[seq], custom_rollout=rollout,
                                           modify_residual=residual, resample_true=False)


def sysid_fit(name: str, mjcf: str, folder: Path) -> dict:
    """Identify the case's unknowns with mujoco.sysid; fit, 90% intervals and RMS (σ)."""
    from mujoco import sysid

    params, residual_fn = sysid_problem(name, mjcf, folder)
    opt, result = sysid.optimize(params, residual_fn, verbose=False)
    r_star, _, _ = residual_fn(opt.as_vector(), opt)
    _, half = sysid.calculate_intervals(r_star, result.jac, alpha=0.10)
    r = np.concatenate(r_star)
    fit = {u.label: float(v) for u, v in zip(CASES[name].unknowns, opt.as_vector())}
    return {"fit": fit, "lo": {k: fit[k] - h for k, h in zip(fit, half)},
            "hi": {k: fit[k] + h for k, h in zip(fit, half)},
            "rms": float(np.sqrt(np.mean(r ** 2))), "n": int(r.size)}


def _held(path: Path, t: np.ndarray) -> np.ndarray:
    """The CSV's force at times ``t``, each sample held until the next (zero-order hold)."""
    with open(path, newline="") as fh:
        rows = [(float(r["t"]), float(r["force"])) for r in csv.DictReader(fh)]
    ts, fs = np.array(rows).T
    return fs[np.clip(np.searchsorted(ts, t + 1e-9, side="right") - 1, 0, len(fs) - 1)]


# ------------------------------------------------------------------ the physdsl side

def physdsl_fit(folder: Path, run: Path) -> dict:
    """The fit, intervals and RMS (σ) of the run ``physdsl infer`` wrote in ``run``."""
    info = json.loads((run / "run.json").read_text())
    best = max((b for b in info["basins"] if b["log_density"] is not None),
               key=lambda b: b["log_density"])
    fit = {}
    for key, value in best["values"].items():
        flat = np.ravel(np.asarray(value, dtype=float))
        for i, v in enumerate(flat):
            fit[key if flat.size == 1 else f"{key}[{i}]"] = float(v)
    with open(run / "summary.csv", newline="") as fh:
        rows = {r["name"]: r for r in csv.DictReader(fh)}
    return {"fit": fit, "lo": {k: float(rows[k]["q5"]) for k in fit},
            "hi": {k: float(rows[k]["q95"]) for k in fit}, "rms": best["rms_sigma"]}


# ------------------------------------------------------------------ running and printing

def _timed(cmd: list[str], cwd: Path, timeout: float, env=None):
    """(completed process or None on timeout, wall s, CPU s of the child)."""
    from fits import _cpu_since

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                              env=env)
    except subprocess.TimeoutExpired:  # (the child is killed and reaped: its CPU is counted)
        proc = None
    return proc, time.perf_counter() - t0, _cpu_since(before)


def _stages(log: str) -> dict:
    """Wall seconds per stage from physdsl's progress lines (``STAGE: done in X s``)."""
    return {m[1].strip().replace(" ", "_"): float(m[2])
            for m in re.finditer(r"^([a-z][a-z ]*): done in ([0-9.]+) s", log, re.M)}


def _tail(proc) -> str:
    return (proc.stderr.strip().splitlines() or proc.stdout.strip().splitlines()
            or ["no output"])[-1]


def run_case(name: str, timeout: float, warm: bool) -> dict:
    out = {"case": name}
    with tempfile.TemporaryDirectory(prefix=f"peer_sysid_{name}_") as tmp:
        folder = Path(tmp) / "case"
        folder.mkdir()
        mjcf, truth = prepare(name, folder)
        (folder / "model.xml").write_text(mjcf)
        out["truth"] = truth
        proc, wall, cpu = _timed([sys.executable, __file__, "--sysid-worker", name, str(folder)],
                                 folder, timeout)
        line = None if proc is None else next(
            (ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")), None)
        out["sysid"] = ({"error": f"did not finish within {timeout:.0f} s"} if proc is None else
                        {"error": f"failed (exit {proc.returncode}): {_tail(proc)}"} if line is None
                        else {**json.loads(line[len("RESULT "):]), "wall": wall, "cpu": cpu})
        exe = shutil.which("physdsl", path=str(Path(sys.executable).parent)) or "physdsl"
        cache = Path(tmp) / "cache"
        for key in ("physdsl", "physdsl_warm") if warm else ("physdsl",):
            run = Path(tmp) / key
            proc, wall, cpu = _timed([exe, "--cache-dir", str(cache), "infer", "scene.phys",
                                      "-o", str(run), "--backend", "map"], folder, timeout)
            out[key] = ({"error": f"did not finish within {timeout:.0f} s"} if proc is None else
                        {"error": f"failed (exit {proc.returncode}): {_tail(proc)}"}
                        if proc.returncode != 0 else
                        {**physdsl_fit(folder, run), "wall": wall, "cpu": cpu,
                         "stages": _stages(proc.stdout + "\n" + proc.stderr)})
    out["load"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
    return out


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def _print(r: dict) -> None:
    n = r["case"]
    for tool in ("physdsl", "physdsl_warm", "sysid"):
        if tool not in r:
            continue
        res = r[tool]
        if "error" in res:
            print(f"error.{tool}.{n}: {res['error']}", flush=True)
            continue
        print(f"{tool}_wall_s.{n}: {res['wall']:.1f}")
        print(f"{tool}_cpu_s.{n}: {res['cpu']:.1f}")
        print(f"{tool}_rms_sigma.{n}: {res['rms']:.4f}")
        for stage, sec in res.get("stages", {}).items():
            print(f"{tool}_stage_wall_s.{n}.{stage}: {sec:.1f}")
        for k, v in res["fit"].items():
            print(f"{tool}_fit.{n}.{k}: {_fmt(v)} [{_fmt(res['lo'][k])}, {_fmt(res['hi'][k])}]"
                  f" truth {_fmt(r['truth'][k]) if k in r['truth'] else '?'}")
    for tool in ("physdsl", "physdsl_warm"):
        if tool in r and "error" not in r[tool] and "error" not in r["sysid"]:
            print(f"{tool}_over_sysid_wall.{n}: {r[tool]['wall'] / r['sysid']['wall']:.2f}")
            print(f"{tool}_over_sysid_cpu.{n}: {r[tool]['cpu'] / r['sysid']['cpu']:.2f}")
    print(f"load_average.{n}: {r['load']}", flush=True)


def _table(results: list[dict]) -> None:
    print()
    print("| case | unknowns | physdsl wall / CPU (s) | sysid wall / CPU (s) | physdsl / sysid wall "
          "| RMS physdsl / sysid (σ) | load |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        p, s = r.get("physdsl", {}), r.get("sysid", {})
        cell = lambda x: x.get("error") or f"{x['wall']:.1f} / {x['cpu']:.1f}"  # noqa: E731
        ok = "error" not in p and "error" not in s
        print(f"| {r['case']} | {len(CASES[r['case']].unknowns)} | {cell(p)} | {cell(s)} "
              f"| {p['wall'] / s['wall']:.2f}× | {p['rms']:.3f} / {s['rms']:.3f} | {r['load']} |"
              if ok else f"| {r['case']} | {len(CASES[r['case']].unknowns)} | {cell(p)} "
              f"| {cell(s)} | | | {r['load']} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", default=[], choices=list(CASES),
                    help="a case (repeat; default all)")
    ap.add_argument("--timeout", type=float, default=1500.0, help="seconds per process")
    ap.add_argument("--warm", action="store_true",
                    help="also a second physdsl run on the first's compile cache")
    ap.add_argument("--sysid-worker", nargs=2, metavar=("CASE", "DIR"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.sysid_worker:
        name, folder = args.sysid_worker
        folder = Path(folder)
        print("RESULT " + json.dumps(sysid_fit(name, (folder / "model.xml").read_text(), folder)),
              flush=True)
        return
    results = []
    for name in args.case or list(CASES):
        results.append(run_case(name, args.timeout, args.warm))
        _print(results[-1])
    _table(results)


if __name__ == "__main__":
    main()
