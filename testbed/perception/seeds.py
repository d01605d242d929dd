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


def _check(presets: list[str], conditions: list[str]) -> None:
    for p in presets:
        if p not in PRESETS:
            raise ValueError(f"unknown preset {p!r}; known: {', '.join(PRESETS)}")
    for c in conditions:
        if c not in CONDITIONS:
            raise ValueError(f"unknown condition {c!r}; known: {', '.join(CONDITIONS)}")


def cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """One held-out track seed per preset and condition (distinct layouts across conditions)."""
    _check(presets, conditions)
    all_conditions = list(CONDITIONS)
    return [Cell(p, c, HELD_OUT_SEEDS[10 * list(PRESETS).index(p) + all_conditions.index(c)])
            for p in presets for c in conditions]


def check_cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """A second held-out track seed per preset and condition, none of them in `cells`: layouts for checking
    what was fitted on the `cells` ones."""
    _check(presets, conditions)
    first = 10 * len(PRESETS)
    all_conditions = list(CONDITIONS)
    return [Cell(p, c, HELD_OUT_SEEDS[first + len(all_conditions) * list(PRESETS).index(p)
                                      + all_conditions.index(c)])
            for p in presets for c in conditions]
