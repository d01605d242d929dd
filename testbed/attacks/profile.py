"""Offset profiles shared by the adaptive attacks: a linear ramp in and out of a held lateral offset."""

from __future__ import annotations

import math

from testbed.errors import UserError


def ramp_fraction(elapsed: float, ramp: float) -> float:
    """0 before the start, rising linearly to 1 over `ramp` seconds (a step for ramp = 0)."""
    if elapsed < 0.0:
        return 0.0
    return 1.0 if ramp <= 0.0 else min(1.0, elapsed / ramp)


def check_finite(name: str, value: float, low: float | None = None) -> None:
    """UserError unless `value` is finite (and >= `low` when given)."""
    if not math.isfinite(value) or (low is not None and value < low):
        bound = f" >= {low}" if low is not None else ""
        raise UserError(f"{name} must be a finite number{bound}, got {value}")


def side_sign(direction: str, attack: str) -> float:
    """+1 for left, -1 for right; UserError for anything else."""
    if direction not in ("left", "right"):
        raise UserError(f"{attack} direction must be 'left' or 'right', got {direction!r}")
    return 1.0 if direction == "left" else -1.0
