"""Sampling a (proto-)program: N concrete scenes, their simulated trajectories, a parameter table.

``sample`` draws every unknown from its prior (for an exported proto-program: the fitted
posterior), writes each draw as a fully concrete .phys file, simulates it, and writes the
trajectories in the same long CSV format measurements are read in, so a generated scene
can be fitted again unchanged.
"""
from __future__ import annotations

import csv
import io as _io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from . import io
from .errors import PhysError, UsageError
from .syntax.loops import unroll_module

TRAJECTORY_COLUMNS = ("t", "body", "x", "y", "z", "qw", "qx", "qy", "qz")
JOINT_COLUMNS = ("t", "joint", "angle")
OUTPUT_RATE_HZ = 100.0  # trajectories are written at the world timestep or 100 Hz, the coarser
Z_NAME = re.compile(r"^(proto_)+z\d+$")


@dataclass(frozen=True)
class SampleResult:
    """What ``sample`` wrote: the folder, one concrete scene per draw, the parameter table."""

    outdir: Path
    scenes: tuple[Path, ...]
    names: tuple[str, ...]  # parameter columns (components of vectors as name[i])
    table: np.ndarray  # (n, len(names))

    def summary(self) -> str:
        """Mean, sd, 5% and 95% per parameter, as aligned text."""
        head = f"{'parameter':<44} {'mean':>12} {'sd':>11} {'5%':>12} {'95%':>12}"
        lines = [head, "-" * len(head)]
        for k, name in enumerate(self.names):
            col = self.table[:, k]
            q5, q95 = np.quantile(col, [0.05, 0.95])
            sd = col.std(ddof=1) if len(col) > 1 else 0.0
            lines.append(f"{name:<44} {col.mean():>12.5g} {sd:>11.3g} {q5:>12.5g} {q95:>12.5g}")
        return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Values of a program's fields written as expressions of standard-normal params.


def _eval_ast(node, env: Mapping[str, tuple[np.ndarray, object]]):
    """(value in SI, Dim) of an ast expression over ``env`` (name -> (value, Dim)).

    Covers what export writes: numbers, units, vectors, + - * / ^, unary minus, built-in
    functions and names of params. Raises KeyError for anything else (e.g. dotted refs).
    """
    from .expr import FUNCTIONS
    from .syntax import ast as A
    from .syntax.units import DIMLESS, parse_unit

    if isinstance(node, A.Num):
        return np.asarray(node.value), DIMLESS
    if isinstance(node, A.Name):
        return env[node.name]
    if isinstance(node, A.Neg):
        v, d = _eval_ast(node.operand, env)
        return -v, d
    if isinstance(node, A.WithUnit):
        v, d = _eval_ast(node.value, env)
        factor, dim = parse_unit(node.unit)
        return v * factor, d * dim
    if isinstance(node, A.Vector):
        parts = [_eval_ast(i, env) for i in node.items]
        dims = [d for _, d in parts if not d.dimensionless] or [parts[0][1]]
        items = np.broadcast_arrays(*[np.asarray(v, dtype=float) for v, _ in parts])
        return np.stack(items, axis=-1), dims[0]  # draws first: (n, D) or (D,)
    if isinstance(node, A.BinOp):
        (a, da), (b, db) = _eval_ast(node.left, env), _eval_ast(node.right, env)
        if node.op in "+-":
            return (a + b if node.op == "+" else a - b), (da if not da.dimensionless else db)
        if node.op == "*":
            return a * b, da * db
        if node.op == "/":
            return a / b, da / db
        return a ** b, da ** float(b)
    if isinstance(node, A.Call) and node.func in FUNCTIONS:
        args = [_eval_ast(a.value, env) for a in node.args]
        func = FUNCTIONS[node.func][0]
        value = np.asarray(func(*[a for a, _ in args]))
        if node.func == "sqrt":
            return value, args[0][1] ** 0.5
        if node.func in ("abs", "norm"):
            return value, args[0][1]
        return value, DIMLESS
    raise KeyError(type(node).__name__)


