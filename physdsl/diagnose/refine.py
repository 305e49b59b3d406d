"""The loop a user would otherwise run by hand: infer -> check -> re-examine what the loop added
(swap a law, drop an effect) -> diagnose -> add the best confirmed effect to a new scene file ->
infer again, until no addition, swap or drop improves the evidence. It stops when the residuals
are consistent with the noise (the check's statistics, not an RMS threshold) or when nothing in
the library explains what is left, and then says where and how the model still fails. The
user's file is never edited: round k lives in ``OUT/round-k/scene.phys``; ``OUT/refine.json``
records every round's error and action.

A round works on values: its scene file is parsed once (``edits.Draft``), every candidate is an
edit of that AST resolved to a Scene, and the winner is the typed row that was ranked (its
refit's scene); text is printed once, when the next round's file is written. The last round's
Models (its fit, its refits) are kept while the next round runs, so a Model of the same
structure (the next fit is the winner's refit scene; a drop gives the last scene back) reuses
their compiled programs."""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from html import escape
from pathlib import Path


from .. import io
from ..compile import Model
from ..errors import PhysError, UsageError
from ..infer.fit import fit_with_fallback, start_setting
from ..syntax import load
from .candidates import Candidate
from .edits import Draft
from .loo import loo_reliability
from .quality import fit_quality
from .rank import diagnose
from .screening import score_ahead
from .report import html_page, new_figure, save_png
from .stepwise import judge, parse, reexamine, sources_unexamined
from .workflow import check_model, point_estimate


@dataclass
class Round:
    index: int
    scene: Path
    rms_sigma: float
    elpd: float
    added: dict | None  # the effect this round's scene has beyond the previous one's
    verdict: str
    action: str | None = None  # how this scene came from the previous: added | swapped | dropped
    replaced: dict | None = None  # the effect a swap or a drop took out
    log_evidence: float | None = None  # Laplace log marginal likelihood (None: n/a)
    consistent: bool = False  # the check finds no systematic residual


@dataclass
class _Loop:
    """What carries from one round to the next."""

    out: Path
    user_scene: Path
    fit: dict  # settings of each round's fit
    echo: object
    # effects the loop may swap or drop, each with the scene's effects when last examined
    revisable: dict = field(default_factory=dict)
    change: dict = field(default_factory=lambda: {"action": None, "added": None, "replaced": None})
    start: dict = field(default_factory=dict)  # where the first chain of a round's fit starts
    rounds: list = field(default_factory=list)
    kept: tuple = ()  # the last round's Models and diagnosis: their compiled programs stay alive
    # reaching beyond the library (physdsl.discover.beyond_library, passed in by the api) where
    # nothing in it explains the misfit; its law enters a round only with allow_learned
    beyond: object = None
    allow_learned: bool = False
    ties: list = field(default_factory=list)  # this round's re-examination: swaps the data cannot decide
    # whether the round's fit will likely leave systematic residuals, so that its score tests
    # run: the naive scene, or a winner whose refit did; a swap's or drop's scene alike
    misfit_expected: bool = True


# a library winner that removes less than this share of the excess misfit (RMS² - 1) left by the
# effects the loop chose before, with systematic residuals after it, has a learned force beside it
BESIDE_EXPLAINED = 0.9


