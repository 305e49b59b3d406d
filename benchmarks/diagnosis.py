"""Diagnosis benchmark on the hidden-effect examples: prints ``name: value`` lines and a table.

For each ``examples/hidden-effect/CASE`` (``naive.phys`` lacks the effect named in
``truth.json`` ``{"hidden_effect": {"effect", "target"}}``): fit the naive scene (MAP +
Laplace, the backend ``diagnose`` itself refits with), run ``diagnose`` (score tests of every
candidate, then refits of the best ``--confirm`` physical candidates) and report

- ``score_rank.CASE``: rank of the true effect on the true target among the *physical*
  candidates by score test alone (1 = the score test found it),
- ``rank.CASE``: its rank in the final table (all candidates, after confirmation);
  candidates that act exactly alike on the data (``same_as``) share a rank,
- ``winner.CASE``: the confirmed effect (or ``none``), ``verdict.CASE``,
- ``rms_before.CASE`` / ``rms_after.CASE``: residual RMS in noise units without the effect and
  after refitting with the winner,
- ``delta_elpd.CASE`` / ``delta_lfo.CASE``: the winner's and the true effect's evidence
  (when the true effect was among the refitted candidates),
- ``fitted.CASE`` / ``true_fitted.CASE``: the winner's and the true effect's (when refitted)
  fitted strength (median and 90% interval) and the truth,
- ``seconds.CASE``: wall time (fit, score tests, confirmation) and ``cpu_seconds.CASE``, the
  CPU time of the case's process (wall time on a shared machine is inflated by other load;
  the load average is printed with it).

With ``--mode refine`` (or ``both``, the default) the case's naive scene also goes through
``refine`` (the CLI's defaults: MAP, up to 3 rounds) and the run reports

- ``named_all.CASE``: 1 when the final scene has every hidden effect of ``truth.json``
  (``hidden_effect`` and ``also_hidden``: law and target; ``X,*`` is met by the law on any pair
  of ``X``), else 0,
- ``final_rms_sigma.CASE``: the final round's residual RMS in noise units,
- ``rounds.CASE``: the rounds refine fitted (round 0 is the naive scene), with each round's
  action and RMS in ``actions.CASE``,
- ``wall_s.CASE``: refine's wall time, ``cpu_s.CASE`` its CPU time; ``refit.CASE``: each hidden strength in the final fit
  (mean and 90% interval) against the truth,
- ``named_right.CASE``: 1 when every hidden law is on its target and no other law is on any
  hidden target (the right law, not only the right place: ``hinge_viscous`` / ``hinge_coulomb``,
  ``drag_linear`` / ``drag_quadratic``; ``damped_chain``: damping on every hinge),
- ``effects_added.CASE``: the effects refine added beyond the naive scene's.

With ``--mode false-positives`` the refine loop runs on each case of ``examples/no-effect``
(20 MuJoCo recordings whose naive scene is the whole physics; ``tools/make_data/no_effect.py``)
and the run prints ``effects_added.CASE`` and ``false_positive_rate: x/20`` (the cases where
refine added any effect; the goal is at most 2, the nominal rate of its tests).

With ``--profile`` (refine only) the case's ``refine`` runs with timers on its stages (wrappers
put on the functions named in ``PROFILED``; nothing in physdsl changes): per stage
``profile.STAGE.CASE: wall W s, cpu C s, compile K s, calls N`` (inclusive: a refit's time
holds its fits; ``compile`` is JAX's tracing, lowering and XLA compile time spent inside the
stage, from ``jax.monitoring``; compiles in ``physdsl.ahead``'s background thread are not a
stage's, and ``compile_ahead_s.CASE`` sums them). ``--all`` runs every hidden-effect case
that way, each in its own process, and prints ``wall_s.CASE``, ``cpu_s.CASE``,
``compile_s.CASE``, ``peak_rss_mb.CASE``, ``named.CASE`` (1: every hidden effect named) and
``final_rms_sigma.CASE``. Profiled runs start with an empty compilation cache (a user's first
run) unless ``--warm-cache``.

Each case runs in its own process with a time limit (``--timeout``, seconds), so a case that
cannot finish is reported as such and the others still run; its refits are reported on stderr
as they go.

Run: .venv/bin/python benchmarks/diagnosis.py [--case thrown_ball [--case pendulum]] [--confirm 2]
[--mode diagnose|refine|both|false-positives] [--timeout 600] [--profile] [--all]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "examples" / "hidden-effect"
NO_EFFECT = ROOT / "examples" / "no-effect"  # nothing hidden: the false-positive check


def _run_child(name: str, cmd: list[str], timeout: float) -> dict:
    """Run one case in its own process, passing its progress lines (``[name] ...``) on to
    stderr as they come; its result, or why there is none."""
    import threading

    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    def stop():  # SIGTERM first: a profiled case prints the stages it reached
        proc.terminate()
        threading.Timer(60, proc.kill).start()

    timer = threading.Timer(timeout, stop)
    timer.start()
    lines = []
    for ln in proc.stdout:
        if ln.startswith(f"[{name}] "):
            print(ln, end="", file=sys.stderr, flush=True)
        lines.append(ln.rstrip("\n"))
    proc.wait()
    timed_out = not timer.is_alive()
    timer.cancel()
    result = next((ln for ln in lines if ln.startswith("RESULT ")), None)
    if result is not None:
        return json.loads(result[len("RESULT "):])
    if timed_out:
        return {"case": name, "error": f"did not finish within {timeout:.0f} s"}
    lines = [ln for ln in lines if ln.strip() and not ln.startswith(("For simplicity", "-----"))]
    errs = [ln for ln in lines if "Error" in ln.split(":")[0]]
    tail = (errs or lines or ["no output"])[-1]
    return {"case": name, "error": f"failed (exit {proc.returncode}): {tail}"}


def run_case(name: str, confirm: int, seed: int) -> dict:
    """Fit, diagnose and score one case in this process; returns the figures as a dict."""
    import numpy as np

    import physdsl  # noqa: F401 - float64
    from physdsl.compile import Model
    from physdsl.diagnose.edits import unknown_key
    from physdsl.diagnose.rank import diagnose
    from physdsl.infer.fit import quick_fit
    from physdsl.diagnose.candidates import Candidate
    from physdsl.syntax import load

    folder = CASES / name
    truth = json.loads((folder / "truth.json").read_text())
    hidden = truth["hidden_effect"]
    true_key = f"{hidden['effect']}@{hidden['target']}"
    t0, c0 = time.perf_counter(), time.process_time()
    model = Model(load(folder / "naive.phys"))
    idata = quick_fit(model, seed=seed)
    t1 = time.perf_counter()
    diag = diagnose(model, idata, confirm_top=confirm,
                    echo=lambda line: print(f"[{name}] {line}", file=sys.stderr, flush=True))
    t2 = time.perf_counter()
    keys = [f"{r.effect}@{r.target}" for r in diag.ranking]
    physical = sorted((r for r in diag.ranking if r.kind == "effect"),
                      key=lambda r: (r.log_p, -r.statistic))
    # candidates acting exactly alike (same score column) share a place: the data cannot order them
    phys_keys = list(dict.fromkeys(r.same_as or f"{r.effect}@{r.target}" for r in physical))
    row = next((r for r in diag.ranking if f"{r.effect}@{r.target}" == true_key), None)
    true_place = (row.same_as or true_key) if row is not None else None
    w = diag.winner
    out = {
        "case": name, "true": true_key,
        "score_rank": phys_keys.index(true_place) + 1 if true_place in phys_keys else None,
        "n_physical": len(phys_keys),
        "rank": row.rank if row is not None else None,
        "n_candidates": diag.ranking[-1].rank if diag.ranking else 0,
        "top_score": keys[0] if keys else None,
        "winner": f"{w.effect}@{w.target}" if w else None,
        # the true effect acts exactly like the winner on these data (same score column)
        "true_same_as": row.same_as if row is not None else None,
        # the true effect's evidence ties the winner's (ΔELPD and ΔLFO within 4): shared rank
        "true_tied_with": row.tied_with if row is not None else None,
        "verdict": diag.verdict,
        "rms_before": diag.rms_sigma,
        "rms_after": w.rms_after if w else (row.rms_after if row else None),
        "true_confirmed": bool(row.confirmed) if row is not None else None,
        "true_delta_elpd": row.delta_elpd if row is not None else None,
        "true_delta_lfo": row.delta_lfo if row is not None else None,
        "winner_delta_elpd": w.delta_elpd if w else None,
        "winner_delta_lfo": w.delta_lfo if w else None,
        "seconds_fit": t1 - t0, "seconds_score": diag.seconds.get("score_tests"),
        "seconds_confirm": diag.seconds.get("confirmation"), "seconds": t2 - t0,
        "cpu_seconds": time.process_time() - c0,
    }
    for label, r in (("fitted", w), ("true_fitted", row)):
        if r is None or not r.fitted:
            continue
        cand = Candidate("effect", r.effect, tuple(r.target.split(",")))
        key = unknown_key(model.scene, cand)
        value = truth.get("parameters", {}).get(key)
        out[label] = {**r.fitted, "truth": None if value is None else float(np.asarray(value))}
    return out


def _hidden(truth: dict) -> list[tuple[str, str]]:
    """Every hidden effect of a case's truth as (law, target); none for a no-effect case."""
    effects = [truth["hidden_effect"], *truth.get("also_hidden", [])] if truth.get("hidden_effect") else []
    return [(e["effect"], e["target"]) for e in effects]