def _refs(node, names: set[str]) -> bool:
    """True when ast ``node`` mentions one of ``names`` as a bare name."""
    import dataclasses

    from .syntax import ast as A

    if isinstance(node, A.Name):
        return node.name in names
    if isinstance(node, tuple):
        return any(_refs(n, names) for n in node)
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return any(_refs(getattr(node, f.name), names) for f in dataclasses.fields(node)
                   if f.name not in ("span", "unit_span"))
    return False


def derived_fields(module) -> list[tuple[str, object]]:
    """(unknown-style name, ast expression) of every param or field written directly as an
    expression of the standard-normal params ``proto_zK`` (what export writes for
    correlated unknowns), in program order."""
    from .syntax import ast as A

    decl = module.scene
    z = {i.name for i in decl.items if isinstance(i, A.Param) and Z_NAME.match(i.name)}
    out = []
    for item in decl.items:
        if isinstance(item, A.Param) and item.name not in z and not isinstance(item.value, A.Dist):
            if _refs(item.value, z):
                out.append((item.name, item.value))
            continue
        block = getattr(item, "block", None)
        if block is None:
            continue
        if isinstance(item, (A.BodyItem, A.JointItem)):
            prefix = item.name
        elif isinstance(item, A.EffectItem):
            prefix = None
        elif isinstance(item, A.ObserveItem):
            prefix = f"{item.target}.{item.quantity}"
        else:
            continue
        for f in block.fields:
            if isinstance(f, A.Field) and not isinstance(f.value, A.Dist) and _refs(f.value, z):
                name = (f"{item.effect}@{','.join(item.target)}.{f.key}" if prefix is None
                        else f"{prefix}.{f.key}")
                out.append((name, f.value))
    return out


def _param_env(module, values: Mapping[str, np.ndarray], units: Mapping[str, str]):
    """SI values and dimensions of every param computable from the drawn ``values``."""
    from .syntax import ast as A
    from .syntax.units import DIMLESS, parse_unit

    env = {}
    for name, v in values.items():
        unit = units.get(name, "1")
        env[name] = (np.asarray(v, dtype=float), DIMLESS if unit in ("", "1") else parse_unit(unit)[1])
    pending = [i for i in module.scene.items if isinstance(i, A.Param) and not isinstance(i.value, A.Dist)]
    for _ in range(len(pending) + 1):  # params may refer to later ones
        rest = []
        for p in pending:
            try:
                env[p.name] = _eval_ast(p.value, env)
            except KeyError:
                rest.append(p)
        if len(rest) == len(pending):
            break
        pending = rest
    return env


def literal(value, unit: str) -> str:
    """A value in SI as literal text with its unit: ``0.612 m``, ``(1, 2, 3) m/s``."""
    from .export import number

    arr = np.asarray(value, dtype=float)
    text = number(float(arr), 10) if arr.ndim == 0 else \
        "(" + ", ".join(number(float(v), 10) for v in arr.reshape(-1)) + ")"
    return text if unit in ("", "1") else f"{text} {unit}"


# --------------------------------------------------------------------------------------------
# Writing one scene: concrete text, trajectories.


def parameter_values(module, draws: Mapping[str, np.ndarray], units: Mapping[str, str]):
    """Every parameter of the program per draw: the drawn unknowns (without ``proto_zK``) and
    the fields written as expressions of ``proto_zK``; name -> ((n, *shape) SI, unit)."""
    env = _param_env(module, draws, units)
    out = {}
    for name, v in draws.items():
        if not Z_NAME.match(name):
            out[name] = (np.asarray(v, dtype=float), units.get(name, "1"))
    for name, expr in derived_fields(module):
        value, dim = _eval_ast(expr, env)
        n = len(next(iter(draws.values())))
        value = np.asarray(value, dtype=float)
        out[name] = (np.broadcast_to(value, (n, *value.shape[1:])) if value.ndim else
                     np.full(n, float(value)), dim.si_text())
    return out