def refine(scene_path, outdir, *, max_rounds: int = 3, backend: str = "map", chains: int = 2,
           warmup: int = 300, samples: int = 300, seed: int = 0, force: bool = False,
           confirm_top: int = 2, revise=(), echo=print, progress: bool = False,
           beyond=None, allow_learned: bool = False) -> list[Round]:
    """Fit, check, re-examine, diagnose and extend the scene until no addition, swap or drop
    improves the evidence; returns the rounds. ``revise``: effects of the user's scene
    (``effect@target``) to re-examine like those the loop adds. ``beyond``: called where no
    library effect explains the misfit, or beside a winner that only half explains it
    (``half_explained``): learn a force, distil a law; the law is added to the next round only
    with ``allow_learned`` and where it beats the library on the evidence."""
    scene_path = Path(scene_path)
    user = load(scene_path)  # the user's scene checked before anything is written
    if revise:
        _check_revisable(Draft.of(user), [parse(k) for k in revise])
    out = io.prepare_outdir(outdir, force=force)
    current = out / "round-0" / "scene.phys"
    current.parent.mkdir(parents=True, exist_ok=True)
    _copy_scene(scene_path, current)
    loop = _Loop(out, scene_path, dict(backend=backend, chains=chains, warmup=warmup,
                                       samples=samples, seed=seed, progress=progress), echo,
                 revisable={parse(k).key: (parse(k), None) for k in revise},
                 beyond=beyond, allow_learned=allow_learned)
    for k in range(max_rounds + 1):
        current = _round(loop, k, current, k == max_rounds, confirm_top)
        if current is None:
            break
    _write_summary(out, loop.rounds)
    return loop.rounds


def _round(loop: _Loop, k: int, current: Path, last: bool, confirm_top: int) -> Path | None:
    """Round ``k`` on the scene file ``current``: fit, check, re-examine, diagnose; the next
    round's scene file, or None when the loop stops."""
    draft = Draft.read(current)  # the round's one parse
    model = Model(draft.scene)
    # the score tests' program compiles while the round is fitted (its Model holds it)
    augmented = score_ahead(model, draft) if loop.misfit_expected and not last else None  # noqa: F841
    now = _fit(loop, k, current, model)
    effects = _effects(draft.scene)
    due = [c for c, seen in loop.revisable.values() if seen != effects]
    loop.ties = []
    if due and not last:
        nxt = _reexamine(loop, k, current, draft, now, due, effects)
        if nxt is not None:
            return nxt
    if now.report.consistent or last:
        _record(loop, k, current, now, ("residuals consistent with the noise (runs, autocorrelation, "
                "windows and trend tests at the noise level)" if now.report.consistent
                else "stopped: --max-rounds reached")
                + "".join(f"; the data cannot tell: {t}" for t in loop.ties))
        return None
    diag = diagnose(model, now.idata, confirm_top=max(confirm_top, 1),
                    outdir=current.parent / "diagnosis", check_report=now.report, echo=loop.echo,
                    draft=draft)
    loop.echo(f"round {k}: {diag.verdict}")
    loop.echo(diag.table())
    if diag.winner is None:
        learned = _beyond(loop, k, current, model, now, diag) if loop.beyond is not None else None
        if isinstance(learned, Path):
            return learned
        _record(loop, k, current, now, "stopped: no addition, swap or drop improves the evidence; "
                + diag.verdict + (f"; {learned}" if learned else ""))
        return None
    beside = _beside(loop, k, current, model, now, diag)
    if isinstance(beside, Path):
        return beside
    _record(loop, k, current, now, diag.verdict + (f"; beside it, {beside}" if beside else ""))
    loop.kept = (model, now, diag)
    return _add_winner(loop, k, draft, model, now, diag.winner)


def _fit(loop: _Loop, k: int, current: Path, model):
    """The round's fit (from ``loop.start``), its check report and its evidence (``judge``)."""
    rdir = current.parent
    loop.echo(f"round {k}: fitting {current} ({loop.fit['backend']}, {loop.fit['chains']} chains)")
    idata = fit_with_fallback(model, **loop.fit, outdir=rdir / "fit", force=True,
                              start=start_setting(loop.start), quality=fit_quality)
    if "fit_note" in idata.attrs:
        loop.echo(f"round {k}: {idata.attrs['fit_note']}")
    report = check_model(model, idata, outdir=rdir / "check")
    now = judge(model, idata, report)
    z = "n/a" if now.log_z is None else f"{now.log_z:.1f}"
    loop.echo(f"round {k}: residual RMS {report.rms_sigma:.2f}σ, ELPD {now.elpd:.1f}, log Z {z}")
    caveat = loo_reliability(now.loo)
    if caveat:
        loop.echo(f"  note: {caveat}")
    for line in report.text().splitlines()[1:]:
        loop.echo("  " + line)
    return now


