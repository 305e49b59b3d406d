"""A fit written as .phys text: a distribution call per marginal, and for a correlated block
each field's expression ``transform(mean + L_i . z)`` in the standard-normal params (SI + unit)."""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .fit_distributions import Block, Marginal, ProtoFit
from .literals import number, with_unit
from .support import Support


def _digits(mean: float, sd: float) -> int:
    """Significant digits so that rounding ``mean`` moves it by well under 1% of ``sd``."""
    if sd <= 0:
        return 12
    ratio = abs(mean) / sd if mean else 1.0
    return int(min(max(math.ceil(math.log10(max(ratio, 1.0))) + 4, 4), 15))


def _values(arr, shape, fmt) -> str:
    """A scalar or a vector literal (``(a, b, c)``) of flat values ``arr``."""
    items = [fmt(v) for v in np.reshape(arr, -1)]
    return items[0] if not shape else "(" + ", ".join(items) + ")"


def marginal_text(m: Marginal, unit: str) -> str:
    """The distribution call for a marginal, e.g. ``log_normal(-0.5108, 0.0204)``."""
    a = m.args
    if m.dist == "categorical":
        return "categorical(probs: (" + ", ".join(number(p, 6) for p in a["probs"]) + "))"
    if m.dist == "beta":
        return (f"beta({_values(a['concentration1'], m.shape, number)}, "
                f"{_values(a['concentration0'], m.shape, number)})")
    locs, scales = np.reshape(a["loc"], -1), np.reshape(a["scale"], -1)
    digits = max(_digits(lo, s) for lo, s in zip(locs, scales))
    loc = _values(locs, m.shape, lambda v: number(v, digits))
    scale = _values(scales, m.shape, lambda v: number(v, 5))
    if m.dist == "log_normal":  # arguments are of log(value / 1 SI unit): dimensionless
        return f"log_normal({loc}, {scale})"
    if m.dist == "normal":
        return f"normal({with_unit(loc, unit, True)}, {with_unit(scale, unit, True)})"
    if m.dist == "truncated_normal":
        parts = [with_unit(loc, unit, True), with_unit(scale, unit, True)]
        for key in ("low", "high"):
            if key in a:
                parts.append(f"{key}: " + with_unit(_values(a[key], m.shape, lambda v: number(v, 12)),
                                                   unit, True))
        return "truncated_normal(" + ", ".join(parts) + ")"
    raise ValueError(f"no text for distribution {m.dist}")


def transform_text(support: Support, inner: str) -> str:
    """The bijection from the real line onto ``support`` applied to expression text ``inner``."""
    if support.kind == "real":
        return inner
    if support.kind == "lower":
        low = float(support.low)
        return f"exp({inner})" if low == 0 else f"{number(low, 12)} + exp({inner})"
    if support.kind == "upper":
        return f"{number(float(support.high), 12)} - exp({inner})"
    if support.kind == "interval":
        low, high = float(support.low), float(support.high)
        span = f"{number(high - low, 12)} / (1 + exp(-({inner})))"
        return span if low == 0 else f"{number(low, 12)} + {span}"
    raise ValueError(f"no transform for a {support.kind} support")


def block_texts(block: Block, z_names: Sequence[str], fit: ProtoFit,
                units: Mapping[str, str]) -> dict[str, str]:
    """Value text of every unknown of a correlated block: ``transform(mean + L_i . z)``."""
    comps: dict[str, dict[int, str]] = {}
    for k, (name, i) in enumerate(block.components):
        sd = float(np.sqrt(np.sum(block.chol[k] ** 2)))
        terms = [number(block.mean[k], _digits(block.mean[k], sd))]
        for j in range(k + 1):
            c = float(block.chol[k, j])
            if c == 0.0:
                continue
            sign = "-" if c < 0 else "+"
            terms.append(f"{sign} {number(abs(c), 5)} * {z_names[j]}")
        inner = " ".join(terms)
        comps.setdefault(name, {})[i] = transform_text(fit.supports[name].component(i), inner)
    out = {}
    for name, parts in comps.items():
        shape = fit.shapes[name]
        if shape:
            text = "(" + ", ".join(parts[i] for i in range(int(np.prod(shape)))) + ")"
            out[name] = with_unit(text, units.get(name, "1"), atom=True)
        else:
            out[name] = with_unit(parts[0], units.get(name, "1"))
    return out