def _named_right(effects, hidden, naive=frozenset()) -> bool:
    """Every hidden law on its target and no other law added on any hidden target: the right
    law named, not only the right place (viscous vs Coulomb in one hinge, linear vs quadratic
    drag). Laws the naive scene already has (spinning_ball's known drag) are not added."""
    if not all(_named(effects, law, target) for law, target in hidden):
        return False
    places = {tuple(target.split(",")) for _, target in hidden}
    return all((e, t) in {(law, tuple(target.split(","))) for law, target in hidden}
               for e, t in set(effects) - set(naive) if t in places)


def _named(effects, law: str, target: str) -> bool:
    """Whether a scene's (effect, target tuple) pairs contain the law on the target; ``X,*``
    (one coefficient for every contact of X) is met by the law on any pair of X."""
    parts = tuple(target.split(","))
    if parts[-1] == "*":
        return any(e == law and t[0] == parts[0] for e, t in effects)
    return (law, parts) in effects


def run_refine(name: str, seed: int, folder: Path | None = None) -> dict:
    """Run ``refine`` on one case's naive scene (the CLI's defaults) and score the final scene
    against the truth: every hidden effect named (the right law), the effects refine added
    beyond the naive scene's, final RMS, rounds, wall time, refitted values."""
    import csv
    import tempfile

    import physdsl  # noqa: F401 - float64
    from physdsl.diagnose.refine import refine
    from physdsl.syntax import load

    folder = CASES / name if folder is None else folder
    naive = {(e.effect, tuple(e.target)) for e in load(folder / "naive.phys").effects}
    truth = json.loads((folder / "truth.json").read_text())
    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        rounds = refine(folder / "naive.phys", Path(tmp) / "refine", seed=seed,
                        echo=lambda line: print(f"[{name}] {line}", file=sys.stderr, flush=True))
        wall = time.perf_counter() - t0
        last = rounds[-1]
        final = load(last.scene)
        effects = {(e.effect, tuple(e.target)) for e in final.effects}
        with (Path(last.scene).parent / "fit" / "summary.csv").open() as f:
            summary = {r["name"]: r for r in csv.DictReader(f)}
    refit = {}
    naive_unknowns = set(truth.get("naive_unknowns", ()))
    for key, value in truth.get("parameters", {}).items():
        # an effect's strength (``law@target.name``), or a shared ``param`` that refine added
        # for a material-wide law (billiards' ``table_contact_friction``)
        if "@" not in key and (key in naive_unknowns or key not in summary):
            continue
        name = _shared_param(final, key) or key
        rows = [summary[k] for k in summary if k == name or k.startswith(name + "[")]
        refit[key] = {"truth": value, "mean": [float(r["mean"]) for r in rows] or None,
                      "q5": [float(r["q5"]) for r in rows] or None,
                      "q95": [float(r["q95"]) for r in rows] or None}
    return {
        "named_all": int(all(_named(effects, law, target) for law, target in _hidden(truth))),
        "named_right": int(_named_right(effects, _hidden(truth), naive)),
        "effects_added": sorted(f"{e}@{','.join(t)}" for e, t in effects - naive),
        "final_rms_sigma": last.rms_sigma, "rounds": len(rounds), "wall_s": wall,
        "cpu_s": time.process_time() - c0,
        "actions": [{"action": r.action, "added": r.added, "replaced": r.replaced,
                     "rms_sigma": r.rms_sigma} for r in rounds],
        "final_effects": sorted(f"{e}@{','.join(t)}" for e, t in effects if e != "gravity"),
        "refit": refit, "final_verdict": last.verdict,
    }