def _record(loop: _Loop, k: int, current: Path, now, verdict: str) -> None:
    ch = loop.change
    loop.rounds.append(Round(k, current, float(now.report.rms_sigma), now.elpd, ch["added"],
                             verdict, ch["action"], ch["replaced"], now.log_z,
                             bool(now.report.consistent)))


def _reexamine(loop: _Loop, k: int, current: Path, draft: Draft, now, due, effects) -> Path | None:
    """Re-examine ``due`` given the effects now present; the next round's file where a swap or
    a drop wins, else None."""
    loop.echo(f"round {k}: re-examining {', '.join(_name(c) for c in due)} given the effects now present")
    act, _, loop.ties = reexamine(now, draft, due, loop.echo)  # ties: said where the loop stops
    for c in due:
        if c.key in loop.revisable:
            loop.revisable[c.key] = (c, effects)
    if act is None:
        return None
    what = (f"swapped {_name(act.removed)} for {_name(act.added)}" if act.added
            else f"dropped {_name(act.removed)}")
    _record(loop, k, current, now, f"{what} ({act.comparison.text()})")
    loop.echo(f"round {k}: {what}")
    loop.revisable.pop(act.removed.key, None)
    loop.change = {"action": act.kind, "replaced": _ref(act.removed),
                   "added": _ref(act.added) if act.added else None}
    loop.start = point_estimate(act.judged.model, act.judged.idata)
    loop.misfit_expected = True
    loop.kept = (now, act)  # the next round's scene is act's: its compiled program is reused
    nxt = _write_round(loop.out, k + 1, act.draft.text(), loop.user_scene)
    if act.added:  # examined just now, against the same other effects
        loop.revisable[act.added.key] = (act.added, _effects(act.draft.scene))
    return nxt


def _add_winner(loop: _Loop, k: int, draft: Draft, model, now, w) -> Path:
    """Write the next round's scene: this one with the diagnosis's winner ``w`` added (its
    refit's scene), printed here once; the next fit starts where the refit ended."""
    cand: Candidate = w.candidate
    loop.change = {"action": "added", "added": {"effect": w.effect, "target": w.target},
                   "replaced": None}
    # the next round starts where the diagnosis's refit ended: this round's fit and the
    # added strength's fitted median (a start from the prior can settle in a poor basin of
    # a contact scene: billiards' second round ended at 7.85σ where the refit had 0.97σ)
    loop.start = {**point_estimate(model, now.idata),
                  **w.fitted.get("values", {w.fitted["name"]: w.fitted["median"]})}
    new = w.refit.draft if w.refit is not None else draft.with_candidate(cand)
    loop.misfit_expected = w.consistent_after is not True
    nxt = _write_round(loop.out, k + 1, new.text(), loop.user_scene)
    # chosen against these effects; a group with a strength per joint is one effect per
    # joint from now on (each may be swapped or dropped on its own), a shared one stays one;
    # a steady push on a touching body is re-examined next round against its contact sources
    for part in ([cand] if cand.shared else cand.parts()) if cand.kind == "effect" else ():
        fresh = w.refit is not None and sources_unexamined(new, part, w.refit.model, loop.start)
        loop.revisable[part.key] = (part, None if fresh else _effects(new.scene))
    loop.echo(f"round {k}: added `{w.snippet.strip()}` -> {nxt}")
    return nxt


def half_explained(k: int, w) -> bool:
    """The library's winner ``w`` of round ``k`` leaves the data half explained, so a learned
    force is fitted beside it: the library has had its first word (k >= 1: an effect it chose
    is in the scene already), the winner's refit still leaves systematic residuals, and it
    removes less than ``BESIDE_EXPLAINED`` of the excess misfit (RMS² - 1, noise units) left."""
    if k < 1 or w.consistent_after is not False or w.rms_after is None or w.rms_before is None:
        return False
    excess = w.rms_before ** 2 - 1.0
    return excess > 0 and (w.rms_before ** 2 - w.rms_after ** 2) < BESIDE_EXPLAINED * excess


