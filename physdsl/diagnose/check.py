"""The model-versus-measurement check: where (observable, axis, time span) and how (shape) a fitted
physical model disagrees with the measurements, from posterior-predictive draws.

``check(fits)`` returns a ``Report``: RMS of standardised residuals overall, per observable, axis
and time window, and a ``Finding`` for every axis whose residuals are not consistent with noise.
``write_report`` (re-exported from ``report``) writes it as JSON, Markdown, PNG plots and HTML.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy import stats

from .residuals import ObservableFit, Residuals, residuals
from .shapes import (SHAPE_MEANING, AfterEvent, Envelope, Randomness, ShapeScore, after_event,
                     best_shape, envelope, randomness, shape_scores)
from .windows import (MisfitSpan, Window, choose_windows, rms, smoothing_width,
                      systematic_spans)

__all__ = ["ObservableFit", "Finding", "AxisResult", "ObservableResult", "Report", "check",
           "write_report"]

ALPHA = 0.01           # false-alarm budget of a whole check: shared by every axis and its 5 tests
TESTS = 5              # chi2, runs, lag-1, windows, spans
MIN_SHAPE_R = 0.5      # below this |r| no single shape is named ("systematic, unclassified")


@dataclass(frozen=True)
class Finding:
    """One place where the model fails, machine-readable, with a sentence for people."""

    observable: str
    axis: str
    t_start: float
    t_end: float
    rms_sigma: float      # RMS standardised residual inside [t_start, t_end]
    shape: str            # key of shapes.SHAPE_MEANING, or "systematic"
    statistic: float      # the shape's statistic (see statistic_name)
    statistic_name: str   # "r" (correlation with the shape's regressor), "rms ratio", "rms"
    p_value: float
    severity: str         # "fail" (>= 2 sigma RMS in the span), "warn", or "info"
    detail: str           # what the shape means for this axis, in words
    message: str          # the full line: "<observable>.<axis>: <where>; <detail>; <size>"


@dataclass(frozen=True)
class WindowRMS:
    """RMS standardised residual in one time window."""

    label: str
    kind: str
    t_start: float
    t_end: float
    n: int
    rms_sigma: float
    p_value: float  # chi-square: P(at least this large | noise)


@dataclass(frozen=True)
class AxisResult:
    """Everything computed for one axis of one observable."""

    observable: str
    axis: str
    unit: str
    n: int
    rms_sigma: float
    mean_sigma: float
    coverage: float             # fraction of measurements inside the predictive band
    band_level: float
    tests: Randomness
    windows: list[WindowRMS]
    spans: list[MisfitSpan]     # systematic spans, worst first
    shapes: list[ShapeScore]    # every shape's score over the whole axis
    envelope: Envelope | None
    after: AfterEvent | None
    p_values: dict[str, float]  # the tests deciding consistency (already multiplicity-adjusted)
    consistent: bool            # residuals consistent with noise: no flag raised
    level: float = ALPHA / TESTS  # each test's threshold: ALPHA shared by the check's axes and tests


@dataclass(frozen=True)
class ObservableResult:
    """One observable: its axes and the RMS over all axes, overall and per window."""

    name: str
    unit: str
    rms_sigma: float
    n: int
    axes: list[AxisResult]
    windows: list[WindowRMS]
    events: tuple[float, ...]


@dataclass(frozen=True)
class Report:
    """Result of ``check``: overall, per observable, per axis and per window RMS, and the flags."""

    rms_sigma: float
    n: int
    observables: list[ObservableResult]
    flags: list[Finding] = field(default_factory=list)

    @property
    def consistent(self) -> bool:
        """True when no axis of any observable was flagged as failing (info notes do not count)."""
        return not any(f.severity != "info" for f in self.flags)

    def text(self) -> str:
        """The human summary: overall and per-observable RMS, then one line per flag."""
        n_axes = sum(len(o.axes) for o in self.observables)
        lines = [f"check: {len(self.observables)} observable(s), {n_axes} axes, {self.n} "
                 f"measurements; residual RMS {fmt_sigma(self.rms_sigma)} overall "
                 f"(1σ = consistent with the noise)"]
        for o in self.observables:
            per_axis = ", ".join(f"{a.axis} {fmt_sigma(a.rms_sigma)}" for a in o.axes)
            lines.append(f"  {o.name} [{o.unit}]: {fmt_sigma(o.rms_sigma)} RMS ({per_axis})")
            if o.windows:
                lines.append("    windows: " + " | ".join(
                    f"{w.label} {fmt_sigma(w.rms_sigma)}" for w in o.windows))
        if self.consistent:
            lines.append("✓ residuals are consistent with the noise: RMS near 1σ, no systematic "
                         "pattern (runs test, lag-1 autocorrelation, windows, running residual)")
        for f in self.flags:
            mark = {"fail": "✗", "warn": "!", "info": "i"}[f.severity]
            lines.append(f"{mark} {f.message}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (NaN and infinities become null)."""
        return clean({
            "rms_sigma": self.rms_sigma,
            "n": self.n,
            "consistent": self.consistent,
            "observables": [asdict(o) for o in self.observables],
            "flags": [asdict(f) for f in self.flags],
            "summary": self.text().splitlines(),
        })


