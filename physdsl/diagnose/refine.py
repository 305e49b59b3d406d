"""The loop a user would otherwise run by hand: infer -> check -> diagnose -> add the best
confirmed effect to a new scene file -> infer again, until the residuals reach the noise or
nothing in the library helps. The user's file is never edited: round k lives in
``OUT/round-k/scene.phys``; ``OUT/refine.json`` records every round's error."""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from .. import io
from ..compile import Model
from ..syntax import load

CONSISTENT_RMS = 1.3  # residual RMS in noise units that counts as "explained"


@dataclass
class Round:
    index: int
    scene: Path
    rms_sigma: float
    elpd: float
    added: dict | None
    verdict: str


def refine(scene_path, outdir, *, max_rounds: int = 3, backend: str = "map", chains: int = 2,
           warmup: int = 300, samples: int = 300, seed: int = 0, force: bool = False,
           confirm_top: int = 2, echo=print) -> list[Round]:
    """Fit, check, diagnose and extend the scene until it explains the data; returns the rounds."""
    from .candidates import physics_candidates
    from .rank import (combined_loo, diagnose, fit_with_fallback, loo_reliability,
                       start_setting, with_effect)
    from .workflow import point_estimate

    out = io.prepare_outdir(outdir, force=force)
    scene_path = Path(scene_path)
    current = out / "round-0" / "scene.phys"
    current.parent.mkdir(parents=True, exist_ok=True)
    _copy_scene(scene_path, current)
    rounds: list[Round] = []
    added = None
    start: dict = {}  # where the first chain of a round's fit starts (see below)
    for k in range(max_rounds + 1):
        rdir = current.parent
        model = Model(load(current))
        echo(f"round {k}: fitting {current} ({backend}, {chains} chains)")
        idata = fit_with_fallback(model, backend, chains=chains, warmup=warmup, samples=samples,
                                  seed=seed, outdir=rdir / "fit", force=True, progress=False,
                                  start=start_setting(start))
        if "fit_note" in idata.attrs:
            echo(f"round {k}: {idata.attrs['fit_note']}")
        report = model.check(idata, outdir=rdir / "check")
        loo = combined_loo(idata)
        elpd = float(loo.elpd_loo)
        echo(f"round {k}: residual RMS {report.rms_sigma:.2f}σ, ELPD {elpd:.1f}")
        caveat = loo_reliability(loo)
        if caveat:
            echo(f"  note: {caveat}")
        for line in report.text().splitlines()[1:]:
            echo("  " + line)
        if report.rms_sigma <= CONSISTENT_RMS or k == max_rounds:
            verdict = ("residuals consistent with the noise" if report.rms_sigma <= CONSISTENT_RMS
                       else "stopped: --max-rounds reached")
            rounds.append(Round(k, current, float(report.rms_sigma), elpd, added, verdict))
            break
        diag = diagnose(model, idata, confirm_top=max(confirm_top, 1), outdir=rdir / "diagnosis",
                        check_report=report, echo=echo)
        echo(f"round {k}: {diag.verdict}")
        echo(diag.table())
        rounds.append(Round(k, current, float(report.rms_sigma), elpd, added, diag.verdict))
        if diag.winner is None:
            break
        w = diag.winner
        added = {"effect": w.effect, "target": w.target}
        # the next round starts where the diagnosis's refit ended: this round's fit and the
        # added strength's fitted median (a start from the prior can settle in a poor basin of
        # a contact scene: billiards' second round ended at 7.85σ where the refit had 0.97σ)
        start = {**point_estimate(model, idata), w.fitted["name"]: w.fitted["median"]}
        nxt = out / f"round-{k + 1}" / "scene.phys"
        cand = next(c for c in physics_candidates(model.scene) if c.key == f"{w.effect}@{w.target}")
        text = with_effect(model.scene, cand)
        io.write_text(nxt, text)
        _copy_data(scene_path.parent, nxt.parent)
        echo(f"round {k}: added `{w.snippet.strip()}` -> {nxt}")
        current = nxt
    _write_summary(out, rounds)
    return rounds


def _copy_scene(src: Path, dst: Path) -> None:
    """Copy the user's scene and its data, so its relative data paths resolve from ``dst``."""
    io.write_text(dst, src.read_text(encoding="utf-8"))
    _copy_data(src.parent, dst.parent, skip=src.name)


def _copy_data(src_dir: Path, dst_dir: Path, skip: str = "") -> None:
    """Copy the measurement files beside a scene (CSV, JSON, images, meshes) into ``dst_dir``."""
    for item in src_dir.iterdir():
        target = dst_dir / item.name
        if item.name == skip or target.exists():
            continue
        if item.is_file() and item.suffix.lower() in (".csv", ".json", ".png", ".jpg", ".obj", ".phys"):
            shutil.copy2(item, target)
        elif item.is_dir() and item.name == "frames":
            shutil.copytree(item, target)


def _write_summary(out: Path, rounds: list[Round]) -> None:
    data = {"rounds": [{"scene": str(r.scene), "rms_sigma": r.rms_sigma, "elpd": r.elpd,
                        "added": r.added, "verdict": r.verdict} for r in rounds]}
    io.write_json(out / "refine.json", data)
    lines = ["| round | scene | added | RMS (σ) | ELPD |", "|---|---|---|---|---|"]
    for r in rounds:
        add = f"{r.added['effect']} on {r.added['target']}" if r.added else "—"
        lines.append(f"| {r.index} | {r.scene} | {add} | {r.rms_sigma:.2f} | {r.elpd:.1f} |")
    io.write_text(out / "refine.md", "\n".join(lines) + "\n")
    _plot(out, rounds)


def _plot(out: Path, rounds: list[Round]) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.2))
    ax = fig.add_subplot(1, 2, 1)
    idx = [r.index for r in rounds]
    ax.plot(idx, [r.rms_sigma for r in rounds], "o-")
    ax.axhline(1.0, color="gray", ls="--", lw=0.8)
    ax.set_xlabel("round")
    ax.set_ylabel("residual RMS (noise units)")
    ax.set_yscale("log")
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.plot(idx, [r.elpd for r in rounds], "o-", color="C1")
    ax2.set_xlabel("round")
    ax2.set_ylabel("ELPD (PSIS-LOO)")
    fig.tight_layout()
    with io.atomic_path(out / "refine.png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