def concrete_text(module, values: Mapping[str, tuple[np.ndarray, str]], source: str = "") -> str:
    """The program with every unknown and every field written as an expression of the
    standard-normal params replaced by its value ``{name: (value, unit)}`` (literal, SI)."""
    import dataclasses

    from . import syntax
    from .export import _snippet, print_module, set_unknown
    from .syntax import ast as A

    for name, (v, unit) in values.items():
        module = set_unknown(module, name, _snippet(f"x: {literal(v, unit)}"))
    decl = module.scene
    items = [i for i in decl.items if not (isinstance(i, A.Param) and Z_NAME.match(i.name))]
    new_decl = dataclasses.replace(decl, items=tuple(items))
    module = dataclasses.replace(module, items=tuple(new_decl if i is decl else i for i in module.items))
    return syntax.format_source(print_module(module, source))


def _stride(times: np.ndarray) -> int:
    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    return max(int(round((1.0 / OUTPUT_RATE_HZ) / dt)), 1)


def trajectory_csv(rollout, body_names: Sequence[str], moving: Sequence[bool]) -> str:
    """Long-format ``t,body,x,y,z,qw,qx,qy,qz`` of every moving body at <= 100 Hz."""
    t = np.asarray(rollout.t)
    k = _stride(t)
    pos = np.asarray(rollout.body_pos)[::k]
    quat = np.asarray(rollout.body_quat)[::k]
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TRAJECTORY_COLUMNS)
    for i, ti in enumerate(t[::k]):
        for b, name in enumerate(body_names):
            if moving[b]:
                w.writerow([f"{ti:.6f}", name, *(f"{x:.9g}" for x in pos[i, b]),
                            *(f"{x:.9g}" for x in quat[i, b])])
    return buf.getvalue()


def joints_csv(rollout, joint_names: Sequence[str], kinds: Sequence[str]) -> str | None:
    """Long-format ``t,joint,angle`` of every hinge and slider joint (None if there are none)."""
    idx = [j for j, kind in enumerate(kinds) if kind in ("hinge", "slider")]
    if not idx:
        return None
    t = np.asarray(rollout.t)
    k = _stride(t)
    q = np.asarray(rollout.joint_pos)[::k]
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(JOINT_COLUMNS)
    for i, ti in enumerate(t[::k]):
        for j in idx:
            w.writerow([f"{ti:.6f}", joint_names[j], f"{q[i, j]:.9g}"])
    return buf.getvalue()


# --------------------------------------------------------------------------------------------
# The whole command.


def columns(params: Mapping[str, np.ndarray]) -> list[str]:
    """Column names of parameter values: ``name`` or ``name[i]`` per vector component."""
    out = []
    for name, v in params.items():
        size = int(np.size(v))
        out += [name] if np.ndim(v) == 0 else [f"{name}[{i}]" for i in range(size)]
    return out


