"""Search spaces of attack families: the parameters a worst-case search varies and their ranges.

A family's space is a tuple of dimensions; the search samples each by name (prefixed with the family) and
passes the values as the attack's scenario table. Parameters not in the space keep their defaults.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FloatDim:
    """A real parameter in [low, high] (log-uniform with `log`: ramps, where one control tick differs from a
    second)."""

    name: str
    low: float
    high: float
    log: bool = False


@dataclass(frozen=True)
class IntDim:
    """An integer parameter in [low, high]."""

    name: str
    low: int
    high: int


@dataclass(frozen=True)
class ChoiceDim:
    """One of a few values."""

    name: str
    choices: tuple[str | float | int | bool, ...]


Dim = FloatDim | IntDim | ChoiceDim
START = FloatDim("start", 8.0, 30.0)
"""Attack start times the search tries (s): after the MSF has settled, well before a minute's run ends."""
SIDE = ChoiceDim("direction", ("left", "right"))