def _shared_param(scene, key: str) -> str | None:
    """The one ``param`` an effect's strength ``effect@target.param`` is written as in
    ``scene`` (a material-level or body-wide candidate: ``ball_rolling_resistance``), else
    None (the strength is its own unknown, or the effect is not in the scene)."""
    from physdsl.expr import references

    use, _, param = key.rpartition(".")
    refs = [references(e.params[param]) for e in scene.effects if e.key == use and param in e.params]
    return next(iter(refs[0])) if refs and len(refs[0]) == 1 else None


# (module, attribute, stage): the functions timed by ``--profile``. Inclusive: a refit holds
# its fits, a fit its multistart, Laplace, predictions and block check.
PROFILED = (
    ("physdsl.diagnose.refine", "_fit", "round fit (fit, check, evidence)"),
    ("physdsl.infer.fit", "fit_with_fallback", "fit"),
    ("physdsl.infer.fit", "quick_fit", "quick fit"),
    ("physdsl.infer.run", "starts", "multistart"),
    ("physdsl.infer.backends.map", "find_modes", "MAP modes"),
    ("physdsl.infer.backends.map", "laplace_sqrt", "Laplace"),
    ("physdsl.infer.output", "build_inference_data", "predictions"),
    ("physdsl.infer.intervals", "add_robust", "robust intervals"),
    ("physdsl.infer.intervals", "_block_check", "block check"),
    ("physdsl.diagnose.quality", "fit_quality", "fit quality"),
    ("physdsl.diagnose.workflow", "check_model", "check"),
    ("physdsl.diagnose.loo", "combined_loo", "PSIS-LOO"),
    ("physdsl.diagnose.evidence", "laplace_log_evidence", "Laplace evidence"),
    ("physdsl.diagnose.stepwise", "reexamine", "re-examination"),
    ("physdsl.diagnose.rank", "diagnose", "diagnose"),
    ("physdsl.diagnose.screening", "score_all", "score tests"),
    ("physdsl.diagnose.confirm", "confirm", "confirmation"),
    ("physdsl.diagnose.confirm", "Baseline.__init__", "leave-future-out baseline"),
    ("physdsl.diagnose.confirm", "refit", "candidate refit"),
    ("physdsl.diagnose.lfo", "lfo_points", "leave-future-out predictions"),
)
COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration",
                  "/jax/core/compile/jaxpr_to_mlir_module_duration",
                  "/jax/core/compile/backend_compile_duration")