def sample(path: str | Path, n: int, seed: int = 0, outdir: str | Path = "samples", *,
           force: bool = False, simulate: bool = True) -> SampleResult:
    """Draw ``n`` scenes from the program at ``path`` into ``outdir``.

    Writes ``scene-0001/scene.phys`` (concrete), ``trajectory.csv`` and ``joints.csv``
    (simulated, <= 100 Hz) and, per camera, ``frames-CAM/`` (rendered PNG frames, their
    ``times.csv`` and ``render.mp4``) per draw, and ``parameters.csv`` (one row per scene).
    Refuses a non-empty ``outdir`` unless ``force``.
    """
    import jax

    from . import syntax
    from .compile import compile_scene

    if n < 1:
        raise UsageError(f"-n must be at least 1, got {n}")
    path = Path(path)
    source = path.read_text(encoding="utf-8")
    scene = syntax.loads(source, filename=str(path), base_dir=path.parent)
    module = unroll_module(syntax.parse(source, str(path)))  # loops written out
    outdir = io.prepare_outdir(outdir, force=force)
    model = compile_scene(scene)
    draws = model.sample_prior(jax.random.PRNGKey(seed), n)
    units = {u.name: u.unit for u in scene.unknowns}
    params = parameter_values(module, draws, units)
    module = _for_scene_folder(module, path.parent, outdir, scene.duration)
    sim = model.simulator
    moving = [not b.fixed and (b.shape is None or b.shape.kind != "plane") for b in
              (scene.body(name) for name in sim.body_names)]
    kinds = [scene.joint(name).kind for name in sim.joint_names]
    cameras = camera_renderers(model) if simulate else {}
    scenes = []
    for i in range(n):
        folder = outdir / f"scene-{i + 1:04d}"
        text = concrete_text(module, {k: (v[i], u) for k, (v, u) in params.items()}, source)
        io.write_text(folder / "scene.phys", text)
        if simulate:
            rollout = model.simulate({k: v[i] for k, v in draws.items()})
            io.write_text(folder / "trajectory.csv", trajectory_csv(rollout, sim.body_names, moving))
            joints = joints_csv(rollout, sim.joint_names, kinds)
            if joints is not None:
                io.write_text(folder / "joints.csv", joints)
            for cam, (times, draw) in cameras.items():
                write_camera_frames(folder / frames_folder(cam), times,
                                    draw(rollout, {k: v[i] for k, v in draws.items()}))
        scenes.append(folder / "scene.phys")
    names = columns({k: v[0] for k, (v, _) in params.items()})
    table = (np.concatenate([v.reshape(n, -1) for v, _ in params.values()], axis=1)
             if params else np.zeros((n, 0)))
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scene", *names])
    for i, row in enumerate(table):
        w.writerow([f"scene-{i + 1:04d}", *(f"{x:.10g}" for x in row)])
    io.write_text(outdir / "parameters.csv", buf.getvalue())
    return SampleResult(outdir, tuple(scenes), tuple(names), table)


def frames_folder(camera: str) -> str:
    """Folder of a generated scene's frames seen by ``camera``."""
    return f"frames-{camera}"


def camera_renderers(model) -> dict:
    """camera name -> (frame times, jitted ``(rollout, values) -> images``) for every camera
    of the scene (none when it has no body to draw). Times: the camera's observed frame
    times, else every 1/30 s over the simulated span."""
    import jax

    from .render import files
    from .render.scene import drawn_bodies, render_frames

    scene = model.scene
    if not drawn_bodies(scene):
        return {}
    out = {}
    for cam in scene.cameras:
        times = files.frame_times(model, cam.name, None)
        out[cam.name] = (times, jax.jit(
            lambda rollout, values, name=cam.name, times=times: render_frames(
                scene, model.simulator, rollout, values, name, times)))
    return out


def write_camera_frames(folder: Path, times: np.ndarray, images) -> None:
    """PNG frames (and render.mp4) of one camera, with their times as ``times.csv``."""
    from .render import files

    images = np.asarray(images)
    rate = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else files.DEFAULT_FPS
    files.write_frames(images, folder, rate)
    io.write_text(folder / "times.csv", "t\n" + "".join(f"{t:.10g}\n" for t in times))


def _for_scene_folder(module, src_dir: Path, outdir: Path, duration: float):
    """``module`` as written one folder below ``outdir``: file names rebased, the duration
    fixed, and observations re-pointed at the scene's own generated data (positions and
    orientations in trajectory.csv, hinge/slider angles in joints.csv, camera images in
    frames-CAM/; others dropped)."""
    import dataclasses

    from .export import _ensure_duration, _scene_decl, _with_items, rebase_paths
    from .syntax import ast as A

    module = rebase_paths(module, src_dir, Path(outdir) / "scene-0000")
    decl = _scene_decl(module)
    items = []
    for item in decl.items:
        if isinstance(item, A.ObserveItem):
            if item.quantity in ("position", "orientation"):
                item = dataclasses.replace(item, file="trajectory.csv", where=("body", item.target),
                                           rate=None, times=None)
            elif item.quantity == "angle":
                item = dataclasses.replace(item, file="joints.csv", where=("joint", item.target),
                                           rate=None, times=None)
            elif item.quantity == "image":
                folder = frames_folder(item.target)
                item = dataclasses.replace(item, file=f"{folder}/*.png", where=None, rate=None,
                                           times=f"{folder}/times.csv")
            else:
                continue
        items.append(item)
    items = _ensure_duration(items, duration)
    return _with_items(module, decl, items)


del math, PhysError
