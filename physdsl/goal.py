"""What should happen in a scene: the values of a ``goal`` (reach a point, hold a joint, spend
little effort), in SI, for ``physdsl control`` and ``physdsl design``.

Plain values, like ``scene.py``'s: the language builds them, ``physdsl.control`` turns them
into a cost. Every term is dimensionless once divided by its tolerance, so terms add.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .errors import Span


@dataclass(frozen=True)
class Reach:
    """A body's (or marker's) position at time ``at`` within ``within`` metres of ``point``."""

    target: str
    at: float  # s
    point: tuple[float, float, float]  # m
    within: float  # m
    span: Span | None = field(default=None, compare=False)  # where it was written, not what


@dataclass(frozen=True)
class Hold:
    """A hinge's angle (rad) or slider's displacement (m) within ``within`` of ``value`` over
    the window [start, end] (s)."""

    joint: str
    value: float
    start: float
    end: float
    within: float
    span: Span | None = field(default=None, compare=False)  # where it was written, not what


@dataclass(frozen=True)
class Effort:
    """``weight`` times the integral of u² over every chosen control sequence (per N² s, or
    per (N m)² s for torques): cheap pushes are preferred among those that meet the goal."""

    weight: float
    span: Span | None = field(default=None, compare=False)  # where it was written, not what


@dataclass(frozen=True)
class Goal:
    """The terms to meet and the unknowns to choose: ``decisions`` names unknowns besides the
    scene's unknown control sequences (which are always chosen), e.g. a launch velocity."""

    terms: tuple[Reach | Hold | Effort, ...]
    decisions: tuple[str, ...] = ()
    span: Span | None = field(default=None, compare=False)  # where it was written, not what