class StageTimer:
    """Wall, CPU and JAX compile seconds per stage (``PROFILED``), inclusive; a stage nested in
    itself counts once. ``quick fit`` on a Model with a cut-off is the leave-future-out fit."""

    def __init__(self):
        self.totals: dict[str, list[float]] = {}  # stage -> [wall, cpu, compile, calls]
        self.active: list[str] = []
        self.compile = 0.0
        self.compile_ahead = 0.0  # of ``compile``: in the background thread (``physdsl.ahead``)
        self.ahead_thread = ""  # that thread's name (``install``)

    def on_event(self, event: str, seconds: float, **_) -> None:
        if event in COMPILE_EVENTS:
            self.compile += seconds
            if threading.current_thread().name.startswith(self.ahead_thread):
                self.compile_ahead += seconds  # beside the stages, not inside one
                return
            for label in set(self.active):
                self.totals[label][2] += seconds

    def wrap(self, fn, label: str):
        import functools

        timer = self

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            name = label
            if label == "quick fit" and getattr(args[0] if args else kwargs.get("model"),
                                                "until", None) is not None:
                name = "leave-future-out fit"
            if name in timer.active:
                return fn(*args, **kwargs)
            row = timer.totals.setdefault(name, [0.0, 0.0, 0.0, 0])
            timer.active.append(name)
            w, c = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                row[0] += time.perf_counter() - w
                row[1] += time.process_time() - c
                row[3] += 1
                timer.active.remove(name)
        return timed

    def install(self) -> None:
        """Put the timers on every ``PROFILED`` function, wherever physdsl imported it."""
        import importlib

        import jax

        from physdsl.ahead import THREAD_NAME

        self.ahead_thread = THREAD_NAME
        jax.monitoring.register_event_duration_secs_listener(self.on_event)
        importlib.import_module("physdsl.diagnose.refine")
        mods = [m for n, m in list(sys.modules.items()) if n.startswith("physdsl") and m]
        for modname, attr, label in PROFILED:
            owner = importlib.import_module(modname)
            if "." in attr:  # a method
                cls, meth = attr.split(".")
                klass = getattr(owner, cls)
                setattr(klass, meth, self.wrap(getattr(klass, meth), label))
                continue
            orig = getattr(owner, attr)
            new = self.wrap(orig, label)
            for m in mods:
                for k, v in list(vars(m).items()):
                    if v is orig:
                        setattr(m, k, new)