def clean(obj: Any) -> Any:
    """Recursively turn numpy values into plain Python and non-finite floats into None."""
    if isinstance(obj, dict):
        return {str(k): clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [clean(v) for v in obj.tolist()]
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


def fmt_sigma(x: float) -> str:
    """A sigma figure for text: '1.02σ', '38σ', 'n/a'."""
    if not math.isfinite(x):
        return "n/a"
    return f"{x:.3g}σ" if x < 100 else f"{x:.0f}σ"


def check(fits: Sequence[ObservableFit], *, windows: int = 4) -> Report:
    """Compare measurements with the posterior predictive: RMS residuals, windows, flags."""
    names = [f.name for f in fits]
    if len(set(names)) != len(names):
        raise ValueError(f"observable names repeat: {names}")
    results: list[ObservableResult] = []
    flags: list[Finding] = []
    all_r: list[np.ndarray] = []
    # Bonferroni over every axis of every observable and the five tests of each: the check as a
    # whole raises a false alarm on pure noise with probability <= ALPHA (per axis, a pendulum's
    # four axes had given about 5% per scene)
    level = ALPHA / TESTS / max(1, sum(len(f.axes) for f in fits))
    for fit in fits:
        res = residuals(fit)
        wins = choose_windows(res.times, res.events, windows)
        axes = []
        for j, axis in enumerate(res.axes):
            ax = check_axis(res, j, wins, level)
            axes.append(ax)
            finding = explain(res, j, ax)
            if finding is not None:
                flags.append(finding)
        all_r.append(res.r[res.valid])
        results.append(ObservableResult(
            name=res.name, unit=res.unit, rms_sigma=rms(res.r), n=int(res.valid.sum()),
            axes=axes, windows=window_rms(res.times, res.r, wins), events=res.events))
    order = {"fail": 0, "warn": 1, "info": 2}
    flags.sort(key=lambda f: (order[f.severity], -f.rms_sigma))
    r_all = np.concatenate(all_r) if all_r else np.zeros(0)
    return Report(rms(r_all), int(r_all.size), results, flags)


def window_rms(times: np.ndarray, r: np.ndarray, wins: list[Window]) -> list[WindowRMS]:
    """RMS and chi-square p of the standardised residuals (all axes given) in each window."""
    r2 = r if r.ndim == 2 else r[:, None]
    out = []
    for w in wins:
        v = r2[w.contains(times)]
        v = v[np.isfinite(v)]
        p = float(stats.chi2.sf(np.sum(v * v), v.size)) if v.size else float("nan")
        out.append(WindowRMS(w.label, w.kind, w.t_start, w.t_end, int(v.size), rms(v), p))
    return out


def axis_tests(t: np.ndarray, r: np.ndarray, wins: list[Window], level: float = ALPHA / TESTS):
    """The five consistency tests of one axis's standardised residuals ``r`` at times ``t``:
    (randomness tests, window RMS, systematic spans at ``level``, p-value per test). The axis
    is consistent with the noise when every p is at least ``level``."""
    tests = randomness(r)
    wr = window_rms(t, r, wins)
    wp = [w.p_value for w in wr if w.n >= 3]
    window_p = min(1.0, min(wp) * len(wp)) if wp else 1.0
    spans = systematic_spans(t, r, alpha=level)
    p_values = {"chi2": tests.chi2_p, "runs": tests.runs_p, "lag1": tests.lag1_p,
                "windows": window_p, "spans": 0.0 if spans else 1.0}
    return tests, wr, spans, p_values


def check_axis(res: Residuals, j: int, wins: list[Window], level: float = ALPHA / TESTS) -> AxisResult:
    """Run the consistency tests (each at ``level``) and shape fits on axis ``j`` of one
    observable."""
    t, r = res.times, res.r[:, j]
    ok = res.valid[:, j]
    tests, wr, spans, p_values = axis_tests(t, r, wins, level)
    consistent = tests.n < 5 or min(p_values.values()) >= level
    inside = (res.measured[:, j] >= res.band_lo[:, j]) & (res.measured[:, j] <= res.band_hi[:, j])
    coverage = float(np.mean(inside[ok])) if ok.any() else float("nan")
    scores = shape_scores(t, res.error[:, j], res.noise[:, j], res.center[:, j],
                          res.velocity[:, j], res.speed)
    env = envelope(t, res.measured[:, j], res.center[:, j])
    after = after_event(t, r, res.events, guard=max(1, smoothing_width(tests.n) // 2),
                        alpha=ALPHA) if not consistent else None
    return AxisResult(res.name, res.axes[j], res.unit, tests.n, tests.rms_sigma, tests.mean_sigma,
                      coverage, res.band_level, tests, wr, spans, scores, env, after, p_values,
                      consistent, level)


def explain(res: Residuals, j: int, ax: AxisResult) -> Finding | None:
    """Turn a failing axis into a Finding (where, shape, size); None when consistent with noise."""
    t, r = res.times, res.r[:, j]
    ok = np.isfinite(r)
    if not ok.any():
        return None
    tv = t[ok]
    if ax.consistent:
        if ax.tests.rms_sigma < 0.5 and ax.tests.chi2_p_low < ALPHA:
            detail = (f"residuals are only {ax.tests.rms_sigma:.2g}× the noise scale: the noise is "
                      f"overestimated (or the measurement smoothed), so uncertainties are too wide")
            return make_finding(res, j, tv[0], tv[-1], ax.tests.rms_sigma, "noise_overestimated",
                                ax.tests.rms_sigma, "rms", ax.tests.chi2_p_low, "info", detail,
                                where="throughout")
        return None
    # where: the worst systematic span, else the worst window, else everything
    if ax.spans:
        a, b = ax.spans[0].t_start, ax.spans[0].t_end
    elif ax.p_values["windows"] < ax.p_values["chi2"]:
        worst = min((w for w in ax.windows if w.n >= 3), key=lambda w: w.p_value)
        a, b = worst.t_start, worst.t_end
    else:
        a, b = tv[0], tv[-1]
    systematic = min(ax.p_values["runs"], ax.p_values["lag1"], ax.p_values["spans"]) < ax.level
    if ax.after is not None:
        e = ax.after
        a, b = e.event, tv[-1]
        post = t >= e.event
        scores = shape_scores(t[post], res.error[post, j], res.noise[post, j], res.center[post, j],
                              res.velocity[post, j], None if res.speed is None else res.speed[post])
        best = best_shape(scores)
        detail = (f"misfit starts after the contact at t={e.event:.3g} s: {fmt_sigma(e.rms_before)}"
                  f" RMS before, {fmt_sigma(e.rms_after)} after (F test p={e.p_value:.2g})")
        if best is not None and abs(best.r) >= MIN_SHAPE_R:
            detail += "; after it, " + shape_phrase(best, res, j, ax, t[post])
        shape, stat, stat_name, p = "after_contact", e.rms_after / max(e.rms_before, 1e-300), \
            "rms ratio", e.p_value
    elif systematic:
        best = best_shape(ax.shapes)
        if best is not None and abs(best.r) >= MIN_SHAPE_R:
            detail = shape_phrase(best, res, j, ax, tv)
            shape, stat, stat_name, p = best.shape, best.r, "r", best.p_value
        else:
            near = f" (closest: {best.shape}, r={best.r:.2f})" if best is not None else ""
            detail = (f"systematic residual (runs test p={ax.tests.runs_p:.2g}, lag-1 "
                      f"ρ={ax.tests.lag1:.2f}) that no single simple shape explains{near}")
            shape, stat, stat_name, p = "systematic", ax.tests.lag1, "lag1", ax.tests.runs_p
    else:
        detail = (f"residuals look random (runs test p={ax.tests.runs_p:.2g}, lag-1 "
                  f"ρ={ax.tests.lag1:.2f}) but are {ax.tests.rms_sigma:.2g}× the noise scale: noise "
                  f"underestimated or unmodelled jitter")
        shape, stat, stat_name, p = "random", ax.tests.rms_sigma, "rms", ax.tests.chi2_p
    inside = ok & (t >= a) & (t <= b)
    span_rms = rms(r[inside])
    severity = "fail" if span_rms >= 2.0 else "warn"
    return make_finding(res, j, a, b, span_rms, shape, stat, stat_name, p, severity, detail)


def make_finding(res: Residuals, j: int, a: float, b: float, span_rms: float, shape: str,
                 stat: float, stat_name: str, p: float, severity: str, detail: str,
                 where: str | None = None) -> Finding:
    """Assemble the Finding and its one-line message."""
    t, r = res.times, res.r[:, j]
    ok = np.isfinite(r)
    tv = t[ok]
    inside = ok & (t >= a) & (t <= b)
    mean = float(np.mean(r[inside])) if inside.any() else 0.0
    if where is None:
        where = when_phrase(a, b, tv)
    if shape in ("noise_overestimated", "random"):
        verb = "fits too well" if shape == "noise_overestimated" else "scatters"
    elif mean < -0.5 * span_rms:
        verb = "overshoots (prediction above measurement)"
    elif mean > 0.5 * span_rms:
        verb = "undershoots (prediction below measurement)"
    else:
        verb = "misses (on both sides)"
    message = (f"{res.name}.{res.axes[j]}: model {verb} {where}; {detail}; "
               f"{fmt_sigma(span_rms)} RMS in that window")
    return Finding(res.name, res.axes[j], float(a), float(b), float(span_rms), shape, float(stat),
                   stat_name, float(p), severity, detail, message)


def when_phrase(a: float, b: float, tv: np.ndarray) -> str:
    """'throughout', 'from t=0.45 s on', 'until t=..', or 'between t=.. and .. s'."""
    step = float(np.median(np.diff(tv))) if tv.size > 1 else 0.0
    at_start = a <= tv[0] + 2 * step
    at_end = b >= tv[-1] - 2 * step
    if at_start and at_end:
        return "throughout"
    if at_end:
        return f"from t={a:.3g} s on"
    if at_start:
        return f"until t={b:.3g} s"
    return f"between t={a:.3g} and {b:.3g} s"


def shape_phrase(s: ShapeScore, res: Residuals, j: int, ax: AxisResult, tv: np.ndarray) -> str:
    """The misfit shape in words, with its statistic and its size in physical terms."""
    unit = res.unit
    rr = f"r={s.r:.2f}"
    if s.shape == "offset":
        sig = s.coef / float(np.nanmean(res.noise[:, j]))
        return f"constant offset of {s.coef:+.3g} {unit} ({sig:+.2g}σ, {rr})"
    if s.shape == "gain":
        return (f"gain error: residual proportional to the predicted value ({rr}); measured ≈ "
                f"{1 + s.coef:.4g} × predicted")
    if s.shape == "delay":
        tau = -s.coef
        verb = "lags" if tau > 0 else "leads"
        return (f"time delay: residual follows the predicted velocity ({rr}); the measurement "
                f"{verb} the model by {abs(tau) * 1e3:.3g} ms")
    if s.shape == "trend_t":
        return f"residual grows linearly with time ({rr})"
    if s.shape == "trend_t2":
        return f"residual grows like time² ({rr}), as from an unmodelled constant force"
    if s.shape == "speed":
        return f"residual grows with speed ({rr}), as from an unmodelled linear drag or friction"
    if s.shape == "speed2":
        return f"residual grows like speed² ({rr}), as from an unmodelled quadratic drag"
    if s.shape == "drag_linear":
        return (f"residual matches the path a missing force ∝ −velocity would bend ({rr}), as "
                f"from linear drag or viscous friction (rate {-s.coef:.3g} 1/s)")
    if s.shape == "drag_quadratic":
        return (f"residual matches the path a missing force ∝ −speed·velocity would bend ({rr}), "
                f"as from quadratic drag (coefficient per mass {-s.coef:.3g} 1/{unit})")
    if s.shape == "phase":
        eps = s.coef
        pace, length = ("faster", "shorter") if eps > 0 else ("slower", "longer")
        return (f"phase drift ({rr}): the measured oscillation runs {pace}, its period about "
                f"{abs(eps) * 100:.2g}% {length} than predicted")
    if s.shape == "decay":
        env = ax.envelope
        faster = s.coef < 0
        text = (f"oscillation amplitude decays {'faster' if faster else 'slower'} than predicted "
                f"({rr})")
        if env is not None:
            span = float(env.times[-1] - env.times[0])
            text += (f"; measured/predicted amplitude goes from {env.ratio[0]:.2f} to "
                     f"{env.ratio[-1]:.2f} over {span:.3g} s")
            if env.rate != 0:
                kind = "extra damping" if env.rate < 0 else "missing damping"
                text += f" ({kind}: e-folding time {1 / abs(env.rate):.3g} s)"
        return text
    return SHAPE_MEANING.get(s.shape, s.shape)

