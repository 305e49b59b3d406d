"""What ``physdsl mpc`` writes: the closed-loop trajectory, the estimates over time and a
summary (goal held, errors, milliseconds per MPC step), each file written atomically."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..io import prepare_outdir, write_json, write_text
from .mpc import MpcResult


def _csv(rows: list[list], header: list[str]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


def trajectory_csv(result: MpcResult) -> str:
    """t, each joint's coordinate and velocity, each force applied from t (empty at the end)."""
    header = (["t"] + [f"{j}.position" for j in result.joints]
              + [f"{j}.velocity" for j in result.joints] + [f"{c}.force" for c in result.targets]
              + ["step_ms"])
    rows = []
    for k, (t, x) in enumerate(zip(result.times, result.states)):
        tail = (list(result.forces[k]) + [result.step_ms[k]] if k < len(result.forces)
                else [""] * (len(result.targets) + 1))
        rows.append([f"{t:.6g}"] + [f"{v:.9g}" for v in x] + [
            v if v == "" else f"{v:.6g}" for v in tail])
    return _csv(rows, header)


def estimates_csv(result: MpcResult) -> str:
    """One row per refit (and the prior's centre at step 0): value and sd of each unknown."""
    names = list(result.estimates[0]["values"])
    header = ["step", "t"] + [c for n in names for c in (n, f"{n}.sd")] + ["refit_ms"]
    rows = [[e["step"], f"{e['t']:.6g}"] + [f"{v:.6g}" for n in names
                                            for v in (e["values"][n], e["sd"][n])]
            + [f"{e['refit_ms']:.3g}"] for e in result.estimates]
    return _csv(rows, header)


def summary(result: MpcResult, settle: float = 0.0) -> dict:
    """The run's figures: goal held, each hold term's largest error, ms per step and refit."""
    steady = result.step_ms[1:] if len(result.step_ms) > 1 else result.step_ms
    refits = [e["refit_ms"] for e in result.estimates[2:]]  # the first refit compiles
    return {
        "held": result.held(settle), "settle_s": settle,
        "hold_errors": {f"{h.joint}": {"max_error": e, "within": h.within}
                        for h, e in zip(result.holds, result.hold_errors(settle))},
        "steps": len(result.forces), "period_s": float(np.diff(result.times[:2])[0])
        if len(result.times) > 1 else None,
        "cost": result.cost,
        "step_ms": {"median": float(np.median(steady)), "p90": float(np.percentile(steady, 90)),
                    "max": float(np.max(steady)), "first": float(result.step_ms[0])},
        "refit_ms_median": float(np.median(refits)) if refits else None,
        "final_estimates": result.estimates[-1]["values"],
        "final_sd": result.estimates[-1]["sd"],
    }


def write(result: MpcResult, outdir: str | Path, *, settle: float = 0.0, force: bool = False,
          settings: dict | None = None) -> Path:
    """trajectory.csv, estimates.csv and mpc.json (the summary and ``settings``) in ``outdir``."""
    out = prepare_outdir(outdir, force=force)
    write_text(out / "trajectory.csv", trajectory_csv(result))
    write_text(out / "estimates.csv", estimates_csv(result))
    write_json(out / "mpc.json", {**summary(result, settle), "settings": settings or {}})
    return out