def run_profiled(name: str, seed: int) -> dict:
    """``run_refine`` with the stage timers on; adds the profile, compile seconds and peak RSS."""
    import resource

    import signal

    def stop(signum, frame):  # the parent's time limit: end with the profile so far
        raise TimeoutError("stopped at the time limit")

    signal.signal(signal.SIGTERM, stop)
    timer = StageTimer()
    timer.install()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        res = run_refine(name, seed)
    except BaseException as err:  # noqa: BLE001 - report the stages reached
        res = {"error": f"{type(err).__name__}: {err}", "wall_s": time.perf_counter() - t0,
               "cpu_s": time.process_time() - c0}
    res["profile"] = {k: v for k, v in timer.totals.items()}
    res["compile_s"] = timer.compile
    res["compile_ahead_s"] = timer.compile_ahead
    from physdsl import ahead
    res["ahead"] = dict(ahead.COUNTS)
    res["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return res


def run_check(name: str, seed: int) -> dict:
    """Fit one no-effect case as ``refine``'s round 0 does (MAP, its defaults) and run the check:
    whether it calls the residuals consistent with the noise, each axis's test p-values, and
    the standardised residuals themselves (to measure other statistics without refitting)."""
    import numpy as np

    import physdsl  # noqa: F401 - float64
    from physdsl.compile import Model
    from physdsl.diagnose.quality import fit_quality
    from physdsl.diagnose.residuals import residuals
    from physdsl.diagnose.check import check
    from physdsl.diagnose.workflow import observable_fits
    from physdsl.infer.fit import fit_with_fallback, start_setting
    from physdsl.syntax import load

    t0, c0 = time.perf_counter(), time.process_time()
    model = Model(load(NO_EFFECT / name / "naive.phys"))
    idata = fit_with_fallback(model, "map", chains=2, warmup=300, samples=300, seed=seed,
                              progress=False, start=start_setting({}), quality=fit_quality)
    fits = observable_fits(model, idata)
    report = check(fits)
    axes = {}
    for fit, obs in zip(fits, report.observables):
        r = residuals(fit).r
        for j, ax in enumerate(obs.axes):
            axes[f"{obs.name}.{ax.axis}"] = {
                "p": {k: float(v) for k, v in ax.p_values.items()}, "consistent": bool(ax.consistent),
                "r": [None if not np.isfinite(x) else round(float(x), 5) for x in r[:, j]]}
    return {"consistent": bool(report.consistent), "rms_sigma": float(report.rms_sigma),
            "axes": axes, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def _check_summary(results: list[dict]) -> str:
    """Per case: the check's verdict at the fitted true model and its smallest p-value (test and
    axis); then ``check_false_alarm_rate: x/N``."""
    lines = []
    ran = [r for r in results if "axes" in r]
    for r in results:
        n = r["case"]
        if "axes" not in r:
            lines.append(f"error.{n}: {r.get('error')}")
            continue
        test, axis, p = min(((t, a, v) for a, ax in r["axes"].items() for t, v in ax["p"].items()),
                            key=lambda x: x[2])
        lines.append(f"check_consistent.{n}: {int(r['consistent'])} (RMS {r['rms_sigma']:.3f}σ, "
                     f"smallest p {p:.2g}: {test} on {axis}; {len(r['axes'])} axes; "
                     f"{r['wall_s']:.0f} s wall, {r['cpu_s']:.0f} s CPU)")
    alarms = sum(not r["consistent"] for r in ran)
    lines.append(f"check_false_alarm_rate: {alarms}/{len(ran)}")
    return "\n".join(lines)


def _fmt(v, spec="") -> str:
    if v is None:
        return "—"
    return format(v, spec) if spec else str(v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", default=[],
                    help="a case to run (repeat for several; default: all)")
    ap.add_argument("--confirm", type=int, default=2, help="physical candidates to refit")
    ap.add_argument("--timeout", type=float, default=2400.0, help="seconds per case")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mode", choices=("diagnose", "refine", "both", "false-positives", "check"),
                    default="both",
                    help="one diagnosis round, the refine loop, or both (hidden-effect cases); "
                         "false-positives: the refine loop on the no-effect cases (examples/no-effect); "
                         "check: the check's verdict at the fitted true model of the no-effect cases")
    ap.add_argument("--json", type=Path, help="also write every case's result to this JSON file")
    ap.add_argument("--profile", action="store_true",
                    help="refine with timers per stage (implies --mode refine)")
    ap.add_argument("--all", action="store_true",
                    help="every hidden-effect case, profiled, each in its own process")
    ap.add_argument("--warm-cache", action="store_true",
                    help="profiled runs use the user's compilation cache (default: an empty one)")
    ap.add_argument("--one", default="", help=argparse.SUPPRESS)  # worker mode
    args = ap.parse_args()
    if args.all or args.profile:
        args.mode, args.profile = "refine", True
    if args.one:
        if args.profile:
            res = {"case": args.one, **run_profiled(args.one, args.seed)}
            print("RESULT " + json.dumps(res), flush=True)
            return
        res = {"case": args.one}
        if args.mode == "false-positives":
            res.update(run_refine(args.one, args.seed, NO_EFFECT / args.one))
            print("RESULT " + json.dumps(res), flush=True)
            return
        if args.mode == "check":
            res.update(run_check(args.one, args.seed))
            print("RESULT " + json.dumps(res), flush=True)
            return
        if args.mode != "refine":
            res.update(run_case(args.one, args.confirm, args.seed))
        if args.mode != "diagnose":
            res.update(run_refine(args.one, args.seed))
        print("RESULT " + json.dumps(res), flush=True)
        return
    where = NO_EFFECT if args.mode in ("false-positives", "check") else CASES
    known = sorted(p.name for p in where.iterdir() if (p / "truth.json").exists())
    unknown = [n for n in args.case if n not in known]
    if unknown:
        ap.error(f"no case {', '.join(unknown)} in {where.relative_to(ROOT)} (cases: {', '.join(known)})")
    names = args.case or known
    results = []
    for name in names:
        t0 = time.perf_counter()
        cmd = [sys.executable, __file__, "--one", name, "--confirm", str(args.confirm),
               "--seed", str(args.seed), "--mode", args.mode] + (["--profile"] if args.profile else [])
        if args.profile and not args.warm_cache:  # a user's first run: nothing compiled yet
            import tempfile
            with tempfile.TemporaryDirectory() as cache:
                os.environ["PHYSDSL_CACHE_DIR"] = cache
                res = _run_child(name, cmd, args.timeout)
        else:
            res = _run_child(name, cmd, args.timeout)
        res.setdefault("seconds", time.perf_counter() - t0)
        res["load"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
        results.append(res)
        if args.json:
            args.json.write_text(json.dumps(results))
        if args.mode != "check":
            _print_lines(res)
    print()
    if args.mode == "check":
        print(_check_summary(results))
        return
    if args.mode == "false-positives":
        print(_false_positive_summary(results))
        return
    if args.mode != "refine":
        print(_table(results))
    if args.mode != "diagnose":
        print(_refine_table(results))


def _print_lines(r: dict) -> None:
    n = r["case"]
    if "error" in r:
        print(f"error.{n}: {r['error']}", flush=True)
        if "profile" in r:
            print(f"wall_s.{n}: {r['wall_s']:.0f}\ncpu_s.{n}: {r['cpu_s']:.0f}")
            _print_profile(r)
        return
    if "named_all" in r:
        _print_refine(r)
    if "profile" in r:
        _print_profile(r)
    if "score_rank" not in r:
        print(f"load_average.{n}: {r['load']}", flush=True)
        return
    print(f"score_rank.{n}: {_fmt(r['score_rank'])} of {r['n_physical']} physical")
    print(f"rank.{n}: {_fmt(r['rank'])} of {r['n_candidates']}")
    same = f"; the true effect acts exactly like {r['true_same_as']}" if r.get("true_same_as") else ""
    print(f"winner.{n}: {r['winner'] or 'none'} (true {r['true']}{same})")
    print(f"verdict.{n}: {r['verdict']}")
    print(f"delta_elpd.{n}: winner {_fmt(r.get('winner_delta_elpd'), '+.1f')}, true effect "
          f"{_fmt(r.get('true_delta_elpd'), '+.1f')} (confirmed: {r.get('true_confirmed')})")
    print(f"delta_lfo.{n}: winner {_fmt(r.get('winner_delta_lfo'), '+.1f')}, true effect "
          f"{_fmt(r.get('true_delta_lfo'), '+.1f')}")
    print(f"rms_before.{n}: {r['rms_before']:.3f}")
    print(f"rms_after.{n}: {_fmt(r['rms_after'], '.3f')}")
    for label in ("fitted", "true_fitted"):
        if r.get(label):
            f = r[label]
            print(f"{label}.{n}: {f['name']} = {f['median']:.4g} [{f['q5']:.4g}, {f['q95']:.4g}] "
                  f"(truth {_fmt(f['truth'], '.4g')})")
    print(f"seconds.{n}: {r['seconds']:.0f} (fit {r['seconds_fit']:.0f}, score "
          f"{r['seconds_score']:.0f}, confirm {r['seconds_confirm']:.0f})")
    print(f"cpu_seconds.{n}: {r['cpu_seconds']:.0f}")
    print(f"load_average.{n}: {r['load']}", flush=True)


def _print_profile(r: dict) -> None:
    """``--profile``'s stage lines and the per-case figures of ``--all``."""
    n = r["case"]
    for k, (w, c, comp, calls) in sorted(r["profile"].items(), key=lambda kv: -kv[1][0]):
        print(f"profile.{k.replace(' ', '_')}.{n}: wall {w:.1f} s, cpu {c:.1f} s, "
              f"compile {comp:.1f} s, calls {calls}")
    print(f"compile_s.{n}: {r['compile_s']:.1f}")
    if "compile_ahead_s" in r:
        print(f"compile_ahead_s.{n}: {r['compile_ahead_s']:.1f}")
    if "ahead" in r:  # programs compiled ahead; run: called since; taken back: by their caller
        a = r["ahead"]
        print(f"ahead.{n}: prepared {a['prepared']}, run {a['run']}, taken back {a['taken_back']}")
    print(f"peak_rss_mb.{n}: {r['peak_rss_mb']:.0f}")
    if "named_all" in r:
        print(f"named.{n}: {r['named_all']}", flush=True)


def _false_positive_summary(results: list[dict]) -> str:
    """The table of the no-effect cases and ``false_positive_rate: x/N`` (a case that did not
    finish counts as not run, and the rate says how many ran)."""
    ran = [r for r in results if "effects_added" in r]
    bad = [r for r in ran if r["effects_added"]]
    lines = ["| case | effects added | rounds | final RMS (σ) | wall (s) | load |", "|---|---|---|---|---|---|"]
    for r in results:
        if "effects_added" not in r:
            lines.append(f"| {r['case']} | {r.get('error', '')} | | | {r['seconds']:.0f} | {r['load']} |")
            continue
        lines.append(f"| {r['case']} | {', '.join(r['effects_added']) or 'none'} | {r['rounds']} | "
                     f"{r['final_rms_sigma']:.2f} | {r['wall_s']:.0f} | {r['load']} |")
    rate = f"false_positive_rate: {len(bad)}/{len(ran)}"
    if len(ran) < len(results):
        rate += f" ({len(results) - len(ran)} of {len(results)} did not finish)"
    return "\n".join(lines) + "\n" + rate


def _print_refine(r: dict) -> None:
    n = r["case"]
    print(f"effects_added.{n}: {len(r['effects_added'])} ({', '.join(r['effects_added']) or 'none'})")
    print(f"named_right.{n}: {r['named_right']}")
    print(f"named_all.{n}: {r['named_all']} (final effects: {', '.join(r['final_effects']) or 'none'})")
    print(f"final_rms_sigma.{n}: {r['final_rms_sigma']:.3f}")
    print(f"rounds.{n}: {r['rounds']}")
    print(f"actions.{n}: {_actions(r)}")
    print(f"wall_s.{n}: {r['wall_s']:.0f}")
    print(f"cpu_s.{n}: {_fmt(r.get('cpu_s'), '.0f')}")
    for key, f in r["refit"].items():
        got = ("not in the final scene" if f["mean"] is None else
               ", ".join(f"{m:.4g} [{a:.4g}, {b:.4g}]" for m, a, b in zip(f["mean"], f["q5"], f["q95"])))
        print(f"refit.{n}: {key} = {got} (truth {f['truth']})")
    print(f"final_verdict.{n}: {r['final_verdict']}", flush=True)


def _actions(r: dict) -> str:
    """Each round's action and RMS, e.g. ``0: 4.10σ; 1: added quadratic_drag@ball 1.3σ``."""
    out = []
    for i, a in enumerate(r["actions"]):
        what = "" if a["action"] is None else " " + a["action"] + " " + " for ".join(
            f"{d['effect']}@{d['target']}" for d in (a["added"], a["replaced"]) if d)
        out.append(f"{i}:{what} {a['rms_sigma']:.2f}σ")
    return "; ".join(out)


def _refine_table(results: list[dict]) -> str:
    lines = ["| case | rounds | actions and RMS per round | named all | refitted (mean, 90%) vs truth "
             "| wall (s) | CPU (s) | load |", "|---|---|---|---|---|---|---|---|"]
    for r in results:
        if "named_all" not in r:
            lines.append(f"| {r['case']} | | {r.get('error', '')} | | | {r['seconds']:.0f} | | {r['load']} |")
            continue
        refit = "; ".join(
            f"{k}: " + ("—" if f["mean"] is None else ", ".join(f"{m:.3g} [{a:.3g}, {b:.3g}]" for m, a, b
                                                               in zip(f["mean"], f["q5"], f["q95"])))
            + f" vs {f['truth']}" for k, f in r["refit"].items())
        lines.append(f"| {r['case']} | {r['rounds']} | {_actions(r)} | {r['named_all']} | {refit} | "
                     f"{r['wall_s']:.0f} | {_fmt(r.get('cpu_s'), '.0f')} | {r['load']} |")
    return "\n".join(lines)


def _table(results: list[dict]) -> str:
    lines = ["| case | true effect | score rank (physical) | final rank | winner | RMS before → after "
             "| fitted (90%; true effect if refitted, else winner) vs truth | wall / CPU (s) | load |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        if "error" in r:
            lines.append(f"| {r['case']} | | | | {r['error']} | | | {r['seconds']:.0f} | {r['load']} |")
            continue
        rms = f"{r['rms_before']:.2f}σ → {_fmt(r['rms_after'], '.2f')}σ"
        f = r.get("true_fitted") or r.get("fitted")
        fitted = (f"{f['name'].split('.')[-1]} {f['median']:.4g} [{f['q5']:.4g}, {f['q95']:.4g}] "
                  f"vs {_fmt(f['truth'], '.4g')}" if f else "")
        lines.append(f"| {r['case']} | {r['true']} | {_fmt(r['score_rank'])}/{r['n_physical']} | "
                     f"{_fmt(r['rank'])}/{r['n_candidates']} | {r['winner'] or 'none'}"
                     f"{' (≡ true)' if r.get('true_same_as') == r['winner'] and r['winner'] else ''} | {rms} | "
                     f"{fitted} | {r['seconds']:.0f} / {_fmt(r.get('cpu_seconds'), '.0f')} | "
                     f"{r['load']} |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
