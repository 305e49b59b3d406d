"""Coverage of the 90% intervals on MuJoCo-made data: robust (the default) against the plain
model posterior, with ``name: value`` lines.

Cases: every ``examples/hidden-effect/CASE`` with its hidden effect added to ``naive.phys``
(what ``refine``'s first round fits: the right effect, its strength unknown with the
library's prior; ``hidden_cases.scene_text``), and
the MuJoCo-made examples that have no hidden effect (``double_pendulum``, ``cart_pole``).
Each is fitted once by MAP + Laplace (``infer --backend map``, default starts, 2 chains x
``--samples`` draws), in its own process with a time limit. Per true parameter component:
whether it lies in the 5-95% interval of the model posterior and of the robust one, and
the width ratio. Printed:

- ``case.CASE``: residual RMS (noise units) and the residual components with a discrepancy,
- ``row.CASE.PARAM``: truth, model interval, robust interval, width ratio,
- ``coverage_90.model`` / ``coverage_90.robust``: fraction of all true components inside,
- ``width_ratio.median``: median robust / model width over all components,
- ``width_ratio.max_white``: the largest ratio among cases fitted at the noise (RMS <= 1.05
  with no discrepancy found in the residuals and the block check not rejecting at its
  ``LEVEL``: a rejection is a mismatch found, which the widening is for),
- ``width_ratio.max_block_rejected``: the largest ratio among cases at the noise whose block
  check rejects (the parts of the record disagree beyond the posterior's spread).

Run: .venv/bin/python benchmarks/coverage.py [--case pendulum ...] [--samples 500]

``--saved DIR`` re-reads the posteriors ``fits.py --save DIR`` wrote (DIR/CASE.nc, fits.py's
cases) and recomputes the robust intervals with the current method, without refitting: the
same fits' intervals before and after a change of ``infer/intervals.py`` (``--no-hac``: the
method without the scores' HAC term, as before issue 21's last change; ``--no-contact-law``:
without the contact law's error term, ``infer/contact_law.py``).
"""
from __future__ import annotations

import physdsl

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from hidden_cases import scene_text as hidden_scene

ROOT = Path(__file__).resolve().parent.parent
HIDDEN = ROOT / "examples" / "hidden-effect"
PLAIN = ("double_pendulum", "cart_pole")  # MuJoCo-made examples whose scene has every effect


def cases() -> dict[str, Path]:
    out = {p.name: p for p in sorted(HIDDEN.iterdir()) if (p / "naive.phys").exists()}
    out.update({n: ROOT / "examples" / n for n in PLAIN if (ROOT / "examples" / n).exists()})
    return out


def scene_text(folder: Path) -> str:
    """The case's scene: naive.phys with the hidden effect(s) added as ``refine`` adds them
    (``hidden_cases``), or the example's own."""
    if not (folder / "naive.phys").exists():
        return (folder / f"{folder.name}.phys").read_text()
    return hidden_scene(folder)


def truth_values(folder: Path, names) -> dict:
    t = json.loads((folder / "truth.json").read_text())
    values = {**t.get("unknowns", {}), **t.get("parameters", {})}
    return {k: values[k] for k in names if k in values}


def interval_rows(truth: dict, model_post, robust_post) -> list[dict]:
    """Per true component: its 5-95% interval in the model posterior and in the robust one
    (datasets of draws (chain, draw, ...)), whether each holds it, and their width ratio."""
    import numpy as np

    rows = []
    for k, v in truth.items():
        a = np.asarray(model_post[k].values).reshape(-1, np.size(v))
        b = np.asarray(robust_post[k].values).reshape(-1, np.size(v))
        for i, x in enumerate(np.ravel(v)):
            qa, qb = np.quantile(a[:, i], [0.05, 0.95]), np.quantile(b[:, i], [0.05, 0.95])
            rows.append({"param": k if np.size(v) == 1 else f"{k}[{i}]", "truth": float(x),
                         "model": [float(qa[0]), float(qa[1])], "robust": [float(qb[0]), float(qb[1])],
                         "in_model": bool(qa[0] <= x <= qa[1]), "in_robust": bool(qb[0] <= x <= qb[1]),
                         "ratio": float((qb[1] - qb[0]) / max(qa[1] - qa[0], 1e-300))})
    return rows


def _print_rows(name: str, rows: list[dict]) -> None:
    for r in rows:
        print(f"row.{name}.{r['param']}: truth {r['truth']:.6g} model [{r['model'][0]:.6g}, "
              f"{r['model'][1]:.6g}] {'in' if r['in_model'] else 'OUT'} robust "
              f"[{r['robust'][0]:.6g}, {r['robust'][1]:.6g}] "
              f"{'in' if r['in_robust'] else 'OUT'} ratio {r['ratio']:.2f}", flush=True)


