"""Track seeds of the lane-detector data: the ones it trains on, the ones held out for evaluation (never
trained on), and the held-out layout driven for each preset × condition."""

from __future__ import annotations

from dataclasses import dataclass

from testbed.conditions import CONDITIONS
from tracks.presets import PRESETS

TRAIN_SEEDS = range(1, 9000)
HELD_OUT_SEEDS = range(9000, 9100)


@dataclass(frozen=True)
class Cell:
    """One held-out drive layout: a preset under a condition on its track seed."""

    preset: str
    condition: str
    track_seed: int


def _cells(presets: list[str], conditions: list[str], first: int, per_preset: int) -> list[Cell]:
    """Cells whose track seed is HELD_OUT_SEEDS[first + per_preset · preset index + condition index]."""
    for p in presets:
        if p not in PRESETS:
            raise ValueError(f"unknown preset {p!r}; known: {', '.join(PRESETS)}")
    for c in conditions:
        if c not in CONDITIONS:
            raise ValueError(f"unknown condition {c!r}; known: {', '.join(CONDITIONS)}")
    all_presets, all_conditions = list(PRESETS), list(CONDITIONS)
    return [Cell(p, c, HELD_OUT_SEEDS[first + per_preset * all_presets.index(p) + all_conditions.index(c)])
            for p in presets for c in conditions]


def cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """One held-out track seed per preset and condition (distinct layouts across conditions)."""
    return _cells(presets, conditions, 0, 10)


def check_cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """A second held-out track seed per preset and condition, none of them in `cells`: layouts for checking
    what was fitted on the `cells` ones."""
    return _cells(presets, conditions, 10 * len(PRESETS), len(CONDITIONS))
