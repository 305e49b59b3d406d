"""Issue 17's experiment-design check on the cart of cart.phys (m = 1.5 kg, c = 0.8 N s/m):
per seed, simulate the pilot (pilot_push.csv, noise 2 mm), fit it (MAP + Laplace), design the
next push (``physdsl.design_experiment``), simulate that experiment and refit pilot and
experiment together (``BOTH``: two copies of the cart sharing m and c); random pushes of the same energy are predicted, and
``refit_random`` of them simulated and refitted the same way.

Used by tests/design/test_information_slow.py and benchmarks/control.py (``info_gain_ratio``).
Run: .venv/bin/python examples/experiment_cart/trials.py [SEEDS]
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

import physdsl
from physdsl.design.excite import random_settings
from physdsl.design.vary import varied
from physdsl.infer.fit import fit_with_fallback

HERE = Path(__file__).resolve().parent
TRUTH = {"m": 1.5, "c": 0.8}
NOISE = 0.002
PUSH = "control_force@rail.values"
PILOT_PUSH = (1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # N, one per 0.2 s
TIMES = np.round(np.arange(0.0, 2.0 + 1e-9, 0.04), 6)


BOTH = """\
scene cart_both {
  world { timestep: 10 ms  duration: 2 s  integrator: rk4 }
  param m ~ log_normal(0, 0.5)
  param c ~ log_normal(0, 1)
  body cart { shape: box(size: (20, 10, 10) cm)  mass: m  position: (0, 0, 0.5) m  collide: false }
  body cart2 { shape: box(size: (20, 10, 10) cm)  mass: m  position: (0, 1, 0.5) m  collide: false }
  joint rail: slider(world -> cart) { axis: (1, 0, 0) }
  joint rail2: slider(world -> cart2) { axis: (1, 0, 0) }
  effect joint_damping on rail { coefficient: c }
  effect joint_damping on rail2 { coefficient: c }
  control push on rail from "pilot_push.csv" column u
  control push2 on rail2 from "control_rail.csv" column u
  observe rail.angle from "pilot.csv" where joint == "rail" { noise: 2 mm }
  observe rail2.angle from "experiment.csv" where joint == "rail2" { noise: 2 mm }
}
"""


def _csv(path: Path, column: str, rows, label: str | None = None) -> None:
    head = f"t,joint,{column}" if label else f"t,{column}"
    lines = [head] + [f"{t:.6f},{label},{v:.10g}" if label else f"{t:.6f},{v:.10g}"
                      for t, v in rows]
    path.write_text("\n".join(lines) + "\n")


def _observe(model, values, rng) -> np.ndarray:
    clean = np.asarray(model.predict(values)["rail.angle"])[:, 0]
    return clean + rng.normal(0.0, NOISE, clean.shape)


def setup(folder: Path, seed: int) -> None:
    """The scenes, the pilot push and a pilot recording (seeded noise) in ``folder``."""
    for name in ("cart.phys", "pilot.phys"):
        shutil.copy(HERE / name, folder / name)
    (folder / "both.phys").write_text(BOTH)
    _csv(folder / "pilot_push.csv", "u", zip(np.arange(10) * 0.2, PILOT_PUSH))
    _csv(folder / "pilot.csv", "angle", zip(TIMES, np.zeros_like(TIMES)), "rail")
    pilot = physdsl.compile(folder / "pilot.phys")
    y = _observe(pilot, TRUTH, np.random.default_rng(1000 + seed))
    _csv(folder / "pilot.csv", "angle", zip(TIMES, y), "rail")


def fit(model, seed: int = 0):
    return fit_with_fallback(model, "map", chains=2, warmup=200, samples=200, seed=seed,
                             progress=False)


def width90(idata, name: str) -> float:
    v = np.asarray(idata.posterior[name].values).ravel()
    return float(np.quantile(v, 0.95) - np.quantile(v, 0.05))


def refit_width(folder: Path, push, seed: int, cart) -> dict[str, float]:
    """Simulate the experiment with ``push`` (truth, seeded noise), refit pilot + experiment
    together (``BOTH``); each unknown's 90% width."""
    _csv(folder / "control_rail.csv", "u", zip(np.arange(10) * 0.2, np.ravel(push)))
    y = _observe(cart, {**TRUTH, PUSH: np.asarray(push)}, np.random.default_rng(2000 + seed))
    _csv(folder / "experiment.csv", "angle", zip(TIMES, y), "rail2")
    post = fit(physdsl.compile(folder / "both.phys"), seed)
    return {n: width90(post, n) for n in TRUTH}


def trial(seed: int, folder: Path, refit_random: int = 2, steps: int = 60,
          restarts: int = 4, random: int = 8) -> dict:
    """One seed's figures: widths before, predicted after (chosen, random mean), refitted after."""
    setup(folder, seed)
    run = fit(physdsl.compile(folder / "pilot.phys"), seed)
    cart = physdsl.compile(folder / "cart.phys")
    d = physdsl.design_experiment(cart, None, ["rail"], idata_a=run, seed=seed, steps=steps,
                                  restarts=restarts, random=random)
    worst = d.worst()
    before = {n: width90(run, n) for n in TRUTH}
    out = {"worst": worst, "before": before, "predicted_before": d.widths("before"),
           "predicted_after": d.widths("after"), "random_after": d.widths("random"),
           "energy": d.energy, "budget": d.budget, "push": np.ravel(d.settings[PUSH]).tolist(),
           "refit_after": refit_width(folder, d.settings[PUSH], seed, cart)}
    rng = np.random.default_rng(3000 + seed)
    item = (varied(cart, PUSH),)
    out["refit_random"] = [refit_width(folder, random_settings(cart, item, d.budget, rng)[PUSH],
                                       seed, cart) for _ in range(refit_random)]
    return out


def summary(results: list[dict]) -> dict[str, float]:
    """Seed-averaged figures for the worse-determined unknown of each seed."""
    pred_ratio = [r["random_after"][r["worst"]] / r["predicted_after"][r["worst"]] for r in results]
    pred_shrink = [r["predicted_before"][r["worst"]] / r["predicted_after"][r["worst"]] for r in results]
    refit_shrink = [r["before"][r["worst"]] / r["refit_after"][r["worst"]] for r in results]
    out = {"info_gain_ratio": float(np.mean(pred_ratio)),
           "predicted_shrink": float(np.mean(pred_shrink)),
           "refit_shrink": float(np.mean(refit_shrink)),
           "shrink_error": float(np.mean(pred_shrink) / np.mean(refit_shrink) - 1)}
    measured = [np.mean([rr[r["worst"]] for rr in r["refit_random"]]) / r["refit_after"][r["worst"]]
                for r in results if r["refit_random"]]
    if measured:
        out["info_gain_ratio_refit"] = float(np.mean(measured))
    return out


def trials(seeds: int = 4, **options) -> tuple[list[dict], dict[str, float]]:
    results = []
    for seed in range(seeds):
        with tempfile.TemporaryDirectory() as tmp:
            results.append(trial(seed, Path(tmp), **options))
    return results, summary(results)


if __name__ == "__main__":
    rows, figures = trials(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
    for r in rows:
        print(r)
    for k, v in figures.items():
        print(f"{k}: {v:.3g}")