def _print_totals(rows: list[dict]) -> None:
    for kind in ("model", "robust"):
        inside = [r[f"in_{kind}"] for r in rows]
        print(f"coverage_90.{kind}: {sum(inside) / len(inside):.3f} ({sum(inside)} of {len(inside)})")


def run_case(name: str, samples: int) -> dict:
    """Fit one case in this process: per true component, the two intervals."""
    import numpy as np

    import physdsl  # noqa: F401 - float64
    from physdsl.compile import Model
    from physdsl.infer.intervals import GROUP
    from physdsl.observe import trajectory
    from physdsl.syntax import loads

    folder = cases()[name]
    model = Model(loads(scene_text(folder), filename=str(folder / "scene.phys"),
                        base_dir=folder))
    t0 = time.time()
    idata = physdsl.infer(model, backend="map", chains=2, samples=samples, progress=False)
    wall = time.time() - t0
    truth = truth_values(folder, model.unknown_names)
    rows = interval_rows(truth, idata.posterior, getattr(idata, GROUP))
    sq, n = 0.0, 0
    pp = idata.posterior_predictive
    mean_values = {u: np.asarray(idata.posterior[u].values).mean(axis=(0, 1)) for u in model.unknown_names}
    for o in model.observed:
        pred = np.asarray(pp["pred:" + o.obs.name].values).mean(axis=(0, 1))
        d = model.data[o.obs.name]
        r = np.asarray(trajectory.residual(o.obs.quantity, pred, d["measured"]))
        r = r / np.asarray(model.noise_scale(o.obs, mean_values))
        sq += float(np.sum(np.where(d["mask"], r, 0.0) ** 2))
        n += int(np.sum(d["mask"]))
    attrs = getattr(idata, GROUP).attrs
    block = json.loads(attrs.get("block_check", "{}"))
    return {"rows": rows, "rms": (sq / max(n, 1)) ** 0.5, "wall_s": wall,
            "discrepancies": attrs.get("discrepancies", ""),
            "block_p": block.get("p_value"), "block_factors": block.get("factors"),
            "block_note": block.get("note", "")}


def saved_case(name: str, path: Path, hac: bool = True, contact: bool = True) -> dict:
    """One fits.py case's saved posterior: the robust intervals recomputed now (the draws,
    their predictions and the scene are those of the fit), per true component in
    ``run_case``'s form, and the CPU seconds the intervals took."""
    import jax
    import numpy as np
    from jax.flatten_util import ravel_pytree
    from numpyro.infer.util import unconstrain_fn

    import fits
    from physdsl.compile import Model
    from physdsl.infer import intervals, posterior_data
    from physdsl.infer.problem import model_problem
    from physdsl.syntax import loads

    folder, scene = fits.cases()[name]
    model = Model(loads(fits.scene_text(folder, scene), filename=str(folder / "scene.phys"),
                        base_dir=folder))
    idata = posterior_data.read(path)
    post = posterior_data.group(idata, "posterior")
    pred = posterior_data.group(idata, "posterior_predictive")
    chains, draws = post.sizes["chain"], post.sizes["draw"]
    flat_of = lambda ds, k: np.asarray(ds[k].values).reshape(chains * draws, *ds[k].shape[2:])  # noqa: E731
    values = {k: flat_of(post, k) for k in model.unknown_names}
    ravel = jax.jit(jax.vmap(lambda v: ravel_pytree(unconstrain_fn(model.prior_values, (), {}, v))[0]))
    flat = np.asarray(ravel(values)).reshape(chains, draws, -1)
    constrained = {**values, **{k: flat_of(pred, k) for k in pred.data_vars}}
    fresh = posterior_data.from_dict({"posterior": {k: np.asarray(post[k].values)
                                                   for k in model.unknown_names}})
    level, pairs = intervals.HAC_LEVEL, intervals.contact_law.nuisance_pairs
    intervals.HAC_LEVEL = level if hac else 0.0
    if not contact:
        intervals.contact_law.nuisance_pairs = lambda scene: []
    t0 = time.process_time()
    try:
        fresh = intervals.add_robust(fresh, model, model_problem(model), flat, constrained)
    finally:
        intervals.HAC_LEVEL, intervals.contact_law.nuisance_pairs = level, pairs
    cpu = time.process_time() - t0
    robust = posterior_data.group(fresh, intervals.GROUP)
    truth = json.loads((folder / "truth.json").read_text()).get("parameters", {})
    rows = interval_rows({k: v for k, v in truth.items() if k in values}, post, robust)
    block = json.loads(robust.attrs.get("block_check", "{}"))
    return {"rows": rows, "intervals_cpu_s": cpu, "hac": json.loads(robust.attrs.get("score_hac", "{}")),
            "block_p": block.get("p_value"), "block_factors": block.get("factors"),
            "contact_law": json.loads(robust.attrs.get("contact_law", "{}"))}


