"""Write a check Report to a folder: report.json, report.md, PNG plots and an offline index.html.

Plots use matplotlib's object API with the Agg canvas (no pyplot, no global backend change). Every
file is written atomically with ``physdsl.io``; the caller prepares (and guards) the folder.
"""
from __future__ import annotations

import html
import re
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..io import atomic_path, write_json, write_text
from .check import Finding, Report
from .residuals import ObservableFit, Residuals, residuals
from .windows import running_mean, smoothing_width

if TYPE_CHECKING:  # matplotlib itself is imported on the first plot (new_figure)
    from matplotlib.figure import Figure


def slug(name: str) -> str:
    """A file-name-safe form of an observable name ('ball.position' -> 'ball_position')."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_") or "observable"


def write_report(report: "Report", fits: Sequence[ObservableFit], outdir: Path) -> dict[str, Path]:
    """Write report.json, report.md, index.html and per-observable PNGs; return them by key."""
    outdir = Path(outdir)
    files: dict[str, Path] = {}
    plots: dict[str, list[tuple[str, str]]] = {}
    for fit in fits:
        res = residuals(fit)
        flags = [f for f in report.flags if f.observable == fit.name]
        base = slug(fit.name)
        made = []
        for kind, draw in (("fit", plot_fit), ("residuals", plot_residuals),
                           ("speed", plot_speed)):
            fig = draw(res, flags)
            if fig is None:
                continue
            path = outdir / f"{kind}_{base}.png"
            save_png(fig, path)
            files[f"{kind}:{fit.name}"] = path
            made.append((kind, path.name))
        plots[fit.name] = made
    files["json"] = write_json(outdir / "report.json", report.to_dict())
    files["markdown"] = write_text(outdir / "report.md", markdown(report, plots))
    files["html"] = write_text(outdir / "index.html", index_html(report, plots))
    return files


def new_figure(**options) -> "Figure":
    """A matplotlib Figure drawn by Agg, no global pyplot state. matplotlib is imported here, on
    the first plot: it is slow to import (a command that draws nothing should not pay it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**options)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: "Figure", path: Path, dpi: int = 90) -> None:
    """Write ``fig`` atomically as PNG."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)


def _axes(n: int, width: float = 8.0, height: float = 2.4):
    fig = new_figure(figsize=(width, height * n), layout="constrained")
    return fig, [fig.add_subplot(n, 1, i + 1) for i in range(n)]


def _mark_events(ax, events: tuple[float, ...]) -> None:
    for k, e in enumerate(events):
        ax.axvline(e, color="tab:purple", ls=":", lw=1, label="model contact" if k == 0 else None)


def plot_fit(res: Residuals, flags: list["Finding"]) -> Figure:
    """Measured vs central prediction with the predictive band, one panel per axis."""
    fig, axs = _axes(len(res.axes))
    for j, ax in enumerate(axs):
        ok = res.valid[:, j]
        ax.fill_between(res.times, res.band_lo[:, j], res.band_hi[:, j], color="tab:blue",
                        alpha=0.2, lw=0, label=f"{res.band_level:.0%} predictive band")
        ax.plot(res.times, res.center[:, j], color="tab:blue", lw=1.2, label="model")
        ax.plot(res.times[ok], res.measured[ok, j], ".", ms=3, color="k", label="measured")
        _mark_events(ax, res.events)
        ax.set_ylabel(f"{res.axes[j]} [{res.unit}]")
        ax.set_title(f"{res.name}.{res.axes[j]}", fontsize=9, loc="left")
    axs[-1].set_xlabel("t [s]")
    axs[0].legend(fontsize=7, loc="best")
    return fig


def plot_residuals(res: Residuals, flags: list["Finding"]) -> Figure:
    """Standardised residuals over time with ±1σ/±2σ lines, running mean, flagged spans shaded."""
    fig, axs = _axes(len(res.axes))
    for j, ax in enumerate(axs):
        r = res.r[:, j]
        ok = np.isfinite(r)
        ax.axhspan(-1, 1, color="0.9", lw=0)
        for y in (-2, 2):
            ax.axhline(y, color="0.6", ls="--", lw=0.8)
        ax.axhline(0, color="0.4", lw=0.8)
        ax.plot(res.times[ok], r[ok], ".", ms=3, color="k", label="(measured − model) / noise")
        if ok.sum() >= 3:
            sm = running_mean(r, smoothing_width(int(ok.sum())))
            ax.plot(res.times[ok], sm[ok], color="tab:red", lw=1.2, label="running mean")
        for k, f in enumerate(x for x in flags if x.axis == res.axes[j]):
            ax.axvspan(f.t_start, f.t_end, color="tab:orange", alpha=0.25, lw=0,
                       label=f"flagged: {f.shape}" if k == 0 else None)
        _mark_events(ax, res.events)
        ax.set_ylabel(f"{res.axes[j]} [σ]")
        ax.set_title(f"{res.name}.{res.axes[j]} standardised residual", fontsize=9, loc="left")
        ax.legend(fontsize=7, loc="best")
    axs[-1].set_xlabel("t [s]")
    return fig


def plot_speed(res: Residuals, flags: list["Finding"]) -> Figure | None:
    """Standardised residual against model speed, one panel per axis (None without speed)."""
    if res.speed is None:
        return None
    n = len(res.axes)
    fig = new_figure(figsize=(3.2 * n, 3.0), layout="constrained")
    for j in range(n):
        ax = fig.add_subplot(1, n, j + 1)
        ok = np.isfinite(res.r[:, j]) & np.isfinite(res.speed)
        sc = ax.scatter(res.speed[ok], res.r[ok, j], c=res.times[ok], s=6, cmap="viridis")
        ax.axhline(0, color="0.4", lw=0.8)
        ax.set_xlabel("model speed")
        ax.set_ylabel(f"{res.axes[j]} residual [σ]")
        ax.set_title(f"{res.name}.{res.axes[j]}", fontsize=9, loc="left")
    fig.colorbar(sc, ax=fig.axes, label="t [s]")
    return fig


def _num(x: float, digits: int = 3) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}g}"


def markdown(report: "Report", plots: dict[str, list[tuple[str, str]]]) -> str:
    """The report in Markdown: summary, per-axis and per-window tables, flags, plots."""
    out = ["# Model check", "", "```", report.text(), "```", ""]
    if report.flags:
        out += ["## Flags", ""]
        out += [f"- **{f.severity}** `{f.observable}.{f.axis}` {f.t_start:.3g}–{f.t_end:.3g} s, "
                f"shape `{f.shape}` ({f.statistic_name}={_num(f.statistic)}, p={_num(f.p_value, 2)}):"
                f" {f.message}" for f in report.flags]
        out.append("")
    for o in report.observables:
        out += [f"## {o.name} [{o.unit}]", "",
                f"RMS {_num(o.rms_sigma)}σ over {o.n} measurements.", "",
                "| axis | n | RMS σ | mean σ | in band | runs p | lag-1 ρ | verdict |",
                "|---|---|---|---|---|---|---|---|"]
        for a in o.axes:
            out.append(f"| {a.axis} | {a.n} | {_num(a.rms_sigma)} | {_num(a.mean_sigma, 2)} | "
                       f"{_num(a.coverage, 2)} | {_num(a.tests.runs_p, 2)} | "
                       f"{_num(a.tests.lag1, 2)} | {'ok' if a.consistent else 'MISFIT'} |")
        out += ["", "| window | kind | n | RMS σ |", "|---|---|---|---|"]
        out += [f"| {w.label} | {w.kind} | {w.n} | {_num(w.rms_sigma)} |" for w in o.windows]
        out.append("")
        out += [f"![{kind}]({name})" for kind, name in plots.get(o.name, [])]
        out.append("")
    return "\n".join(out)


def index_html(report: "Report", plots: dict[str, list[tuple[str, str]]]) -> str:
    """A self-contained page (inline CSS, relative image links) gathering summary, tables, plots."""
    e = html.escape
    parts = ["<h1>Model check</h1>", f"<pre>{e(report.text())}</pre>",
             "<p><a href='report.json'>report.json</a> · <a href='report.md'>report.md</a></p>"]
    if report.flags:
        parts.append("<h2>Flags</h2><ul>")
        parts += [f"<li class='{f.severity}'>{e(f.message)}</li>" for f in report.flags]
        parts.append("</ul>")
    else:
        parts.append("<p class='ok'>No flags: residuals are consistent with the noise.</p>")
    for o in report.observables:
        parts.append(f"<h2>{e(o.name)} [{e(o.unit)}]</h2>")
        parts.append("<table><tr><th>axis</th><th>n</th><th>RMS σ</th><th>mean σ</th>"
                     "<th>in band</th><th>runs p</th><th>lag-1 ρ</th><th>verdict</th></tr>")
        for a in o.axes:
            verdict = "<span class='ok'>ok</span>" if a.consistent else \
                "<span class='fail'>misfit</span>"
            parts.append(f"<tr><td>{e(a.axis)}</td><td>{a.n}</td><td>{_num(a.rms_sigma)}</td>"
                         f"<td>{_num(a.mean_sigma, 2)}</td><td>{_num(a.coverage, 2)}</td>"
                         f"<td>{_num(a.tests.runs_p, 2)}</td><td>{_num(a.tests.lag1, 2)}</td>"
                         f"<td>{verdict}</td></tr>")
        parts.append("</table><table><tr><th>window</th><th>kind</th><th>n</th><th>RMS σ</th></tr>")
        parts += [f"<tr><td>{e(w.label)}</td><td>{e(w.kind)}</td><td>{w.n}</td>"
                  f"<td>{_num(w.rms_sigma)}</td></tr>" for w in o.windows]
        parts.append("</table>")
        parts += [f"<img src='{e(name)}' alt='{e(kind)} plot of {e(o.name)}'>"
                  for kind, name in plots.get(o.name, [])]
    return html_page("physdsl check", parts)


def html_page(title: str, body: list[str]) -> str:
    """A self-contained page (inline CSS, relative links) around ``body``, HTML already escaped;
    the check report's and refine's summary share it."""
    return "\n".join([
        "<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>",
        "body{font-family:sans-serif;max-width:1000px;margin:1em auto;padding:0 1em}",
        "pre{background:#f4f4f4;padding:.6em;white-space:pre-wrap}",
        "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;"
        "padding:2px 8px;text-align:right}th{background:#eee}",
        ".fail{color:#b00}.warn{color:#a60}.info{color:#06a}.ok{color:#070}",
        "img{max-width:100%;display:block;margin:.5em 0}", "</style></head><body>",
        *body, "</body></html>"]) + "\n"
