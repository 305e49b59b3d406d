"""Numbers as .phys literal text: short significant-digit numbers, values with their unit."""
from __future__ import annotations

import math

import numpy as np


def number(x: float, sig: int = 6) -> str:
    """A float as short .phys number text with ``sig`` significant digits (no exponent sign noise)."""
    x = float(x)
    if x == 0 or not math.isfinite(x):
        return "0" if x == 0 else repr(x)
    text = f"{x:.{sig}g}"
    if "e" in text:
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def with_unit(text: str, unit: str, atom: bool = False) -> str:
    """``text`` in SI followed by ``unit`` (nothing for dimensionless ``1``)."""
    if unit in ("", "1"):
        return text
    return f"{text} {unit}" if atom else f"({text}) {unit}"


def literal(value, unit: str) -> str:
    """A value in SI as literal text with its unit: ``0.612 m``, ``(1, 2, 3) m/s``."""
    arr = np.asarray(value, dtype=float)
    text = number(float(arr), 10) if arr.ndim == 0 else \
        "(" + ", ".join(number(float(v), 10) for v in arr.reshape(-1)) + ")"
    return text if unit in ("", "1") else f"{text} {unit}"
