"""How well a fit matches its data, in the check's numbers: what ``infer`` keeps in run.json
as ``fit_quality`` (the api passes ``fit_quality`` to ``infer.run.infer`` as its ``quality``)
and the CLI prints after a fit."""
from __future__ import annotations

import numpy as np

from ..infer.data_starts import track_estimates
from .check import check, clean, fmt_sigma
from .workflow import observable_fits

FAR_RMS = 3.0  # residual RMS (noise units) above which a fit is far from the data
FAR_START = 5.0  # a track's fitted start this many standard errors from its first samples


def fit_quality(model, idata) -> dict:
    """How well the fit matches the data, from the check's own numbers (``diagnose.check``):
    residual RMS in noise units overall and per observable, the worst time window, the
    check's one-line verdict, each observed track's start against its first samples, and
    warnings in words where the fit is far from the data (its intervals then describe a
    wrong model)."""
    fits = observable_fits(model, idata)
    report = check(fits)
    windows = [(o.name, w) for o in report.observables for w in o.windows
               if np.isfinite(w.rms_sigma)]
    worst = max(windows, key=lambda p: p[1].rms_sigma, default=None)
    if report.consistent:
        verdict = "residuals are consistent with the noise"
    else:
        f = report.flags[0]
        verdict = f.message
    q = {"rms_sigma": report.rms_sigma, "n": report.n,
         "observables": {o.name: o.rms_sigma for o in report.observables},
         "worst_window": None if worst is None else {
             "observable": worst[0], "label": worst[1].label, "t_start": worst[1].t_start,
             "t_end": worst[1].t_end, "rms_sigma": worst[1].rms_sigma},
         "consistent": report.consistent, "verdict": verdict,
         "starts": start_agreement(model, fits)}
    warnings = []
    if np.isfinite(report.rms_sigma) and report.rms_sigma > FAR_RMS:
        warnings.append(
            f"the fit is far from the data (residual RMS {fmt_sigma(report.rms_sigma)}, above "
            f"{FAR_RMS:g}σ): its intervals describe a model that does not fit, not the "
            "uncertainty of the real values. Look for a missing effect (`physdsl check`, "
            "`physdsl diagnose`) or another basin (start values with --init)")
    far = [s for s in q["starts"] if s["sigma"] > FAR_START]
    if far:
        s = max(far, key=lambda s: s["sigma"])
        warnings.append(
            f"{s['observable']} starts at {s['fitted']} in the fit but at {s['first_samples']} "
            f"in the first samples ({s['sigma']:.0f} standard errors apart): the initial-state "
            "unknowns are far from what the data show, and the intervals describe a wrong "
            "model. Give start values from the first samples with --init")
    q["warnings"] = warnings
    return clean(q)


def start_agreement(model, fits) -> list[dict]:
    """Per observed track that starts near t = 0: its fitted value at the first measured time
    against the first samples' estimate there (a low-order polynomial through them, from
    ``data_starts``), in standard errors of that estimate."""
    by_name = {f.name: f for f in fits}
    out = []
    for e in track_estimates(model.scene):
        f = by_name.get(e.obs)
        if f is None or e.quantity == "orientation" or not f.mask[0].all():
            continue
        t0 = float(f.times[0])
        first = np.asarray(e.value, float) + (0.0 if e.slope is None else np.asarray(e.slope) * t0)
        diff = np.asarray(f.point[0], float) - first
        if e.quantity == "angle":
            diff = (diff + np.pi) % (2 * np.pi) - np.pi
        sd = np.maximum(np.asarray(e.value_sd, float), 1e-300)
        z = float(np.max(np.abs(diff) / sd))
        fmt = lambda v: ("(" + ", ".join(f"{x:.4g}" for x in v) + ")" if v.size > 1  # noqa: E731
                         else f"{float(v[0]):.4g}") + f" {f.unit}"
        out.append({"observable": e.obs, "t": t0, "fitted": fmt(np.asarray(f.point[0], float)),
                    "first_samples": fmt(first), "sigma": z})
    return out


def fit_quality_lines(q: dict) -> list[str]:
    """The fit quality as the CLI prints it (stdout)."""
    def sig(x):
        return fmt_sigma(float("nan") if x is None else x)

    if "error" in q:
        return [f"fit: quality not computed ({q['error']})"]

    per = ", ".join(f"{k} {sig(v)}" for k, v in q["observables"].items())
    lines = [f"fit: residual RMS {sig(q['rms_sigma'])} overall in noise units ({per})"]
    w = q.get("worst_window")
    if w:
        lines.append(f"  worst window: {w['observable']} {w['label']} {sig(w['rms_sigma'])}")
    lines.append(f"  check: {q['verdict']}")
    return lines
