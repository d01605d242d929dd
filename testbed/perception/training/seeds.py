"""Track seeds of the lane-detector data: the ones it trains on, the ones held out for evaluation (never
trained on), and the held-out layout driven for each preset × condition.

Seeds from 9000 up are never trained on; held-out datasets draw from the first hundred. The drive layouts of the
first six presets (in registry order) lie in that hundred, those of presets added after them beyond it, so a new
preset changes no earlier preset's layout."""

from __future__ import annotations

from dataclasses import dataclass

from testbed.conditions import CONDITIONS
from tracks.presets import PRESETS

TRAIN_SEEDS = range(1, 9000)
HELD_OUT_SEEDS = range(9000, 9100)
FIRST_PRESETS = 6
"""Presets whose drive layouts lie in HELD_OUT_SEEDS: 10 cell seeds each from 9000, then a check block from 9060."""
LATER_STRIDE = 20
"""Seeds per later preset beyond HELD_OUT_SEEDS: 10 for its cells, then 10 for its check cells."""


@dataclass(frozen=True)
class Cell:
    """One held-out drive layout: a preset under a condition on its track seed."""

    preset: str
    condition: str
    track_seed: int


def _seed(preset: str, condition: str, check: bool) -> int:
    """The held-out track seed of a preset × condition cell (of its check cell with `check`)."""
    i, c = list(PRESETS).index(preset), list(CONDITIONS).index(condition)
    if i < FIRST_PRESETS:
        index = (10 * FIRST_PRESETS + len(CONDITIONS) * i if check else 10 * i) + c
        return HELD_OUT_SEEDS[index]
    return HELD_OUT_SEEDS.stop + LATER_STRIDE * (i - FIRST_PRESETS) + (10 if check else 0) + c


def _cells(presets: list[str], conditions: list[str], check: bool) -> list[Cell]:
    for p in presets:
        if p not in PRESETS:
            raise ValueError(f"unknown preset {p!r}; known: {', '.join(PRESETS)}")
    for c in conditions:
        if c not in CONDITIONS:
            raise ValueError(f"unknown condition {c!r}; known: {', '.join(CONDITIONS)}")
    return [Cell(p, c, _seed(p, c, check)) for p in presets for c in conditions]


def cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """One held-out track seed per preset and condition (distinct layouts across conditions)."""
    return _cells(presets, conditions, check=False)


def check_cells(presets: list[str], conditions: list[str]) -> list[Cell]:
    """A second held-out track seed per preset and condition, none of them in `cells`: layouts for checking
    what was fitted on the `cells` ones."""
    return _cells(presets, conditions, check=True)