def _beside(loop: _Loop, k: int, current: Path, model, now, diag) -> Path | str | None:
    """Where the winner only half explains the round (``half_explained``), learn a force beside
    it (``_beyond``, the winner as the library's side of the comparison); the next round's file
    where the law wins and ``allow_learned`` permits, else its words (None: not tried)."""
    if loop.beyond is None or not half_explained(k, diag.winner):
        return None
    loop.echo(f"round {k}: the library's winner leaves systematic residuals and explains less "
              f"than {BESIDE_EXPLAINED:.0%} of the misfit left: learning a force beside it")
    return _beyond(loop, k, current, model, now, diag, best=diag.winner)


def _beyond(loop: _Loop, k: int, current: Path, model, now, diag, best=None) -> Path | str:
    """Learn a force where the library explains nothing, or beside its winner ``best``
    (``loop.beyond``); the next round's file with its law where ``allow_learned`` permits, a
    law was found and the library's side does not win, else the verdict's words."""
    if best is None:
        rows = [r for r in diag.ranking if r.rms_after is not None]
        best = min(rows, key=lambda r: r.rms_after, default=None)
    library = None if best is None else {"effect": best.key, "rms": best.rms_after,
                                         "log_z": best.log_evidence}
    try:
        res = loop.beyond(model, now.idata, now.report, current.parent / "beyond",
                          library=library, echo=loop.echo)
    except PhysError as err:  # the library's verdict stands; say why nothing was learned
        loop.echo(f"round {k}: learning a force failed: {err.message}")
        return f"learning a force failed ({err.message})"
    if not (loop.allow_learned and res.proposed and res.scene_text and not res.library_wins):
        why = "" if not (res.proposed and res.scene_text) or res.library_wins else \
            " (not added: pass --allow-learned to add the distilled law)"
        return res.verdict + why
    _record(loop, k, current, now, res.verdict)
    loop.change = {"action": "learned", "replaced": None,
                   "added": {"effect": "distilled_law", "target": res.target,
                             "outside_library": True, "terms": res.law["terms"]}}
    loop.start = {}
    nxt = _write_round(loop.out, k + 1, res.scene_text, loop.user_scene)
    loop.echo(f"round {k}: added the distilled law (outside the library) -> {nxt}")
    return nxt


def _check_revisable(draft: Draft, cands) -> None:
    """A UsageError naming a ``--revise`` effect the scene does not have."""
    for c in cands:
        try:
            draft.remove(c)
        except (PhysError, KeyError, AttributeError):
            raise UsageError(f"--revise {c.key}: the scene has no effect {c.name} on "
                             f"{','.join(c.target)}", hint="give EFFECT@TARGET of an effect in "
                             "the scene, e.g. linear_drag@ball") from None


def _write_round(out: Path, index: int, text: str, scene_path: Path) -> Path:
    """Write round ``index``'s scene (and copies of the data beside it); its path."""
    nxt = out / f"round-{index}" / "scene.phys"
    io.write_text(nxt, text)
    _copy_data(scene_path.parent, nxt.parent, dirs=_recording_dirs(scene_path))
    return nxt


def _effects(scene) -> frozenset:
    """The scene's effects as (effect, target) pairs: what an examination was made against."""
    return frozenset((e.effect, tuple(e.target)) for e in scene.effects)


def _ref(c) -> dict:
    return {"effect": c.name, "target": ",".join(c.target)}


def _name(c) -> str:
    return f"{c.name} on {','.join(c.target)}"


def _copy_scene(src: Path, dst: Path) -> None:
    """Copy the user's scene and its data, so its relative data paths resolve from ``dst``."""
    io.write_text(dst, src.read_text(encoding="utf-8"))
    _copy_data(src.parent, dst.parent, skip=src.name, dirs=_recording_dirs(src))


