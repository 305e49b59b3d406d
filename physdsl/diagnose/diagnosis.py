"""What a diagnosis says: a row per candidate (``Ranked``: its score test, and for the refitted
its comparison with the scene as it is), the verdict, and their text forms (the table,
diagnosis.md, diagnosis.json, fix.phys)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .. import io
from .candidates import Candidate
from .check import clean


@dataclass(frozen=True, eq=False)
class Refit:
    """A candidate's refit: the scene with it added (a ``edits.Draft``) and its compiled Model.
    Kept so the winner's scene needs no second edit, and so later Models of the same structure
    (the next round's fit, a drop or swap that gives this scene back) reuse its compiled
    program. Shared, not copied: a copy of a row refers to the same refit."""

    draft: object
    model: object

    def __deepcopy__(self, memo):
        return self


@dataclass
class Ranked:
    rank: int
    kind: str
    effect: str
    target: str
    statistic: float
    p_value: float
    dof: int
    log_p: float = 0.0
    z: float | None = None
    estimate: float | None = None
    confirmed: bool | None = None
    delta_elpd: float | None = None
    delta_elpd_se: float | None = None
    delta_lfo: float | None = None
    rms_before: float | None = None
    rms_after: float | None = None
    fitted: dict | None = None
    snippet: str | None = None
    same_as: str | None = None  # "effect@target" of a better ranked candidate that acts alike
    tied_with: str | None = None  # "effect@target" of the winner whose evidence this one ties
    log_evidence: float | None = None  # Laplace log marginal likelihood of the refit (None: n/a)
    model_prob: float | None = None  # posterior probability among the confirmed (equal odds)
    consistent_after: bool | None = None  # the refit's check finds no systematic residual
    elpd_reliable: bool = True  # the refit's PSIS-LOO is evidence (``loo.unreliable``)
    note: str = ""
    # pointwise differences to the fit without the effect (LOO per measurement time; log
    # predictive density per time after the cut-off): the standard errors of ties
    elpd_points: np.ndarray | None = field(default=None, repr=False)
    lfo_points: np.ndarray | None = field(default=None, repr=False)
    candidate: Candidate | None = field(default=None, repr=False)  # what was scored
    refit: Refit | None = field(default=None, repr=False)  # where it was refitted

    @property
    def key(self) -> str:
        """``effect@target``, as ``same_as`` and ``tied_with`` name a row."""
        return f"{self.effect}@{self.target}"

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.name not in _NOT_IN_JSON}


_NOT_IN_JSON = ("elpd_points", "lfo_points", "candidate", "refit")


@dataclass
class Diagnosis:
    ranking: list[Ranked]
    verdict: str
    winner: Ranked | None
    rms_sigma: float
    seconds: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return clean({"verdict": self.verdict, "rms_sigma": self.rms_sigma,
                      "winner": self.winner.to_dict() if self.winner else None,
                      "ranking": [r.to_dict() for r in self.ranking], "seconds": self.seconds})

    def table(self) -> str:
        head = (f"{'#':>2} {'candidate':<34} {'score':>9} {'p-value':>9} "
                f"{'ΔELPD ± se':>16} {'ΔLFO':>8} {'P(model)':>8} {'RMS before → after':>20}")
        lines = [head, "-" * len(head)]
        for r in self.ranking:
            de = (f"{r.delta_elpd:+.1f} ± {r.delta_elpd_se:.1f}" if r.delta_elpd is not None else "")
            rms = (f"{r.rms_before:.2f}σ → {r.rms_after:.2f}σ" if r.rms_after is not None else "")
            name = f"{r.effect} on {r.target}" if r.kind == "effect" else f"sensor {r.effect} on {r.target}"
            lfo = f"{r.delta_lfo:+.1f}" if r.delta_lfo is not None else ""
            prob = ("" if not r.confirmed else "n/a" if r.model_prob is None else f"{r.model_prob:.3g}")
            lines.append(f"{r.rank:>2} {name:<34} {r.statistic:>9.1f} {p_value_text(r):>9} {de:>16} "
                         f"{lfo:>8} {prob:>8} {rms:>20}")
        return "\n".join(lines)

    def markdown(self) -> str:
        lines = ["# Diagnosis", "", self.verdict, "", "```", self.table(), "```"]
        if self.winner and self.winner.snippet:
            lines += ["", "Add to the scene:", "", "```", self.winner.snippet, "```"]
        return "\n".join(lines) + "\n"

    def write(self, outdir) -> None:
        """diagnosis.json, diagnosis.md and (with a winner) fix.phys in ``outdir``."""
        out = io.prepare_outdir(outdir, force=True)
        io.write_json(out / "diagnosis.json", self.to_dict())
        io.write_text(out / "diagnosis.md", self.markdown())
        if self.winner is not None and self.winner.snippet:
            io.write_text(out / "fix.phys", self.winner.snippet + "\n")


def p_value_text(r: Ranked) -> str:
    """The p-value for a table; one that underflows shows its order of magnitude from log p."""
    if r.p_value > 0 or r.log_p == 0.0:
        return f"{r.p_value:.2g}"
    return f"<1e{int(np.floor(r.log_p / np.log(10))) + 1}"

