"""Beyond-the-library benchmark (issue 19): three hidden laws outside the library, simulated by
physdsl (``tests/discover/cases.py``): a ball with drag F = -k sqrt|v| v, a ball attracted by a
fixed point with an inverse-square force, a hinge with a cubic spring. For each case: fit the
naive scene, let ``diagnose`` refit the library's best candidates, learn a residual force
(``physdsl.beyond_library``), distil and refit the law, and print

- ``law_found.CASE``: 1 when the distilled law has exactly the true terms and every true
  coefficient lies in its 90% interval, else 0 (``law.CASE``: the terms and intervals),
- ``rms_naive.CASE``, ``rms_library.CASE`` (the library's best refit), ``rms_learned.CASE``,
  ``rms_law.CASE``: residual RMS in noise units,
- ``log_z.CASE``: Laplace log evidence of library best / learned / law,
- ``wall_s.CASE`` and ``cpu_s.CASE``.

``--source mujoco``: the same cases with data made by MuJoCo (the law applied as
``xfrc_applied`` / ``qfrc_applied`` before every 0.1 ms step; ``tests/discover/mujoco_data.py``).

``--mode no-effect --datasets 20``: the same scenes without any hidden law (the ball cases'
naive scene is then the whole physics); prints ``proposed.CASE.SEED`` and
``false_positive_rate: x/N`` (a learned term proposed where nothing is missing).

Run: .venv/bin/python benchmarks/discovery.py [--case sqrt_drag] [--mode laws|no-effect]
[--source mujoco] [--no-library]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import physdsl  # noqa: E402
from physdsl.infer.fit import quick_fit  # noqa: E402
from tests.discover.cases import CASES, make  # noqa: E402


def library_best(model, idata, echo) -> dict | None:
    """The library's best refit by the diagnosis (lowest RMS after): effect, rms, log_z."""
    diag = physdsl.diagnose(model, idata, confirm_top=2, echo=echo)
    rows = [r for r in diag.ranking if r.rms_after is not None]
    best = min(rows, key=lambda r: r.rms_after, default=None)
    return None if best is None else {"effect": best.key, "rms": best.rms_after,
                                      "log_z": best.log_evidence}


def law_found(case, res) -> bool:
    if res.law is None or set(res.law["terms"]) != set(case.law):
        return False
    return all(lo <= case.law[t] <= hi for t, (_, lo, hi) in res.law["coefficients"].items())


def run_case(name: str, folder: Path, echo, source: str = "physdsl", library: bool = True) -> dict:
    case = CASES[name]
    t0, c0 = time.time(), time.process_time()
    if source == "mujoco":
        from tests.discover.mujoco_data import make_mujoco
        path = make_mujoco(case, folder)
    else:
        path = make(case, folder)
    model = physdsl.compile(path)
    idata = quick_fit(model)
    report = physdsl.check(model, idata)
    echo(f"{name}: naive {report.rms_sigma:.2f}σ")
    library = library_best(model, idata, echo) if library else None
    echo(f"{name}: library best {library}")
    res = physdsl.beyond_library(model, idata, folder / "beyond", report=report,
                                 library=library, target=case.target, center=case.center,
                                 echo=echo)
    out = {f"law_found.{name}": int(law_found(case, res)),
           f"rms_naive.{name}": round(report.rms_sigma, 3),
           f"rms_library.{name}": None if library is None else round(library["rms"], 3),
           f"rms_learned.{name}": round(res.rms_learned, 3),
           f"rms_law.{name}": None if res.law is None else round(res.law["rms"], 3),
           f"log_z.{name}": (None if library is None else library["log_z"], res.log_z_learned,
                             None if res.law is None else res.law["log_z"]),
           f"law.{name}": None if res.law is None else res.law["coefficients"],
           f"truth.{name}": case.law,
           f"library_wins.{name}": int(res.library_wins),  # the law does not beat the library
           f"verdict.{name}": res.verdict,
           f"wall_s.{name}": round(time.time() - t0, 1),
           f"cpu_s.{name}": round(time.process_time() - c0, 1)}
    return out


def run_no_effect(datasets: int, folder: Path, echo) -> dict:
    """Cases without a hidden law: a learned term proposed counts as a false positive."""
    out, proposed = {}, 0
    names = list(CASES)
    for i in range(datasets):
        name = names[i % len(names)]
        case = CASES[name]
        sub = folder / f"{name}-{i}"
        model = physdsl.compile(make(case, sub, law=False, seed=100 + i))
        idata = quick_fit(model, seed=i)
        report = physdsl.check(model, idata)
        hit = False
        if not report.consistent:  # refine reaches beyond only where the check fails
            res = physdsl.beyond_library(model, idata, sub / "beyond", report=report,
                                         target=case.target, center=case.center, echo=echo)
            hit = bool(res.proposed)
        proposed += hit
        out[f"proposed.{name}.{i}"] = int(hit)
        echo(f"{name}.{i}: check {'consistent' if report.consistent else 'flagged'} "
             f"{report.rms_sigma:.2f}σ, proposed {int(hit)}")
    out["false_positive_rate"] = f"{proposed}/{datasets}"
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", choices=sorted(CASES))
    ap.add_argument("--mode", choices=["laws", "no-effect"], default="laws")
    ap.add_argument("--datasets", type=int, default=20)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--source", choices=["physdsl", "mujoco"], default="physdsl",
                    help="who simulates the hidden law (mujoco: xfrc_applied / qfrc_applied)")
    ap.add_argument("--no-library", action="store_true",
                    help="skip the diagnosis's library refits (rms_library None): the costly part")
    args = ap.parse_args()
    folder = args.out or Path(tempfile.mkdtemp(prefix="physdsl-discovery-"))
    echo = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    print(f"load: {os.getloadavg()[0]:.1f}")
    if args.mode == "no-effect":
        results = run_no_effect(args.datasets, folder, echo)
    else:
        results = {}
        for name in args.case or sorted(CASES):
            case_results = run_case(name, folder / name, echo, args.source,
                                    not args.no_library)
            for k, v in case_results.items():  # each case as it ends (runs are long)
                print(f"{k}: {v}", flush=True)
            print(f"load: {os.getloadavg()[0]:.1f}", flush=True)
    for k, v in results.items():
        print(f"{k}: {v}", flush=True)
    print(f"load: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
