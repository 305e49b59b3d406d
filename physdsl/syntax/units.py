"""Units: a small dimension algebra over the 7 SI base exponents plus angle, and SI conversion.

Angle is dimensionless for checking (rad/s and Hz agree) but tracked so messages can say
"an angular velocity". Units are written as one token: ``m/s^2``, ``N*m*s/rad``, ``kg/m^3``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction

BASES = ("m", "kg", "s", "A", "K", "mol", "cd", "rad")  # the last is angle


@dataclass(frozen=True)
class Dim:
    """Exponents of (m, kg, s, A, K, mol, cd) and of angle (ignored when comparing)."""

    exps: tuple[Fraction, ...] = (Fraction(0),) * 8

    @staticmethod
    def of(**kw) -> "Dim":
        return Dim(tuple(Fraction(kw.get(b, 0)) for b in BASES))

    def __mul__(self, other: "Dim") -> "Dim":
        return Dim(tuple(a + b for a, b in zip(self.exps, other.exps)))

    def __truediv__(self, other: "Dim") -> "Dim":
        return Dim(tuple(a - b for a, b in zip(self.exps, other.exps)))

    def __pow__(self, k) -> "Dim":
        if k == 1:
            return self
        k = Fraction(int(k)) if float(k).is_integer() else Fraction(k).limit_denominator(1000)
        return Dim(tuple(a * k for a in self.exps))

    def same(self, other: "Dim") -> bool:
        """Equal ignoring angle."""
        return self.exps[:7] == other.exps[:7]

    @property
    def dimensionless(self) -> bool:
        return all(e == 0 for e in self.exps[:7])

    @property
    def is_angle(self) -> bool:
        return self.dimensionless and self.exps[7] == 1

    def name(self) -> str:
        """Words for messages: 'a velocity (m/s)'."""
        for dim, words in _NAMED:
            if dim == self:
                return f"{words} ({self.si_text()})"
        for dim, words in _NAMED:
            if dim.same(self) and not self.dimensionless:
                return f"{words} ({self.si_text()})"
        if self.dimensionless:
            return "a plain number (no unit)"
        return f"a quantity in {self.si_text()}"

    def si_text(self) -> str:
        """SI unit text of this dimension (``kg``, ``m/s``, ``N*m*s/rad``, ``1``)."""
        for dim, text in _PREFERRED:
            if dim == self:
                return text
        num, den = [], []
        for base, e in zip(BASES, self.exps):
            if e == 0:
                continue
            target = num if e > 0 else den
            a = abs(e)
            target.append(base if a == 1 else f"{base}^{a}" if a.denominator == 1 else f"{base}^({a})")
        text = "*".join(num) or "1"
        if den:
            text += "/" + "/".join(den)
        return text


DIMLESS = Dim()
LENGTH = Dim.of(m=1)
MASS = Dim.of(kg=1)
TIME = Dim.of(s=1)
ANGLE = Dim.of(rad=1)
VEL = Dim.of(m=1, s=-1)
ACC = Dim.of(m=1, s=-2)
ANGVEL = Dim.of(rad=1, s=-1)
FREQ = Dim.of(s=-1)
FORCE = Dim.of(kg=1, m=1, s=-2)
TORQUE = Dim.of(kg=1, m=2, s=-2)
DENSITY = Dim.of(kg=1, m=-3)
INERTIA = Dim.of(kg=1, m=2)

# (scale to SI, dimension) of unprefixed units
_BASE_UNITS: dict[str, tuple[float, Dim]] = {
    "m": (1.0, LENGTH),
    "g": (1e-3, MASS),
    "s": (1.0, TIME),
    "A": (1.0, Dim.of(A=1)),
    "K": (1.0, Dim.of(K=1)),
    "mol": (1.0, Dim.of(mol=1)),
    "cd": (1.0, Dim.of(cd=1)),
    "rad": (1.0, ANGLE),
    "sr": (1.0, Dim.of(rad=2)),
    "N": (1.0, Dim.of(kg=1, m=1, s=-2)),
    "J": (1.0, Dim.of(kg=1, m=2, s=-2)),
    "W": (1.0, Dim.of(kg=1, m=2, s=-3)),
    "Pa": (1.0, Dim.of(kg=1, m=-1, s=-2)),
    "Hz": (1.0, Dim.of(s=-1)),
}
# units that take no prefix
_PLAIN_UNITS: dict[str, tuple[float, Dim]] = {
    "deg": (math.pi / 180.0, ANGLE),
    "rev": (2 * math.pi, ANGLE),
    "min": (60.0, TIME),
    "h": (3600.0, TIME),
    "rpm": (2 * math.pi / 60.0, Dim.of(rad=1, s=-1)),
    "px": (1.0, DIMLESS),
    "percent": (0.01, DIMLESS),
}
_PREFIXES = {"n": 1e-9, "u": 1e-6, "µ": 1e-6, "m": 1e-3, "c": 1e-2, "d": 1e-1, "k": 1e3,
             "M": 1e6, "G": 1e9, "h": 1e2}

_NAMED = [
    (LENGTH, "a length"), (MASS, "a mass"), (TIME, "a time"), (ANGLE, "an angle"),
    (Dim.of(m=1, s=-1), "a velocity"), (Dim.of(m=1, s=-2), "an acceleration"),
    (Dim.of(rad=1, s=-1), "an angular velocity"), (Dim.of(s=-1), "a frequency"),
    (Dim.of(kg=1, m=1, s=-2), "a force"), (Dim.of(kg=1, m=2, s=-2, rad=-1), "a torque"),
    (Dim.of(kg=1, m=2, s=-2), "a torque or energy"), (Dim.of(kg=1, m=-3), "a density"),
    (Dim.of(kg=1, m=2), "a moment of inertia"), (Dim.of(kg=1, s=-1), "a linear drag coefficient"),
    (Dim.of(kg=1, m=-1), "a quadratic drag coefficient"), (Dim.of(kg=1, s=-2), "a stiffness"),
    (Dim.of(m=2), "an area"), (Dim.of(m=3), "a volume"), (DIMLESS, "a plain number"),
]
_PREFERRED = [
    (DIMLESS, "1"), (Dim.of(kg=1, m=1, s=-2), "N"), (Dim.of(kg=1, m=2, s=-2), "N*m"),
    (Dim.of(kg=1, m=2, s=-2, rad=-1), "N*m/rad"), (Dim.of(kg=1, s=-2), "N/m"),
    (Dim.of(kg=1, s=-1), "kg/s"), (Dim.of(kg=1, m=-1), "kg/m"), (Dim.of(kg=1, m=-3), "kg/m^3"),
    (Dim.of(m=1, s=-2), "m/s^2"), (Dim.of(m=1, s=-1), "m/s"), (Dim.of(rad=1, s=-1), "rad/s"),
    (Dim.of(kg=1, m=2, s=-1, rad=-1), "N*m*s/rad"), (Dim.of(kg=1, m=2), "kg*m^2"),
    (Dim.of(kg=1, m=2, s=-1), "N*m*s"), (Dim.of(s=-1), "1/s"), (Dim.of(kg=1, m=1, s=-1), "N*s"),
    (Dim.of(kg=1, m=2, s=-1, rad=-1), "N*m*s/rad"),
]


class UnitError(ValueError):
    """A unit text that cannot be read; ``part`` names the offending piece."""

    def __init__(self, message: str, part: str):
        super().__init__(message)
        self.part = part


def lookup(symbol: str) -> tuple[float, Dim]:
    """Scale and dimension of one unit symbol, with an optional SI prefix."""
    if symbol in _PLAIN_UNITS:
        return _PLAIN_UNITS[symbol]
    if symbol in _BASE_UNITS:
        return _BASE_UNITS[symbol]
    if symbol == "kg":
        return 1.0, MASS
    for p, scale in _PREFIXES.items():
        if symbol.startswith(p) and symbol[len(p):] in _BASE_UNITS:
            base_scale, dim = _BASE_UNITS[symbol[len(p):]]
            return scale * base_scale, dim
    raise UnitError(f"unknown unit '{symbol}'", symbol)


_PART = re.compile(r"([*/]?)([A-Za-z_µ][A-Za-z0-9_]*)(?:\^(-?[0-9]+))?")


def parse_unit(text: str) -> tuple[float, Dim]:
    """Scale to SI and dimension of a unit text like ``kg*m^2/s``; ``1`` is dimensionless."""
    if text.strip() == "1":
        return 1.0, DIMLESS
    scale, dim, pos = 1.0, DIMLESS, 0
    if text.startswith("1/"):
        text, pos, first_div = text, 1, True
    while pos < len(text):
        m = _PART.match(text, pos)
        if not m or (pos == 0 and m.group(1)):
            raise UnitError(f"cannot read unit '{text}'", text)
        op, sym, power = m.group(1), m.group(2), int(m.group(3) or 1)
        s, d = lookup(sym)
        s, d = s**power, d**power
        if op == "/":
            scale, dim = scale / s, dim / d
        else:
            scale, dim = scale * s, dim * d
        pos = m.end()
    return scale, dim


def known_units() -> list[str]:
    """Unit symbols for 'did you mean' suggestions."""
    names = list(_BASE_UNITS) + list(_PLAIN_UNITS) + ["kg"]
    names += [p + b for b in ("m", "g", "s", "N", "Pa", "Hz", "rad") for p in ("m", "c", "k", "u")]
    return sorted(set(names))


def example_text(dim: Dim) -> str:
    """A unit to suggest for a dimension (its SI text)."""
    return dim.si_text()
