"""What ``physdsl control`` writes: the chosen control sequences as CSV (readable by
``control NAME on TARGET from "FILE" column u``), the scene with every choice written in
(``planned.phys``: it simulates the plan as it stands), the predicted trajectory, the cost
history and ``plan.json`` (choices, errors against tolerances, whether the goal is met).
"""
from __future__ import annotations

import csv
import dataclasses
import io as textio
from pathlib import Path

import numpy as np

from .. import io
from ..export.literals import literal, number
from ..export.program import rebase_paths
from ..goal import Effort, Hold, Reach
from ..diagnose.report import new_figure, save_png
from ..syntax import ast, parse
from ..syntax.edit import value_set, with_scene_items
from ..syntax.printer import format_module
from .cost import control_effects
from .problem import ControlProblem
from .solve import Plan

BODY_COLUMNS = ("fx", "fy", "fz", "tx", "ty", "tz")


def control_file(target: str) -> str:
    return f"control_{target}.csv"


def _rows(use, values, on_joint: bool) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """(times, values (N, width), column names): ``u`` on a joint, ``fx, fy, fz[, tx, ty, tz]``."""
    times = np.asarray(use.tables["times"], dtype=float)
    rows = np.reshape(np.asarray(values, dtype=float), (len(times), -1))
    return times, rows, ("u",) if on_joint else BODY_COLUMNS[:rows.shape[1]]


def control_table(use, values, on_joint: bool) -> str:
    """CSV text of one control sequence (``t`` then its columns)."""
    times, rows, names = _rows(use, values, on_joint)
    out = textio.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["t", *names])
    for t, row in zip(times, rows):
        writer.writerow([number(t, 12), *(number(v, 12) for v in row)])
    return out.getvalue()


def planned_scene(problem: ControlProblem, plan: Plan, out_dir: Path) -> str:
    """The scene's text with each chosen control read from its CSV and each decision set."""
    scene = problem.model.scene
    module = parse(scene.source, str(scene.path or "<string>"))
    if scene.path is not None:  # the scene's own files, seen from out_dir (the plan's lie there)
        module = rebase_paths(module, Path(scene.path).parent, out_dir)
    uses = control_effects(scene)
    joints = {j.name for j in scene.joints}
    for name in plan.chosen:
        if name in uses:
            target = uses[name].target[0]
            columns = _rows(uses[name], plan.values[name], target in joints)[2]
            module = _control_from_file(module, target, columns)
        else:
            module = value_set(module, name, literal(plan.values[name], scene.unknown(name).unit))
    return format_module(_decided(module, set(plan.chosen)))


def _decided(module: ast.Module, chosen: set[str]) -> ast.Module:
    """``module`` whose goal no longer lists the chosen unknowns in ``decide:`` (they are known
    values now); the line goes when nothing is left to decide."""
    def name(node) -> str:
        return node.name if isinstance(node, ast.Name) else ".".join(getattr(node, "parts", ()))

    items = []
    for it in module.scene.items:
        if isinstance(it, ast.GoalItem):
            terms = []
            for t in it.terms:
                if isinstance(t, ast.GoalField) and t.key == "decide":
                    left = tuple(v for v in t.values if name(v) not in chosen)
                    if not left:
                        continue
                    t = dataclasses.replace(t, values=left)
                terms.append(t)
            it = dataclasses.replace(it, terms=tuple(terms))
        items.append(it)
    return with_scene_items(module, items)


def _control_from_file(module: ast.Module, target: str, columns: tuple[str, ...]) -> ast.Module:
    """``module`` with the control on ``target`` reading its CSV (its gain kept)."""
    items = []
    for it in module.scene.items:
        if isinstance(it, ast.ControlItem) and it.target == target:
            gain = it.block.get("gain") if it.block else None
            block = ast.Block((gain,), it.block.span) if gain else None
            it = dataclasses.replace(it, file=control_file(target), columns=columns, block=block)
        items.append(it)
    return with_scene_items(module, items)


def predicted_rows(problem: ControlProblem, plan: Plan) -> str:
    """CSV of every body's predicted position at each simulated step (t, body, x, y, z)."""
    sim = problem.model.simulator
    pos = np.asarray(plan.rollout.body_pos)
    out = textio.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["t", "body", "x", "y", "z"])
    for k, t in enumerate(sim.times):
        for b, name in enumerate(sim.body_names):
            writer.writerow([f"{t:.6f}", name, *(f"{v:.6f}" for v in pos[k, b])])
    return out.getvalue()


def summary(problem: ControlProblem, plan: Plan, wall_s: float) -> dict:
    """plan.json: the choices (SI, with units), each term's error against its tolerance."""
    scene = problem.model.scene
    terms = []
    for term, err in zip(problem.goal.terms, plan.errors):
        if isinstance(term, Reach):
            terms.append({"reach": term.target, "at_s": term.at, "point_m": list(term.point),
                          "error_m": err, "within_m": term.within, "met": err <= term.within})
        elif isinstance(term, Hold):
            terms.append({"hold": term.joint, "from_s": term.start, "to_s": term.end,
                          "value": term.value, "max_error": err, "within": term.within,
                          "met": err <= term.within})
        elif isinstance(term, Effort):
            terms.append({"effort_weight": term.weight, "integral_u2": err})
    return {
        "met": plan.met, "cost": plan.cost, "terms": terms,
        "chosen": {n: {"value": np.asarray(plan.values[n]).tolist(), "unit": scene.unknown(n).unit}
                   for n in plan.chosen},
        "held": {n: {"value": np.asarray(v).tolist(), "unit": scene.unknown(n).unit}
                 for n, v in plan.values.items() if n not in plan.chosen},
        "robust_over_draws": int(problem.rows.shape[0]),
        "screened_starts": plan.screened, "steps": len(plan.history) - 1, "wall_s": wall_s,
    }


def cost_plot(plan: Plan, path: Path) -> None:
    fig = new_figure(figsize=(5, 3.2))
    ax = fig.add_subplot(1, 1, 1)
    ax.semilogy(np.maximum(np.asarray(plan.history), 1e-300))
    ax.set_xlabel("L-BFGS step")
    ax.set_ylabel("goal cost")
    ax.set_title("met" if plan.met else "not met")
    fig.tight_layout()
    save_png(fig, path, dpi=110)


def write_plan(problem: ControlProblem, plan: Plan, out_dir: Path, wall_s: float) -> list[Path]:
    """Write every output of a plan into ``out_dir`` (prepared by the caller); their paths."""
    out_dir = Path(out_dir)
    written = []
    scene = problem.model.scene
    uses = control_effects(scene)
    joints = {j.name for j in scene.joints}
    for name in plan.chosen:
        if name in uses:
            text = control_table(uses[name], plan.values[name], uses[name].target[0] in joints)
            written.append(io.write_text(out_dir / control_file(uses[name].target[0]), text))
    written.append(io.write_text(out_dir / "planned.phys", planned_scene(problem, plan, out_dir)))
    written.append(io.write_text(out_dir / "predicted.csv", predicted_rows(problem, plan)))
    cost_plot(plan, out_dir / "cost.png")
    written.append(out_dir / "cost.png")
    written.append(io.write_json(out_dir / "plan.json", summary(problem, plan, wall_s)))
    return written