def main_saved(folder: str, names: list[str], hac: bool, contact: bool = True) -> None:
    """``--saved``: per case and component, the plain and the recomputed robust interval."""
    import numpy as np

    rows = []
    for path in sorted(Path(folder).glob("*.nc")):
        if names and path.stem not in names:
            continue
        out = saved_case(path.stem, path, hac, contact)
        rows += out["rows"]
        p = out["block_p"]
        print(f"case.{path.stem}: intervals {out['intervals_cpu_s']:.1f} s CPU; block check p "
              f"{'n/a' if p is None else f'{p:.3g}'}; HAC lags "
              f"{out['hac'].get('bandwidth_lags', float('nan')):.1f}; contact law "
              f"{json.dumps(out['contact_law'])}", flush=True)
        _print_rows(path.stem, out["rows"])
        print(f"coverage_90.{path.stem}: model {np.mean([r['in_model'] for r in out['rows']]):.3f} "
              f"robust {np.mean([r['in_robust'] for r in out['rows']]):.3f}", flush=True)
    if rows:
        _print_totals(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", help="only these cases")
    ap.add_argument("--samples", type=int, default=500, help="Laplace draws per chain")
    ap.add_argument("--timeout", type=float, default=1500.0, help="seconds per case")
    ap.add_argument("--saved", help="recompute the intervals of fits.py --save DIR's posteriors")
    ap.add_argument("--no-hac", action="store_true", help="with --saved: without the HAC term")
    ap.add_argument("--no-contact-law", action="store_true",
                    help="with --saved: without the contact law's error term")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.saved:
        main_saved(args.saved, args.case or [], not args.no_hac, not args.no_contact_law)
        return
    if args.one:
        print(json.dumps(run_case(args.one, args.samples)))
        return
    results = {}
    for name in args.case or list(cases()):
        t0 = time.time()
        try:
            p = subprocess.run([sys.executable, __file__, "--one", name, "--samples",
                                str(args.samples)], capture_output=True, text=True,
                               timeout=args.timeout, cwd=ROOT)
            out = json.loads(p.stdout.strip().splitlines()[-1]) if p.returncode == 0 else None
            if out is None:
                print(f"case.{name}: failed: {p.stderr.strip().splitlines()[-1:]}", flush=True)
                continue
        except subprocess.TimeoutExpired:
            print(f"case.{name}: timed out after {args.timeout:.0f} s", flush=True)
            continue
        results[name] = out
        if out.get("block_note"):
            print(f"block_check.{name}: {out['block_note']}", flush=True)
        if out.get("block_p") is not None:
            print(f"block_check.{name}: p {out['block_p']:.3g}, factors "
                  f"{' '.join(f'{f:.2f}' for f in out['block_factors'])}", flush=True)
        print(f"case.{name}: rms {out['rms']:.3f} sigma; discrepancies {out['discrepancies']}; "
              f"fit {out['wall_s']:.0f} s (wall {time.time() - t0:.0f} s, load "
              f"{os.getloadavg()[0]:.1f})", flush=True)
        _print_rows(name, out["rows"])
    rows = [r for out in results.values() for r in out["rows"]]
    if not rows:
        return
    import numpy as np

    from physdsl.infer.block_check import LEVEL

    at_noise = [out for out in results.values()
                if out["rms"] <= 1.05 and out["discrepancies"].startswith("0 ")]
    rejected = lambda out: out.get("block_p") is not None and out["block_p"] < LEVEL  # noqa: E731
    white = [r["ratio"] for out in at_noise if not rejected(out) for r in out["rows"]]
    flagged = [r["ratio"] for out in at_noise if rejected(out) for r in out["rows"]]
    _print_totals(rows)
    print(f"width_ratio.median: {np.median([r['ratio'] for r in rows]):.2f}")
    print(f"width_ratio.max_white: {max(white):.2f}" if white else "width_ratio.max_white: n/a")
    print(f"width_ratio.max_block_rejected: {max(flagged):.2f}" if flagged
          else "width_ratio.max_block_rejected: n/a")


if __name__ == "__main__":
    main()