def _recording_dirs(scene_path: Path) -> set[str]:
    """The folders beside a scene that hold its recordings (``experiments``): copied too."""
    ex = load(scene_path).experiments
    if ex is None:
        return set()
    return {r.folder.resolve().relative_to(scene_path.parent.resolve()).parts[0]
            for r in ex.recordings if r.folder.resolve() != scene_path.parent.resolve()}


def _copy_data(src_dir: Path, dst_dir: Path, skip: str = "", dirs=()) -> None:
    """Copy the measurement files beside a scene (CSV, JSON, images, meshes) and the folders
    ``dirs`` (frames, recordings) into ``dst_dir``."""
    for item in src_dir.iterdir():
        target = dst_dir / item.name
        if item.name == skip or target.exists():
            continue
        if item.is_file() and item.suffix.lower() in (".csv", ".json", ".png", ".jpg", ".obj", ".phys"):
            shutil.copy2(item, target)
        elif item.is_dir() and (item.name == "frames" or item.name in dirs):
            shutil.copytree(item, target)


def _write_summary(out: Path, rounds: list[Round]) -> None:
    data = {"rounds": [{"scene": str(r.scene), "rms_sigma": r.rms_sigma, "elpd": r.elpd,
                        "added": r.added, "action": r.action, "replaced": r.replaced,
                        "log_evidence": r.log_evidence, "consistent": r.consistent,
                        "verdict": r.verdict} for r in rounds]}
    io.write_json(out / "refine.json", data)
    lines = ["| round | scene | action | added | replaced | RMS (σ) | ELPD | log Z |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rounds:
        action, add, rep, rms, elpd, z = _cells(r)
        lines.append(f"| {r.index} | {r.scene} | {action} | {add} | {rep} | {rms} | {elpd} | {z} |")
    io.write_text(out / "refine.md", "\n".join(lines) + "\n")
    _plot(out, rounds)
    io.write_text(out / "index.html", _html(out, rounds))


def _cells(r: Round) -> tuple[str, ...]:
    """A round's action, added, replaced, RMS, ELPD and log Z as table text (refine.md, index.html)."""
    add = f"{r.added['effect']} on {r.added['target']}" if r.added else "—"
    rep = f"{r.replaced['effect']} on {r.replaced['target']}" if r.replaced else "—"
    z = "n/a" if r.log_evidence is None else f"{r.log_evidence:.1f}"
    return r.action or "—", add, rep, f"{r.rms_sigma:.2f}", f"{r.elpd:.1f}", z


def _html(out: Path, rounds: list[Round]) -> str:
    """refine.md's table as a page, with refine.png and links to each round's scene and check."""
    e = escape
    rows = []
    for r in rounds:
        scene = Path(os.path.relpath(Path(r.scene).resolve(), out.resolve())).as_posix()
        check = Path(scene).parent / "check" / "index.html"
        cells = "".join(f"<td>{e(c)}</td>" for c in _cells(r))
        rows.append(f"<tr><td>{r.index}</td><td><a href='{e(scene)}'>{e(scene)}</a></td>{cells}"
                    f"<td><a href='{e(check.as_posix())}'>check</a></td></tr>")
    return html_page("physdsl refine", [
        "<h1>Refine</h1>", f"<p>{e(rounds[-1].verdict)}</p>" if rounds else "",
        "<table id='rounds'><tr><th>round</th><th>scene</th><th>action</th><th>added</th>"
        "<th>replaced</th><th>RMS (σ)</th><th>ELPD</th><th>log Z</th><th>report</th></tr>",
        *rows, "</table>", "<img src='refine.png' alt='residual RMS and ELPD per round'>",
        "<p><a href='refine.json'>refine.json</a> · <a href='refine.md'>refine.md</a></p>"])


def _plot(out: Path, rounds: list[Round]) -> None:
    fig = new_figure(figsize=(6, 3.2))
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
    save_png(fig, out / "refine.png", dpi=100)
