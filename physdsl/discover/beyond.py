"""Beyond the library: where no library effect brings the residuals to the noise, learn the
missing force on the body or joint the check points at, distil it into a law, refit the law
as ordinary unknowns, and compare the evidence of the library's best, the learned force and the
law. Nothing here edits a scene: the result says what would be added (``Beyond.scene_text``)
and ``refine --allow-learned`` decides."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import io
from ..diagnose.evidence import STRONG, laplace_log_evidence
from ..diagnose.workflow import point_estimate
from ..errors import UsageError
from .distil import MAX_TERMS, learned_samples, supports
from .law import Law, refit_law
from .learn import HIDDEN, Fit, fit_residual, fitted, target_kind
from .phys_text import declaration
from .plot import plot_learned
from .terms import TERMS, coefficient_unit

WITHIN_NOISE = 1.2  # RMS (noise units) a law must reach to count as explaining the data
MAX_REFITS = 4  # supports refitted as laws, sparsest first
LIBRARY_TERMS = {"v", "v_speed", "q", "qdot", "sign_qdot"}  # linear/quadratic drag, joint laws


@dataclass
class Beyond:
    """What reaching beyond the library found (``to_dict``: beyond.json)."""

    target: str
    kind: str
    rms_before: float
    rms_learned: float
    log_z_before: float | None
    log_z_learned: float | None
    proposed: bool  # the learned force explains enough to be worth a law
    verdict: str
    library: dict | None = None  # the library's best refit: effect, rms, log_z
    law: dict | None = None  # terms, coefficients, rms, log_z, in_library
    laws_tried: list = field(default_factory=list)
    law_phys: str | None = None  # the declaration + use, ready for a scene
    scene_text: str | None = None  # the round's scene with the law added
    files: dict = field(default_factory=dict)
    outside_library: bool = True
    library_wins: bool = False  # the library's effect explains the data as well: nothing is added

    def to_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "scene_text"}


def pointed_target(scene, report) -> str:
    """The body or joint whose observation misses most (the check's worst observable)."""
    names = {b.name for b in scene.bodies} | {j.name for j in scene.joints}
    worst = sorted(report.observables, key=lambda o: -o.rms_sigma)
    for o in worst:
        owner = o.name.split(".")[0]
        if owner in names:
            return owner
    raise UsageError("the check points at no body or joint a residual force could act on",
                     hint="pass target= (a moving body, a hinge or a slider)")


def _log_z(fit: Fit) -> float | None:
    if fit.log_z is not None:
        return fit.log_z
    try:
        return laplace_log_evidence(fit.model, fit.idata)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return None  # no Laplace evidence here: n/a


def _gain(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None else a - b


def learned_helps(base: Fit, learned: Fit, z0, z1) -> bool:
    """The learned force explains a real part of the misfit: the RMS falls by 10% or more and
    the evidence (where both are known) rises strongly."""
    gain = _gain(z1, z0)
    return learned.rms < 0.9 * base.rms and (gain is None or gain > STRONG)


def choose_law(base: Fit, learned: Fit, target: str, kind: str, center, echo) -> list[Law]:
    """Refit the sparsest supports of the learned force as laws, stopping at the first within
    the noise; all those tried, the last the chosen one when one is within the noise."""
    s = learned_samples(learned, target, kind)
    tried: list[Law] = []
    limit = max(WITHIN_NOISE, learned.rms)
    for sup in supports(s)[:MAX_REFITS]:
        law = refit_law(base, target, kind, sup, center)
        echo(f"  law {' + '.join(sup.terms)}: RMS {law.fit.rms:.2f}σ")
        tried.append(law)
        if law.fit.rms <= limit:
            break
    return tried


def _law_dict(law: Law, log_z) -> dict:
    return {"terms": list(law.terms), "coefficients": law.coefficients, "rms": law.fit.rms,
            "log_z": log_z, "in_library": set(law.terms) <= LIBRARY_TERMS}


def law_phys(law: Law, target: str, kind: str, center) -> str:
    """The law's declaration and its use with the fitted coefficients (medians, SI)."""
    decl = declaration(kind, list(law.terms),
                       {t: (0.0, 5 * max(abs(c[0]), 1e-12)) for t, c in law.coefficients.items()},
                       center, f"distilled by physdsl.discover from a residual force on {target}: "
                       "outside the library")
    fields = "  ".join(f"{t}: {c[0]:.6g} {coefficient_unit(TERMS[t], kind)}"
                       for t, c in law.coefficients.items())
    return decl + f"# its use, coefficients as fitted (leave them out to fit them):\n" \
                  f"# effect distilled_law on {target} {{ {fields} }}\n"


def library_wins(lib: dict | None, law: dict | None) -> bool:
    """The library's effect stands against the law (Honesty: the library wins ties): it reaches
    the noise and no law beats it, or the law's Laplace evidence is not better by more than
    ``STRONG``; where an evidence is n/a, the law must reach the noise where the library does not."""
    if lib is None or lib.get("rms") is None:
        return False
    if law is None:
        return lib["rms"] <= WITHIN_NOISE
    if lib.get("log_z") is not None and law.get("log_z") is not None:
        return lib["log_z"] >= law["log_z"] - STRONG
    return lib["rms"] <= WITHIN_NOISE or law["rms"] > WITHIN_NOISE


def verdict(res: Beyond) -> str:
    """One paragraph: what the learned force explains, the law, the comparison."""
    lib = res.library
    head = (f"outside the library: a learned force on {res.target} brings the residual RMS "
            f"{res.rms_before:.2f}σ -> {res.rms_learned:.2f}σ")
    if library_wins(lib, res.law):
        z = "" if res.law is None or lib.get("log_z") is None or res.law.get("log_z") is None \
            else f", log Z {lib['log_z']:.1f} vs the law's {res.law['log_z']:.1f}"
        return (f"the library's {lib['effect']} explains the data as well ({lib['rms']:.2f}σ{z}): "
                f"it wins; nothing learned is proposed ({head})")
    if not res.proposed:
        return f"nothing learned is proposed: {head}, too little to be worth a law"
    if res.law is None:
        return f"{head}; no sparse law of the dictionary reaches the noise"
    law = res.law
    words = " + ".join(law["terms"])
    extra = " (terms the library holds)" if law["in_library"] else ""
    against = "" if lib is None or lib.get("rms") is None else (
        f"; against the library's {lib['effect']}: {lib['rms']:.2f}σ"
        + ("" if lib.get("log_z") is None else f", log Z {lib['log_z']:.1f}"))
    return (f"{head}; distilled law: {words}{extra}, refitted to {law['rms']:.2f}σ "
            f"(log Z {law['log_z'] if law['log_z'] is None else round(law['log_z'], 1)} vs "
            f"learned {res.log_z_learned if res.log_z_learned is None else round(res.log_z_learned, 1)})"
            f"{against}")


def beyond_library(model, idata, report, outdir, *, target: str | None = None,
                   hidden: int = HIDDEN, center=(0.0, 0.0, 0.0), library: dict | None = None,
                   seed: int = 0, echo=print) -> Beyond:
    """Learn a residual force on ``target`` (default: where the check points), distil it and
    refit the law; write beyond.json, law.phys, scene.phys and learned.png into ``outdir``.
    ``library``: the library's best refit ({effect, rms, log_z}), for the comparison."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    base = fitted(model, idata) if report is None else Fit(model, idata, report,
                                                             point_estimate(model, idata))
    target = target or pointed_target(model.scene, base.report)
    kind = target_kind(model.scene, target)
    echo(f"beyond the library: learning a residual force on {target} ({kind})")
    learned = fit_residual(base, target, hidden, center, seed)
    z0, z1 = _log_z(base), _log_z(learned)
    res = Beyond(target, kind, base.rms, learned.rms, z0, z1, learned_helps(base, learned, z0, z1),
                 "", library)
    law = None
    if res.proposed:
        tried = choose_law(base, learned, target, kind, center, echo)
        res.laws_tried = [{"terms": list(t.terms), "rms": t.fit.rms} for t in tried]
        within = [t for t in tried if t.fit.rms <= max(WITHIN_NOISE, learned.rms)]
        law = within[0] if within else min(tried, key=lambda t: t.fit.rms)
        res.law = _law_dict(law, _log_z(law.fit))
        res.law_phys = law_phys(law, target, kind, center)
        res.scene_text = law.text
        res.files["law"] = str(io.write_text(outdir / "law.phys", res.law_phys))
        res.files["scene"] = str(io.write_text(outdir / "scene.phys", law.text))
    res.library_wins = library_wins(library, res.law)
    res.verdict = verdict(res)
    s = learned_samples(learned, target, kind)
    coefs = None if law is None else {t: c[0] for t, c in law.coefficients.items()}
    res.files["plot"] = str(plot_learned(s, coefs, f"learned force on {target} (outside the "
                                         "library)", outdir / "learned.png"))
    io.write_json(outdir / "beyond.json", res.to_dict())
    echo(res.verdict)
    return res
