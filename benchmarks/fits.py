"""Fit benchmark: how fast and how well the default MAP fit does, per case; ``name: value`` lines.

Cases: every ``examples/hidden-effect/CASE`` made from a dev corpus case (its ``naive.phys``
with the hidden effect of ``truth.json`` added as ``refine`` adds it, its strength unknown, so the model can fit and
its intervals can cover the truth), and ``examples/chain_hit`` (a ball thrown at a hanging
chain; its ``scene.phys`` has no missing effect). For each, one ``infer --backend map`` with the
default settings (4 chains = starts, 500 optimisation steps) and ``--samples`` Laplace draws:

- ``fit_wall_s.CASE``: wall time of the fit (compile, starts, optimisation, Laplace, draws),
- ``fit_rms_sigma.CASE``: residual RMS in noise units at the posterior's best draw,
- ``basins_found.CASE``: basins the multistart reported (``n/a`` where the run reports none),
- ``coverage_90.CASE``: fraction of true parameter components inside the 5-95% interval of
  the run's summary (the intervals it shows: robust by default),
- ``cpu_s.CASE``: CPU seconds of the case's process (the quiet-machine time on a shared one).

Each case runs in its own process with a time limit (``--timeout``), so one that cannot finish
is reported as such. Wall times on a shared machine: the load average is printed beside them.

Run: .venv/bin/python benchmarks/fits.py [--case pendulum [--case chain_hit]] [--samples 200]
"""
from __future__ import annotations

import physdsl

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from hidden_cases import scene_text as hidden_scene

ROOT = Path(__file__).resolve().parent.parent
HIDDEN = ROOT / "examples" / "hidden-effect"
CHAIN = ROOT / "examples" / "chain_hit"


def cases() -> dict[str, tuple[Path, str | None]]:
    """name -> (folder, scene file name or None for naive.phys + the hidden effect)."""
    out = {}
    for p in sorted(HIDDEN.iterdir()):
        truth = p / "truth.json"
        if truth.exists() and "dev corpus" in json.loads(truth.read_text()).get("source", ""):
            out[p.name] = (p, None)
    if (CHAIN / "scene.phys").exists():
        out["chain_hit"] = (CHAIN, "scene.phys")
    return out


def scene_text(folder: Path, scene: str | None) -> str:
    """The scene's text: ``scene`` as it is, or naive.phys with the hidden effect added as
    ``refine`` adds it (``hidden_cases``)."""
    return (folder / scene).read_text() if scene is not None else hidden_scene(folder)


def run_case(name: str, samples: int, seed: int, save: str = "") -> dict:
    """Fit one case in this process; its figures as a dict (its posterior written to
    ``save``/CASE.nc where given, for re-reading the intervals without a refit)."""
    import numpy as np

    import physdsl  # noqa: F401 - float64
    from physdsl.compile import Model
    from physdsl.diagnose.workflow import point_estimate
    from physdsl.infer.output import summary_rows
    from physdsl.syntax import loads

    folder, scene = cases()[name]
    truth = json.loads((folder / "truth.json").read_text())
    model = Model(loads(scene_text(folder, scene), filename=str(folder / "scene.phys"),
                        base_dir=folder))
    t0 = time.perf_counter()
    idata = physdsl.infer(model, backend="map", samples=samples, seed=seed, progress=False)
    wall = time.perf_counter() - t0
    if save:
        from physdsl.infer import posterior_data

        posterior_data.write(idata, Path(save) / f"{name}.nc")
    values = point_estimate(model, idata)
    r = np.asarray(model.standardized_residuals(values, model.predict(values)))
    n = sum(int(np.sum(o.mask)) for o in model.observed)
    rows = {row["name"]: row for row in summary_rows(model, idata)}
    inside = []
    for key, value in truth.get("parameters", {}).items():
        flat = np.ravel(np.asarray(value, dtype=float))
        for i, v in enumerate(flat):
            label = key if flat.size == 1 else f"{key}[{i}]"
            if label in rows:
                inside.append(bool(rows[label]["q5"] <= v <= rows[label]["q95"]))
    basins = json.loads(idata.attrs["basins"]) if "basins" in idata.attrs else None
    return {"case": name, "wall": wall, "rms": float(np.sqrt(np.sum(r**2) / max(n, 1))),
            "basins": None if basins is None else sum(b["log_density"] is not None for b in basins),
            "coverage": float(np.mean(inside)) if inside else None, "n_params": len(inside)}


def _cpu_since(before) -> float:
    """CPU seconds (user + system) of the children reaped since ``before`` (a getrusage)."""
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def _run_child(name: str, cmd: list[str], timeout: float) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:  # (the child is killed and reaped: its CPU is counted)
        return {"case": name, "error": f"did not finish within {timeout:.0f} s "
                                       f"({_cpu_since(before):.0f} s CPU)"}
    cpu = _cpu_since(before)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")), None)
    if line is not None:
        return {**json.loads(line[len("RESULT "):]), "cpu": cpu}
    tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return {"case": name, "error": f"failed (exit {proc.returncode}): {tail}"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", default=[], help="a case (repeat; default all)")
    ap.add_argument("--samples", type=int, default=200, help="Laplace draws per chain")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per case")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--save", default="", help="write each case's posterior to DIR/CASE.nc")
    ap.add_argument("--one", default="", help=argparse.SUPPRESS)  # worker mode
    args = ap.parse_args()
    if args.one:
        print("RESULT " + json.dumps(run_case(args.one, args.samples, args.seed, args.save)),
              flush=True)
        return
    known = cases()
    bad = [n for n in args.case if n not in known]
    if bad:
        ap.error(f"no case {', '.join(bad)} (cases: {', '.join(known)})")
    results = []
    for name in args.case or list(known):
        cmd = [sys.executable, __file__, "--one", name, "--samples", str(args.samples),
               "--seed", str(args.seed)] + (["--save", args.save] if args.save else [])
        res = _run_child(name, cmd, args.timeout)
        res["load"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
        results.append(res)
        _print(res)
    print()
    print("| case | fit wall (s) | CPU (s) | RMS (σ) | basins | 90% coverage | load |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        if "error" in r:
            print(f"| {r['case']} | {r['error']} | | | | | {r['load']} |")
            continue
        cov = "—" if r["coverage"] is None else f"{r['coverage']:.2f} of {r['n_params']}"
        print(f"| {r['case']} | {r['wall']:.0f} | {r['cpu']:.0f} | {r['rms']:.2f} | {_fmt(r['basins'])} | {cov} "
              f"| {r['load']} |")


def _fmt(v) -> str:
    return "n/a" if v is None else str(v)


def _print(r: dict) -> None:
    n = r["case"]
    if "error" in r:
        print(f"error.{n}: {r['error']}", flush=True)
        return
    print(f"fit_wall_s.{n}: {r['wall']:.1f}")
    print(f"cpu_s.{n}: {r['cpu']:.1f}")
    print(f"fit_rms_sigma.{n}: {r['rms']:.3f}")
    print(f"basins_found.{n}: {_fmt(r['basins'])}")
    print(f"coverage_90.{n}: {_fmt(None if r['coverage'] is None else round(r['coverage'], 3))}")
    print(f"load_average.{n}: {r['load']}", flush=True)


if __name__ == "__main__":
    main()
